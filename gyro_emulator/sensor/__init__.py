"""
The sensor error model: configuration, noise processes and ``GyroModel``.

``config`` holds the frozen, validated ``SensorConfig`` and its presets,
``noise`` the noise processes and Brownian ARW, ``model`` the ``GyroModel``
API (batch and streaming) and ``profiles`` the scripted rate and temperature
inputs. No ROS.
"""
