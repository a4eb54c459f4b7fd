"""
gyro_emulator: a virtual MEMS vibratory gyroscope for ROS 2, built from physics.

Sub-packages, with imports running one way only (``docs/architecture.md``,
enforced by ``test/test_layering.py``)::

    units, validation, resources -> physics -> sensor -> recording
        -> analysis -> ros -> cli

Only ``gyro_emulator.ros`` imports rclpy or message packages.
"""

__version__ = '0.1.0'
