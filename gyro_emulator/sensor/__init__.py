"""
The sensor error model: configuration, noise processes and ``GyroModel``.

``config`` holds the frozen, validated ``SensorConfig`` and its presets,
``noise`` the noise processes and Brownian ARW and ``model`` the
``GyroModel`` API (batch and streaming); the inputs it runs on are in
:mod:`gyro_emulator.emulation.profiles`. No ROS.
"""
