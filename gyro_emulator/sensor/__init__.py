"""
The sensor error model: configuration, noise processes, ``GyroModel`` and ``ImuModel``.

``config`` holds the frozen, validated ``SensorConfig`` and its presets
(``accel`` its accelerometer's ``AccelConfig``), ``noise`` the noise
processes and the Brownian ARW and VRW, ``model`` the ``GyroModel`` API
(batch and streaming) and ``imu`` the ``ImuModel`` (the gyro and the
accelerometer on the same kernel); the inputs they run on are in
:mod:`gyro_emulator.emulation.profiles`. No ROS.
"""
