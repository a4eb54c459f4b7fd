"""
The ROS 2 edge of gyro_emulator: the only modules that import rclpy.

``node`` is the emulated gyro driver (``ros2 run gyro_emulator node``) and
``scenario`` plays rate and temperature profiles onto its ``cmd/`` topics;
``params``, ``inputs`` and ``diagnostics`` are their parameter table, command
validation and diagnostics bookkeeping. ``recorder``, ``replay`` and
``codec`` record and play back MCAP bags (``program``: what the recorder and
replay programs share). ``inputs`` and the profile parsing
in ``scenario`` are plain Python, so they test without a ROS graph.
"""
