"""
gyro_emulator: a virtual MEMS vibratory gyroscope for ROS 2, built from physics.

Layers, with imports running one way only (enforced by ``test/test_layering.py``):
units/params -> physics -> dynamics -> error model/sensor -> analysis and
recording -> ROS edge -> command line. Only the ROS edge imports rclpy.
"""

import os

__version__ = '0.1.0'

# The models run many small matrix operations (ZOH discretisation, matrix
# exponentials of 6x6..42x42 matrices). With OpenBLAS's default thread pool on
# a loaded 2-core machine one scipy.linalg.expm of a 42x42 matrix took 12.6 ms
# against 0.14 ms single-threaded (measured 2026-11-22). Default to one thread
# unless the user chose otherwise; this only takes effect if numpy has not
# been imported yet.
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
