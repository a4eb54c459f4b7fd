"""
Running the emulator: the inputs it runs on and the runs themselves.

Input profiles (rate, temperature, specific force against time), offline
runs of :class:`gyro_emulator.sensor.model.GyroModel` written as CSV or bags,
the driver under the ROS node (:mod:`.driver`: from times and inputs to the
samples to publish, with its input checks, sample clock, input timeline,
block stepper and fault schedules) and synthetic measured records with
hidden effects. Everything here is testable with numpy alone: no ROS imports.
"""
