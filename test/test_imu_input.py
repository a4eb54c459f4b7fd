"""A simulator's ideal-IMU time line (emulation.driver.imu_timeline) and the rate changes."""

from gyro_emulator.emulation.driver.block_stepper import BlockStepper
from gyro_emulator.emulation.driver.imu_timeline import (InputTimeline, MAX_GAP_S,
                                                         MAX_RATE_HZ, SpacingRefused,
                                                         StampNotNewer)
from gyro_emulator.sensor.config import SensorConfig
from gyro_emulator.sensor.model import GyroModel
import numpy as np
import pytest
from scipy import stats

MS = 1_000_000


def advances(stamps_ns, nominal_hz=200.0):
    timeline = InputTimeline(nominal_hz)
    return timeline, [timeline.advance(s) for s in stamps_ns]


def test_a_steady_input_rate_replans_once_from_the_first_spacing():
    timeline, steps = advances(np.arange(500) * 4 * MS + 10**9)
    assert [s.samples for s in steps] == [1] * 500
    assert steps[1].rate_hz == pytest.approx(250.0) and timeline.replans == 1
    assert all(s.rate_hz is None and s.restart is None for s in steps[2:])
    assert timeline.rate_hz == pytest.approx(250.0)


def test_alternating_spacings_give_their_mean_rate_without_replanning_each_time():
    """A 300 Hz sensor on a 1 ms physics step is stamped 3, 3, 4 ms apart."""
    stamps = np.cumsum([3, 3, 4] * 300) * MS
    timeline, steps = advances(stamps)
    assert all(s.samples == 1 for s in steps)
    assert timeline.replans == 2, timeline.replans  # the first spacing, the first window
    assert timeline.rate_hz == pytest.approx(300.0, rel=0.01)


def test_a_lost_message_runs_the_model_through_the_gap():
    stamps = list(np.arange(20) * 5 * MS) + [110 * MS, 115 * MS]
    _, steps = advances(stamps)
    assert [s.samples for s in steps[-3:]] == [1, 3, 1]


def test_jumps_back_and_long_gaps_restart_and_a_repeated_stamp_is_refused():
    timeline, steps = advances([0, 5 * MS, 10 * MS, 2 * MS, 7 * MS])
    assert steps[3].restart == 'jump_back' and steps[3].samples == 1
    assert steps[4].restart is None and steps[4].samples == 1
    gap = timeline.advance(7 * MS + int((MAX_GAP_S + 0.5) * 1e9))
    assert gap.restart == 'gap' and timeline.restarts == 2
    with pytest.raises(StampNotNewer, match='repeats the previous one'):
        timeline.advance(7 * MS + int((MAX_GAP_S + 0.5) * 1e9))


def test_the_white_noise_follows_the_rate_the_stamps_give():
    """Stamped at 800 Hz, the per-sample sigma is N sqrt(800 Hz), not N sqrt(200 Hz)."""
    config = SensorConfig(electronics_noise_rad_s_sqrt_hz=1e-3).with_terms(
        sense_dynamics=False, output_filter=False, bias_instability=False,
        rate_random_walk=False, turn_on_bias=False, mechanical_noise=False,
        quantization=False)
    stepper = BlockStepper(GyroModel(config, 200.0, np.random.default_rng(1)), 1)
    timeline = InputTimeline(200.0)
    out = []
    for k in range(4001):
        step = timeline.advance(10**9 + k * 1_250_000)
        if step.rate_hz is not None:
            stepper.set_sample_rate(step.rate_hz)
        out.append(stepper.step((0.0, 0.0, 0.0), 25.0).gyro_rad_s[0])
    y = np.array(out[1:])
    sigma = 1e-3 * np.sqrt(800.0)
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], len(y)) / len(y)
    assert lo < np.mean(y ** 2) / sigma ** 2 < hi
    assert stepper.sigma_rad_s[0] == pytest.approx(sigma)


def test_a_rate_below_the_output_filters_nyquist_is_refused_and_the_model_keeps_its_rate():
    model = GyroModel(SensorConfig(output_filter_hz=40.0), 200.0, np.random.default_rng(0))
    with pytest.raises(ValueError, match='below Nyquist'):
        model.set_sample_rate(60.0)
    assert model.sample_rate_hz == 200.0 and model.dt_s == 1 / 200.0
    with pytest.raises(ValueError, match='sample_rate_hz = 0.0 is out of range'):
        model.set_sample_rate(0.0)


def test_restarted_filters_start_from_steady_state_at_the_next_input():
    config = SensorConfig(output_filter_hz=20.0).with_terms(
        mechanical_noise=False, electronics_noise=False,
        bias_instability=False, rate_random_walk=False, turn_on_bias=False,
        quantization=False)
    model = GyroModel(config, 200.0, np.random.default_rng(0))
    model.run(np.zeros((50, 3)), 25.0)
    model.step((0.0, 0.0, 1.0), 25.0)   # the ZOH sense dynamics: 0 on the first sample
    ringing = model.step((0.0, 0.0, 1.0), 25.0).gyro_rad_s[2]
    assert 0.0 < ringing < 0.9          # ... then settling
    model.restart_filters()
    settled = model.step((0.0, 0.0, 1.0), 25.0).gyro_rad_s[2]
    assert settled == pytest.approx(1.0, abs=1e-12)


def test_stamps_closer_than_the_top_rate_are_refused_and_the_time_line_runs_on():
    """Two imu/ideal messages 1 ns apart must not set a 1 GHz period (issue 26)."""
    timeline = InputTimeline(200.0)
    timeline.advance(10**9)
    with pytest.raises(SpacingRefused, match='1 ns after the previous one: allowed at least '
                       '200000 ns'):
        timeline.advance(10**9 + 1)
    steps = [timeline.advance(10**9 + k * 5 * MS) for k in range(1, 200)]
    assert [s.samples for s in steps] == [1] * 199
    assert timeline.rate_hz == pytest.approx(200.0) and timeline.period_s == pytest.approx(0.005)
    # A faster input is thinned to MAX_RATE_HZ: every other 10 kHz stamp is refused.
    fast = InputTimeline(200.0)
    refused = 0
    for k in range(1000):
        try:
            fast.advance(k * 100_000)
        except SpacingRefused:
            refused += 1
    assert refused == 500 and fast.rate_hz == pytest.approx(MAX_RATE_HZ)
