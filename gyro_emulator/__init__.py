"""
gyro_emulator: a virtual MEMS vibratory gyroscope for ROS 2, built from physics.

Layers, with imports running one way only (enforced by ``test/test_layering.py``):
units/params -> physics -> dynamics -> error model/sensor -> analysis and
recording -> ROS edge -> command line. Only the ROS edge imports rclpy.
"""

__version__ = '0.1.0'
