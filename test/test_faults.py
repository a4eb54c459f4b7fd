"""Injected faults (sensor.faults): each type's signature, block invariance, schedules."""

import math

from gyro_emulator.sensor import faults
from gyro_emulator.sensor.config import SensorConfig
from gyro_emulator.sensor.model import GyroModel
import numpy as np
import pytest
from scipy import stats

RATE_HZ = 200.0
RANGE = np.array([8.0, 8.0, 8.0])


def base_output(seed=3, n=600):
    """Return a noisy output at rest, then turning (the paper preset plus white noise)."""
    config = SensorConfig(electronics_noise_rad_s_sqrt_hz=2e-4, range_rad_s=8.0)
    model = GyroModel(config, RATE_HZ, np.random.default_rng(seed))
    rate = np.zeros((n, 3))
    rate[n // 2:, 2] = 0.5
    t = np.arange(n) / RATE_HZ
    return t, model.run(rate, 25.0).gyro_rad_s


def window(t, fault):
    return (t >= fault.start_s) & (t < fault.end_s)


def test_every_type_has_a_severity_and_a_unit():
    assert set(faults.SEVERITY) == set(faults.FAULT_TYPES) - {'none'}
    assert set(faults.MAGNITUDE_UNITS) == set(faults.FAULT_TYPES)
    assert {faults.SEVERITY[k] for k in ('stuck', 'dropout', 'saturate')} == {faults.ERROR}


def test_none_and_a_fault_outside_its_window_change_nothing():
    t, y = base_output()
    for fault in (faults.Fault(), faults.Fault('bias_step', 'x', 1.0, 10.0, 1.0)):
        effect = faults.apply_block(fault, t, y, RANGE)
        assert np.array_equal(effect.gyro_rad_s, y) and effect.published.all()
        assert not effect.active.any() and not effect.saturated.any()


def test_stuck_repeats_the_last_value_bit_for_bit_then_lets_go():
    t, y = base_output()
    fault = faults.Fault('stuck', 'y', 0.0, 1.0, 0.5)
    effect = faults.apply_block(fault, t, y, RANGE)
    inside = window(t, fault)
    first = np.flatnonzero(inside)[0]
    held = y[first - 1, 1]
    assert effect.gyro_rad_s[inside, 1].tobytes() == np.full(inside.sum(), held).tobytes()
    assert np.array_equal(effect.gyro_rad_s[:, [0, 2]], y[:, [0, 2]])
    assert np.array_equal(effect.gyro_rad_s[~inside], y[~inside])
    # The noise makes every real sample differ from its neighbour.
    assert len(np.unique(y[inside, 1])) == inside.sum()


def test_bias_step_and_drift_add_their_bias_on_their_axis_only():
    t, y = base_output()
    step = faults.Fault('bias_step', 'z', 0.02, 0.5, 1.0)
    effect = faults.apply_block(step, t, y, RANGE)
    inside = window(t, step)
    diff = effect.gyro_rad_s - y
    assert np.allclose(diff[inside, 2], 0.02, rtol=0, atol=1e-15)
    assert not diff[~inside].any() and not diff[:, :2].any()
    drift = faults.Fault('drift', 'all', -0.01, 1.0)   # until cleared
    diff = faults.apply_block(drift, t, y, RANGE).gyro_rad_s - y
    inside = t >= 1.0
    slope = np.polyfit(t[inside], diff[inside, 0], 1)[0]
    assert slope == pytest.approx(-0.01, rel=1e-9)
    assert np.allclose(diff[inside], (-0.01 * (t[inside] - 1.0))[:, None], atol=1e-15)


def test_a_spike_hits_exactly_one_sample_even_across_blocks():
    t, y = base_output()
    fault = faults.Fault('spike', 'x', 0.7, 1.0, 2.0)
    diff = faults.apply_block(fault, t, y, RANGE).gyro_rad_s - y
    hit = np.flatnonzero(diff[:, 0])
    assert len(hit) == 1 and t[hit[0]] == 1.0
    assert diff[hit[0], 0] == pytest.approx(0.7, abs=1e-15)
    # The next block (samples after the spike) gets none.
    later = faults.apply_block(fault, t[hit[0] + 1:], y[hit[0] + 1:], RANGE,
                               previous_t_s=t[hit[0]])
    assert np.array_equal(later.gyro_rad_s, y[hit[0] + 1:])


def test_dropout_publishes_nothing_in_its_window():
    t, y = base_output()
    fault = faults.Fault('dropout', 'all', 0.0, 0.25, 0.5)
    effect = faults.apply_block(fault, t, y, RANGE)
    assert np.array_equal(effect.published, ~window(t, fault))
    assert window(t, fault).sum() == 100


@pytest.mark.parametrize('sign', [1.0, -1.0])
def test_saturate_pins_the_axis_at_the_range_and_flags_it(sign):
    t, y = base_output()
    fault = faults.Fault('saturate', 'z', sign, 2.0, 0.5)
    effect = faults.apply_block(fault, t, y, RANGE)
    inside = window(t, fault)
    assert np.all(effect.gyro_rad_s[inside, 2] == sign * 8.0)
    assert np.array_equal(effect.saturated[:, 2], inside) and not effect.saturated[:, :2].any()


def test_noise_burst_adds_white_noise_of_its_sigma_calibrated_over_seeds():
    """The burst's sample variance falls outside its 95 % chi-square interval ~5 % of runs."""
    t, y = base_output(n=400)
    fault = faults.Fault('noise_burst', 'x', 0.05, 0.5, 1.0)
    inside = window(t, fault)
    n = int(inside.sum())
    lo, hi = stats.chi2.ppf([0.025, 0.975], n) / n
    outside = 0
    runs = 400
    for seed in range(runs):
        diff = faults.apply_block(fault, t, y, RANGE, np.random.default_rng(seed)).gyro_rad_s - y
        assert not diff[~inside].any() and not diff[:, 1:].any()
        ratio = np.mean(diff[inside, 0] ** 2) / 0.05 ** 2
        outside += not lo <= ratio <= hi
    # Binomial(400, 0.05): mean 20, sd 4.4; allow 3 sd either way.
    assert 7 <= outside <= 33, outside
    with pytest.raises(ValueError, match='needs a numpy Generator'):
        faults.apply_block(fault, t, y, RANGE)


@pytest.mark.parametrize('kind', [k for k in faults.FAULT_TYPES if k != 'none'])
def test_blocks_give_the_same_output_as_one_pass(kind):
    t, y = base_output()
    fault = faults.Fault(kind, 'all' if kind != 'spike' else 'y', 0.3, 0.77, 1.1)
    whole = faults.Injector([fault], RANGE, np.random.default_rng(5)).apply(t, y)
    injector = faults.Injector([fault], RANGE, np.random.default_rng(5))
    cuts = [0, 1, 7, 154, 155, 156, 300, 399, len(t)]
    parts = [injector.apply(t[a:b], y[a:b]) for a, b in zip(cuts, cuts[1:])]
    assert np.array_equal(np.concatenate([p.gyro_rad_s for p in parts]), whole.gyro_rad_s)
    assert np.array_equal(np.concatenate([p.published for p in parts]), whole.published)
    assert np.array_equal(np.concatenate([p.saturated for p in parts]), whole.saturated)


def test_stuck_from_the_first_sample_repeats_the_value_before_the_block():
    t, y = base_output()
    last = np.array([0.1, 0.2, 0.3])
    effect = faults.Injector([faults.Fault('stuck')], RANGE, last_rad_s=last).apply(t, y)
    assert np.all(effect.gyro_rad_s == last)


def test_a_schedule_applies_each_fault_in_turn():
    t, y = base_output()
    schedule = faults.parse_schedule('profile.faults', [
        {'type': 'dropout', 'start_s': 2.0, 'duration_s': 0.5},
        {'type': 'bias_step', 'axis': 'x', 'magnitude': 0.1, 'start_s': 0.5,
         'duration_s': 1.0}])
    assert [f.kind for f in schedule] == ['bias_step', 'dropout']
    effect = faults.Injector(schedule, RANGE).apply(t, y)
    diff = effect.gyro_rad_s - y
    assert np.allclose(diff[(t >= 0.5) & (t < 1.5), 0], 0.1, atol=1e-15)
    assert not diff[(t < 0.5) | (t >= 1.5)].any()
    assert np.array_equal(effect.published, ~((t >= 2.0) & (t < 2.5)))


@pytest.mark.parametrize('raw,match', [
    ([{'type': 'melt'}], r"faults\[0\]: fault.type = 'melt' is not allowed: choose one of"),
    ([{'type': 'stuck', 'axis': 'w'}], r"fault.axis = 'w' is not allowed"),
    ([{'type': 'spike', 'magnitude': math.inf}], r'fault.magnitude = inf is out of range'),
    ([{'type': 'spike', 'start_s': -1}], r'fault.start_s = -1 is out of range: allowed \[0'),
    ([{'type': 'noise_burst', 'magnitude': -0.1}], r'allowed \[0, 1000\] rad/s \(sigma\)'),
    ([{'type': 'stuck', 'when': 3}], r'unknown key\(s\) when; allowed: type, axis'),
    ([{'axis': 'x'}], r'faults\[0\].type is missing'),
    ([{'type': 'stuck', 'start_s': 1, 'duration_s': 2}, {'type': 'spike', 'start_s': 2}],
     r'faults\[1\] starts at 2 s, before faults\[0\] ends \(3 s\): faults may not overlap'),
    ([{'type': 'stuck', 'start_s': 1}, {'type': 'spike', 'start_s': 5}],
     r'before faults\[0\] ends \(inf s\)'),
    ('stuck', r'must be a list of faults'),
], ids=['type', 'axis', 'magnitude', 'start', 'sigma', 'key', 'missing', 'overlap',
        'forever', 'list'])
def test_schedule_errors_name_the_entry_field_and_range(raw, match):
    with pytest.raises(ValueError, match=match):
        faults.parse_schedule('faults', raw)


def test_describe_says_what_and_when():
    assert faults.Fault('bias_step', 'z', 0.01, 2.0, 1.0).describe() == \
        'bias_step 0.01 rad/s on z, from 2 s for 1 s'
    assert faults.Fault('saturate', 'x', -1.0).describe() == 'saturate at -range on x, from 0 s'
    assert faults.Fault().describe() == 'none'
