"""
From a measured log to the estimator's files and back to an emulated twin.

:mod:`.noise` identifies the IEEE Std 952 noise terms of a static log and
:mod:`.export_noise` writes them for Kalibr, OpenVINS, VINS-Fusion,
ORB-SLAM3, Gazebo and this emulator; :mod:`.thermal` fits bias against
temperature and :mod:`.export_thermal` writes it for PX4, ArduPilot and this
emulator; :mod:`.twin` simulates the fitted preset and compares it with the
log (the round trip).
"""
