"""
The accelerometer (issue 32): its configuration, the IMU model on the gyro's kernel, its figures.

Configuration: validation with one-line errors, datasheet-unit aliases both
ways, the one sensor-YAML writer. Model: batch == streaming for any split,
the gyro bit for bit as a GyroModel's with the accelerometer on, no
non-finite sample. Figures: the paper preset's noise is the proof mass's
Brownian noise, and an Allan fit recovers the configured N, B and K.
"""

from dataclasses import replace
import math

from gyro_emulator import units
from gyro_emulator.analysis.allan import identify
from gyro_emulator.physics import first_order
from gyro_emulator.sensor import accel as sensor_accel
from gyro_emulator.sensor.accel import accel_from_mapping, AccelConfig, AccelTerms
from gyro_emulator.sensor.config import (config_from_mapping, config_yaml, load_sensor_config,
                                         PRESET_NAMES, SensorConfig, YamlKey)
from gyro_emulator.sensor.imu import ImuModel
from gyro_emulator.sensor.model import GyroModel
import numpy as np
import pytest
from scipy import signal
import yaml

G = units.STANDARD_GRAVITY_M_S2
RANGES = sensor_accel.field_ranges()


def _inputs(n, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 200.0
    rate = np.column_stack([0.4 * np.sin(t), 0.2 * np.cos(0.7 * t), np.full(n, 0.1)])
    force = np.column_stack([rng.normal(0, 2.0, n), np.full(n, -1.0), np.full(n, G)])
    return rate, np.linspace(10.0, 60.0, n), force


# --- configuration --------------------------------------------------------------------

@pytest.mark.parametrize('name', PRESET_NAMES)
def test_every_preset_reads_back_through_the_one_writer(name):
    config = load_sensor_config(name)
    assert isinstance(config.accelerometer, AccelConfig)
    text = config_yaml(config)
    assert 'accelerometer:' in text
    assert config_from_mapping(yaml.safe_load(text)) == config


def test_a_yaml_without_the_key_gets_the_physics_only_default():
    config = config_from_mapping({})
    assert config.accelerometer == AccelConfig()
    assert load_sensor_config('paper').accelerometer == AccelConfig()
    default = AccelConfig()
    assert default.terms.enabled() == AccelTerms.names()
    assert default.range_m_s2 == (16.0 * G,) * 3
    assert not any(default.electronics_noise_m_s2_sqrt_hz + default.bias_instability_m_s2
                   + default.turn_on_bias_sigma_m_s2 + default.lsb_m_s2)


#: Each alias with a value in its datasheet unit and the SI value it stands for.
ALIASES = {
    'electronics_noise_ug_sqrt_hz': (400.0, 400.0 * G * 1e-6),
    'electronics_vrw_m_s_sqrt_h': (0.06, 0.001),
    'bias_instability_mg': (0.05, 0.05 * G * 1e-3),
    'turn_on_bias_mg': (-50.0, -0.05 * G),
    'turn_on_bias_sigma_mg': (16.7, 0.0167 * G),
    'bias_temp_coeff_mg_k': (0.5, 0.0005 * G),
    'scale_factor_temp_coeff_ppm_k': (200.0, 2e-4),
    'scale_factor_error_ppm': (300.0, 3e-4),
    'scale_factor_error_pct': (3.0, 0.03),
    'lsb_mg': (1.0 / 16.384, G / 16384.0),
    'range_g': (2.0, 2.0 * G),
}


@pytest.mark.parametrize('alias', sorted(ALIASES))
def test_datasheet_units_convert_both_ways(alias):
    given, si = ALIASES[alias]
    field = sensor_accel.YAML_ALIASES[alias][0]
    config = accel_from_mapping({alias: given})
    np.testing.assert_allclose(getattr(config, field), (si,) * 3, rtol=1e-12)
    written = sensor_accel.accel_yaml_value(config, [YamlKey(alias, '.6g')])[alias]
    np.testing.assert_allclose(np.array(written, dtype=float), given, rtol=1e-6)
    back = accel_from_mapping(yaml.safe_load(yaml.safe_dump({alias: np.asarray(
        written, dtype=float).tolist()})))
    np.testing.assert_allclose(getattr(back, field), getattr(config, field), rtol=1e-6)


def test_the_misalignment_alias_and_a_preset_layout_read_back_exactly():
    figures = {'misalignment_pct': [[0.0, 0.8, -1.2], [1.0, 0.0, 0.5], [-0.6, 1.5, 0.0]],
               'electronics_noise_ug_sqrt_hz': 399.95, 'range_g': 2.0, 'lsb_mg': 0.06103515625,
               'bias_temp_coeff_mg_k': [0.4, -0.3, 0.6], 'terms': {'random_walk': False}}
    config = config_from_mapping({'accelerometer': figures})
    assert config.accelerometer.misalignment[0][2] == pytest.approx(-0.012)
    keys = [YamlKey(n, scalar=not isinstance(v, list)) for n, v in figures.items()
            if n != 'terms'] + [YamlKey('terms')]
    text = config_yaml(config, [YamlKey('accelerometer', parts=tuple(keys))])
    assert config_from_mapping(yaml.safe_load(text)) == config
    assert 'range_g: 2.0\n' in text and 'random_walk: false' in text


@pytest.mark.parametrize('mapping,match', [
    ({'lsb_m_s2': 1e-12}, r'AccelConfig.lsb_m_s2\[0\] = 1e-12 is out of range: allowed 0 '
                          r'\(no quantisation\) or \[1e-09, 10\] m/s\^2'),
    ({'lsb_m_s2': 5e-324}, r'lsb_m_s2\[0\] = 5e-324 is out of range'),
    ({'range_m_s2': 0.0}, r'AccelConfig.range_m_s2\[0\] = 0.0 is out of range: allowed \(0.0, '),
    ({'electronics_noise_m_s2_sqrt_hz': [0.0, math.nan, 0.0]},
     r'electronics_noise_m_s2_sqrt_hz\[1\] = nan is out of range'),
    ({'bias_temp_coeff_m_s2_k': 1.0},
     r'bias_temp_coeff_m_s2_k\[0\] = 1.0 is out of range: allowed \[-0.1, 0.1\] m/s\^2/K'),
    ({'scale_factor_temp_coeff_ppm_k': 2e5}, r'scale_factor_temp_coeff_per_k\[0\] = 0\.\d+ is '
                                             r'out of range: allowed \[-0.01, 0.01\] 1/K'),
    ({'misalignment': [[0.1, 0, 0], [0, 0, 0], [0, 0, 0]]}, 'diagonal'),
    ({'output_filter_order': 2.5}, 'choose 1, 2, 3 or 4'),
    ({'bias_instability_band_s': [10.0, 1.0]}, 'must not exceed'),
    ({'terms': {'rate_random_walk': True}}, 'unknown term'),
    ({'nonsense': 1}, "unknown key 'nonsense'"),
    ({'range_g': 2.0, 'range_m_s2': 19.6}, 'range_m_s2 is set twice'),
    ({'turn_on_bias_mg': 'big'}, 'turn_on_bias_mg = .big. is not a number'),
    ({'electronics_noise_m_s2_sqrt_hz': True}, 'not a number'),
])
def test_bad_accelerometer_values_are_refused_in_one_line(mapping, match):
    with pytest.raises(ValueError, match=match) as error:
        config_from_mapping({'accelerometer': mapping}, source='part.yaml')
    text = str(error.value)
    assert '\n' not in text and text.startswith('part.yaml: accelerometer: ')


def _ends(name):
    kind, low, high, _, low_open = RANGES[name]
    span = max(abs(high - low), 1.0)
    inside = [high, (low + 1e-9 * max(1.0, abs(low))) if low_open else low]
    beyond = [high + 1e-6 * span, low if low_open else low - 1e-6 * span]
    if name == 'output_filter_order':
        inside, beyond = [int(high), int(low)], [int(high) + 1, int(low) - 1]
    if name == 'bias_instability_band_s':
        return [(low, high)], [(low * 0.999, high), (low, high * 1.001)]
    if kind == 'matrix':
        def off(x):
            return tuple(tuple(0.0 if i == j else x for j in range(3)) for i in range(3))
        return [off(v) for v in inside], [off(v) for v in beyond]
    return inside, beyond


@pytest.mark.parametrize('name', sorted(RANGES))
def test_every_field_at_the_ends_of_its_range_runs_or_says_why(name):
    base = load_sensor_config('consumer')
    inside, beyond = _ends(name)
    for value in beyond:
        with pytest.raises(ValueError, match=f'AccelConfig.{name}.*(out of range|allowed)'):
            replace(base.accelerometer, **{name: value})
    for value in inside:
        config = replace(base, accelerometer=replace(base.accelerometer, **{name: value}))
        try:
            model = ImuModel(config, 1000.0, np.random.default_rng(3))
            batch = model.run(*_inputs(300))
            sample = model.step((0.1, 0.0, 0.0), 40.0, (1.0, 0.0, G))
        except ValueError as exc:
            assert '\n' not in str(exc) and 'output_filter_hz' in str(exc), str(exc)
            continue
        assert np.all(np.isfinite(batch.accel_m_s2)), (name, value)
        assert np.all(np.isfinite(sample.accel_m_s2)), (name, value)
        assert np.all(np.isfinite(model.accel_white_noise_sigma_m_s2))


# --- the model ------------------------------------------------------------------------

@pytest.mark.parametrize('name', PRESET_NAMES)
def test_the_gyro_is_bit_for_bit_a_gyro_models_with_the_accelerometer_on(name):
    config = load_sensor_config(name)
    rate, temp, force = _inputs(4000)
    gyro = GyroModel(config, 200.0, np.random.default_rng(7)).run(rate, temp, force)
    imu = ImuModel(config, 200.0, np.random.default_rng(7)).run(rate, temp, force)
    for field in ('gyro_rad_s', 'die_temp_c', 'bias_rad_s', 'scale_factor', 'saturated',
                  'output_delay_s'):
        assert np.array_equal(getattr(gyro, field), getattr(imu, field)), field
    # and without a specific force, as a noise run gives none
    a = GyroModel(config, 200.0, np.random.default_rng(8)).run(rate, temp)
    b = ImuModel(config, 200.0, np.random.default_rng(8)).run(rate, temp)
    assert np.array_equal(a.gyro_rad_s, b.gyro_rad_s)
    assert np.std(b.accel_m_s2) > 0.0


def test_whatever_spawns_after_the_model_draws_what_it_drew_before():
    first, second = np.random.default_rng(9), np.random.default_rng(9)
    GyroModel(load_sensor_config('consumer'), 100.0, first)
    ImuModel(load_sensor_config('consumer'), 100.0, second)
    assert first.bit_generator.seed_seq.n_children_spawned == \
        second.bit_generator.seed_seq.n_children_spawned
    assert np.array_equal(first.bit_generator.seed_seq.spawn(1)[0].generate_state(4),
                          second.bit_generator.seed_seq.spawn(1)[0].generate_state(4))


@pytest.mark.parametrize('seed', range(4))
def test_batch_and_streaming_agree_bit_for_bit_for_random_splits(seed):
    config = load_sensor_config('consumer')
    rate, temp, force = _inputs(3000, seed)
    whole = ImuModel(config, 200.0, np.random.default_rng(seed)).run(rate, temp, force)
    model = ImuModel(config, 200.0, np.random.default_rng(seed))
    cuts = np.sort(np.random.default_rng(100 + seed).choice(np.arange(1, 3000), 8,
                                                            replace=False))
    parts = []
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, 3000]):
        if b - a <= 3:
            parts += [model.step(rate[k], temp[k], force[k]) for k in range(a, b)]
        else:
            parts.append(model.run(rate[a:b], temp[a:b], force[a:b]))
    for field in ('accel_m_s2', 'accel_bias_m_s2', 'accel_scale_factor', 'accel_saturated',
                  'gyro_rad_s', 'die_temp_c'):
        joined = np.concatenate([np.reshape(getattr(p, field), (-1, 3) if field != 'die_temp_c'
                                            else (-1,)) for p in parts])
        assert np.array_equal(joined, getattr(whole, field)), field
    assert np.array_equal(whole.true_specific_force_m_s2, force)


def test_a_copy_continues_identically_and_a_held_force_is_a_constant_one():
    config = load_sensor_config('tactical')
    rate, temp, _ = _inputs(500)
    model = ImuModel(config, 200.0, np.random.default_rng(2))
    model.run(rate[:100], temp[:100], (0.0, 0.0, G))
    twin = model.copy()
    a = model.run(rate[100:], temp[100:], (0.0, 0.0, G))
    b = twin.run(rate[100:], temp[100:], np.tile([0.0, 0.0, G], (400, 1)))
    assert np.array_equal(a.accel_m_s2, b.accel_m_s2)
    assert np.array_equal(a.gyro_rad_s, b.gyro_rad_s)


def test_a_step_of_plain_floats_is_the_step_of_arrays_and_of_run_bit_for_bit():
    """The driver's inputs (tuples of floats) take a shorter path through ``step``: same bits."""
    config = load_sensor_config('paper')
    rate, temp, force = _inputs(400, seed=8)
    whole = ImuModel(config, 200.0, np.random.default_rng(3)).run(rate, temp, force)
    plain, arrays = (ImuModel(config, 200.0, np.random.default_rng(3)) for _ in range(2))
    for k in range(400):
        a = plain.step(tuple(rate[k].tolist()), float(temp[k]), tuple(force[k].tolist()))
        b = arrays.step(rate[k], temp[k], force[k])
        for name in a.__dataclass_fields__:
            want = np.asarray(getattr(whole, name))[k].tobytes()
            assert np.asarray(getattr(a, name)).tobytes() == want, (k, name)
            assert np.asarray(getattr(b, name)).tobytes() == want, (k, name)
    # bad values in plain floats are refused as before, naming the field
    for args, match in ((((0.0, math.nan, 0.0), 25.0, (0.0, 0.0, G)), 'rate_rad_s'),
                        (((0.0, 0.0, 0.0), 25.0, (0.0, math.inf, G)), 'specific_force'),
                        (((0.0, 0.0, 0.0), 1e4, (0.0, 0.0, G)), 'ambient_temp_c')):
        with pytest.raises(ValueError, match=match):
            plain.step(*args)
    assert plain.sample_index == 400


def test_a_snapshot_restored_continues_identically_any_number_of_times():
    config = load_sensor_config('consumer')
    rate, temp, force = _inputs(6000, seed=3)
    model = ImuModel(config, 200.0, np.random.default_rng(5))
    model.run(rate[:700], temp[:700], force[:700])
    snap = model.snapshot()
    # past several refills of the normal streams (MIN_REFILL) and back, twice
    first = model.run(rate[700:], temp[700:], force[700:])
    for _ in range(2):
        model.restore(snap)
        again = [model.step(rate[700], temp[700], force[700])]
        again.append(model.run(rate[701:], temp[701:], force[701:]))
        for name in ('gyro_rad_s', 'accel_m_s2', 'bias_rad_s', 'accel_bias_m_s2', 'die_temp_c',
                     'output_delay_s'):
            joined = np.concatenate([np.atleast_1d(getattr(again[0], name))[None]
                                     if name not in ('die_temp_c', 'output_delay_s')
                                     else [getattr(again[0], name)], getattr(again[1], name)])
            assert joined.tobytes() == getattr(first, name).tobytes(), name
    assert model.sample_index == 6000
    # a snapshot of another plan is refused, and nothing moves
    model.update_config(load_sensor_config('tactical'))
    with pytest.raises(ValueError, match='another plan'):
        model.restore(snap)
    assert model.sample_index == 6000


def test_the_accelerometer_terms_act_as_configured():
    acc = AccelConfig(turn_on_bias_m_s2=(0.1, -0.2, 0.3), scale_factor_error=(0.01, 0.0, -0.02),
                      scale_factor_temp_coeff_per_k=(1e-3, 0.0, 0.0),
                      bias_temp_coeff_m_s2_k=(0.0, 0.01, 0.0),
                      misalignment=((0.0, 0.02, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
                      terms=replace(AccelTerms(), mechanical_noise=False))
    config = replace(SensorConfig.ideal(), accelerometer=acc)
    force = np.array([[1.0, 2.0, G], [3.0, -1.0, 0.5]])
    batch = ImuModel(config, 100.0, np.random.default_rng(0)).run(np.zeros((2, 3)),
                                                                  [35.0, 35.0], force)
    dt = 35.0 - 25.0
    x = force[:, 0] + 0.02 * force[:, 1]
    np.testing.assert_allclose(batch.accel_m_s2[:, 0], 1.01 * (1 + 1e-3 * dt) * x + 0.1,
                               rtol=1e-12)
    np.testing.assert_allclose(batch.accel_m_s2[:, 1], force[:, 1] - 0.2 + 0.01 * dt,
                               rtol=1e-12)
    np.testing.assert_allclose(batch.accel_m_s2[:, 2], 0.98 * force[:, 2] + 0.3, rtol=1e-12)
    ideal = ImuModel(SensorConfig.ideal(), 100.0, np.random.default_rng(0)).run(
        np.zeros((2, 3)), 25.0, force)
    assert np.array_equal(ideal.accel_m_s2, force)


def test_saturation_quantisation_and_bad_input():
    config = load_sensor_config('consumer')
    model = ImuModel(config, 200.0, np.random.default_rng(1))
    force = np.tile([0.0, 0.0, 50.0], (400, 1))        # 5 g on a +-2 g part
    batch = model.run(np.zeros((400, 3)), 25.0, force)
    lsb = G / 16384.0
    assert batch.accel_saturated[:, 2].all() and not batch.accel_saturated[:, :2].any()
    assert np.max(batch.accel_m_s2[:, 2]) <= 2.0 * G
    steps = batch.accel_m_s2 / lsb
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    before = model.sample_index
    for bad in ([0.0, math.nan, 0.0], [0.0, 0.0, math.inf], [2e6, 0.0, 0.0]):
        with pytest.raises(ValueError, match=r'specific_force_m_s2 = .* is out of range: '
                                             r'allowed finite'):
            model.run(np.zeros((2, 3)), 25.0, np.tile(bad, (2, 1)))
        with pytest.raises(ValueError, match='specific_force_m_s2'):
            model.step((0.0, 0.0, 0.0), 25.0, bad)
    with pytest.raises(ValueError, match=r'has shape \(2, 2\)'):
        model.run(np.zeros((5, 3)), 25.0, np.zeros((2, 2)))
    assert model.sample_index == before


def test_an_output_filter_above_nyquist_is_refused_naming_the_accelerometer():
    config = replace(SensorConfig(), accelerometer=AccelConfig(output_filter_hz=60.0))
    with pytest.raises(ValueError, match=r'SensorConfig.accelerometer.output_filter_hz = 60.0 '
                                         r'is out of range at 100 Hz'):
        ImuModel(config, 100.0, np.random.default_rng(0))
    model = ImuModel(config, 200.0, np.random.default_rng(0))
    with pytest.raises(ValueError, match='accelerometer.output_filter_hz'):
        model.set_sample_rate(100.0)
    assert model.sample_rate_hz == 200.0          # neither sensor changed


# --- honest figures ------------------------------------------------------------------

def _brownian_one_sided(device, temp_c):
    """sqrt(4 k_B T c) / m from the lumped parameters (Gabrielson 1993), m/s^2/sqrt(Hz)."""
    p = first_order.lumped_parameters(device, temp_c)
    kelvin = temp_c + units.ZERO_CELSIUS_K
    return math.sqrt(4.0 * units.BOLTZMANN_J_K * kelvin * float(p.damping_sense_n_s_m)) \
        / float(p.mass_kg)


@pytest.mark.parametrize('temp_c', [-20.0, 25.0, 85.0])
def test_the_paper_accelerometer_is_the_brownian_noise_of_the_proof_mass(temp_c):
    config = replace(load_sensor_config('paper'), initial_die_temp_c=temp_c)
    fs = 1000.0
    model = ImuModel(config, fs, np.random.default_rng(4))
    a_n = _brownian_one_sided(config.device[0], temp_c)
    # the published per-sample sigma: the two-sided density a_n / sqrt(2) times sqrt(fs)
    np.testing.assert_allclose(model.accel_white_noise_sigma_m_s2,
                               a_n / math.sqrt(2.0) * math.sqrt(fs), rtol=1e-9)
    # and the output's one-sided PSD is a_n^2 (Welch: 2^18 samples, 511 segments)
    n = 1 << 18
    batch = model.run(np.zeros((n, 3)), np.full(n, temp_c), (0.0, 0.0, G))
    for axis in range(3):
        freq, psd = signal.welch(batch.accel_m_s2[:, axis], fs=fs, nperseg=1024)
        level = np.mean(psd[(freq > 5.0) & (freq < 450.0)])
        assert level == pytest.approx(a_n ** 2, rel=0.02), axis


def test_the_paper_brownian_noise_is_a_few_ug_and_moves_with_the_gas():
    paper = load_sensor_config('paper').device[0]
    assert _brownian_one_sided(paper, 25.0) / math.sqrt(2.0) / (G * 1e-6) == pytest.approx(
        6.52, abs=0.01)
    sealed = load_sensor_config('tactical').device[0]            # 100 Pa
    assert _brownian_one_sided(sealed, 25.0) < 0.2 * _brownian_one_sided(paper, 25.0)


@pytest.mark.parametrize('name,figure', [('consumer', 400.0), ('tactical', 0.06 / 60.0)])
def test_preset_noise_totals_the_datasheet_density_in_quadrature(name, figure):
    config = load_sensor_config(name)
    physics = _brownian_one_sided(config.device[0], 25.0) / math.sqrt(2.0)
    elec = config.accelerometer.electronics_noise_m_s2_sqrt_hz[0]
    total = math.hypot(physics, elec)
    want = figure * G * 1e-6 if name == 'consumer' else figure
    assert total == pytest.approx(want, rel=1e-4)


def test_an_allan_fit_recovers_the_configured_noise_terms():
    """
    N, B and K of a static run fall inside the 95 % intervals of the IEEE 952 fit.

    30 fits (10 seeds x 3 axes): at the nominal 95 % coverage, 25 or more
    hits per term happen with probability 0.98; a wrong discretisation (a
    factor sqrt(2) in N, or K sqrt(dt) off) would miss nearly every time.
    """
    n_density, b_level, k_walk = 2e-3, 4e-4, 4e-5
    acc = AccelConfig(terms=replace(AccelTerms(), mechanical_noise=False),
                      electronics_noise_m_s2_sqrt_hz=n_density, bias_instability_m_s2=b_level,
                      random_walk_m_s3_sqrt_hz=k_walk)
    config = replace(SensorConfig.ideal(), accelerometer=acc)
    fs, n = 50.0, int(4 * 3600 * 50.0)
    hits = dict.fromkeys(('arw', 'bias_instability', 'rrw'), 0)
    truth = {'arw': n_density, 'bias_instability': b_level, 'rrw': k_walk}
    for seed in range(10):
        batch = ImuModel(config, fs, np.random.default_rng(seed)).run(
            np.zeros((n, 3)), 25.0, (0.0, 0.0, G))
        for axis in range(3):
            _, fit = identify([batch.accel_m_s2[:, axis]], fs)
            for term, value in truth.items():
                hits[term] += fit.intervals[term].low <= value <= fit.intervals[term].high
    assert all(count >= 25 for count in hits.values()), hits


# --- the offline paths carry the accelerometer ----------------------------------------

def test_a_static_bags_acceleration_variance_matches_its_published_covariance(tmp_path):
    from gyro_emulator.emulation import simulate
    from gyro_emulator.recording import bag, record
    path = str(tmp_path / 'static')
    simulate.write_record(path, 'consumer', 'static', 120.0, 200.0, seed=6, start_time_ns=0)
    stream = record.read_stream(bag.BagReader(path), '/imu/data_raw')
    accel = stream.field('linear_acceleration')
    cov = stream.field('linear_acceleration_covariance')
    assert len(accel) == 24_000 and np.all(cov == cov[0])
    published = cov[0].reshape(3, 3)
    assert np.count_nonzero(published - np.diag(np.diag(published))) == 0
    # within 3 sigma of the turn-on bias (16.7, 16.7, 26.7 mg) and the 0.8 % gain error on z
    assert np.all(np.abs(np.mean(accel, axis=0) - [0.0, 0.0, G]) < [0.5, 0.5, 0.87])
    variance = np.var(accel, axis=0, ddof=1)
    np.testing.assert_allclose(variance, np.diag(published), rtol=0.10)
    gyro_cov = stream.field('angular_velocity_covariance')[0].reshape(3, 3)
    assert np.all(np.diag(gyro_cov) > 0.0)
    assert stream.field('orientation_covariance[0]')[0] == -1.0


def test_simulate_csv_has_the_accelerometer_columns_and_the_gyro_of_before(tmp_path):
    from gyro_emulator.emulation import simulate
    from gyro_emulator.emulation.profiles import make_profile
    from gyro_emulator.recording import csvio
    out = str(tmp_path / 'steps.csv')
    simulate.write_record(out, 'consumer', 'steps', 20.0, 100.0, seed=3)
    columns = csvio.read_csv(out)
    assert tuple(columns) == simulate.CSV_COLUMNS
    assert simulate.CSV_COLUMNS[-3:] == ('accel_x_m_s2', 'accel_y_m_s2', 'accel_z_m_s2')
    assert abs(np.mean(columns['accel_z_m_s2']) - G) < 0.87     # 3 sigma turn-on + gain
    # the built-in profile turns about z only: gravity stays exactly on z, so the gyro
    # (g-sensitivity on in this preset) is what a GyroModel gives with a level force
    config = load_sensor_config('consumer')
    model = GyroModel(config, 100.0, np.random.default_rng(3))
    t = np.arange(2000) * model.sample_period_s
    samples = make_profile('steps', 20.0).samples(t)
    gyro = model.run(samples.rate_rad_s, samples.temp_c, np.tile([0.0, 0.0, G], (2000, 1)))
    for i, axis in enumerate('xyz'):
        np.testing.assert_array_equal(columns[f'gyro_{axis}_rad_s'],
                                      [float(f'{v:.10g}') for v in gyro.gyro_rad_s[:, i]])


def test_a_turn_about_x_in_a_profile_moves_gravity_from_z_to_y():
    from gyro_emulator.emulation import simulate
    from gyro_emulator.emulation.profiles import profile_from_mapping
    profile = profile_from_mapping({'segments': [
        {'duration_s': 1.0, 'rate_deg_s': [0, 0, 0]},
        {'duration_s': 2.0, 'rate_deg_s': [45, 0, 0]},
        {'duration_s': 2.0, 'rate_deg_s': [0, 0, 0]}]})
    config = replace(load_sensor_config('paper'), accelerometer=AccelConfig.ideal())
    _, samples, batch = simulate.run_simulation(config, profile, 5.0, 200.0, seed=1)
    after = slice(700, 1000)                  # after the turn (at 3 s + one sample)
    np.testing.assert_allclose(batch.accel_m_s2[after], np.tile([0.0, G, 0.0], (300, 1)),
                               rtol=0, atol=0.01 * G)
    np.testing.assert_allclose(batch.accel_m_s2[:200], np.tile([0.0, 0.0, G], (200, 1)),
                               rtol=0, atol=1e-12)
    assert np.array_equal(samples.accel_m_s2, batch.true_specific_force_m_s2)
    # a profile that gives its specific force keeps it, and refuses motion keys with it
    given = profile_from_mapping({'accel_m_s2': [1.0, 2.0, 3.0],
                                  'segments': [{'duration_s': 1.0, 'rate_deg_s': [90, 0, 0]}]})
    assert np.array_equal(given.samples(np.array([0.5])).accel_m_s2, [[1.0, 2.0, 3.0]])
    with pytest.raises(ValueError, match='linear_accel_m_s2 is for a specific force left to'):
        profile_from_mapping({'accel_m_s2': [0, 0, G], 'segments': [
            {'duration_s': 1.0, 'linear_accel_m_s2': [1, 0, 0]}]})
    with pytest.raises(ValueError, match='gravity_m_s2 = 0.0 is out of range'):
        profile_from_mapping({'gravity_m_s2': 0.0, 'segments': [{'duration_s': 1.0}]})


def test_replay_drives_the_accelerometer_from_the_bag(tmp_path):
    from gyro_emulator.analysis.replay.inputs import emulate, load_inputs
    from gyro_emulator.emulation import simulate
    path = str(tmp_path / 'sim')
    simulate.write_record(path, 'consumer', 'steps', 10.0, 100.0, seed=2, start_time_ns=0)
    _, samples, batch = simulate.run_simulation('consumer', 'steps', 10.0, 100.0, seed=2)
    # command source: the bag's applied acceleration, gravity turned in from the attitude
    commands = load_inputs(path, source='command')
    assert commands.accel_m_s2 is None
    np.testing.assert_array_equal(commands.linear_accel_m_s2, samples.linear_accel_m_s2)
    np.testing.assert_array_equal(commands.completed().accel_m_s2, samples.accel_m_s2)
    _, replayed = emulate(commands, 'consumer', 2)
    np.testing.assert_array_equal(replayed.accel_m_s2, batch.accel_m_s2)
    # imu source (a simulator's Imu): its linear_acceleration is the specific force
    imu = load_inputs(path, source='imu')
    np.testing.assert_array_equal(imu.accel_m_s2, batch.accel_m_s2)
    _, from_imu = emulate(imu, 'consumer', 2)
    np.testing.assert_array_equal(from_imu.true_specific_force_m_s2, batch.accel_m_s2)
