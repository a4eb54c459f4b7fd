"""
One model sample per tick at block cost, exactly (no ROS imports).

``GyroModel.step`` runs the compiled kernel on one sample, but its Python
argument handling makes it ~15 us a call. At 1 kHz the node then used
1.33-1.41x the CPU of a bare rclpy Imu publisher, against 1.13-1.26x with
blocks of 50 (``bench/bench_node.py``). :class:`BlockStepper`
calls ``GyroModel.run`` on K samples of the current (held) input ahead of
time and hands them out one per tick. When the input changes before the block is used
up, it restores a copy of the model taken before the block and re-runs only
the samples already handed out, so the model is exactly where per-sample
stepping would have left it. ``GyroModel`` guarantees that ``run`` and
``step`` give identical samples however a record is split into calls, so
the output equals ``step`` per tick bit for bit, for any input sequence.

Blocks pay off only while the input holds: a block starts once the input
has been unchanged for ``max_block`` ticks, and any change falls back to
plain ``step`` until it holds again. A rate that changes every few ticks
therefore costs what ``step`` costs, and a held rate a few microseconds.
"""

import numpy as np

#: Most samples of one model call that runs dropped samples (:meth:`BlockStepper.skip`).
SKIP_CHUNK = 10000


def _accel_sigma(model):
    """Return the accelerometer's white-noise sigma of an ImuModel, m/s^2 (None: a gyro)."""
    sigma = getattr(model, 'accel_white_noise_sigma_m_s2', None)
    return None if sigma is None else np.asarray(sigma, dtype=float)


class BlockStepper:
    """
    Serve ``GyroModel`` (or ``ImuModel``) samples one per tick from blocks computed ahead.

    Parameters
    ----------
    model : gyro_emulator.sensor.model.GyroModel or gyro_emulator.sensor.imu.ImuModel
        The model; it advances only through this object from now on.
    max_block : int
        Largest block, samples (1: call ``step`` every tick).

    """

    def __init__(self, model, max_block=50):
        self.model = model
        self.max_block = max(1, int(max_block))
        self.rewinds = 0
        self.model_calls = 0
        self._batch = None
        self._used = 0
        self._key = None
        self._checkpoint = None
        self._last_key = None
        self._held = 0
        self.sigma_rad_s = np.asarray(model.white_noise_sigma_rad_s, dtype=float)
        self.accel_sigma_m_s2 = _accel_sigma(model)
        self.sigma_version = 0
        self._since_sigma = 0

    def step(self, rate_rad_s, ambient_temp_c, accel_m_s2=None):
        """
        Return the next sample for this tick's inputs (a ``SensorSample``).

        Parameters
        ----------
        rate_rad_s : tuple of float
            True rate (x, y, z), rad/s.
        ambient_temp_c : float
            Ambient temperature, deg C.
        accel_m_s2 : tuple of float or None
            Specific force (x, y, z), m/s^2; None = none.

        """
        key = (tuple(rate_rad_s), float(ambient_temp_c),
               None if accel_m_s2 is None else tuple(accel_m_s2))
        batch = self._batch
        if batch is not None:
            if key == self._key and self._used < len(batch):
                index = self._used
                self._used += 1
                return batch.sample(index)
            if self._used < len(batch):
                self._rewind()
            self._batch = None
        self._held = self._held + 1 if key == self._last_key else 0
        self._last_key = key
        if self.block == 1:
            self.model_calls += 1
            sample = self.model.step(key[0], key[1], key[2])
            self._since_sigma += 1
            if self._since_sigma >= self.max_block:
                self._refresh_sigma()
            return sample
        return self._start_block(key)

    @property
    def block(self):
        """Return how many samples the next model call computes (1 until the input holds)."""
        return self.max_block if self._held >= self.max_block else 1

    def _start_block(self, key):
        n = self.block
        checkpoint = self.model.copy()
        rates = np.tile(np.asarray(key[0], dtype=float), (n, 1))
        temps = np.full(n, key[1])
        accel = None if key[2] is None else np.tile(np.asarray(key[2], dtype=float), (n, 1))
        self.model_calls += 1
        try:
            batch = self.model.run(rates, temps, accel)
        except ValueError:
            self.model = checkpoint
            raise
        self._checkpoint = checkpoint
        self._batch = batch
        self._key = key
        self._used = 1
        self._refresh_sigma()
        return batch.sample(0)

    def _rewind(self):
        """Put the model back to just after the samples handed out so far."""
        used, key = self._used, self._key
        self.model = self._checkpoint
        self._checkpoint = None
        self.rewinds += 1
        n = used
        accel = None if key[2] is None else np.tile(np.asarray(key[2], dtype=float), (n, 1))
        self.model_calls += 1
        self.model.run(np.tile(np.asarray(key[0], dtype=float), (n, 1)), np.full(n, key[1]),
                       accel)

    def skip(self, count, rate_rad_s, ambient_temp_c, accel_m_s2=None):
        """
        Run ``count`` samples of a held input whose output nobody reads (dropped samples).

        The model advances as ``count`` calls of :meth:`step` would move it,
        in calls of at most :data:`SKIP_CHUNK` samples (bounded memory).
        """
        self.sync()
        rate = np.asarray(rate_rad_s, dtype=float)
        accel = None if accel_m_s2 is None else np.asarray(accel_m_s2, dtype=float)
        left = int(count)
        while left > 0:
            n = min(left, SKIP_CHUNK)
            self.model_calls += 1
            self.model.run(np.tile(rate, (n, 1)), np.full(n, float(ambient_temp_c)), accel)
            left -= n
        self._last_key = None
        self._held = 0

    def sync(self):
        """Drop the samples computed ahead so the model stands at the current tick."""
        if self._batch is not None and self._used < len(self._batch):
            self._rewind()
        self._batch = None

    def update_config(self, config):
        """Apply a new SensorConfig from the next tick on, keeping the model's states."""
        self.sync()
        self.model.update_config(config)
        self._refresh_sigma()

    def set_sample_rate(self, sample_rate_hz):
        """Run the model at a new rate from the next tick on (``GyroModel.set_sample_rate``)."""
        self.sync()
        self.model.set_sample_rate(sample_rate_hz)
        self._last_key = None
        self._held = 0
        self._refresh_sigma()

    def _refresh_sigma(self):
        self.sigma_rad_s = np.asarray(self.model.white_noise_sigma_rad_s, dtype=float)
        self.accel_sigma_m_s2 = _accel_sigma(self.model)
        self.sigma_version += 1
        self._since_sigma = 0
