"""The 3-axis error model: exactness, batch = streaming, every term, configuration."""

from dataclasses import fields, replace
import math
import os

from gyro_emulator import units
from gyro_emulator.physics import dynamics, first_order
from gyro_emulator.physics.presets import PAPER_DEVICE
from gyro_emulator.resources import config_dir
from gyro_emulator.sensor import noise, streams
from gyro_emulator.sensor.config import (config_from_mapping, ErrorTerms, load_sensor_config,
                                         PRESET_NAMES, SensorConfig)
from gyro_emulator.sensor.model import GyroModel, SensorBatch, TemperatureTable
import noise_reference
import numpy as np
import pytest
from scipy import signal

FS = 200.0

#: Every term on with non-zero values.
FULL = SensorConfig(
    output_filter_hz=40.0, thermal_time_constant_s=20.0, self_heating_c=1.5,
    turn_on_bias_rad_s=(0.01, -0.02, 0.005), turn_on_bias_sigma_rad_s=0.002,
    bias_temp_coeff_rad_s_k=(1e-4, -2e-4, 5e-5), bias_temp_coeff2_rad_s_k2=1e-6,
    electronics_noise_rad_s_sqrt_hz=2e-4, bias_instability_rad_s=5e-5,
    rate_random_walk_rad_s_sqrt_s=2e-5, scale_factor_error=(0.01, -0.02, 0.003),
    nonlinearity_s_rad=1e-3, misalignment=((0, 0.01, -0.004), (0.003, 0, 0.002),
                                           (-0.006, 0.005, 0)),
    g_sensitivity_rad_s_m_s2=((1e-4, 2e-5, 0), (0, 1e-4, 0), (3e-5, 0, 1e-4)),
    lsb_rad_s=1e-4, range_rad_s=4.0, latency_s=0.003, timestamp_jitter_s=2e-4,
    clock_drift_ppm=50.0, mode_split_hz=(0.0, 20.0, 0.0))


def _inputs(n, seed=0):
    rng = np.random.default_rng(seed)
    rate = np.cumsum(rng.standard_normal((n, 3)), axis=0) * 0.02
    rate[n // 2: n // 2 + 5] = 5.0                        # saturates
    temp = 25.0 + 15.0 * np.sin(np.arange(n) / 300.0)
    accel = np.array([0.3, -0.2, 9.8]) + rng.standard_normal((n, 3)) * 0.5
    return rate, temp, accel


def _assert_batches_equal(a, b):
    for f in fields(SensorBatch):
        assert np.array_equal(getattr(a, f.name), getattr(b, f.name)), f.name


def test_ideal_sensor_outputs_the_true_rate_exactly():
    rate, temp, accel = _inputs(3000)
    out = GyroModel(SensorConfig.ideal(), FS, np.random.default_rng(1)).run(rate, temp, accel)
    assert np.array_equal(out.gyro_rad_s, rate)
    assert np.array_equal(out.bias_rad_s, np.zeros_like(rate))
    assert np.array_equal(out.scale_factor, np.ones_like(rate))
    assert np.array_equal(out.die_temp_c, temp)
    assert not out.saturated.any() and not out.output_delay_s.any()


@pytest.mark.parametrize('preset', [None] + list(PRESET_NAMES))
def test_run_equals_step_bit_for_bit(preset):
    config = FULL if preset is None else load_sensor_config(preset)
    rate, temp, accel = _inputs(1500)
    batch = GyroModel(config, FS, np.random.default_rng(42)).run(rate, temp, accel)
    model = GyroModel(config, FS, np.random.default_rng(42))
    samples = [model.step(rate[i], temp[i], accel[i]) for i in range(len(temp))]
    stepped = SensorBatch(**{f.name: np.array([getattr(s, f.name) for s in samples])
                             for f in fields(SensorBatch)})
    _assert_batches_equal(batch, stepped)


def test_run_is_independent_of_how_the_record_is_split():
    rate, temp, accel = _inputs(30000, seed=3)
    whole = GyroModel(FULL, FS, np.random.default_rng(9)).run(rate, temp, accel)
    model = GyroModel(FULL, FS, np.random.default_rng(9))
    rng = np.random.default_rng(0)
    cuts = np.sort(rng.choice(np.arange(1, 30000), size=12, replace=False))
    parts = [model.run(rate[i], temp[i], accel[i]) for i in np.split(np.arange(30000), cuts)]
    _assert_batches_equal(whole, SensorBatch.concatenate(parts))


def test_seeds_differ_and_repeat():
    rate, temp, accel = _inputs(500)
    a = GyroModel(FULL, FS, np.random.default_rng(1)).run(rate, temp, accel)
    b = GyroModel(FULL, FS, np.random.default_rng(1)).run(rate, temp, accel)
    c = GyroModel(FULL, FS, np.random.default_rng(2)).run(rate, temp, accel)
    _assert_batches_equal(a, b)
    assert not np.array_equal(a.gyro_rad_s, c.gyro_rad_s)


def _only(name, **values):
    return replace(SensorConfig.ideal(), terms=replace(ErrorTerms.none(), **{name: True}),
                   **values)


def test_scale_factor_temperature_is_the_physics_ratio():
    temps = np.linspace(-50.0, 190.0, 97)
    rate = np.tile([0.3, -1.0, 2.0], (len(temps), 1))
    out = GyroModel(_only('scale_factor_temperature'), FS,
                    np.random.default_rng(0)).run(rate, temps)
    ratio = first_order.scale_factor_ratio(PAPER_DEVICE, temps)
    np.testing.assert_allclose(out.gyro_rad_s, rate * ratio[:, np.newaxis], rtol=1e-10)
    np.testing.assert_allclose(out.scale_factor[:, 2], ratio, rtol=1e-10)


def test_temperature_table_accuracy():
    table = TemperatureTable(lambda t: first_order.scale_factor_ratio(PAPER_DEVICE, t))
    temps = np.random.default_rng(0).uniform(-60.0, 200.0, 2000)
    np.testing.assert_allclose(table(temps), first_order.scale_factor_ratio(PAPER_DEVICE, temps),
                               rtol=1e-10)


def test_gain_nonlinearity_misalignment_and_g_sensitivity():
    rate, temp, accel = _inputs(200)
    mis = np.array(FULL.misalignment)
    g_sens = np.array(FULL.g_sensitivity_rad_s_m_s2)
    cases = (
        ('scale_factor_error', lambda: rate * (1 + np.array(FULL.scale_factor_error))),
        ('nonlinearity', lambda: rate + 1e-3 * rate ** 2),
        ('misalignment', lambda: rate @ (np.eye(3) + mis).T),
        ('g_sensitivity', lambda: rate + accel @ g_sens.T),
    )
    for name, expect in cases:
        config = replace(FULL, terms=replace(ErrorTerms.none(), **{name: True}))
        out = GyroModel(config, FS, np.random.default_rng(0)).run(rate, temp, accel)
        np.testing.assert_allclose(out.gyro_rad_s, expect(), rtol=1e-12, atol=1e-15,
                                   err_msg=name)


def test_turn_on_bias_fixed_and_random_parts():
    rate, temp, _ = _inputs(100)
    fixed = replace(FULL, turn_on_bias_sigma_rad_s=0.0,
                    terms=replace(ErrorTerms.none(), turn_on_bias=True))
    out = GyroModel(fixed, FS, np.random.default_rng(0)).run(rate, temp)
    np.testing.assert_allclose(out.gyro_rad_s - rate,
                               np.tile(FULL.turn_on_bias_rad_s, (100, 1)), atol=1e-15)
    spread = replace(fixed, turn_on_bias_rad_s=0.0, turn_on_bias_sigma_rad_s=0.01)
    draws = np.array([GyroModel(spread, FS, np.random.default_rng(s)).run(rate, temp)
                      .bias_rad_s[0] for s in range(300)])
    assert np.all(np.ptp(GyroModel(spread, FS, np.random.default_rng(1)).run(
        rate, temp).bias_rad_s, axis=0) == 0)            # constant in a run
    assert draws.std() == pytest.approx(0.01, rel=5 / math.sqrt(2 * 900))


def test_bias_temperature_coefficients():
    rate, temp, _ = _inputs(300)
    out = GyroModel(replace(FULL, terms=replace(ErrorTerms.none(), bias_temperature=True)),
                    FS, np.random.default_rng(0)).run(rate, temp)
    d_t = (temp - 25.0)[:, np.newaxis]
    expect = np.array(FULL.bias_temp_coeff_rad_s_k) * d_t + 1e-6 * d_t ** 2
    np.testing.assert_allclose(out.bias_rad_s, expect, rtol=1e-12, atol=1e-18)


def test_thermal_lag_is_the_exact_first_order_response():
    tau = 20.0
    config = _only('thermal_lag', thermal_time_constant_s=tau, initial_die_temp_c=25.0)
    n = 4000
    out = GyroModel(config, FS, np.random.default_rng(0)).run(np.zeros((n, 3)), 35.0)
    t_end = (np.arange(n) + 1) / FS                 # ambient held over each period
    np.testing.assert_allclose(out.die_temp_c, 35.0 - 10.0 * np.exp(-t_end / tau),
                               rtol=1e-12)


def test_sense_dynamics_match_the_dynamics_module():
    config = _only('sense_dynamics', mode_split_hz=(0.0, 30.0, 0.0))
    n = 400
    rate = np.zeros((n, 3))
    rate[100:] = [0.5, 0.5, -0.2]
    out = GyroModel(config, 2000.0, np.random.default_rng(0)).run(rate, 25.0)
    for axis, split in ((0, 0.0), (1, 30.0)):
        disc = dynamics.rate_channel_discrete(PAPER_DEVICE, 2000.0, 25.0, split)
        ref, _ = dynamics.rate_channel_filter(disc, rate[:, axis])
        np.testing.assert_allclose(out.gyro_rad_s[:, axis], ref, rtol=1e-9, atol=1e-12)
    assert out.gyro_rad_s[-1, 0] == pytest.approx(0.5, rel=1e-9)    # DC gain 1


def test_sense_dynamics_do_not_delay_the_samples():
    """A sample reflects the rate at its own instant (tau ~ 1 ms << dt at 100 Hz)."""
    config = _only('sense_dynamics', mode_split_hz=(0.0, 30.0, 0.0))
    rate = np.zeros((300, 3))
    rate[100:] = [0.5, 0.5, -0.2]
    out = GyroModel(config, 100.0, np.random.default_rng(0)).run(rate, 25.0).gyro_rad_s
    np.testing.assert_allclose(out[:100], 0.0, atol=1e-12)
    # the step is in the sample it is applied at: exp(-sigma dt) ~ 5e-5 is left of it
    np.testing.assert_allclose(out[100], [0.5, 0.5, -0.2], rtol=1e-3)
    lags = np.arange(-3, 4)
    corr = [np.dot(np.diff(rate[:, 0])[3:-3], np.roll(np.diff(out[:, 0]), -k)[3:-3])
            for k in lags]
    assert lags[int(np.argmax(corr))] == 0


def test_output_filter_is_3db_down_at_its_cutoff():
    fs, cutoff = 1000.0, 50.0
    t = np.arange(20000) / fs
    rate = np.zeros((len(t), 3))
    rate[:, 0] = np.sin(2 * np.pi * cutoff * t)
    rate[:, 1] = 0.7
    out = GyroModel(_only('output_filter', output_filter_hz=cutoff), fs,
                    np.random.default_rng(0)).run(rate, 25.0)
    tail = out.gyro_rad_s[10000:, 0]
    assert np.sqrt(2 * np.mean(tail ** 2)) == pytest.approx(1 / math.sqrt(2), rel=1e-3)
    np.testing.assert_allclose(out.gyro_rad_s[:, 1], 0.7, rtol=1e-12)   # steady start


@pytest.mark.parametrize('lpf_hz', [0.0, 30.0])
def test_white_noise_sigma_matches_output(lpf_hz):
    density = 3e-4
    config = _only('electronics_noise', electronics_noise_rad_s_sqrt_hz=density,
                   output_filter_hz=lpf_hz)
    if lpf_hz:
        config = config.with_terms(output_filter=True)
    model = GyroModel(config, FS, np.random.default_rng(3))
    out = model.run(np.zeros((200_000, 3)), 25.0)
    sigma = model.white_noise_sigma_rad_s
    if not lpf_hz:
        assert sigma == pytest.approx(np.full(3, density * math.sqrt(FS)), rel=1e-12)
    n_eff = 200_000 / (1 + 2 * FS / (2 * max(lpf_hz, FS)))  # correlation of the filter
    np.testing.assert_allclose(out.gyro_rad_s.std(axis=0), sigma,
                               rtol=5 / math.sqrt(2 * n_eff))


def test_mechanical_noise_follows_the_brownian_arw_with_temperature():
    model = GyroModel(_only('mechanical_noise'), FS, np.random.default_rng(4))
    for temp in (25.0, 85.0):
        out = model.run(np.zeros((100_000, 3)), temp)
        expect = noise.brownian_arw_rad_s_sqrt_hz(PAPER_DEVICE, temp) * math.sqrt(FS)
        assert model.white_noise_sigma_rad_s == pytest.approx(np.full(3, expect), rel=1e-9)
        np.testing.assert_allclose(out.gyro_rad_s.std(axis=0), expect,
                                   rtol=5 / math.sqrt(2e5))


def test_quantisation_and_saturation():
    config = replace(FULL, terms=replace(ErrorTerms.none(), quantization=True,
                                         saturation=True), lsb_rad_s=0.01, range_rad_s=1.005)
    rate = np.linspace(-2.0, 2.0, 4001)[:, np.newaxis] * np.ones(3)
    out = GyroModel(config, FS, np.random.default_rng(0)).run(rate, 25.0)
    codes = out.gyro_rad_s / 0.01
    np.testing.assert_allclose(codes, np.round(codes), atol=1e-9)
    inside = np.abs(rate) <= 1.0
    assert np.all(np.abs(out.gyro_rad_s - rate)[inside] <= 0.005 + 1e-12)
    assert np.max(np.abs(out.gyro_rad_s)) == pytest.approx(1.0)    # whole LSBs in range
    np.testing.assert_array_equal(out.saturated, np.abs(rate) > 1.005)


def test_latency_jitter_and_clock_drift():
    n = 20000
    lat = replace(FULL, terms=replace(ErrorTerms.none(), latency=True))
    out = GyroModel(lat, FS, np.random.default_rng(0)).run(np.zeros((n, 3)), 25.0)
    assert np.all(out.output_delay_s == 0.003)
    jit = lat.with_terms(timestamp_jitter=True)
    out = GyroModel(jit, FS, np.random.default_rng(0)).run(np.zeros((n, 3)), 25.0)
    assert np.all(out.output_delay_s >= 0.0)
    assert out.output_delay_s.mean() == pytest.approx(0.003, abs=5 * 2e-4 / math.sqrt(n))
    assert out.output_delay_s.std() == pytest.approx(2e-4, rel=5 / math.sqrt(2 * n))
    # Clock drift sets the part's sample period (its output data rate), never the
    # stamps: the delay stays bounded however long the record (issue 14).
    drift = replace(FULL, terms=replace(ErrorTerms.none(), clock_drift=True))
    model = GyroModel(drift, FS, np.random.default_rng(0))
    out = model.run(np.zeros((n, 3)), 25.0)
    assert np.all(out.output_delay_s == 0.0)
    assert model.sample_period_s == pytest.approx(1.0 / (FS * (1.0 + 50e-6)), rel=1e-15)
    assert GyroModel(lat, FS, np.random.default_rng(0)).sample_period_s == 1.0 / FS


def test_update_config_keeps_the_states():
    rate, temp, accel = _inputs(6000, seed=5)
    ref = GyroModel(FULL, FS, np.random.default_rng(8)).run(rate, temp, accel)
    model = GyroModel(FULL, FS, np.random.default_rng(8))
    first = model.run(rate[:2500], temp[:2500], accel[:2500])
    model.update_config(FULL.with_terms(electronics_noise=False, mechanical_noise=False))
    second = model.run(rate[2500:], temp[2500:], accel[2500:])
    # white noise has its own stream: the bias walk, flicker and die temperature continue
    assert np.array_equal(first.bias_rad_s, ref.bias_rad_s[:2500])
    assert np.array_equal(second.bias_rad_s, ref.bias_rad_s[2500:])
    assert np.array_equal(second.die_temp_c, ref.die_temp_c[2500:])
    assert model.white_noise_sigma_rad_s == pytest.approx(np.zeros(3))


def test_copy_continues_exactly_like_the_original():
    rate, temp, accel = _inputs(3000, seed=6)
    model = GyroModel(FULL, FS, np.random.default_rng(9))
    model.run(rate[:1000], temp[:1000], accel[:1000])
    twin = model.copy()
    ahead = model.run(rate[1000:], temp[1000:], accel[1000:])
    # independent: advancing the original left the copy where it was
    assert (twin.sample_index, model.sample_index) == (1000, 3000)
    again = twin.run(rate[1000:], temp[1000:], accel[1000:])
    for name in ('gyro_rad_s', 'bias_rad_s', 'die_temp_c', 'output_delay_s'):
        assert np.array_equal(getattr(ahead, name), getattr(again, name)), name


@pytest.mark.parametrize('bad', [math.nan, math.inf])
def test_non_finite_inputs_are_rejected(bad):
    model = GyroModel(FULL, FS, np.random.default_rng(0))
    with pytest.raises(ValueError, match='not finite'):
        model.step([0.0, bad, 0.0], 25.0)
    with pytest.raises(ValueError, match='not finite'):
        model.step([0.0, 0.0, 0.0], bad)
    with pytest.raises(ValueError, match='not finite'):
        model.run(np.zeros((3, 3)), [25.0, bad, 25.0])
    with pytest.raises(ValueError, match='accel'):
        model.step([0.0, 0.0, 0.0], 25.0, [0.0, bad, 9.8])


def test_bad_shapes_and_temperatures_are_rejected():
    model = GyroModel(FULL, FS, np.random.default_rng(0))
    assert model.temp_range_c == (-60.0, 200.0)
    with pytest.raises(ValueError, match=r'\(N, 3\)'):
        model.run(np.zeros((5, 2)), 25.0)
    with pytest.raises(ValueError, match='ambient_temp_c = 250.0'):
        model.step(np.zeros(3), 250.0)
    with pytest.raises(ValueError, match='sample_rate_hz'):
        GyroModel(FULL, 0.0, np.random.default_rng(0))
    with pytest.raises(ValueError, match=r'output_filter_hz = 40.0 .*allowed \(0, 25\)'):
        GyroModel(FULL, 50.0, np.random.default_rng(0))


def test_presets_load_from_config_dir():
    assert os.path.isfile(os.path.join(config_dir(), 'sensor_paper.yaml'))
    configs = {name: load_sensor_config(name) for name in PRESET_NAMES}
    assert load_sensor_config() == configs['paper']
    # the paper preset is physics only: its ARW is the Brownian one
    model = GyroModel(configs['paper'], FS, np.random.default_rng(0))
    arw = units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(model.white_noise_sigma_rad_s / math.sqrt(FS))
    np.testing.assert_allclose(arw, units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(
        noise.brownian_arw_rad_s_sqrt_hz(PAPER_DEVICE, 25.0)), rtol=1e-9)
    # datasheet aliases are converted: consumer range 250 deg/s, tactical B 0.5 deg/h
    assert configs['consumer'].range_rad_s[0] == pytest.approx(math.radians(250.0))
    assert configs['tactical'].bias_instability_rad_s[1] == pytest.approx(
        units.deg_h_to_rad_s(0.5))


@pytest.mark.parametrize('mapping,match', [
    ({'bias_instabilty_deg_h': 1.0}, "unknown key 'bias_instabilty_deg_h'"),
    ({'range_rad_s': -1.0},
     r'range_rad_s\[0\] = -1.0 is out of range: allowed \(0.0, 1000.0\] rad/s'),
    ({'latency_s': 2.0}, r'SensorConfig.latency_s = 2.0 is out of range: allowed \[0.0, 1.0\]'),
    ({'lsb_rad_s': [1e-3, 'x', 0]}, 'lsb_rad_s'),
    ({'scale_factor_error': [0.1, 0.2]}, r'scale_factor_error .*shape \(2,\)'),
    ({'misalignment': [[0.1, 0, 0], [0, 0, 0], [0, 0, 0]]}, 'diagonal'),
    ({'terms': {'white_noise': False}}, 'unknown term.*white_noise'),
    ({'terms': {'quantization': 'no'}}, r'ErrorTerms.quantization = .no.'),
    ({'device': 'no_such_device'}, "physics preset 'no_such_device' is unknown"),
    ({'device': {'gas': {'pressure_pa': -5.0}}}, r'Gas.pressure_pa = -5.0'),
    ({'bias_instability_deg_h': 1.0, 'bias_instability_rad_s': 1e-6}, 'set twice'),
])
def test_bad_config_values_name_key_value_and_range(mapping, match):
    with pytest.raises(ValueError, match=match):
        config_from_mapping(mapping)


def test_yaml_loading_errors(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('range_deg_s: [1, 2\n')
    with pytest.raises(ValueError, match='malformed YAML'):
        load_sensor_config(str(bad))
    with pytest.raises(ValueError, match='neither a preset'):
        load_sensor_config('no-such-preset')
    good = tmp_path / 'good.yaml'
    good.write_text('device: paper_sutherland\nelectronics_arw_deg_sqrt_h: 0.2\n'
                    'terms: {quantization: false}\n')
    config = load_sensor_config(str(good))
    assert config.device[2].gas.viscosity_law == 'sutherland'
    assert config.electronics_noise_rad_s_sqrt_hz[0] == pytest.approx(
        units.arw_deg_sqrt_h_to_rad_s_sqrt_hz(0.2))
    assert not config.terms.quantization and config.terms.saturation


def test_config_is_frozen_and_ideal_has_every_term_off():
    ideal = SensorConfig.ideal()
    assert ideal.terms.enabled() == ()
    with pytest.raises(Exception):
        ideal.latency_s = 1.0
    assert FULL.only('latency').terms.enabled() == ('latency',)
    with pytest.raises(ValueError, match='unknown error term'):
        FULL.only('latencyy')


def test_lpf_noise_gain_matches_the_impulse_response():
    b, a = signal.butter(2, 30.0, fs=FS)
    h = signal.lfilter(b, a, np.r_[1.0, np.zeros(5000)])
    config = _only('electronics_noise', electronics_noise_rad_s_sqrt_hz=1e-3,
                   output_filter_hz=30.0).with_terms(output_filter=True)
    sigma = GyroModel(config, FS, np.random.default_rng(0)).white_noise_sigma_rad_s
    assert sigma[0] == pytest.approx(1e-3 * math.sqrt(FS) * math.sqrt(np.sum(h ** 2)),
                                     rel=1e-9)


def _child_normals(seed, stream, n):
    """Return the normals of child ``stream`` of default_rng(seed) via numpy SFC64."""
    child = np.random.default_rng(seed).bit_generator.seed_seq.spawn(11)[stream]
    return np.random.Generator(np.random.SFC64(child)).standard_normal(n)


def test_white_noise_draws_numpys_sfc64_normals_of_its_own_child_stream():
    """Kernel ziggurat = numpy's, bit for bit; white sigma = N sqrt(fs) exactly."""
    density = (1e-4, 2e-4, 3e-4)
    model = GyroModel(_only('electronics_noise', electronics_noise_rad_s_sqrt_hz=density),
                      FS, np.random.default_rng(7))
    n = 50_000
    out = model.run(np.zeros((n, 3)), 25.0)
    for i in range(3):      # streams: turn-on, jitter, white x/y/z, ...
        sigma = density[i] * math.sqrt(FS)
        assert np.array_equal(out.gyro_rad_s[:, i], _child_normals(7, 2 + i, n) * sigma)


@pytest.mark.parametrize('seed', range(8))
def test_compiled_fill_draws_numpys_normals_and_advances_the_same_state(seed):
    """
    streams.fill_standard_normal = numpy's standard_normal, bit for bit, on one state.

    200 000 draws per seed reach the ziggurat's rare paths (the tail beyond
    3.44 and the wedges) hundreds of times; after the compiled fill, numpy's
    own draws continue the same stream, and the other way round.
    """
    mine = np.random.Generator(np.random.SFC64(seed))
    ref = np.random.Generator(np.random.SFC64(seed))
    got = np.empty(200_000)
    streams.fill_standard_normal(mine, got[:1])
    streams.fill_standard_normal(mine, got[1:])
    want = ref.standard_normal(200_000)
    assert np.array_equal(got, want)
    assert np.sum(np.abs(want) > 3.442619855899) > 50          # the tail path ran
    assert np.array_equal(mine.standard_normal(1000), ref.standard_normal(1000))
    more = np.empty(1000)
    streams.fill_standard_normal(mine, more)
    assert np.array_equal(more, ref.standard_normal(1000))


def test_flicker_and_random_walk_match_the_noise_module_generators():
    """The kernel's recursions equal noise_reference.flicker / random_walk on the same normals."""
    n = 20_000
    config = _only('bias_instability', bias_instability_rad_s=(1e-4, 2e-4, 5e-5),
                   bias_instability_band_s=(0.05, 50.0))
    out = GyroModel(config, FS, np.random.default_rng(3)).run(np.zeros((n, 3)), 25.0)
    plan = noise.flicker_plan(config.bias_instability_band_s, 1.0 / FS)
    k = len(plan.phi)
    z = np.column_stack([_child_normals(3, 5 + i, k + n) for i in range(3)])
    b = np.array(config.bias_instability_rad_s)
    state = noise.flicker_initial_state(plan, b, z[:k])
    ref, _ = noise_reference.flicker(z[k:], plan, b, state)
    np.testing.assert_allclose(out.bias_rad_s, ref, rtol=1e-12, atol=1e-20)
    config = _only('rate_random_walk', rate_random_walk_rad_s_sqrt_s=(1e-5, 2e-5, 3e-5))
    out = GyroModel(config, FS, np.random.default_rng(4)).run(np.zeros((n, 3)), 25.0)
    z = np.column_stack([_child_normals(4, 8 + i, n) for i in range(3)])
    step = units.rrw_to_step_sigma(config.rate_random_walk_rad_s_sqrt_s, FS)
    ref, _ = noise_reference.random_walk(z, step, np.zeros(3))
    np.testing.assert_allclose(out.bias_rad_s, ref, rtol=1e-12, atol=1e-20)


def test_die_temperature_out_of_range_raises_and_leaves_the_model_unchanged():
    config = replace(FULL, self_heating_c=20.0, thermal_time_constant_s=1.0)
    rate, temp, accel = _inputs(400)
    ref = GyroModel(config, FS, np.random.default_rng(5)).run(rate, temp, accel)
    model = GyroModel(config, FS, np.random.default_rng(5))
    hot = np.full(400, 199.0)
    with pytest.raises(ValueError, match=r'die temperature 2\d\d.* allowed \[-60.0, 200.0\]'):
        model.run(rate, hot, accel)
    with pytest.raises(ValueError, match='die temperature 219'):
        model.step(rate[0], hot[0], accel[0])
    # the failed calls produced no sample, drew no random number, moved no state
    assert model.sample_index == 0 and model.die_temp_c is None
    _assert_batches_equal(model.run(rate, temp, accel), ref)


def test_input_layout_does_not_matter():
    rate, temp, accel = _inputs(1000, seed=6)
    ref = GyroModel(FULL, FS, np.random.default_rng(2)).run(rate, temp, accel)
    fortran, strided = np.asfortranarray(rate), np.repeat(temp, 2)[::2]
    frozen = accel.copy()
    frozen.flags.writeable = False
    out = GyroModel(FULL, FS, np.random.default_rng(2)).run(fortran, strided, frozen)
    _assert_batches_equal(out, ref)
    assert out.gyro_rad_s.flags.c_contiguous
    # a (3,) specific force is held for every sample
    held = GyroModel(FULL, FS, np.random.default_rng(2)).run(rate, temp, accel[0])
    again = GyroModel(FULL, FS, np.random.default_rng(2)).run(
        rate, temp, np.tile(accel[0], (1000, 1)))
    _assert_batches_equal(held, again)
