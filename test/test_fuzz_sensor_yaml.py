"""
Sensor YAMLs fuzzed: every field and extended term, denormals, wrong types, aliases.

Each case ends in a configuration whose model gives finite samples over a
temperature ramp and fast rates, or in a one-line ValueError that quotes at
most about 200 characters of the value: never NaN, never another exception,
never a huge message. Seeded: the same cases every run.
"""

from dataclasses import fields

from gyro_emulator.physics import params
from gyro_emulator.sensor import accel, extensions
from gyro_emulator.sensor.config import field_ranges, load_sensor_config
from gyro_emulator.sensor.imu import ImuModel
from gyro_emulator.sensor.model import NonFiniteOutput
import numpy as np
import pytest
import yaml

#: Values every numeric field is tried with: denormals, tiny, zero, huge, not finite.
EXTREMES = [5e-324, -5e-324, 1e-310, 1e-300, 1e-20, 1e-9, 0.0, 1e308, -1e308,
            float('inf'), float('nan')]
#: Values of the wrong type.
WRONG = ['abc', True, None, [], {}, [1.0, 2.0], [[1.0, 2.0, 3.0]] * 4, {'a': 1}]
N = 400


def _inputs():
    t = np.arange(N) / 100.0
    rate = np.column_stack([10.0 * np.sin(t), -5.0 * np.cos(3 * t), np.full(N, 0.3)])
    temp = np.concatenate([np.linspace(-40.0, 120.0, N // 2), np.linspace(120.0, 20.0, N // 2)])
    return rate, temp, np.tile([0.0, 0.0, 9.81], (N, 1))


RATE, TEMP, ACCEL = _inputs()


def _one_line(exc):
    """
    Return whether ``exc`` is one short line.

    A value is quoted to about 200 characters; an unknown key's message
    lists the allowed keys (about 1200).
    """
    text = str(exc)
    return text and '\n' not in text and 'Traceback' not in text and len(text) < 1600


def _outcome(path):
    """Load the file and run the model: 'ok' (finite samples) or 'refused' (one line)."""
    try:
        config = load_sensor_config(str(path))
    except ValueError as exc:
        assert _one_line(exc), repr(exc)[:2000]
        return 'refused'
    for rate_hz in (100.0, 1000.0):
        try:
            model = ImuModel(config, rate_hz, np.random.default_rng(3))
            out = model.run(RATE, TEMP, ACCEL)
        except NonFiniteOutput as exc:              # the ranges must make this unreachable
            raise AssertionError(f'{path.read_text()[:500]}: {exc}') from None
        except ValueError as exc:                   # e.g. a filter above Nyquist at this rate
            assert _one_line(exc), repr(exc)[:2000]
            continue
        assert np.all(np.isfinite(out.gyro_rad_s)), path.read_text()[:500]
        assert np.all(np.isfinite(out.bias_rad_s)), path.read_text()[:500]
        assert np.all(np.isfinite(out.accel_m_s2)), path.read_text()[:500]
    return 'ok'


def _write(tmp_path, i, mapping):
    path = tmp_path / f'case{i}.yaml'
    path.write_text(yaml.safe_dump(mapping, default_flow_style=None))
    return path


def _term_cases():
    """Every field of every extended term at every extreme and wrong value."""
    for term, cls in extensions.TERM_TYPES.items():
        amplitudes = {name: 0.01 for name, (kind, *_) in cls.RANGES.items() if kind == 'axis'}
        for name, (kind, low, high, _unit) in cls.RANGES.items():
            bounds = [] if low is None else [
                low, high, low * 0.999 if low else -1e-12, high * 1.001]
            for value in EXTREMES + bounds + WRONG:
                yield {'extended': {term: dict(amplitudes, **{name: value})}}


def _sensor_cases():
    """Every SensorConfig field at every extreme, bound and wrong value."""
    for name, (kind, low, high, _unit, _open) in field_ranges().items():
        for value in EXTREMES + [low, high] + WRONG:
            if kind == 'pair' and isinstance(value, float):
                value = [value, max(value, 1.0)] if np.isfinite(value) else [value, 1.0]
            yield {name: value}


def _accel_cases():
    """Every accelerometer field at every extreme, bound and wrong value."""
    for name, (kind, low, high, _unit, _open) in accel.field_ranges().items():
        for value in EXTREMES + [low, high] + WRONG:
            if kind == 'pair' and isinstance(value, float):
                value = [value, max(value, 1.0)] if np.isfinite(value) else [value, 1.0]
            yield {'accelerometer': {name: value}}


def _device_cases():
    """Every ranged device field at its bounds, denormals and beyond."""
    for group in ('geometry', 'material', 'gas', 'drive'):
        cls = type(getattr(params.Device(), group))
        for spec in fields(cls):
            if 'range' not in spec.metadata:
                continue
            low, high, _unit, _open = spec.metadata['range']
            for value in (low, high, 5e-324, 1e-20, 'x'):
                yield {'device': {'preset': 'paper', group: {spec.name: value}}}


@pytest.mark.parametrize('cases', [_term_cases, _sensor_cases, _accel_cases, _device_cases],
                         ids=['extended', 'sensor', 'accelerometer', 'device'])
def test_every_field_ends_in_finite_samples_or_one_line(tmp_path, cases):
    outcomes = {'ok': 0, 'refused': 0}
    for i, mapping in enumerate(cases()):
        outcomes[_outcome(_write(tmp_path, i, mapping))] += 1
    assert outcomes['ok'] > 0 and outcomes['refused'] > 0, outcomes


def test_random_combinations_end_in_finite_samples_or_one_line(tmp_path):
    """Several fields at once, drawn from the extremes, bounds and ordinary values."""
    rng = np.random.default_rng(34)
    singles = list(_term_cases()) + list(_sensor_cases()) + list(_accel_cases())
    outcomes = {'ok': 0, 'refused': 0}
    for i in range(150):
        mapping = {'extended': {}}
        for k in rng.choice(len(singles), size=int(rng.integers(2, 6)), replace=False):
            case = singles[k]
            for key, value in case.items():
                if key in ('extended', 'accelerometer'):
                    mapping.setdefault(key, {}).update(value)
                else:
                    mapping[key] = value
        outcomes[_outcome(_write(tmp_path, i, mapping))] += 1
    assert outcomes['ok'] > 0 and outcomes['refused'] > 0, outcomes


def test_denormal_and_vanishing_widths_are_refused_in_one_line(tmp_path):
    for name, term, value in (('hysteresis_width_k', 'bias_hysteresis', 1e-310),
                              ('hysteresis_width_k', 'bias_hysteresis', 1e-20),
                              ('gradient_time_constant_s', 'temperature_rate_bias', 1e-310),
                              ('gradient_time_constant_s', 'temperature_rate_bias', 1e-20),
                              ('warmup_time_constant_s', 'bias_time', 5e-324)):
        path = _write(tmp_path, 0, {'extended': {term: {name: value}}})
        with pytest.raises(ValueError, match=rf'{name} = {value!r} is out of range: '
                                             r'allowed \[1e-06, '):
            load_sensor_config(str(path))


@pytest.mark.parametrize('where', ['misalignment', 'extended', 'device', 'terms'])
def test_alias_bombs_anywhere_are_refused_with_a_short_message(tmp_path, where):
    anchors = 'x0: &a0 [0, 0, 0, 0, 0, 0, 0, 0, 0]\n'
    for i in range(1, 9):
        anchors += f'x{i}: &a{i} [' + ', '.join([f'*a{i - 1}'] * 9) + ']\n'
    body = {'misalignment': 'misalignment: *a8\n',
            'extended': 'extended:\n  bias_step: {bias_step_rad_s: *a8}\n',
            'device': 'device: {preset: paper, geometry: {thickness_m: *a8}}\n',
            'terms': 'terms: {turn_on_bias: *a8}\n'}[where]
    path = tmp_path / 'bomb.yaml'
    path.write_text(anchors + body)
    with pytest.raises(ValueError, match='aliases expand to more than') as caught:
        load_sensor_config(str(path))
    assert _one_line(caught.value)
    # a bomb small enough to expand: refused by the field, quoted in under 700 characters
    path.write_text('misalignment: [&a0 [0, 0, 0, 0, 0, 0, 0, 0, 0], '
                    + ', '.join(['*a0'] * 2000) + ']\n')
    with pytest.raises(ValueError, match='misalignment = .*shown in part') as caught:
        load_sensor_config(str(path))
    assert _one_line(caught.value) and len(str(caught.value)) < 500
