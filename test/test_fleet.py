"""Fleets (issue 16): tolerance draws, per-device physics, determinism, attribution, errors."""

from dataclasses import replace
import glob
import json
import os
import signal
import sys
import threading
import time

from conftest import ROOT
from distributed.diagnostics.plugin import WorkerPlugin
from gyro_emulator.analysis.fleet import config as fleet_config
from gyro_emulator.analysis.fleet import engine, evaluate, report, run, sampling
from gyro_emulator.cli import main
from gyro_emulator.interrupts import Terminated, TerminateOnSignal
from gyro_emulator.physics import first_order
from gyro_emulator.sensor import noise
from gyro_emulator.units import rad_s_sqrt_hz_to_arw_deg_sqrt_h
import numpy as np
import pytest


def fleet(**mapping):
    """Build a FleetConfig from keyword sections (paper device by default)."""
    return fleet_config.config_from_mapping(mapping)


def test_block_seeds_are_the_spawned_children_of_the_root_seed():
    children = np.random.SeedSequence(2026).spawn(5)
    for k, child in enumerate(children):
        assert np.array_equal(child.generate_state(4),
                              sampling.block_seed(2026, k).generate_state(4))


@pytest.mark.parametrize('seed', [1, 2, 3])
def test_tolerances_have_the_asked_moments(seed):
    """Normal and uniform, absolute and %, with an offset: mean and spread within 4.5 SE."""
    cfg = fleet(tolerances={
        'geometry.thickness_m': {'normal': '2%'},
        'geometry.comb_gap_m': {'uniform': 0.1e-6, 'offset': 0.02e-6},
        'gas.pressure_pa': {'uniform': '10%', 'offset': '-5%'},
        'drive.ac_voltage_v': {'normal': 0.3}})
    n = 2 * sampling.BLOCK_DEVICES
    values = {}
    for block in range(2):
        for name, arr in sampling.draw_block(cfg, seed, block, n // 2).values().items():
            values.setdefault(name, []).append(arr)
    expect = {  # name: (mean, standard deviation)
        'geometry.thickness_m': (2e-6, 0.02 * 2e-6),
        'geometry.comb_gap_m': (2.02e-6, 0.1e-6 / np.sqrt(3.0)),
        'gas.pressure_pa': (101325.0 * 0.95, 0.1 * 101325.0 / np.sqrt(3.0)),
        'drive.ac_voltage_v': (20.0, 0.3)}
    for name, (mean, sd) in expect.items():
        x = np.concatenate(values[name])
        assert abs(x.mean() - mean) < 4.5 * sd / np.sqrt(n), name
        # SE of the variance: sd^2 sqrt(2/n) (normal); uniform is smaller.
        assert abs(x.var() - sd ** 2) < 4.5 * sd ** 2 * np.sqrt(2.0 / n), name
    width = np.concatenate(values['geometry.comb_gap_m'])
    assert width.min() >= 1.92e-6 and width.max() <= 2.12e-6      # uniform stays in bounds


def test_a_factor_correlates_the_lengths_it_moves():
    """Over-etch thins beams and widens gaps together: the correlation the factor implies."""
    s_f, s_w, s_g = 20e-9, 10e-9, 30e-9
    cfg = fleet(tolerances={'geometry.beam1_width_m': {'normal': s_w},
                            'geometry.comb_gap_m': {'normal': s_g}},
                factors={'etch': {'normal': s_f, 'moves': {'geometry.beam1_width_m': -2.0,
                                                           'geometry.comb_gap_m': 2.0}}})
    n = sampling.BLOCK_DEVICES
    rhos = []
    for seed in range(4):
        v = sampling.draw_block(cfg, seed, 0, n).values()
        rhos.append(np.corrcoef(v['geometry.beam1_width_m'], v['geometry.comb_gap_m'])[0, 1])
    var_f = (2 * s_f) ** 2
    rho = -var_f / np.sqrt((var_f + s_w ** 2) * (var_f + s_g ** 2))
    for r in rhos:                                    # SE of r: (1 - rho^2) / sqrt(n)
        assert abs(r - rho) < 4.5 * (1 - rho ** 2) / np.sqrt(n)
    # A relative factor moves by a fraction of each nominal.
    rel = fleet(factors={'bias': {'uniform': '1%', 'moves': {'geometry.thickness_m': 1.0,
                                                             'geometry.plate_side_m': 1.0}}})
    v = sampling.draw_block(rel, 0, 0, 1000).values()
    assert np.allclose(v['geometry.thickness_m'] / 2e-6, v['geometry.plate_side_m'] / 855.5e-6,
                       rtol=1e-12)


def _scalar_device(cfg, values, i):
    from gyro_emulator.analysis.fleet.sensor_runs import part_device
    return part_device(cfg, values, i)


def test_sf_spread_matches_a_per_device_loop(tmp_path):
    """Every metric of a small fleet equals the physics evaluated part by part."""
    cfg = fleet(tolerances={'geometry.beam1_width_m': {'uniform': '3%'},
                            'geometry.thickness_m': {'normal': '2%'},
                            'gas.pressure_pa': {'uniform': '30%'},
                            'mismatch.sense_beam_width_m': {'normal': 5e-9},
                            'electronics.noise_rad_s_sqrt_hz': {'uniform': 2e-5, 'offset': 3e-5}},
                exact=True, attribution_devices=0)
    n = 300
    summary = run.run_fleet(cfg, n, 11, str(tmp_path), scheduler='in-process')
    values, invalid, _ = sampling.checked(cfg, sampling.draw_block(cfg, 11, 0, n).values(), n)
    assert not invalid.any()
    metrics = evaluate.evaluate(cfg, values, n)
    temps = np.array(cfg.temperatures_c)
    ratios, arws, splits = [], [], []
    for i in range(n):
        dev = _scalar_device(cfg, values, i)
        ratios.append(first_order.scale_factor_ratio(dev, temps, 25.0))
        brown = noise.brownian_arw_rad_s_sqrt_hz(dev, temps).max()
        arws.append(rad_s_sqrt_hz_to_arw_deg_sqrt_h(np.hypot(
            brown, values['electronics.noise_rad_s_sqrt_hz'][i])))
        delta = values['mismatch.sense_beam_width_m'][i]
        sense = replace(dev.geometry, beam1_width_m=dev.geometry.beam1_width_m + delta,
                        beam2_width_m=dev.geometry.beam2_width_m + delta)
        k_y = first_order.stiffness_n_m(sense, dev.material, 25.0)
        p = first_order.lumped_parameters(dev, 25.0)
        splits.append(first_order.resonant_frequency_hz(k_y, p.mass_kg) - p.freq_x_hz)
    ratios = np.array(ratios).T
    np.testing.assert_allclose(metrics['sf_ratio'], ratios, rtol=1e-13)
    np.testing.assert_allclose(metrics['arw_deg_sqrt_h'], arws, rtol=1e-13)
    np.testing.assert_allclose(metrics['split_hz'], splits, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(metrics['sf_error_pct'],
                               100 * np.abs(ratios - 1).max(axis=0), rtol=1e-12)
    # The spread written to summary.json and to the Parquet rows.
    q = summary['quantiles']['sf_error_pct_at_m40c']
    assert q['5%'] == pytest.approx(np.percentile(100 * (ratios[0] - 1), 5), rel=1e-12)
    assert q['95%'] == pytest.approx(np.percentile(100 * (ratios[0] - 1), 95), rel=1e-12)
    assert 0.5 < q['95%'] - q['5%'] < 3.0                # pressure +-30 % spreads SF(-40 C)
    table = _rows(tmp_path)
    np.testing.assert_allclose(table['sf_ratio_m40c'].to_numpy(), ratios[0], rtol=1e-6)
    assert summary['devices'] == n == table.num_rows


def _rows(out):
    import pyarrow as pa
    import pyarrow.parquet as pq
    return pa.concat_tables([pq.read_table(f) for f in sorted(glob.glob(
        os.path.join(str(out), 'devices', '*.parquet')))])


def _without_run(summary):
    return json.dumps({k: v for k, v in summary.items() if k != 'run'}, sort_keys=True)


def test_output_is_the_same_in_process_and_on_a_two_worker_local_cluster(tmp_path):
    """
    Same seed: identical rows and summary for any scheduler, worker count or partitioning.

    Two in-process partitionings against a LocalCluster of two worker
    processes, reached by its address (already up, so the cluster runs all
    but the first task; ``local`` starts one the same way and runs tasks here
    while it starts).
    """
    import logging

    from dask.distributed import LocalCluster

    cfg = fleet(tolerances={'geometry.beam1_width_m': {'uniform': '2%'},
                            'gas.pressure_pa': {'uniform': '10%'},
                            'mismatch.sense_beam_width_m': {'uniform': 5e-9}},
                factors={'etch': {'uniform': 20e-9, 'moves': {'geometry.beam2_width_m': -2.0,
                                                              'geometry.comb_gap_m': 2.0}}},
                specs={'split_hz': {'abs_max': 30.0}, 'sf_tempco_ppm_k': {'max': 550.0}},
                attribution_devices=2048,
                sensor_runs={'devices': 1, 'duration_s': 20.0, 'rate_hz': 50.0})
    n = 2 * sampling.BLOCK_DEVICES + 1000
    a = run.run_fleet(cfg, n, 9, str(tmp_path / 'a'), scheduler='in-process',
                      blocks_per_task=3)
    b = run.run_fleet(cfg, n, 9, str(tmp_path / 'b'), scheduler='in-process',
                      blocks_per_task=1)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, scheduler_port=0,
                      dashboard_address=':0', silence_logs=logging.ERROR) as cluster:
        c = run.run_fleet(cfg, n, 9, str(tmp_path / 'c'), scheduler=cluster.scheduler_address,
                          blocks_per_task=1)
        e = run.run_fleet(cfg, n, 9, str(tmp_path / 'e'), scheduler=cluster.scheduler_address,
                          blocks_per_task=3)
    assert c['run']['tasks'] == 3 and c['run']['tasks_here'] < 3
    rows = _rows(tmp_path / 'a')
    assert rows.num_rows == n
    assert np.array_equal(rows['device_id'].to_numpy(), np.arange(n))
    for other in ('b', 'c', 'e'):
        assert rows.equals(_rows(tmp_path / other)), other
    assert _without_run(a) == _without_run(b) == _without_run(c) == _without_run(e)
    d = run.run_fleet(cfg, n, 10, str(tmp_path / 'd'), scheduler='in-process', write=False)
    assert _without_run(d) != _without_run(a)                   # the seed matters


@pytest.mark.parametrize('blocks', [1, 7, 8, 9, 100, 1530])
@pytest.mark.parametrize('workers', [1, 2, 16])
def test_guided_tasks_cover_every_block_once_and_shrink(blocks, workers):
    """Each block once and in order; sizes never grow, stay in 1..16, end at one block."""
    tasks = engine.guided_tasks(blocks * sampling.BLOCK_DEVICES - 5, workers)
    assert [b for task in tasks for b in task] == list(range(blocks))
    sizes = [len(task) for task in tasks]
    assert all(1 <= s <= engine.MAX_BLOCKS_PER_TASK for s in sizes)
    assert sizes == sorted(sizes, reverse=True) and sizes[-1] == 1
    if blocks >= 4 * workers * engine.MAX_BLOCKS_PER_TASK:
        assert sizes[0] == engine.MAX_BLOCKS_PER_TASK


def test_the_local_scheduler_starts_and_stops_its_own_cluster(tmp_path):
    """``local``: a LocalCluster of two processes; this process works while it starts."""
    cfg = fleet(tolerances={'gas.pressure_pa': {'uniform': '10%'}}, attribution_devices=0)
    n = 3 * sampling.BLOCK_DEVICES
    local = run.run_fleet(cfg, n, 2, str(tmp_path / 'l'), scheduler='local', workers=2,
                          blocks_per_task=1, write=False)
    here = run.run_fleet(cfg, n, 2, str(tmp_path / 'h'), scheduler='in-process', write=False)
    assert local['run']['scheduler'] == 'local' and local['run']['tasks'] == 3
    assert _without_run(local) == _without_run(here)


def test_attribution_names_the_parameter_behind_each_failing_spec(tmp_path):
    """
    Pressure moves the SF temperature coefficient; the drive voltage only the SF itself.

    The SF tempco (a ratio of SFs) is blind to V_ac exactly (F_d cancels), and
    SF(25 C) is blind to the pressure only weakly; a sense-overlap tolerance
    moves neither spec much. Each spec must be pinned on its own cause.
    """
    cfg = fleet(tolerances={'gas.pressure_pa': {'uniform': '50%'},
                            'drive.ac_voltage_v': {'uniform': '20%'},
                            'geometry.sense_overlap_m': {'uniform': '5%'}},
                specs={'sf_tempco_ppm_k': {'min': 530.0, 'max': 560.0},
                       'sf_m_per_rad_s': {'min': 6.2e-9, 'max': 6.7e-9}},
                attribution_devices=20000)
    summary = run.run_fleet(cfg, 20000, 4, str(tmp_path), scheduler='in-process', write=False)
    assert summary['yield'] < 0.5
    attribution = summary['attribution']
    assert attribution['spec_driver'] == {'sf_tempco_ppm_k': 'gas.pressure_pa',
                                          'sf_m_per_rad_s': 'drive.ac_voltage_v'}
    gains = attribution['sources']
    assert gains['drive.ac_voltage_v']['spec_gain']['sf_tempco_ppm_k'] == 0.0
    assert gains['gas.pressure_pa']['spec_gain']['sf_tempco_ppm_k'] > 0.3
    assert attribution['drives_the_yield'] in ('gas.pressure_pa', 'drive.ac_voltage_v')


def test_two_sources_with_the_same_effect_are_said_to_be_indistinguishable(tmp_path, capsys):
    """
    A pressure tolerance and a factor that moves the pressure the same way.

    Removing either leaves the other, so their gains are equal in
    expectation: the summary names the larger but lists the other as a
    source these parts cannot tell apart from it, and the CLI says so. A
    source without effect on the spec (V_ac on the SF tempco: F_d cancels)
    changes no part and is not named.
    """
    cfg = fleet(tolerances={'gas.pressure_pa': {'uniform': '5%'},
                            'drive.ac_voltage_v': {'uniform': '20%'}},
                factors={'twin': {'uniform': '5%', 'moves': {'gas.pressure_pa': 1.0}}},
                specs={'sf_tempco_ppm_k': {'min': 535.0, 'max': 555.0}},
                attribution_devices=8000)
    summary = run.run_fleet(cfg, 8000, 3, str(tmp_path / 'a'), scheduler='in-process',
                            write=False)
    attribution = summary['attribution']
    pair = {'gas.pressure_pa', 'factor.twin'}
    assert attribution['drives_the_yield'] in pair
    assert attribution['indistinguishable_from'] == list(pair - {attribution['drives_the_yield']})
    voltage = attribution['sources']['drive.ac_voltage_v']
    assert voltage['gain'] == 0.0 and voltage['gain_ci95'][0] < 0.0 < voltage['gain_ci95'][1]
    assert 'drive.ac_voltage_v' not in attribution['indistinguishable_from']
    low, high = summary['yield_ci95']
    assert low < summary['yield'] < high and high - low < 0.03
    path = tmp_path / 'fleet.yaml'
    path.write_text('tolerances:\n  gas.pressure_pa: {uniform: 5%}\n'
                    'factors:\n  twin: {uniform: 5%, moves: {gas.pressure_pa: 1.0}}\n'
                    'specs:\n  sf_tempco_ppm_k: {min: 535, max: 555}\n'
                    'attribution_devices: 8000\n')
    assert main(['fleet', str(path), '--devices', '8000', '--seed', '3', '--out',
                 str(tmp_path / 'b'), '--no-parquet']) == 0
    assert 'cannot be told apart from' in capsys.readouterr().out


def test_a_source_that_changes_no_verdict_is_not_said_to_drive_the_yield(tmp_path, capsys):
    """Only V_ac varies and the spec is blind to it: no source is named, and the CLI says so."""
    path = tmp_path / 'fleet.yaml'
    path.write_text('tolerances:\n  drive.ac_voltage_v: {uniform: 20%}\n'
                    'specs:\n  sf_tempco_ppm_k: {min: 540, max: 560}\n')
    assert main(['fleet', str(path), '--devices', '2000', '--seed', '1', '--out',
                 str(tmp_path / 'o'), '--no-parquet']) == 0
    assert 'no source is shown to drive the yield' in capsys.readouterr().out
    summary = json.loads((tmp_path / 'o' / 'summary.json').read_text())
    assert summary['attribution']['drives_the_yield'] is None
    assert summary['attribution']['spec_driver'] == {'sf_tempco_ppm_k': None}


@pytest.mark.parametrize('passed,n', [(0, 1), (0, 10), (1, 10), (5, 10), (10, 10), (3, 1000),
                                      (268_000, 1_000_000), (999_999, 1_000_000)])
def test_yield_interval_is_statsmodels_wilson_interval(passed, n):
    from statsmodels.stats.proportion import proportion_confint

    low, high = report.wilson_interval(passed, n)
    ref_low, ref_high = proportion_confint(passed, n, alpha=0.05, method='wilson')
    assert low == pytest.approx(ref_low, abs=1e-12) and high == pytest.approx(ref_high, abs=1e-12)
    assert low <= passed / n <= high


@pytest.mark.parametrize('n', [1, 10, 4096])
def test_yield_interval_ends_are_exact_floats_at_no_and_all_parts_passing(n):
    assert report.wilson_interval(0, n)[0] == 0.0 and report.wilson_interval(n, n)[1] == 1.0
    assert all(type(end) is float for k in (0, 1, n) for end in report.wilson_interval(k, n))
    assert report.wilson_interval(0, 0) == [None, None]


@pytest.mark.parametrize('p_up,p_down', [(0.2, 0.05), (0.02, 0.02), (0.3, 0.0), (0.001, 0.0)])
def test_paired_gain_interval_covers_the_true_gain_95_percent_of_the_time(p_up, p_down):
    """
    Coverage of the attribution's interval over 2000 seeded paired samples of 2000 parts.

    Each part flips up with p_up and down with p_down; the true gain is
    p_up - p_down. Nominal coverage 95 %: over 2000 trials the count of
    misses is Binomial(2000, 0.05), mean 100, sd 9.7; more than 140 misses
    (4 sd) fails. The floor of 3 / n makes rare flips conservative.
    """
    rng = np.random.default_rng(16)
    n, trials = 2000, 2000
    u = rng.random((trials, n))
    up = (u < p_up).sum(axis=1)
    down = ((u >= p_up) & (u < p_up + p_down)).sum(axis=1)
    misses = 0
    for k_up, k_down in zip(up, down):
        gain, half = report.paired_gain(int(k_up - k_down), int(k_up + k_down), n)
        misses += abs(gain - (p_up - p_down)) > half
    assert misses <= 140


def test_a_fleet_without_tolerances_is_n_copies_of_the_nominal_part(tmp_path):
    summary = run.run_fleet(fleet(specs={'split_hz': {'abs_max': 1.0}}), 1000, 0,
                            str(tmp_path), scheduler='in-process')
    assert summary['yield'] == 1.0 and summary['valid'] == 1000
    rows = _rows(tmp_path)
    assert rows.num_rows == 1000 and np.ptp(rows['f_drive_hz'].to_numpy()) == 0.0
    nominal = first_order.scale_factor_ratio(fleet().device, -40.0, 25.0)
    assert rows['sf_ratio_m40c'].to_numpy()[0] == pytest.approx(nominal, rel=1e-7)


def test_impossible_parts_are_rejected_or_clipped_and_counted(tmp_path):
    """A tolerance wide enough to draw negative widths never crashes the run."""
    tol = {'geometry.beam1_width_m': {'normal': '60%'}}
    spec = {'split_hz': {'abs_max': 1e6}}
    rejected = run.run_fleet(fleet(tolerances=tol, specs=spec, attribution_devices=256), 5000,
                             1, str(tmp_path / 'r'), scheduler='in-process')
    frac = rejected['invalid'] / 5000
    assert 0.03 < frac < 0.08                          # P(z < -1/0.6) = 4.8 %
    assert rejected['yield'] == pytest.approx(1 - frac)
    rows = _rows(tmp_path / 'r')
    bad = ~rows['valid'].to_numpy()
    assert np.isnan(rows['sf_error_pct'].to_numpy()[bad]).all()
    assert not rows['pass'].to_numpy()[bad].any()
    clipped = run.run_fleet(fleet(tolerances=tol, specs=spec, invalid='clip',
                                  attribution_devices=256), 5000, 1, str(tmp_path / 'c'),
                            scheduler='in-process')
    assert clipped['clipped'] == rejected['invalid'] and clipped['invalid'] == 0


@pytest.mark.parametrize('mapping, match', [
    ({'tolerance': {}}, r'unknown key\(s\) tolerance'),
    ({'tolerances': {'geometry.beam_width_m': {'normal': 1e-9}}},
     r"unknown parameter 'geometry.beam_width_m'"),
    ({'tolerances': {'geometry.hole_count': {'normal': 10}}}, r'hole_count is a count'),
    ({'tolerances': {'gas.pressure_pa': {'normal': '1%', 'uniform': '1%'}}},
     r'exactly one of normal'),
    ({'tolerances': {'gas.pressure_pa': {'normal': -3.0}}}, r'normal: -3.0 is out of range'),
    ({'tolerances': {'mismatch.sense_beam_width_m': {'normal': '1%'}}},
     r'percentage of a zero nominal'),
    ({'tolerances': {'gas.pressure_pa': {'normal': 'lots'}}}, r"'lots' is not a number"),
    ({'device': {'geometry': {'hole_side_m': 50e-6}}}, r'hole_count .* removes more'),
    ({'device': {'geometry': {'thickness_m': -1e-6}}}, r'thickness_m = -1e-06 is out of range'),
    ({'device': {'geometry': {'flux_m': 1.0}}}, r'unknown field\(s\) flux_m'),
    ({'temperatures_c': [-100, 25]}, r'temperatures_c'),
    ({'specs': {'yield': {'min': 1}}}, r"unknown metric 'yield'"),
    ({'model_checks': {'exact_ratio': {'min': 0.9}}}, r'set exact: true'),
    ({'specs': {'exact_ratio': {'min': 0.9}}, 'exact': True},
     r'specs.exact_ratio: is a check of the first-order model, not a part spec: put it '
     r'under model_checks'),
    ({'model_checks': {'split_hz': {'abs_max': 1}}}, "unknown metric 'split_hz'; allowed: "
                                                     r'exact_ratio'),
    ({'specs': {'split_hz': {'min': 5, 'max': 1}}}, r'min 5.0 is above max 1.0'),
    ({'factors': {'etch': {'normal': 1e-9, 'moves': {'geometry.frame_count': 1}}}},
     r'frame_count is a count'),
    ({'invalid': 'ignore'}, r"'ignore' is not allowed"),
    ({'sensor_runs': {'devices': 0}}, r'devices = 0'),
    ({'extended': {'bias_wobble': {}}}, r"extended: unknown term 'bias_wobble'; allowed: "),
    ({'extended': {'bias_step': {'step_s': 1.0}}},
     r'extended.bias_step: unknown parameter\(s\) step_s; allowed: step_time_s'),
    ({'extended': {'bias_hysteresis': {'hysteresis_width_k': -1.0}}},
     r'BiasHysteresis.hysteresis_width_k = -1.0 is out of range'),
    ({'extended': {'bias_step': {'bias_step_rad_s': [1e-3, 0.0, 0.0]}}},
     r'extended.bias_step.bias_step_rad_s: \[0.001, 0.0, 0.0\] is not allowed: a fleet part '
     r'has one read-out axis'),
    ({'extended': {'bias_step': {'bias_step_rad_s': 1e-3}},
      'tolerances': {'extended.bias_step.bias_step_rads': {'normal': 1e-4}}},
     r"unknown parameter 'bias_step_rads' of extended.bias_step; allowed: step_time_s, "
     r'bias_step_rad_s'),
    ({'tolerances': {'extended.bias_step.bias_step_rad_s': {'normal': 1e-4}}},
     r"extended.bias_step is not on in the fleet's extended: mapping"),
    ({'extended': {'bias_step': {'enabled': False}},
      'tolerances': {'extended.bias_step.step_time_s': {'normal': 1.0}}},
     r"extended.bias_step is not on in the fleet's extended: mapping"),
    ({'tolerances': {'extended.bias_wobble.a': {'normal': 1.0}}},
     r"unknown extended term 'bias_wobble'"),
    ({'extended': {'scale_factor_temperature': {}},
      'tolerances': {'extended.scale_factor_temperature.sf_temp_coeff_per_k':
                     {'normal': '5%'}}}, r'percentage of a zero nominal'),
])
def test_bad_fleet_yaml_gives_one_line_naming_the_field(mapping, match):
    with pytest.raises(ValueError, match=match) as info:
        fleet_config.config_from_mapping(mapping)
    assert '\n' not in str(info.value)


def test_an_exponent_without_a_dot_is_a_number_in_every_field(tmp_path):
    # YAML 1.1 reads 2e-8 (no dot) as a string; the device mapping took it as
    # the number it spells, the tolerances, factors, specs and nominals must too.
    path = tmp_path / 'fleet.yaml'
    path.write_text('device: {preset: paper, geometry: {thickness_m: 2e-6}}\n'
                    'electronics: {noise_rad_s_sqrt_hz: 1e-4}\n'
                    'factors:\n'
                    '  etch: {uniform: 2e-8, moves: {geometry.beam1_width_m: -2e0}}\n'
                    'tolerances:\n'
                    '  gas.pressure_pa: {normal: 1e+1, offset: 5e-1}\n'
                    'specs:\n'
                    '  arw_deg_sqrt_h: {max: 3e-1}\n')
    config = fleet_config.load_fleet_config(path)
    assert config.parameters['geometry.thickness_m'].nominal == 2e-6
    assert config.parameters['electronics.noise_rad_s_sqrt_hz'].nominal == 1e-4
    assert config.factors[0].scale == 2e-8 and config.factors[0].moves[0][1] == -2.0
    assert (config.tolerances[0].scale, config.tolerances[0].offset) == (10.0, 0.5)
    assert config.specs[0].high == 0.3
    for text, match in (('{normal: 1e-8x}', r"normal: '1e-8x' is not a number"),
                        ('{normal: "nan"}', r'normal: nan is not a finite number'),
                        ('{normal: 1e-3, offset: -1e999}', r'offset: -inf is not a finite')):
        path.write_text(f'tolerances:\n  gas.pressure_pa: {text}\n')
        with pytest.raises(ValueError, match=match) as info:
            fleet_config.load_fleet_config(path)
        assert '\n' not in str(info.value)


def test_cli_runs_a_fleet_and_refuses_bad_input_in_one_line(tmp_path, capsys):
    path = tmp_path / 'fleet.yaml'
    path.write_text('tolerances:\n  gas.pressure_pa: {uniform: 10%}\n'
                    'specs:\n  sf_tempco_ppm_k: {max: 546}\n')
    out = tmp_path / 'out'
    assert main(['fleet', str(path), '--devices', '3000', '--seed', '5', '--out',
                 str(out)]) == 0
    printed = capsys.readouterr().out
    assert 'sf_tempco_ppm_k' in printed and 'drives the yield: gas.pressure_pa' in printed
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['devices'] == 3000 and 0.2 < summary['yield'] < 0.8
    for name in ('sf_envelope', 'split_histogram', 'yield_per_spec', 'fails_most'):
        assert (out / 'plots' / f'{name}.png').stat().st_size > 1000
    assert main(['fleet', str(path), '--devices', '3000', '--out', str(out)]) == 2
    assert 'already holds a fleet' in capsys.readouterr().err
    path.write_text('tolerances:\n  gas.presure_pa: {uniform: 10%}\n')
    assert main(['fleet', str(path), '--devices', '10', '--out', str(tmp_path / 'x')]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and "unknown parameter 'gas.presure_pa'" in err
    assert main(['fleet', str(tmp_path / 'none.yaml'), '--devices', '10', '--out',
                 str(tmp_path / 'y')]) == 2
    assert main(['fleet', str(path), '--devices', '0', '--out', str(tmp_path / 'z')]) == 2


def test_a_second_run_on_a_directory_in_use_is_refused_until_the_first_ends(tmp_path, capsys):
    """
    Two runs writing one DIR at once: the second is refused before it touches anything.

    Without the lock, a second ``--overwrite`` run deleted the first one's
    files under it (the first died with "part-000000.parquet: nothing was
    written") and a second ``--resume`` ran the same tasks twice. The holder
    here is another process; ``kill -9`` releases it.
    """
    import subprocess
    import sys

    path = tmp_path / 'fleet.yaml'
    path.write_text('tolerances:\n  gas.pressure_pa: {uniform: 10%}\n'
                    'specs:\n  sf_tempco_ppm_k: {max: 546}\nattribution_devices: 0\n')
    out = tmp_path / 'out'
    assert main(['fleet', str(path), '--devices', '100', '--out', str(out)]) == 0
    before = sorted(p.name for p in out.rglob('*'))
    holder = subprocess.Popen(
        [sys.executable, '-c', 'import sys\nfrom gyro_emulator.analysis.fleet import state\n'
         'with state.exclusive(sys.argv[1]):\n    print("held", flush=True)\n'
         '    sys.stdin.read()\n', str(out)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
        env={**os.environ, 'PYTHONPATH': ROOT})
    try:
        assert holder.stdout.readline() == 'held\n'
        capsys.readouterr()
        for extra in (['--overwrite'], ['--resume'], []):
            assert main(['fleet', str(path), '--devices', '200', '--out', str(out),
                         *extra]) == 2
            err = capsys.readouterr().err
            assert err.count('\n') == 1 and 'is being written by another fleet run' in err
        assert sorted(p.name for p in out.rglob('*')) == before
    finally:
        holder.kill()
        holder.wait()
    assert main(['fleet', str(path), '--devices', '200', '--out', str(out),
                 '--overwrite']) == 0
    assert json.loads((out / 'summary.json').read_text())['devices'] == 200
    # a run refused for another reason (1e10 parts: 1.4 TB) leaves no directory it made
    assert main(['fleet', str(path), '--devices', '1e10', '--out', str(tmp_path / 'new')]) == 2
    assert 'free' in capsys.readouterr().err and not (tmp_path / 'new').exists()


def test_a_file_system_that_cannot_lock_runs_the_fleet_unguarded(tmp_path, monkeypatch):
    import errno
    import fcntl

    def no_locks(handle, operation):
        raise OSError(errno.ENOLCK, 'No locks available')

    monkeypatch.setattr(fcntl, 'flock', no_locks)
    summary = run.run_fleet(fleet(attribution_devices=0), 10, 1, str(tmp_path / 'o'),
                            scheduler='in-process')
    assert summary['devices'] == 10 and (tmp_path / 'o' / 'summary.json').exists()


def test_no_spec_is_said_to_fail_most_when_every_part_passes(tmp_path, capsys):
    # it named the first spec ("fails most: f_drive_hz", and a fails_most.png
    # titled so) on a fleet where every part passed every spec
    path = tmp_path / 'fleet.yaml'
    path.write_text('tolerances:\n  gas.pressure_pa: {uniform: 10%}\nattribution_devices: 0\n'
                    'specs:\n  f_drive_hz: {min: 1000}\n  split_hz: {abs_max: 1000}\n')
    out = tmp_path / 'all'
    assert main(['fleet', str(path), '--devices', '500', '--out', str(out)]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['pass'] == 500 and summary['fails_most'] is None
    assert 'fails most' not in printed
    assert sorted(p.name for p in (out / 'plots').iterdir()) == [
        'sf_envelope.png', 'split_histogram.png', 'yield_per_spec.png']
    # one part failing one spec is enough to name it
    path.write_text(path.read_text() + '  sf_tempco_ppm_k: {max: 546}\n')
    assert main(['fleet', str(path), '--devices', '500', '--out', str(out),
                 '--overwrite']) == 0
    summary = json.loads((out / 'summary.json').read_text())
    assert 0 < summary['pass'] < 500
    assert summary['fails_most'] == 'sf_tempco_ppm_k'
    assert (out / 'plots' / 'fails_most.png').exists()


def test_sensor_runs_find_the_part_s_own_angle_random_walk(tmp_path):
    """A short static run of a part: the Allan N it finds is the ARW its physics predicts."""
    cfg = fleet(tolerances={'gas.pressure_pa': {'uniform': '50%'}},
                electronics={'noise_rad_s_sqrt_hz': 4e-5},
                sensor_runs={'devices': 3, 'duration_s': 200.0, 'rate_hz': 100.0},
                attribution_devices=0)
    summary = run.run_fleet(cfg, 50, 3, str(tmp_path), scheduler='in-process', write=False)
    runs = summary['sensor_runs']
    assert [r['device_id'] for r in runs] == [0, 1, 2]
    predicted = [r['arw_predicted_deg_sqrt_h'] for r in runs]
    assert np.ptp(predicted) > 0.01                      # the parts differ
    for r in runs:                          # 20 000 samples: N to a few % (1 sigma ~1 %)
        assert r['arw_deg_sqrt_h'] == pytest.approx(r['arw_predicted_deg_sqrt_h'], rel=0.06)


def test_model_checks_are_reported_apart_and_not_in_the_yield(tmp_path, capsys):
    """
    exact_ratio says where the first-order model holds, not whether the part is good.

    It has its own section (summary.json ``model_checks``, the command's
    output, a ``check_exact_ratio`` column), and neither the yield, nor
    ``fails_most``, nor the attribution counts it.
    """
    path = tmp_path / 'fleet.yaml'
    path.write_text('tolerances:\n  mismatch.sense_beam_width_m: {uniform: 5.0e-9}\n'
                    '  gas.pressure_pa: {uniform: 10%}\nexact: true\n'
                    'specs:\n  split_hz: {abs_max: 40}\n'
                    'model_checks:\n  exact_ratio: {min: 0.99}\nattribution_devices: 2000\n')
    assert main(['fleet', str(path), '--devices', '4e3', '--seed', '1', '--out',
                 str(tmp_path / 'o')]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((tmp_path / 'o' / 'summary.json').read_text())
    assert list(summary['specs']) == ['split_hz'] and summary['fails_most'] == 'split_hz'
    check = summary['model_checks']['exact_ratio']
    assert summary['pass'] == summary['specs']['split_hz']['pass']     # only the spec
    assert 0.0 < check['share'] < summary['yield']     # fails more often than the spec
    assert check['share_ci95'][0] < check['share'] < check['share_ci95'][1]
    assert list(summary['attribution']['spec_driver']) == ['split_hz']
    assert 'model validity' in printed and 'exact_ratio            holds for' in printed
    assert 'fails most: split_hz' in printed
    rows = _rows(tmp_path / 'o')
    ratio = rows['exact_ratio'].to_numpy().astype(float)
    assert np.array_equal(rows['check_exact_ratio'].to_numpy(), ratio >= 0.99)
    assert rows['pass'].to_numpy().sum() == summary['pass']


def test_devices_takes_1e6_and_refuses_a_fraction(tmp_path, capsys):
    from gyro_emulator.cli import fleet as fleet_cli

    parser = __import__('argparse').ArgumentParser()
    fleet_cli.add_arguments(parser)
    for text, n in (('1e6', 10 ** 6), ('1000000', 10 ** 6), ('1e10', 10 ** 10), ('7', 7)):
        assert parser.parse_args(['f.yaml', '--devices', text, '--out', 'o']).devices == n
    with pytest.raises(SystemExit):
        parser.parse_args(['f.yaml', '--devices', '1.5', '--out', 'o'])
    assert 'not a whole number of parts' in capsys.readouterr().err


def test_a_fleet_larger_than_the_free_disk_is_refused_before_it_starts(tmp_path, monkeypatch):
    """The estimate of the output is close to what a run writes; a fake small disk refuses it."""
    from gyro_emulator.analysis.fleet import resources

    cfg = fleet(tolerances={'gas.pressure_pa': {'uniform': '10%'}},
                specs={'split_hz': {'abs_max': 1.0}}, attribution_devices=0)
    n = sampling.BLOCK_DEVICES + 5000
    run.run_fleet(cfg, n, 1, str(tmp_path / 'a'), scheduler='in-process', blocks_per_task=1)
    written = sum(os.path.getsize(p) for p in glob.glob(str(tmp_path / 'a' / 'devices' / '*')))
    estimate = resources.output_bytes(cfg, n, 2) - resources.SUMMARY_BYTES
    assert written <= estimate < 1.02 * written
    monkeypatch.setattr(resources, 'free_bytes', lambda path: 10 ** 7)
    with pytest.raises(ValueError, match=r'fleet.out = .*: 10000000000 parts need about '
                                         r'767 GB \(77 bytes a part\) but 0.01 GB is free') \
            as info:
        run.run_fleet(cfg, 10 ** 10, 1, str(tmp_path / 'b'), scheduler='in-process')
    assert '\n' not in str(info.value) and not (tmp_path / 'b').exists()
    run.run_fleet(cfg, 100, 1, str(tmp_path / 'c'), scheduler='in-process', write=False)


def test_sensor_runs_that_do_not_fit_in_memory_are_refused_with_the_figure(tmp_path,
                                                                           monkeypatch):
    """The reproducer: 1024 parts x 86400 s x 10 kHz is in range, but one part needs 147 GB."""
    from gyro_emulator.analysis.fleet import resources

    big = fleet(sensor_runs={'devices': 1024, 'duration_s': 86400.0, 'rate_hz': 10000.0})
    monkeypatch.setattr(resources, 'available_memory_bytes', lambda: 24 * 10 ** 9)
    with pytest.raises(ValueError, match=r'sensor_runs: one part of 86400 s at 10000 Hz holds '
                                         r'864000000 samples, about 147 GB .* 24 GB of memory '
                                         r'is available: allowed duration_s x rate_hz <= '
                                         r'141176470 here') as info:
        run.run_fleet(big, 10, 1, str(tmp_path / 'o'), scheduler='in-process')
    assert '\n' not in str(info.value) and not (tmp_path / 'o').exists()


def test_an_interrupted_fleet_resumes_to_the_rows_and_summary_of_an_uninterrupted_one(
        tmp_path, monkeypatch):
    cfg = fleet(tolerances={'gas.pressure_pa': {'uniform': '10%'},
                            'mismatch.sense_beam_width_m': {'uniform': 5e-9}},
                specs={'split_hz': {'abs_max': 30.0}}, attribution_devices=1000)
    n = 3 * sampling.BLOCK_DEVICES + 10
    whole = run.run_fleet(cfg, n, 4, str(tmp_path / 'whole'), scheduler='in-process',
                          blocks_per_task=1)
    real, calls = engine.run_task, []

    def dies_on_the_third(job, blocks, progress=None):
        calls.append(blocks)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(job, blocks, progress)
    monkeypatch.setattr(engine, 'run_task', dies_on_the_third)
    out = tmp_path / 'cut'
    with pytest.raises(KeyboardInterrupt):
        run.run_fleet(cfg, n, 4, str(out), scheduler='in-process', blocks_per_task=1)
    monkeypatch.setattr(engine, 'run_task', real)
    assert sorted(os.listdir(out / '.fleet-state')) == ['run.json', 'task-000000.json',
                                                        'task-000001.json']
    (out / 'devices' / 'part-000002.parquet.partial').write_bytes(b'half')  # a lost task
    with pytest.raises(ValueError, match='unfinished fleet .* pass --resume'):
        run.run_fleet(cfg, n, 4, str(out), scheduler='in-process')
    with pytest.raises(ValueError, match='another fleet, seed or size'):
        run.run_fleet(cfg, n, 5, str(out), scheduler='in-process', resume=True)
    resumed = run.run_fleet(cfg, n, 4, str(out), scheduler='in-process', blocks_per_task=2,
                            resume=True)
    assert resumed['run']['tasks_resumed'] == 2 and not (out / '.fleet-state').exists()
    assert _without_run(resumed) == _without_run(whole)
    assert _rows(out).equals(_rows(tmp_path / 'whole'))
    assert not glob.glob(str(out / 'devices' / '*.partial'))
    with pytest.raises(ValueError, match='finished fleet: nothing to resume'):
        run.run_fleet(cfg, n, 4, str(out), scheduler='in-process', resume=True)


def test_sensor_runs_give_unresolved_terms_as_upper_bounds(tmp_path, capsys):
    """A white-noise part has no B and no K: a short run bounds them, never claims them."""
    path = tmp_path / 'fleet.yaml'
    path.write_text('sensor_runs: {devices: 2, duration_s: 200, rate_hz: 100}\n'
                    'attribution_devices: 0\n')
    assert main(['fleet', str(path), '--devices', '10', '--seed', '2026', '--out',
                 str(tmp_path / 'o'), '--no-parquet']) == 0
    printed = capsys.readouterr().out
    runs = json.loads((tmp_path / 'o' / 'summary.json').read_text())['sensor_runs']
    for r in runs:
        assert r['rrw_deg_h_sqrt_h'] is None and r['rrw_upper_deg_h_sqrt_h'] > 0.0
        assert r['rrw_model_deg_h_sqrt_h'] == 0.0 and r['bias_instability_model_deg_h'] == 0.0
        assert r['bias_instability_deg_h'] is None
    assert 'sensor runs (200 s at 100 Hz' in printed
    assert printed.count('deg/h/sqrt(h) (not resolved; model 0)') == 2


class _KillFleetTasks(WorkerPlugin):
    """
    A Dask worker plugin: a worker that starts a fleet task dies (SIGKILL), ``times`` times.

    The count is kept in ``marker`` files, one per kill, shared by the
    workers and the ones the nannies start in their place.
    """

    name = 'kill-fleet-tasks'

    def __init__(self, marker, times):
        self.marker, self.times = marker, times

    def transition(self, key, start, finish, **kwargs):
        """Kill this worker when a fleet task starts, until ``times`` kills are counted."""
        import signal

        if finish != 'executing' or not str(key).startswith('fleet'):
            return
        for k in range(self.times):
            try:
                os.close(os.open(f'{self.marker}.{k}', os.O_CREAT | os.O_EXCL))
            except FileExistsError:
                continue
            os.kill(os.getpid(), signal.SIGKILL)


#: How long a wait for the nannies' restarted workers may take: a new worker
#: process imports distributed and this module; beside a loaded suite (load
#: 6-7 on 2 cores) 120 s was once not enough. A wait, not a figure measured.
WORKERS_BACK_S = 300.0


def _wait_settled(client, cluster, timeout_s=WORKERS_BACK_S):
    """
    Wait until every nanny still open has its worker running.

    A nanny can close itself under the killing (CI: "Closing Nanny ...
    Reason: nanny-close" after a fourth kill in a few seconds), and a wait
    for both workers then waited 300 s for one that never came.
    """
    from distributed.core import Status

    def settled():
        nannies = sum(n.status == Status.running for n in cluster.workers.values())
        workers = client.scheduler_info()['workers'].values()
        return nannies >= 1 and sum(w.get('status') == 'running' for w in workers) >= nannies

    deadline = time.monotonic() + timeout_s
    while not settled():
        assert time.monotonic() < deadline, f'the workers did not settle in {timeout_s} s'
        time.sleep(0.1)


def _unregister_when_settled(client, cluster):
    """
    Remove the killing plugin once the workers are up (:func:`_wait_settled`).

    A killed worker's nanny restarts it, and a plugin change broadcast to a
    worker still dying or starting fails in distributed ("Stream is
    closed", CommClosedError). The scheduler drops the plugin from its
    registry before the broadcast, so a worker it restarts after that
    starts without it: the error leaves nothing to undo.
    """
    from distributed.comm import CommClosedError

    _wait_settled(client, cluster)
    try:
        client.unregister_worker_plugin(_KillFleetTasks.name)
    except CommClosedError:
        pass


def test_lost_tasks_are_submitted_again_then_the_run_stops_in_one_line_and_resumes(tmp_path):
    """
    A LocalCluster whose scheduler gives up on a task at its first lost worker.

    A worker plugin kills the worker that starts a fleet task. Once: the run
    submits the task again and its rows and summary are those of an
    in-process run. Always: after TASK_ATTEMPTS the run stops with one
    line, keeps its finished tasks (those this process ran while the client
    connected), and ``resume`` (in-process) finishes it to the same rows and
    summary. Bounded: three attempts of one task, each one worker restart.
    """
    import logging

    import dask
    from dask.distributed import Client, LocalCluster

    cfg = fleet(tolerances={'gas.pressure_pa': {'uniform': '10%'},
                            'mismatch.sense_beam_width_m': {'uniform': 5e-9}}, exact=True,
                specs={'split_hz': {'abs_max': 30.0}}, attribution_devices=500)
    n = 8 * sampling.BLOCK_DEVICES - 9
    whole = run.run_fleet(cfg, n, 3, str(tmp_path / 'whole'), scheduler='in-process')
    with dask.config.set({'distributed.scheduler.allowed-failures': 0}):
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                               scheduler_port=0, dashboard_address=':0',
                               silence_logs=logging.CRITICAL)
    with cluster, Client(cluster.scheduler_address, set_as_default=False) as client:
        client.register_plugin(_KillFleetTasks(str(tmp_path / 'once'), 1))
        once = run.run_fleet(cfg, n, 3, str(tmp_path / 'once'),
                             scheduler=cluster.scheduler_address, blocks_per_task=1)
        assert once['run']['tasks_resubmitted'] >= 1
        assert _without_run(once) == _without_run(whole)
        assert _rows(tmp_path / 'once').equals(_rows(tmp_path / 'whole'))
        _unregister_when_settled(client, cluster)
        client.register_plugin(_KillFleetTasks(str(tmp_path / 'always'), 10 ** 6))
        with pytest.raises(run.FleetIncomplete, match=r'the cluster lost the task of blocks '
                                                      r'\d+-\d+ 3 times \(KilledWorker') as info:
            run.run_fleet(cfg, n, 3, str(tmp_path / 'kept'),
                          scheduler=cluster.scheduler_address, blocks_per_task=1)
        _unregister_when_settled(client, cluster)
        # let the nannies finish restarting the killed workers before the cluster
        # closes: closing a nanny whose new process has not started yet fails in
        # distributed's own teardown ("can only join a started process")
        _wait_settled(client, cluster)
    assert '\n' not in str(info.value) and 'run again with --resume' in str(info.value)
    resumed = run.run_fleet(cfg, n, 3, str(tmp_path / 'kept'), scheduler='in-process',
                            resume=True)
    assert _without_run(resumed) == _without_run(whole)
    assert _rows(tmp_path / 'kept').equals(_rows(tmp_path / 'whole'))


# --- extended terms (sensor.extensions) with a tolerance (issue 24) ----------------------

SF_POLY = {'sf_temp_coeff_per_k': 2e-4, 'sf_temp_coeff2_per_k2': -1e-6}


def test_an_extended_sf_polynomial_drawn_per_part_acts_in_the_sf_metrics():
    """
    The drawn c1, c2 of scale_factor_temperature multiply SF(T)/SF(T_cal).

    Checked against the emulator itself: the gain GyroModel reports with the
    part's term over the gain without it, at each grid temperature.
    """
    tol = {'extended.scale_factor_temperature.sf_temp_coeff_per_k': {'normal': 5e-5},
           'extended.scale_factor_temperature.sf_temp_coeff2_per_k2': {'uniform': 5e-7},
           'gas.pressure_pa': {'uniform': '10%'}}
    cfg = fleet(extended={'scale_factor_temperature': SF_POLY}, tolerances=tol,
                sensor_runs={'devices': 1, 'duration_s': 10.0}, attribution_devices=0)
    plain = fleet(tolerances={'gas.pressure_pa': {'uniform': '10%'}}, attribution_devices=0)
    n = 200
    values, invalid, _ = sampling.checked(cfg, sampling.draw_block(cfg, 4, 0, n).values(), n)
    assert not invalid.any()
    c1 = values['extended.scale_factor_temperature.sf_temp_coeff_per_k']
    assert np.std(c1) == pytest.approx(5e-5, rel=0.2) and np.mean(c1) == pytest.approx(
        2e-4, abs=3 * 5e-5 / np.sqrt(n))
    ext = evaluate.evaluate(cfg, values, n)
    base = evaluate.evaluate(plain, {k: v for k, v in values.items()
                                     if not k.startswith('extended.')}, n)
    temps = np.array(cfg.temperatures_c)
    from gyro_emulator.analysis.fleet import sensor_runs
    from gyro_emulator.sensor.model import GyroModel
    for i in (0, 1, 2):
        part = sensor_runs.part_sensor_config(cfg, values, ext, i)
        term = part.extended.scale_factor_temperature
        assert term.sf_temp_coeff_per_k == (c1[i],) * 3
        gains = [GyroModel(c, 100.0, np.random.default_rng(0)).run(
            np.zeros((temps.size, 3)), temps).scale_factor[:, 0]
            for c in (part, replace(part, extended=replace(part.extended,
                                                           scale_factor_temperature=None)))]
        poly = gains[0] / gains[1]
        np.testing.assert_allclose(ext['sf_ratio'][:, i], base['sf_ratio'][:, i] * poly,
                                   rtol=1e-12)
    # The linear coefficient moves the tempco by about c1 (ppm/K).
    np.testing.assert_allclose(ext['sf_tempco_ppm_k'] - base['sf_tempco_ppm_k'], 1e6 * c1,
                               atol=30.0)
    assert not np.array_equal(ext['sf_error_pct'], base['sf_error_pct'])
    np.testing.assert_array_equal(ext['sf_m_per_rad_s'], base['sf_m_per_rad_s'])


def test_a_drawn_extended_term_reaches_the_part_s_sensor_run_and_its_range_is_checked():
    """A part's bias step is its drawn value; a value outside the term's range is rejected."""
    cfg = fleet(extended={'bias_step': {'step_time_s': 0.0, 'bias_step_rad_s': 1e-3},
                          'bias_hysteresis': {'hysteresis_width_k': 0.5}},
                tolerances={'extended.bias_step.bias_step_rad_s': {'normal': 2e-4},
                            'extended.bias_hysteresis.hysteresis_width_k': {'normal': 0.25}},
                sensor_runs={'devices': 1, 'duration_s': 10.0}, attribution_devices=0)
    n = 400
    values, invalid, _ = sampling.checked(cfg, sampling.draw_block(cfg, 9, 0, n).values(), n)
    raw = sampling.draw_block(cfg, 9, 0, n).values()
    # Width is open at 0 (sensor.extensions.BiasHysteresis.RANGES): P(z < -2) ~ 2.3 %.
    np.testing.assert_array_equal(invalid, raw['extended.bias_hysteresis.hysteresis_width_k']
                                  <= 0.0)
    assert 0 < invalid.sum() < 0.06 * n
    from gyro_emulator.analysis.fleet import sensor_runs
    from gyro_emulator.sensor.model import GyroModel
    metrics = evaluate.evaluate(cfg, values, n)
    i = int(np.flatnonzero(~invalid)[0])
    part = sensor_runs.part_sensor_config(cfg, values, metrics, i)
    step = values['extended.bias_step.bias_step_rad_s'][i]
    assert part.extended.bias_step.bias_step_rad_s == (step,) * 3
    quiet = replace(part, terms=replace(part.terms, **dict.fromkeys(part.terms.names(), False)))
    out = GyroModel(quiet, 100.0, np.random.default_rng(0)).run(np.zeros((50, 3)),
                                                                np.full(50, 25.0))
    np.testing.assert_allclose(out.gyro_rad_s[-1], step, rtol=1e-9)


def test_a_run_logged_to_a_file_says_its_progress_every_minute():
    """A log, not a terminal: a line per LOG_PROGRESS_S with the rate of this run only."""
    import io

    now = [0.0]
    out = io.StringIO()
    bar = run.LogProgress(1000, initial=200, clock=lambda: now[0], stream=out)
    for t, n in ((30.0, 100), (61.0, 100), (90.0, 100), (121.0, 100)):
        now[0] = t
        bar.update(n)
    lines = out.getvalue().splitlines()
    # 200 devices of this run in 61 s: 3.28/s, 600 left; then 400 in 121 s, 400 left
    assert lines == ['fleet: 400 of 1000 devices (40.0 %), 3.28 devices/s, '
                     'time left at that rate 183 s',
                     'fleet: 600 of 1000 devices (60.0 %), 3.31 devices/s, '
                     'time left at that rate 121 s']
    quiet = io.StringIO()
    short = run.LogProgress(10, clock=lambda: 0.0, stream=quiet)
    short.update(10)
    assert quiet.getvalue() == ''


class _InterruptedOnce:
    """A thread's end (an event) whose first wait a signal interrupts; set after two waits."""

    def __init__(self):
        self.waits = 0

    def is_set(self):
        return self.waits >= 2

    def wait(self, timeout=None):
        self.waits += 1
        if self.waits == 1:
            raise Terminated(signal.SIGTERM)


def test_a_signal_while_the_cluster_closes_is_raised_once_it_is_closed():
    """The process then ends without the interpreter's exit: nothing else would close it."""
    dask_run = object.__new__(run._DaskRun)
    dask_run.closed = _InterruptedOnce()
    with pytest.raises(Terminated):
        dask_run.join()
    assert dask_run.closed.waits == 2


def test_a_signal_another_thread_takes_while_the_cluster_starts_is_handled_at_once():
    """The kernel may hand SIGTERM to any thread; the main thread's wait must look at it."""
    main_thread = threading.get_ident()
    release = threading.Event()

    def waiting_in_run():
        frame = sys._current_frames()[main_thread]
        top = frame.f_code.co_name
        while frame is not None and frame.f_code is not run._DaskRun.run.__code__:
            frame = frame.f_back
        return frame is not None and top == 'wait'

    def start():                        # the cluster's start, on until it is released
        while not waiting_in_run():     # until the main thread waits for the start
            time.sleep(0.001)
        signal.pthread_kill(threading.get_ident(), signal.SIGTERM)
        release.wait(30)
        dask_run.started.set()

    dask_run = object.__new__(run._DaskRun)
    dask_run.started = threading.Event()
    starter = threading.Thread(target=start)
    try:
        with TerminateOnSignal():
            starter.start()
            with pytest.raises(Terminated):
                dask_run.run(None, [], None, None)
            starting = not dask_run.started.is_set()
    finally:
        release.set()
        starter.join()
    assert starting                     # handled while the start went on, not after it


def test_ctrl_c_gives_the_resume_hint_and_stops_as_the_command_line_does(
        tmp_path, monkeypatch, capsys):
    """A Ctrl-C reaches the command line: status 130, and from the entry point no exit hooks."""
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(run, 'run_fleet', interrupted)
    out = tmp_path / 'o'
    status = main(['fleet', os.path.join(ROOT, 'config', 'fleet_paper_etch2.yaml'),
                   '--devices', '10', '--out', str(out)])
    assert status == 130
    assert capsys.readouterr().err.splitlines() == [
        f'gyro-emulator fleet: interrupted; the finished tasks are kept in {out}: run again '
        'with --resume to finish', 'gyro-emulator fleet: interrupted']
