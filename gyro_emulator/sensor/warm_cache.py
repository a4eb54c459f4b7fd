"""
Compile the sensor kernel into numba's cache: ``python -m gyro_emulator.sensor.warm_cache``.

numba keeps the compiled kernel (:mod:`gyro_emulator.sensor.kernel`) beside
its source, in ``__pycache__``, keyed to the source file's path, time and
size. Every new install is a new path, so without this step the first
program to run the model after an install compiles it (about 8 s on a quiet
core, far longer on a loaded machine): a colcon-built node's first sample
came 10-11 s after its first start. The install steps run this module once
instead (``./dev.sh setup`` after its pip install; ``colcon build`` and
``setup.py install`` through ``setup.py``'s ``install`` command), so a
fresh install's first start only loads the cache (``bench/bench_startup.py``).

One sample of the default model compiles every signature of the sensor
kernel: it has one entry (``kernel.advance``), and its array types are the
same for every configuration, the extended terms and the accelerometer's
channel (``ImuModel``) included. The other compiled functions, which the
node does not run (the kinematics of ``physics.kinematics``, the Allan
deviation of ``analysis.allan.adev``), compile at their first use.
:func:`main` also byte-compiles the package's modules (``compileall``),
which ``colcon build`` leaves to the first import.
"""

import compileall
import os
import sys
import time

from gyro_emulator.sensor import config as sensor_config
from gyro_emulator.sensor import model as sensor_model
import numpy as np


def warm_up():
    """Load the compiled sensor kernel (numba's cache; compiled if absent): one model sample."""
    config = sensor_config.SensorConfig()
    sensor_model.GyroModel(config, 100.0, np.random.default_rng(0)).step(
        (0.0, 0.0, 0.0), 25.0)


def main():
    """Warm the caches of the gyro_emulator imported here; print where and how long."""
    began = time.monotonic()
    warm_up()
    package = os.path.dirname(os.path.dirname(os.path.abspath(sensor_model.__file__)))
    compileall.compile_dir(package, quiet=2)
    print(f'gyro_emulator: sensor kernel cached and modules compiled in {package} '
          f'({time.monotonic() - began:.1f} s)', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
