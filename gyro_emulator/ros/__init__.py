"""
The ROS 2 edge of gyro_emulator: the only modules that import rclpy.

``node`` is the emulated gyro driver (``ros2 run gyro_emulator node``) and
``scenario`` plays rate and temperature profiles (and fault schedules) onto
it; ``params`` and ``diagnostics`` are their parameter table and
diagnostics bookkeeping. The node takes its commands through ``intake``,
publishes through ``outputs`` and prints ``--help`` from ``node_help``; the
plain-Python machinery it drives (command checks, a simulator's input time
line, the block stepper, the fault state) and the scenario file ``scenario``
plays live in :mod:`gyro_emulator.emulation`. ``gyro_array`` runs redundant
instances. ``recorder``, ``replay`` and ``codec`` record and play back MCAP
bags (``program``: what the recorder and replay programs share;
``spinning``: how every program spins and stops). ``gyro_array`` is plain
Python, so it tests without a ROS graph.
"""
