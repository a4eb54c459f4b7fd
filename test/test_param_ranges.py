"""
Every numeric sensor parameter at both ends of its documented range and just beyond.

Inside the range the model runs and its output is finite, or it refuses with
a one-line ValueError naming the field; beyond the range the configuration
itself refuses. No other exception, ever (issue 14: an ``lsb_rad_s`` of
1e-310 once overflowed in ``math.floor``).
"""

from dataclasses import replace
import math

from gyro_emulator.sensor import config as sensor_config
from gyro_emulator.sensor.model import GyroModel
import numpy as np
import pytest

RANGES = sensor_config.field_ranges()
BASE = sensor_config.load_sensor_config('consumer')
FS_HZ = 1000.0


def _value(kind, x):
    """Return a value of ``kind`` with every element ``x`` (off-diagonal in a matrix)."""
    if kind == 'pair':
        return (x, x)
    if kind == 'matrix':
        return tuple(tuple(0.0 if i == j else x for j in range(3)) for i in range(3))
    return x


def _ends(name):
    kind, low, high, _, low_open = RANGES[name]
    inside = [high, (low + 1e-9 * max(1.0, abs(low))) if low_open else low]
    span = max(abs(high - low), 1.0)
    beyond = [high + 1e-6 * span, low - 1e-6 * span] if not low_open else \
        [high + 1e-6 * span, low]
    if name == 'output_filter_order':
        inside, beyond = [int(high), int(low)], [int(high) + 1, int(low) - 1]
    if name == 'bias_instability_band_s':
        return kind, [(low, high)], [(low * 0.999, high), (low, high * 1.001)]
    return kind, [_value(kind, v) for v in inside], [_value(kind, v) for v in beyond]


def _run(config):
    model = GyroModel(config, FS_HZ, np.random.default_rng(3))
    n = 400
    t = np.arange(n) / FS_HZ
    rate = np.column_stack([0.3 * np.sin(5 * t), np.full(n, -0.2), np.full(n, 1.0)])
    batch = model.run(rate, np.linspace(20.0, 40.0, n), np.array([0.0, 0.0, 9.81]))
    sample = model.step((0.1, 0.0, 0.0), 40.0, (0.0, 0.0, 9.81))
    return batch, sample


@pytest.mark.parametrize('name', sorted(RANGES))
def test_inside_the_range_runs_or_says_why_in_one_line(name):
    kind, inside, _ = _ends(name)
    for value in inside:
        config = replace(BASE, **{name: value})
        try:
            batch, sample = _run(config)
        except ValueError as exc:
            text = str(exc)
            assert '\n' not in text and name.split('_')[0] in text, text
            continue
        assert np.all(np.isfinite(batch.gyro_rad_s)), (name, value)
        assert np.all(np.isfinite(sample.gyro_rad_s)), (name, value)
        assert math.isfinite(sample.output_delay_s)


@pytest.mark.parametrize('name', sorted(RANGES))
def test_just_beyond_the_range_is_refused_naming_field_and_range(name):
    _, _, beyond = _ends(name)
    for value in beyond:
        with pytest.raises(ValueError, match=f'SensorConfig.{name}.*(out of range|allowed)'):
            replace(BASE, **{name: value})


@pytest.mark.parametrize('value', [1e-310, 5e-10, float('nan'), float('inf'), -1e-9])
def test_a_tiny_or_bad_lsb_is_refused_not_overflowed(value):
    with pytest.raises(ValueError, match=r'SensorConfig.lsb_rad_s.* = .*(allowed|finite)'):
        replace(BASE, lsb_rad_s=(value, 0.0, 0.0))


def test_the_smallest_lsb_quantises():
    lsb = sensor_config.MIN_LSB_RAD_S
    batch, _ = _run(replace(BASE, lsb_rad_s=(lsb,) * 3))
    steps = batch.gyro_rad_s / lsb
    assert np.allclose(steps, np.round(steps), atol=1e-3)


@pytest.mark.parametrize('low_open', [True, False])
@pytest.mark.parametrize('high_open', [True, False])
@pytest.mark.parametrize('seed', range(4))
def test_check_range_refuses_exactly_the_arrays_with_an_element_outside(seed, low_open,
                                                                        high_open):
    """The min/max fast path and the element mask agree: bounds, NaN, inf, empty, scalars."""
    from gyro_emulator.validation import check_range, outside

    edges = np.array([0.0, 1.0, np.nan, np.inf, 0.5])
    assert outside(edges, 0.0, 1.0, True, False).tolist() == [True, False, True, True, False]
    assert outside(edges, 0.0, 1.0, False, True).tolist() == [False, True, True, True, False]
    assert outside(edges, None, None).tolist() == [False, False, True, True, False]
    rng = np.random.default_rng(seed)
    specials = np.array([0.0, 1.0, np.nextafter(0.0, 1.0), np.nextafter(1.0, 0.0),
                         -1e-300, np.nan, np.inf, -np.inf, 0.5])
    for trial in range(300):
        size = int(rng.integers(0, 6))
        arr = np.where(rng.random(size) < 0.3, rng.choice(specials, size),
                       rng.uniform(-0.2, 1.2, size))
        if trial % 7 == 0 and size:
            arr = arr[:1].reshape(())                   # a 0-d value
        low, high = [(0.0, 1.0), (None, 1.0), (0.0, None), (None, None)][trial % 4]
        expect_bad = bool(np.any(outside(arr, low, high, low_open, high_open)))
        try:
            check_range('T', 'x', arr, low, high, 'm', low_open, high_open)
            refused = False
        except ValueError as exc:
            refused = True
            assert str(exc).startswith('T.x = ') and '\n' not in str(exc)
        assert refused == expect_bad, (arr, low, high, low_open, high_open)
