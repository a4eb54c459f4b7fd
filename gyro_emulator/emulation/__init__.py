"""
Running the emulator: the inputs it runs on and the runs themselves.

Input profiles (rate, temperature, specific force against time), offline
runs of :class:`gyro_emulator.sensor.model.GyroModel` written as CSV or bags,
the streaming machinery a node drives (input checks, the input timeline, the
block stepper, fault schedules) and synthetic measured records with hidden
effects. Everything here is testable with numpy alone: no ROS imports.
"""
