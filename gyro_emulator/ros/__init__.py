"""
The ROS 2 edge of gyro_emulator: the only modules that import rclpy.

``node`` is the emulated gyro driver (``ros2 run gyro_emulator node``) and
``scenario`` plays rate and temperature profiles (and fault schedules) onto
it. The node is thin over a plain-Python driver
(:mod:`gyro_emulator.emulation.driver`: due samples, inputs, stamps, faults,
the parameter transaction, the diagnostics counters): it declares its
parameters through ``params``, takes its commands through ``intake``,
publishes through ``outputs`` and ``diagnostics`` and prints ``--help`` from
``node_help``. The scenario file ``scenario`` plays lives in
:mod:`gyro_emulator.emulation` too. ``gyro_array`` runs redundant
instances. ``recorder``, ``replay`` and ``codec`` record and play back MCAP
bags (``program``: what the recorder and replay programs share;
``spinning``: how every program spins and stops). ``gyro_array`` is plain
Python, so it tests without a ROS graph.
"""
