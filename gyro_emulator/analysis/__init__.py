"""
Analysis: replay, Allan deviation, calibrate, diagnose and fleet.

Compares the sensor model with measured data (a recorded bag replayed
through it, Allan terms, identified calibrations, named causes) and runs
fleets of parts. The runs themselves are :mod:`gyro_emulator.emulation`. No ROS.
"""
