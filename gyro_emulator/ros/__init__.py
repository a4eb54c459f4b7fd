"""
The ROS 2 edge of gyro_emulator: the only modules that import rclpy.

``node`` is the emulated gyro driver (``ros2 run gyro_emulator node``) and
``scenario`` plays rate and temperature profiles (and fault schedules) onto
it; ``params``, ``inputs`` and ``diagnostics`` are their parameter table,
command validation and diagnostics bookkeeping. The node takes its commands
through ``intake``, publishes through ``outputs``, follows a simulator's
stamps with ``imu_input``, injects faults with ``fault_injection`` and
prints ``--help`` from ``node_help``; ``gyro_array`` runs redundant
instances. ``recorder``, ``replay`` and
``codec`` record and play back MCAP bags (``program``: what the recorder and
replay programs share). ``inputs``, ``imu_input``, ``fault_injection``,
and ``gyro_array`` are plain Python, so they test without a ROS graph; the
scenario file ``scenario`` plays is :mod:`gyro_emulator.emulation.scenario`.
"""
