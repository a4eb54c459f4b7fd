"""Extended error terms (sensor.extensions): closed forms, streaming = batch, config."""

from dataclasses import replace

from gyro_emulator.analysis.diagnose.generic import play
from gyro_emulator.physics import first_order
from gyro_emulator.sensor import extensions as ex
from gyro_emulator.sensor.config import config_from_mapping, load_sensor_config, SensorConfig
from gyro_emulator.sensor.model import GyroModel
import numpy as np
import pytest

FS = 50.0
N = 4000
T_S = np.arange(N) / FS
TEMP = 25.0 + 20.0 * np.sin(T_S / 10.0)          # heating and cooling
RATE = np.stack([0.5 + 0.1 * np.sin(T_S), -0.3 + 0 * T_S, 0.2 * np.cos(T_S / 3)], 1)
A = np.array([1e-3, -2e-3, 3e-3])


def _run(terms, temp=TEMP, rate=RATE, base=None, **kw):
    config = replace(base or SensorConfig.ideal(), extended=ex.ExtendedTerms(**terms, **kw))
    return GyroModel(config, FS, np.random.default_rng(1)).run(rate, temp)


def _cal():
    return SensorConfig.ideal().device[0].calibration_temp_c


def _closed_forms():
    """(terms, expected bias (N, 3), expected gain (N, 3)) of each term alone."""
    one, zero = np.ones((N, 3)), np.zeros((N, 3))
    w, tau, t0, kap, tg = 2.0, 30.0, 41.3, 0.05, 7.0
    p = play(TEMP, w)
    d = TEMP - _cal()
    th = (T_S - 20.0) / 3600.0
    c1, c2, k1, k2 = np.array([1e-4, -2e-4, 3e-4]), np.array([1e-6, 0, -1e-6]), A, -A
    return {
        'bias_hysteresis': (ex.BiasHysteresis(w, A), A * ((p - TEMP) / w)[:, None], one),
        'bias_time': (ex.BiasTime(tau, A, 2 * A, 20.0),
                      A * np.exp(-T_S / tau)[:, None] + 2 * A * th[:, None], one),
        'bias_step': (ex.BiasStep(t0, A), A * (T_S >= t0)[:, None], one),
        'scale_factor_step': (ex.ScaleFactorStep(t0, A), zero, 1 + A * (T_S >= t0)[:, None]),
        'scale_factor_temperature': (
            ex.ScaleFactorTemperature(c1, c2), zero,
            1 + c1 * d[:, None] + c2 * (d * d)[:, None]),
        'scale_factor_time': (ex.ScaleFactorTime(k1, k2, 20.0), zero,
                              1 + k1 * th[:, None] + k2 * (th * th)[:, None]),
        'temperature_rate_bias': None, 'pressure_drift': None, '_': (kap, tg)}


@pytest.mark.parametrize('name', ['bias_hysteresis', 'bias_time', 'bias_step',
                                  'scale_factor_step', 'scale_factor_temperature',
                                  'scale_factor_time'])
def test_term_matches_its_closed_form(name):
    term, bias, gain = _closed_forms()[name]
    out = _run({name: term})
    np.testing.assert_allclose(out.bias_rad_s, bias, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(out.scale_factor, gain, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(out.gyro_rad_s, RATE * gain + bias, rtol=1e-12, atol=1e-15)


def test_temperature_rate_bias_on_a_ramp():
    """T = T0 + r t: T - T_g = r tau (1 - exp(-t/tau)) exactly (first-order lag)."""
    r, tau, kap = 0.05, 7.0, np.array([0.01, -0.02, 0.0])
    temp = 10.0 + r * T_S
    out = _run({'temperature_rate_bias': ex.TemperatureRateBias(tau, kap)}, temp=temp)
    expected = kap * (r * (1.0 - np.exp(-T_S / tau)))[:, None]
    np.testing.assert_allclose(out.bias_rad_s, expected, rtol=1e-9, atol=1e-15)


def test_pressure_drift_follows_the_physics():
    """SF multiplier = Y(T, P(t)) / Y(T, P_ref), P(t) = 1 + k t_h (Eq 8-11)."""
    k = -0.2
    t = np.arange(N) * 2.0                      # 8000 s: P falls to 0.56 P_ref
    fs = 0.5
    config = replace(SensorConfig.ideal(), extended=ex.ExtendedTerms(
        pressure_drift=ex.PressureDrift(k)))
    out = GyroModel(config, fs, np.random.default_rng(1)).run(RATE, TEMP)
    dev = config.device[0]
    rows = np.arange(0, N, 397)
    for i in rows:
        pres = dev.with_gas(pressure_pa=dev.gas.pressure_pa * (1 + k * t[i] / 3600.0))
        ref = first_order.sense_scale_factor_m_per_rad_s(dev, TEMP[i])
        got = first_order.sense_scale_factor_m_per_rad_s(pres, TEMP[i]) / ref
        np.testing.assert_allclose(out.scale_factor[i], got, rtol=2e-5)
    assert abs(out.scale_factor[-1, 0] - 1.0) > 1e-3    # it does drift


def _all_terms(start=3.0):
    forms = _closed_forms()
    terms = {n: forms[n][0] for n in forms if forms[n] and n != '_'}
    terms['temperature_rate_bias'] = ex.TemperatureRateBias(7.0, A)
    terms['pressure_drift'] = ex.PressureDrift(0.5)
    return ex.ExtendedTerms(start_time_s=start, **terms)


def test_a_snapshot_restores_the_extended_terms_exactly():
    config = replace(load_sensor_config('consumer'), extended=_all_terms())
    model = GyroModel(config, 200.0, np.random.default_rng(7))
    model.run(RATE[:1500], TEMP[:1500])
    snap = model.snapshot()
    ahead = model.run(RATE[1500:], TEMP[1500:])
    model.restore(snap)
    again = model.run(RATE[1500:], TEMP[1500:])
    for name in ('gyro_rad_s', 'bias_rad_s', 'scale_factor', 'die_temp_c'):
        assert getattr(ahead, name).tobytes() == getattr(again, name).tobytes(), name


def test_streaming_equals_batch_bit_for_bit():
    config = replace(load_sensor_config('consumer'), extended=_all_terms())
    batch = GyroModel(config, 200.0, np.random.default_rng(7)).run(RATE, TEMP)
    model = GyroModel(config, 200.0, np.random.default_rng(7))
    parts = [model.run(RATE[:1000], TEMP[:1000])]
    steps = [model.step(RATE[i], TEMP[i]).gyro_rad_s for i in range(1000, 1100)]
    parts.append(model.run(RATE[1100:], TEMP[1100:]))
    assert np.array_equal(batch.gyro_rad_s[:1000], parts[0].gyro_rad_s)
    assert np.array_equal(batch.gyro_rad_s[1000:1100], np.array(steps))
    assert np.array_equal(batch.gyro_rad_s[1100:], parts[1].gyro_rad_s)


def test_start_time_shifts_the_record_time():
    """A step at record time 10 s with the first sample at 5 s comes at sample 5 s * fs."""
    out = _run({'bias_step': ex.BiasStep(10.0, A)}, start_time_s=5.0)
    assert np.array_equal(out.bias_rad_s[:, 0] != 0, T_S >= 5.0)


def test_off_by_default_and_switch():
    assert SensorConfig().extended.active() == ()
    for name in ex.TERM_TYPES:
        assert getattr(load_sensor_config('consumer').extended, name) is None
    off = _run({'bias_step': ex.BiasStep(0.0, A, enabled=False)})
    assert np.array_equal(off.gyro_rad_s, RATE)


def test_enabling_later_keeps_the_record_time():
    model = GyroModel(SensorConfig.ideal(), FS, np.random.default_rng(1))
    model.run(RATE[:100], TEMP[:100])
    model.update_config(replace(SensorConfig.ideal(), extended=ex.ExtendedTerms(
        bias_step=ex.BiasStep(3.0, A))))
    out = model.run(RATE[100:], TEMP[100:])
    assert np.array_equal(out.bias_rad_s[:, 0] != 0, T_S[100:] >= 3.0)


def test_yaml(tmp_path):
    path = tmp_path / 's.yaml'
    path.write_text('extended:\n  start_time_s: 2.0\n  bias_hysteresis:\n'
                    '    hysteresis_width_k: 1.5\n    bias_hysteresis_rad_s: 0.001\n'
                    '  bias_step: {step_time_s: 3, bias_step_rad_s: [0.1, 0, 0],'
                    ' enabled: false}\n')
    ext = load_sensor_config(str(path)).extended
    assert ext.bias_hysteresis == ex.BiasHysteresis(1.5, (1e-3,) * 3)
    assert ext.active() == ('bias_hysteresis',) and ext.start_time_s == 2.0


@pytest.mark.parametrize('mapping, words', [
    ({'bias_hysteresis': {'hysteresis_width_k': 0}}, 'BiasHysteresis.hysteresis_width_k = 0'),
    ({'bias_time': {'warmup_rad_s': [0, 0, 2]}}, 'BiasTime.warmup_rad_s = 2.0'),
    ({'pressure_drift': {'pressure_rate_per_h': 5}}, 'allowed [-3.0, 3.0] 1/h'),
    ({'bias_step': {'bias_step_rad_s': True}}, 'is not a number'),
    ({'bias_stepp': {}}, "unknown term 'bias_stepp'"),
    ({'bias_step': {'step_time': 1}}, 'unknown parameter(s) step_time'),
    ({'scale_factor_step': {'enabled': 'yes'}}, 'ScaleFactorStep.enabled'),
])
def test_bad_values_name_field_and_range(mapping, words):
    with pytest.raises(ValueError) as err:
        config_from_mapping({'extended': mapping}, 'f.yaml')
    assert words in str(err.value) and '\n' not in str(err.value)


def test_record_time_follows_a_rate_change_and_a_new_configuration():
    """Warm-up A exp(-t/tau) on the true elapsed time across set_sample_rate and update_config."""
    tau = 3.0
    config = replace(SensorConfig.ideal(), extended=ex.ExtendedTerms(
        bias_time=ex.BiasTime(tau, A)))
    model = GyroModel(config, 100.0, np.random.default_rng(1))
    first = model.run(RATE[:150], TEMP[:150])               # 0 .. 1.49 s
    model.set_sample_rate(200.0)
    second = model.run(RATE[:300], TEMP[:300])              # 1.5 .. 2.995 s
    model.update_config(replace(config, extended=ex.ExtendedTerms(
        bias_time=ex.BiasTime(2 * tau, A))))
    third = model.run(RATE[:10], TEMP[:10])                 # 3.0 .. 3.045 s
    t1, t2, t3 = np.arange(150) / 100.0, 1.5 + np.arange(300) / 200.0, 3.0 + np.arange(10) / 200.0
    np.testing.assert_allclose(first.bias_rad_s, A * np.exp(-t1 / tau)[:, None], rtol=1e-12)
    np.testing.assert_allclose(second.bias_rad_s, A * np.exp(-t2 / tau)[:, None], rtol=1e-12)
    np.testing.assert_allclose(third.bias_rad_s, A * np.exp(-t3 / (2 * tau))[:, None],
                               rtol=1e-12)


def test_set_elapsed_puts_the_record_time_on_a_jumped_time_line():
    """After set_elapsed_s(E) the next sample is at elapsed E: warm-up, drift and step follow."""
    tau = 3.0
    terms = ex.ExtendedTerms(start_time_s=2.0, bias_time=ex.BiasTime(tau, A, A, 10.0),
                             bias_step=ex.BiasStep(30.0, A))
    model = GyroModel(replace(SensorConfig.ideal(), extended=terms), FS,
                      np.random.default_rng(1))
    model.run(RATE[:1000], TEMP[:1000])              # 20 s
    model.set_elapsed_s(40.0)                        # the clock jumped 20 s ahead
    out = model.run(RATE[:100], TEMP[:100])
    elapsed = 40.0 + np.arange(100) / FS
    t = 2.0 + elapsed
    want = A * (np.exp(-elapsed / tau) + (t - 10.0) / 3600.0 + 1.0)[:, None]
    np.testing.assert_allclose(out.bias_rad_s, want, rtol=1e-12)
    for bad in (float('nan'), 2e9, 'x'):
        with pytest.raises(ValueError, match='GyroModel.elapsed_s = .* is out of range'):
            model.set_elapsed_s(bad)


def test_copy_continues_identically():
    config = replace(load_sensor_config('consumer'), extended=_all_terms())
    model = GyroModel(config, 200.0, np.random.default_rng(3))
    model.run(RATE[:500], TEMP[:500])
    twin = model.copy()
    a, b = model.run(RATE[500:], TEMP[500:]), twin.run(RATE[500:], TEMP[500:])
    assert np.array_equal(a.gyro_rad_s, b.gyro_rad_s)


#: Each term with the figures diagnose must find in the emulator's output.
DIAGNOSE_CASES = {
    'bias_hysteresis': ex.BiasHysteresis(2.0, 2e-3),
    'bias_time': ex.BiasTime(900.0, 3e-3, 1e-3, 7200.0),
    'bias_step': ex.BiasStep(5000.0, 2e-3),
    'scale_factor_step': ex.ScaleFactorStep(5000.0, 3e-3),
    'scale_factor_temperature': ex.ScaleFactorTemperature(1e-4, 2e-6),
    'scale_factor_time': ex.ScaleFactorTime(2e-3, 0.0, 7200.0),
    'pressure_drift': ex.PressureDrift(0.2),
    'temperature_rate_bias': ex.TemperatureRateBias(60.0, 0.05),
}


@pytest.mark.parametrize('name', list(DIAGNOSE_CASES))
def test_diagnose_finds_the_term_with_its_parameters(name):
    """The emulator's term, diagnosed: the same cause, parameters and units (issue 24)."""
    from gyro_emulator.analysis.diagnose.data import MeasuredData
    from gyro_emulator.analysis.diagnose import diagnose, to_json
    fs = 10.0
    t = np.arange(int(4 * 3600 * fs)) / fs
    temp = 25.0 + 30.0 * np.clip(1.5 * np.sin(2 * np.pi * t / 5400.0), -1.0, 1.0)
    rate = 0.5 * np.sign(np.sin(2 * np.pi * t / 60.0))
    term = DIAGNOSE_CASES[name]
    config = replace(SensorConfig.ideal().with_terms(scale_factor_temperature=True,
                                                     electronics_noise=True),
                     electronics_noise_rad_s_sqrt_hz=1e-4,
                     extended=ex.ExtendedTerms(**{name: term}))
    out = GyroModel(config, fs, np.random.default_rng(2)).run(
        np.column_stack([0 * t, 0 * t, rate]), temp)
    doc = to_json(diagnose(MeasuredData(t, rate, temp, out.gyro_rad_s[:, 2]), effects=[name]))
    assert doc['verdict'] == 'explained' and [s['effect'] for s in doc['selected']] == [name]
    found = {k: v['value'] for k, v in doc['selected'][0]['parameters'].items()}
    for key, value in found.items():
        planted = getattr(term, key)
        planted = planted[2] if isinstance(planted, tuple) else planted
        if key == 'step_time_s':
            assert abs(value - planted) <= 1.0, (key, value, planted)
        elif planted == 0.0:
            assert abs(value) < 1e-5, (key, value)
        else:
            assert value == pytest.approx(planted, rel=0.06), (key, value, planted)


RANGE_CASES = [(cause, name, spec) for cause, cls in ex.TERM_TYPES.items()
               for name, spec in cls.RANGES.items()]


@pytest.mark.parametrize('cause, name, spec', RANGE_CASES,
                         ids=[f'{c}.{n}' for c, n, _ in RANGE_CASES])
def test_every_extended_field_is_checked_against_its_range(cause, name, spec):
    """Each bound: inside is accepted; just outside is a one-line error naming field and range."""
    kind, low, high = spec[:3]
    cls = ex.TERM_TYPES[cause]
    for bound, outside in ((low, low - 1e-3 * max(1.0, abs(low))),
                           (high, high + 1e-3 * max(1.0, abs(high)))):
        inside = bound if kind != 'open' or bound != low else 0.5 * (low + high)
        cls(**{name: inside})
        with pytest.raises(ValueError) as err:
            cls(**{name: outside})
        text = str(err.value)
        assert f'{cls.__name__}.{name} = ' in text and 'allowed' in text and '\n' not in text


def test_record_clock_places_the_first_sample_on_its_origin_or_says_why_not():
    """record_start_clock_s: the first sample's record time is its clock time - the origin."""
    from gyro_emulator.emulation.driver.record_clock import RecordClock
    config = replace(SensorConfig.ideal(), extended=ex.ExtendedTerms(
        bias_step=ex.BiasStep(10.0, A)))
    notes = []
    model = GyroModel(config, FS, np.random.default_rng(1))
    clock = RecordClock(100.0, notes.append)
    clock.first(model, 109_000_000_000)             # clock 109 s: record time 9 s
    out = model.run(RATE[:100], TEMP[:100])         # 9 .. 10.98 s
    assert np.array_equal(out.bias_rad_s[:, 0] != 0, 9.0 + T_S[:100] >= 10.0) and not notes
    far = GyroModel(config, FS, np.random.default_rng(1))
    RecordClock(0.0, notes.append).first(far, 2_000_000_000 * 10**9)
    assert len(notes) == 1 and 'record_start_clock_s = 0 s is not used' in notes[0]
    assert not far.run(RATE[:10], TEMP[:10]).bias_rad_s.any()     # record time 0: no step
