"""The block stepper against a stepper of fixed blocks: the same samples and covariances."""

from gyro_emulator.emulation.driver.attitude import AttitudeState
from gyro_emulator.emulation.driver.block_stepper import BlockStepper
from gyro_emulator.physics import kinematics
from gyro_emulator.sensor.config import load_sensor_config
from gyro_emulator.sensor.imu import ImuModel
import numpy as np
import pytest


class FixedBlocks:
    """
    The reference: a block of ``max_block`` once the input held that long, else a step.

    A rewind restores the copy taken before the block and re-runs the samples
    handed out; the sigmas are read from the model after each block and every
    ``max_block`` single steps.
    """

    def __init__(self, model, max_block):
        self.model, self.max_block = model, max_block
        self.batch = self.key = self.last_key = self.checkpoint = None
        self.used = self.held = self.since = 0
        self.sigmas = self._sigmas()

    def _sigmas(self):
        return (self.model.white_noise_sigma_rad_s.tobytes()
                + self.model.accel_white_noise_sigma_m_s2.tobytes())

    def step(self, rate, temp, force):
        key = (tuple(rate), float(temp), tuple(force))
        if self.batch is not None:
            if key == self.key and self.used < len(self.batch):
                self.used += 1
                return self.batch.sample(self.used - 1)
            if self.used < len(self.batch):
                self.model = self.checkpoint
                n = self.used
                self.model.run(np.tile(self.key[0], (n, 1)), np.full(n, self.key[1]),
                               np.tile(self.key[2], (n, 1)))
            self.batch = None
        self.held = self.held + 1 if key == self.last_key else 0
        self.last_key = key
        if self.held < self.max_block:
            sample = self.model.step(*key)
            self.since += 1
            if self.since >= self.max_block:
                self.sigmas, self.since = self._sigmas(), 0
            return sample
        n = self.max_block
        self.checkpoint = self.model.copy()
        self.batch = self.model.run(np.tile(key[0], (n, 1)), np.full(n, key[1]),
                                    np.tile(key[2], (n, 1)))
        self.key, self.used = key, 1
        self.sigmas, self.since = self._sigmas(), 0
        return self.batch.sample(0)


def _inputs(n, seed):
    """Rates held 1-300 ticks (steady 10-tick streams among them), temperature steps."""
    rng = np.random.default_rng(seed)
    out, temp = [], 25.0
    while len(out) < n:
        u = rng.random()
        if u < 0.3:
            for _ in range(int(rng.integers(8, 20))):        # a steady stream
                rate = tuple(rng.normal(scale=0.3, size=3))
                out += [(rate, temp)] * 10
        else:
            if u < 0.45:
                temp = float(rng.uniform(0.0, 60.0))
            rate = (0.0, 0.0, 0.0) if u > 0.9 else tuple(rng.normal(scale=0.5, size=3))
            out += [(rate, temp)] * int(rng.choice([1, 2, 7, 60, 300]))
    return out[:n]


def _jittery_inputs(n, seed):
    """Rates held 3-17 ticks at random (commands from a timer on a loaded machine)."""
    rng = np.random.default_rng(seed)
    out, temp = [], 25.0
    while len(out) < n:
        if rng.random() < 0.02:
            temp = float(rng.uniform(0.0, 60.0))
        out += [(tuple(rng.normal(scale=0.3, size=3)), temp)] * int(rng.integers(3, 18))
    return out[:n]


@pytest.mark.parametrize('preset,inputs', [('consumer', _inputs), ('paper', _inputs),
                                           ('paper', _jittery_inputs)])
def test_samples_and_covariances_equal_those_of_fixed_blocks_bit_for_bit(preset, inputs):
    config = load_sensor_config(preset)
    ref = FixedBlocks(ImuModel(config, 1000.0, np.random.default_rng(4)), 50)
    stepper = BlockStepper(ImuModel(config, 1000.0, np.random.default_rng(4)), 50)
    # gravity turns with the rate: the driver's attitude, two copies on one time line
    states = [AttitudeState(kinematics.LEVEL_WXYZ, 9.80665,
                            lambda ns, count: [ns + k * 1_000_000 for k in range(1, count + 1)])
              for _ in range(2)]
    version, refreshes, seen = stepper.sigma_version, 0, set()
    for k, (rate, temp) in enumerate(inputs(6000, seed=9)):
        forces = []
        for state in states:
            state.advance(k * 1_000_000, rate)
            forces.append(state.specific_force((0.0, 0.0, 0.0)))
        want = ref.step(rate, temp, forces[0])
        got = stepper.step(rate, temp, forces[1], states[1])
        for name in ('gyro_rad_s', 'bias_rad_s', 'accel_m_s2', 'true_specific_force_m_s2'):
            assert getattr(got, name).tobytes() == getattr(want, name).tobytes(), (k, name)
        assert got.die_temp_c == want.die_temp_c
        sigmas = stepper.sigma_rad_s.tobytes() + stepper.accel_sigma_m_s2.tobytes()
        assert sigmas == ref.sigmas, k
        seen.add(sigmas)
        refreshes += stepper.sigma_version != version
        version = stepper.sigma_version
    # blocks were used; the covariance moved with the die temperature many times
    assert stepper.model_calls < 0.6 * 6000 and refreshes > 50 and len(seen) > 5
    if inputs is _jittery_inputs:   # blocks at an unsteady pace: rewound, and singles after
        assert stepper.rewinds > 50 and stepper.model_calls > 6000 / 17 + stepper.rewinds
