"""
Issue 23: effects hidden in real noise must be found.

A stretch of a real static log (``../shared/data/real``: ADIS16405 2.8 h,
MPU-6050 7.5 min, the LSM6DSM chamber log) is driven through a profile
(ramp, cycles, soaks, tilt steps, rate steps) with an effect at its
datasheet size or a third of it (:mod:`gyro_emulator.emulation.truth.injection`),
and ``diagnose`` must name it; on a one-way ramp, where temperature and time
cannot be told apart, it must name the pair. The ADIS16405 log is taken as
10 Hz block means (the same part's noise through a 10-sample output
average) so that hours of it stay fast. The raw logs must give no cause.
The figures behind the false-alarm rate are in ``bench/calibrate_diagnose.py --real``.

Skipped when ``../shared/data/real`` is absent.
"""

import functools
import os
import subprocess
import sys

from gyro_emulator.analysis.diagnose import diagnose, to_json
from gyro_emulator.analysis.diagnose.data import measured, write_measured_csv
from gyro_emulator.emulation.truth import injection as inj
from gyro_emulator.recording.record import Record
import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
REAL = os.path.join(os.path.dirname(ROOT), 'shared', 'data', 'real')
LOGS = {
    'adis': (os.path.join(REAL, 'adis16405_static', 'adis16405_run1_100hz.csv.gz'), 10),
    'mpu': (os.path.join(REAL, 'mpu6050_static', 'mpu6050_static_100hz.csv'), 1),
    'lsm': (os.path.join(REAL, 'lsm6dsm_thermal_chamber', 'lsm6dsm_tvc_{}.csv'), 1),
}
DEG = np.pi / 180.0
DS = inj.DATASHEET

pytestmark = pytest.mark.skipif(
    not os.path.isdir(REAL),
    reason=f'the real logs are absent ({REAL}): issue 23 hides effects in their noise')

#: Catalogue causes that name each injected effect.
NAMES = {
    'bias_tempco': {'bias_temperature', 'bias_hysteresis', 'temperature_rate_bias'},
    'sf_tempco': {'scale_factor_temperature', 'viscosity_temperature', 'thermal_lag',
                  'pressure_drift', 'mode_split_drift'},
    'g_sensitivity': {'g_sensitivity'},
    'delay': {'time_delay'},
    'sf_nonlinearity': {'scale_factor_nonlinearity'},
    'sf_step': {'scale_factor_step', 'scale_factor_time'},
}
#: Either of a bias that follows temperature or time (a one-way ramp).
RAMP_PAIR = {'bias_temperature', 'bias_time', 'bias_hysteresis'}


@functools.lru_cache(maxsize=None)
def _log(name, axis):
    path, factor = LOGS[name]
    if name == 'lsm':
        return inj.load_real(path.format(axis))
    t, y, temp = inj.load_real(path, axis)
    t, y = inj.block_means(t, y, factor)
    return t, y, temp


def _record(log, axis, profile, effects, seed, duration_s=None):
    """Real noise of ``log``/``axis`` through ``profile`` with ``effects`` (name -> size)."""
    rng = np.random.default_rng(seed)
    t, y, temp = _log(log, axis)
    if duration_s is None:
        tt, noise = t, y
    else:
        tt, noise = inj.stretch(t, y, duration_s, rng)
    inputs = inj.profile(profile, tt, rng, temp_c=temp)
    return inj.inject(noise, inputs, effects, sf_error=float(rng.uniform(-5e-3, 5e-3)),
                      path=f'{log} {axis} {profile} {effects}')


def _named(doc):
    out = set()
    for entry in doc['selected']:
        out |= {entry['effect']} | set(entry['indistinguishable_from'])
    return out


def _confounded_time_temperature(doc):
    return any({c['a'], c['b']} == {'time', 'temperature'} for c in doc['confounded'])


def _assert_found(doc, effect):
    assert NAMES[effect] & _named(doc), (
        f'{effect} not named: verdict {doc["verdict"]}, selected '
        f'{[e["effect"] for e in doc["selected"]]}, best {doc["best"]["effect"]}, '
        f'{doc["residual"]["message"]}')


def _assert_pair(doc):
    """Check a bias on a one-way ramp: the temperature-or-time pair, never none or no_mismatch."""
    assert doc['verdict'] != 'no_mismatch', doc['residual']['message']
    assert RAMP_PAIR & _named(doc), (
        f'no bias cause named: verdict {doc["verdict"]}, {doc["residual"]["message"]}')
    assert _confounded_time_temperature(doc)


# -- the table -------------------------------------------------------

@pytest.mark.slow
def test_row1_adis_y_cycles_bias_tempco_below_the_datasheet():
    doc = to_json(diagnose(_record('adis', 'y', 'cycles', {'bias_tempco': 0.004 * DEG}, 1)))
    _assert_found(doc, 'bias_tempco')
    assert doc['verdict'] in ('explained', 'partly_explained')


@pytest.mark.slow
def test_row2_adis_x_one_ramp_bias_tempco_is_named_with_its_pair():
    _assert_pair(to_json(diagnose(_record('adis', 'x', 'ramp', {'bias_tempco': 0.01 * DEG}, 2))))


@pytest.mark.slow
def test_row3_adis_x_ramp_and_tilt_finds_g_sensitivity_and_the_bias_pair():
    doc = to_json(diagnose(_record('adis', 'x', 'ramp+tilt', {
        'bias_tempco': 0.01 * DEG, 'g_sensitivity': 0.03 * DEG / 9.80665}, 3)))
    _assert_found(doc, 'g_sensitivity')
    _assert_pair(doc)


@pytest.mark.parametrize('seed', (4, pytest.param(5, marks=pytest.mark.slow)))
def test_row4_mpu_y_rate_steps_delay_is_found_and_its_edges_are_kept(seed):
    record = _record('mpu', 'y', 'rate_steps', {'delay': 0.012}, seed, duration_s=120.0)
    doc = to_json(diagnose(record))
    _assert_found(doc, 'delay')
    assert doc['set_aside']['fraction'] < 0.001
    delay = next(e for e in doc['selected'] if e['effect'] == 'time_delay')
    assert abs(delay['parameters']['delay_s']['value'] - 0.012) < 0.003


# -- effects at datasheet size and a third of it ------------------------------

CASES = [
    # (log, axis, profile, effects, seconds or None for the whole log)
    ('mpu', 'x', 'rate_steps', {'delay': DS['delay']}, 120.0),
    ('mpu', 'z', 'rate_steps', {'delay': DS['delay'] / 3}, 120.0),
    ('mpu', 'x', 'rate_steps', {'sf_nonlinearity': DS['sf_nonlinearity']}, 300.0),
    ('mpu', 'y', 'rate_steps', {'sf_nonlinearity': DS['sf_nonlinearity'] / 3}, 440.0),
    ('mpu', 'z', 'rate_steps', {'sf_step': DS['sf_step']}, 300.0),
    ('mpu', 'x', 'rate_steps', {'sf_step': DS['sf_step'] / 3}, 440.0),
    ('mpu', 'y', 'tilt', {'g_sensitivity': DS['g_sensitivity']}, 300.0),
    ('mpu', 'z', 'tilt', {'g_sensitivity': DS['g_sensitivity'] / 3}, 440.0),
    # an SF tempco with rate and temperature: test_the_parts_own_sf_tempco_... reads it back
    # (here it could not fail: the paper's own +545 ppm/K is named on any such record)
    ('mpu', 'y', 'rate_steps', {'delay': DS['delay'], 'sf_nonlinearity': DS['sf_nonlinearity']},
     300.0),
    ('adis', 'z', 'cycles', {'bias_tempco': DS['bias_tempco']}, None),
    ('adis', 'x', 'cycles', {'bias_tempco': DS['bias_tempco'] / 3}, None),
    # a known miss: a one-way staircase of soaks at 1/3 of the datasheet tempco,
    # p 0.11 against the log's own wander; nulls with a flicker term give p_LR
    # 0.0012-0.09, short of 0.001 (docs/diagnose.md, 'What one record cannot
    # show'; bench/study_null_soaks.py): the record's slow wander is too poorly known
    ('adis', 'y', 'soaks', {'bias_tempco': DS['bias_tempco'] / 3}, None),
    ('adis', 'z', 'tilt', {'g_sensitivity': DS['g_sensitivity'] / 3}, 3600.0),
    ('adis', 'y', 'cycles+tilt', {'bias_tempco': DS['bias_tempco'] / 3,
                                  'g_sensitivity': DS['g_sensitivity'] / 3}, None),
]
#: Effects the likelihood ratio supports in-sample that the held-out data do not
#: confirm (issue 33): listed as such, never chosen. The g-sensitivity at 1/3
#: beside cycles on ADIS16405 y (16 tilts of 10 min): LR p 3e-10, held-out gain
#: -0.4 % per sample and -5 % in the group means.
IN_SAMPLE_ONLY = {13: {'g_sensitivity'}}
#: Cases that run longer than a few seconds (all but the delays at rate edges).
SLOW = {i for i, case in enumerate(CASES) if case[3].keys() != {'delay'}}


def _case_id(case):
    log, axis, profile, effects, _ = case
    size = 'datasheet' if any(v == DS[k] for k, v in effects.items()) else 'third'
    return f'{log}-{axis}-{profile}-{"+".join(effects)}-{size}'


#: Cases the statistics do not find yet; strict: they fail the suite once found.
KNOWN_MISSES = {i for i, case in enumerate(CASES) if case[2] == 'soaks'}


def _marks(i):
    marks = [pytest.mark.slow] if i in SLOW else []
    if i in KNOWN_MISSES:
        marks.append(pytest.mark.xfail(strict=True, reason='not found: a one-way staircase of '
                                       'soaks at 1/3 of the datasheet tempco, p 0.11 (the '
                                       "record's own slow wander; docs/diagnose.md)"))
    return marks


@pytest.mark.parametrize('index', [
    pytest.param(i, marks=_marks(i)) for i in range(len(CASES))],
    ids=[_case_id(c) for c in CASES])
def test_an_effect_hidden_in_real_noise_is_found(index):
    log, axis, profile, effects, duration = CASES[index]
    doc = to_json(diagnose(_record(log, axis, profile, effects, 100 + index, duration)))
    only = IN_SAMPLE_ONLY.get(index, set())
    for effect in set(effects) - only:
        _assert_found(doc, effect)
    for effect in only:
        assert not NAMES[effect] & {e['effect'] for e in doc['selected']}
        assert NAMES[effect] & {e['effect'] for e in doc['supported_in_sample']}, doc['residual']
    assert doc['set_aside']['fraction'] < 0.001
    # what is named holds on held-out data and stands clear of zero (issue 33)
    for entry in doc['selected']:
        assert entry['gain_step'] > 0.0 or entry['gain_binned'] > 0.0
    if doc['verdict'] == 'explained':
        assert all(entry['interval_excludes_zero'] for entry in doc['selected'])


@pytest.mark.slow
def test_the_one_way_staircase_at_a_third_is_found_with_a_reference_record():
    """
    The strict xfail above, with the noise of a static record of the part held fixed.

    The project holds one ADIS16405 log: the reference here is that log's y
    axis at rest, the noise of the very record (the known-noise limit of
    docs/diagnose.md). A disjoint half as the reference, the other half
    through the soaks, is the second case; with nothing injected it finds
    nothing.
    """
    index = next(i for i in KNOWN_MISSES)
    log, axis, profile, effects, _ = CASES[index]
    t, y, _ = _log(log, axis)
    static = measured(Record.from_arrays(t, y, np.zeros(len(t)), None, None, path='ref'))
    doc = to_json(diagnose(_record(log, axis, profile, effects, 100 + index),
                           reference=static))
    _assert_found(doc, 'bias_tempco')
    assert doc['reference']['rrw_rad_s_sqrt_s'] > 0.0
    entry = next(e for e in doc['selected'] if e['effect'] == 'bias_temperature')
    assert entry['evidence']['route'] == 'reference_noise'
    half = len(t) // 2
    first = measured(Record.from_arrays(t[:half], y[:half], np.zeros(half), None, None,
                                        path='first half'))
    rng = np.random.default_rng(7)
    second = t[half:] - t[half]
    for size, found in ((effects['bias_tempco'], True), (0.0, False)):
        record = inj.inject(y[half:], inj.profile(profile, second, rng),
                            {'bias_tempco': size} if size else {})
        doc = to_json(diagnose(record, reference=first))
        assert bool(NAMES['bias_tempco'] & _named(doc)) is found, doc['residual']['message']


@pytest.mark.parametrize('axis,scale,seed,duration', [
    ('x', 1.0, 41, 300.0), ('y', 1 / 3, 42, 440.0), ('x', -1 / 3, 44, 440.0)])
def test_an_sf_step_is_named_as_a_step_at_its_time(axis, scale, seed, duration):
    # the fold test alone missed it (p 0.07: the fold holding the step cannot
    # place it) and a rate polynomial that predicted the folds 140 % worse took
    # its place; the likelihood route now tests the step at its fitted time
    size = scale * DS['sf_step']
    doc = to_json(diagnose(_record('mpu', axis, 'rate_steps', {'sf_step': size}, seed, duration)))
    first = doc['selected'][0]
    assert first['effect'] == 'scale_factor_step', doc['residual']['message']
    got = first['parameters']['sf_step']
    assert abs(got['value'] - size) < 4.0 * got['sigma'] + 0.05 * abs(size), got
    start, end = doc['input']['time_span_s']
    assert abs(first['parameters']['step_time_s']['value'] - (start + end) / 2) < 10.0
    assert all(e['effect'] != 'scale_factor_nonlinearity' for e in doc['selected'])


@pytest.mark.parametrize('axis,scale,seed', [('x', 1.0, 51), ('y', 1 / 3, 55)])
def test_an_sf_step_under_a_rate_sine_on_the_noisier_part_is_named(axis, scale, seed):
    """
    ADIS16405 noise, 1800 s, a rate-table sine of 50-300 deg/s at 0.2-2 Hz.

    A third of the datasheet step gains 0.4-0.6 % per sample at p about
    the level: named only with the rate causes' 0.1 % gain floor, beside a
    pressure drift it cannot be told from (seed 55).
    """
    doc = to_json(diagnose(_record('adis', axis, 'rate_sine', {'sf_step': DS['sf_step'] * scale},
                                   seed, 1800.0)))
    _assert_found(doc, 'sf_step')


@pytest.mark.parametrize('axis,size,seed', [
    ('x', 0.0, 1), ('y', -DS['sf_tempco'], 5), ('z', DS['sf_tempco'] / 3, 6)])
def test_the_parts_own_sf_tempco_is_read_against_the_physics(axis, size, seed):
    # rate and temperature together: a real part (flat SF, or the injected
    # tempco) does not follow the paper's +545 ppm/K, so scale_factor_temperature
    # is named relative to the physics; the part's own slope must be the injected one
    effects = {'sf_tempco': size} if size else {}
    doc = to_json(diagnose(_record('mpu', axis, 'cycles+rate_steps', effects, seed, 440.0)))
    entry = next(e for e in doc['selected'] if e['effect'] == 'scale_factor_temperature')
    own = entry['part_sf_temp_coeff_per_k']
    assert own['compensated'] and own['physics_per_k'] > 3e-4
    assert own['sigma'] < 5e-6  # resolves a third of the datasheet figure
    assert abs(own['value'] - size) < 4.0 * own['sigma'], own
    assert entry['mechanisms'][0].startswith('factory temperature compensation')
    assert 'temperature-compensated part' in doc['residual']['message']


@pytest.mark.slow
@pytest.mark.parametrize('axis,scale', [('x', 1.0), ('y', 1 / 3)])
def test_lsm6dsm_chamber_cooling_names_the_bias_pair(axis, scale):
    # the chamber cools once: temperature and time go together
    doc = to_json(diagnose(_record('lsm', axis, 'chamber',
                                   {'bias_tempco': scale * DS['bias_tempco']}, 7)))
    _assert_pair(doc)


# -- no effect: no cause --------------------------------------------------------

@pytest.mark.parametrize('log,axis,profile,duration,seed', [
    ('mpu', 'x', 'rate_steps', 120.0, 11),
    pytest.param('mpu', 'y', 'tilt', 240.0, 12, marks=pytest.mark.slow),
    pytest.param('mpu', 'z', 'cycles', 240.0, 13, marks=pytest.mark.slow),
    pytest.param('adis', 'x', 'cycles+tilt', 3600.0, 14, marks=pytest.mark.slow),
    ('adis', 'y', 'rate_sine', 1800.0, 15), ('mpu', 'z', 'rate_sine', 300.0, 16)])
def test_the_raw_logs_through_a_profile_give_no_cause(log, axis, profile, duration, seed):
    doc = to_json(diagnose(_record(log, axis, profile, {}, seed, duration)))
    assert doc['best']['effect'] == 'none', doc['residual']['message']
    assert doc['set_aside']['fraction'] < 0.001


# -- the command line: no warnings, no tracebacks ------------------------------

@pytest.mark.parametrize('case', ['raw', 'delay', 'short'])
def test_the_cli_prints_no_warning_or_traceback(tmp_path, case):
    if case == 'raw':
        args = [LOGS['mpu'][0], '--static', '--axis', 'z']
    else:
        effects = {'delay': 0.012} if case == 'delay' else {}
        record = _record('mpu', 'y', 'rate_steps', effects, 21,
                         duration_s=60.0 if case == 'delay' else 0.3)
        path = str(tmp_path / 'injected.csv')
        write_measured_csv(path, measured(record))
        args = [path]
    run = subprocess.run([sys.executable, '-W', 'default', '-m', 'gyro_emulator.cli', 'diagnose',
                          *args, '--report', str(tmp_path / 'report')],
                         capture_output=True, text=True, cwd=ROOT)
    assert 'Warning' not in run.stderr and 'Traceback' not in run.stderr, run.stderr
    assert run.returncode == 0 or len(run.stderr.strip().splitlines()) == 1, run.stderr


def test_the_cli_takes_a_reference_record_and_says_so(tmp_path):
    t, y, _ = _log('mpu', 'x')
    half = len(t) // 2
    ref_csv, rec_csv, out = tmp_path / 'ref.csv', tmp_path / 'rec.csv', tmp_path / 'd.json'
    write_measured_csv(str(ref_csv), measured(Record.from_arrays(
        t[:half], y[:half], np.zeros(half), None, None, path='ref')))
    second = t[half:] - t[half]
    rng = np.random.default_rng(3)
    write_measured_csv(str(rec_csv), measured(inj.inject(
        y[half:], inj.profile('rate_steps', second, rng), {'delay': DS['delay']})))
    run = subprocess.run([sys.executable, '-W', 'default', '-m', 'gyro_emulator.cli', 'diagnose',
                          str(rec_csv), '--reference', str(ref_csv), '--json', str(out)],
                         capture_output=True, text=True, cwd=ROOT)
    assert run.returncode == 0 and not run.stderr.strip(), run.stderr
    assert 'noise held fixed from the reference' in run.stdout
    import json
    doc = json.loads(out.read_text())
    assert doc['reference']['source'].endswith('ref.csv')
    assert 'time_delay' in _named(doc)


def test_a_cause_whose_size_is_not_established_states_its_joint_p():
    """
    Chosen on the joint size rule, its interval holding zero: the report says so, with p.

    A bias tempco of 1e-4 deg/s/K through two 15 <-> 55 C cycles in the
    MPU-6050 x noise: dT and dT^2 together stand clear of zero over the
    folds, neither does alone, so ``bias_temperature`` is chosen and the
    verdict stays ``partly_explained`` (issue 33).
    """
    from gyro_emulator.emulation.profiles import SampledProfile
    t, y, _ = _log('mpu', 'x')
    n = len(t)
    prof = SampledProfile('cycles', t, np.zeros((n, 3)), inj.temperature_cycles(t, phase=0.0),
                          np.tile([0.0, 0.0, 9.80665], (n, 1)))
    diagnosis = diagnose(inj.inject(y, prof, {'bias_tempco': 1e-4 * DEG}))
    doc = to_json(diagnosis)
    entry = doc['selected'][0]
    assert entry['effect'] == 'bias_temperature' and not entry['interval_excludes_zero']
    assert doc['verdict'] == 'partly_explained'
    assert any(v['interval'][0] < 0.0 < v['interval'][1] for v in entry['parameters'].values())
    # below the size rule's joint level, 2 P(t_7 > 2) = 0.086 on 8 folds
    assert 0.0 < entry['joint_p_value'] < 0.086
    assert diagnosis.selected[0].joint_p_value == entry['joint_p_value']
    assert (f"(its coefficients together: p = {entry['joint_p_value']:.2g} over the folds"
            in doc['residual']['message'])
    # a cause whose interval excludes zero does not carry the figure
    strong = to_json(diagnose(inj.inject(y, prof, {'bias_tempco': 1e-3 * DEG})))
    assert strong['selected'][0]['interval_excludes_zero']
    assert 'joint_p_value' not in strong['selected'][0]
