"""
Offline runs and analysis: simulate, replay, Allan deviation and diagnose.

Drives the sensor model from profiles or recorded bags and compares it with
measured data. No ROS.
"""
