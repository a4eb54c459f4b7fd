"""The report says what was done (issue 25, item 9): every line checked against its numbers."""

import os
from types import SimpleNamespace

from gyro_emulator.analysis.calibrate import thermal
from gyro_emulator.analysis.diagnose import generic, report
from gyro_emulator.analysis.diagnose import verdict as vd
from gyro_emulator.analysis.diagnose.baseline import Calibration
from gyro_emulator.analysis.diagnose.noise_model import NoiseModel
import numpy as np
import pytest

REAL = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), '..',
                    'shared', 'data', 'real')
MPU = os.path.join(REAL, 'mpu6050_static', 'mpu6050_static_100hz.csv')
LSM_X = os.path.join(REAL, 'lsm6dsm_thermal_chamber', 'lsm6dsm_tvc_x.csv')


def _res(excess=1.001, slow=1.094, r2=0.26, r2_limit=0.05, margin=0.22, tau=35.8, b=0.0):
    """Return a residual dict shaped as :func:`.verdict.residual_floor` returns (MPU-6050 z)."""
    return {'excess': excess, 'excess_limit': 1.02, 'excess_slow': slow,
            'excess_slow_limit': 1.067, 'averaging_s': 0.935, 'rms_rad_s': 1.63e-3,
            'floor_rad_s': 1.63e-3, 'wander_measured_to_s': tau,
            'follows': {'regressor': 'time', 'r2': r2, 'r2_limit': r2_limit, 'margin': margin},
            'noise': {'bias_instability_rad_s': b, 'rrw_rad_s_sqrt_s': 0.0},
            'r2': {'time': 0.01}, 'strongest_correlate': 'time'}


def _diagnosis(has_temp):
    """Return what calibration_samples_text reads of a diagnosis (the record, the calibration)."""
    cal = Calibration(ref_temp_c=25.0, window_c=2.0, bias_rad_s=0.0, scale_factor=1.0,
                      scale_factor_calibrated=False, samples=44930, mean_time_s=0.0)
    return SimpleNamespace(record=SimpleNamespace(has_temp=has_temp), calibration=cal)


def test_calibration_of_a_record_without_temperature_says_all_samples():
    text = report.calibration_samples_text(_diagnosis(has_temp=False))
    assert text.startswith('all 44930 samples') and 'no temperature' in text
    assert 'within' not in text
    assert (report.calibration_samples_text(_diagnosis(has_temp=True))
            == '44930 samples within 2.00 C of 25.0 C')


def test_noise_line_never_claims_an_allan_deviation_up_to_0_s():
    assert 'up to 35.8 s' in report.allan_text(NoiseModel(1e-3, 1e-3, 0.0, 0.0, 35.8))
    text = report.allan_text(NoiseModel(1e-3, 1e-3, 0.0, 0.0, 0.0))
    assert 'up to 0' not in text and 'not measured' in text


def test_unexplained_message_names_the_comparison_that_failed_and_the_rule_r2():
    res = _res()
    text = vd.message('unexplained', [], res, vd.coverage_text(['bias_time', 'bias_step'], 15))
    assert 'exceeds what noise alone reaches in 0.935 s means' in text
    assert 'per sample' not in text                       # 1.001x is within 1.020x
    assert 'follow time (R^2 = 0.26; noise alone reaches 0.05)' in text
    assert '0.01' not in text and 'largest share' not in text
    assert '2 of 15 causes could be tested' in text
    # the floor has no wander (B = K = 0): the message says what else could do it
    assert 'no wander' in text
    assert vd.follows(res) == 'time'


def test_no_regressor_is_said_to_be_followed_within_what_noise_reaches():
    res = _res(slow=1.2, r2=0.04, r2_limit=0.05, margin=-0.01)
    text = vd.message('unexplained', [], res)
    assert 'follow no regressor beyond what noise does' in text
    assert vd.follows(res) is None
    assert not any('remaining structure follows' in e
                   for e in vd.experiments([], [], True, vd.follows(res)))


def test_a_residual_within_every_limit_is_never_called_above_its_floor():
    res = _res(slow=1.0, margin=0.0)
    assert vd._failed(res) is None
    assert 'exceeds' not in vd.message('unexplained', [], res)


def test_no_mismatch_says_how_little_could_be_tested():
    cov = vd.coverage_text(['bias_time', 'bias_step'], 15)
    assert cov == '2 of 15 causes could be tested (bias_time, bias_step)'
    text = vd.message('no_mismatch', [], _res(slow=0.74, margin=0.0), cov)
    assert text.startswith(cov + '; nothing testable was found')
    assert 'explains' not in text and text.endswith(vd.NOTHING_BOUNDED)
    assert vd.coverage_text(['a', 'b'], 2) is None
    # every cause tested, none bounded: said, never that the baseline explains the data
    text = vd.message('no_mismatch', [], _res(slow=0.74), None)
    assert 'explains' not in text and text.endswith(vd.NOTHING_BOUNDED)
    bounded = vd.message('no_mismatch', [], _res(slow=0.74), None,
                         ruled_out='bias tempco above 0.001 deg/s/K')
    assert bounded.endswith('The data rule out (95 %), beyond the baseline: bias tempco '
                            'above 0.001 deg/s/K.')


@pytest.mark.parametrize('span', [1.0, 4.9, 5.0, 8.2, 14.9, 15.0, 30.0])
@pytest.mark.parametrize('count', [3, 4, 5, 200])
def test_temperature_polynomials_follow_the_rule_of_calibrate(span, count):
    temps = np.linspace(20.0, 20.0 + span, count)
    order, note = generic.polynomial_order(span, temps)
    distinct = thermal.distinct_temperatures(temps)
    try:
        rule = thermal.allowed_order(span, distinct, 2)
    except ValueError:
        rule = 1                                   # diagnose keeps a linear term
    assert order == rule
    assert (note is None) == (order == 2)
    cut = {e.effect_id: e for e in generic.with_polynomial_order(generic.CATALOGUE, order)}
    for name in ('bias_temperature', 'scale_factor_temperature'):
        assert len(cut[name].params) == order == cut[name].n_columns
    # the catalogue itself is not changed
    assert len(generic.effect('bias_temperature').params) == 2


@pytest.mark.skipif(not os.path.exists(LSM_X), reason='real data not present')
def test_real_lsm6dsm_x_fits_no_quadratic_term_over_8_k():
    from gyro_emulator.analysis.diagnose import diagnose, load_measured, to_json

    diagnosis = diagnose(load_measured(LSM_X))
    doc = to_json(diagnosis)
    poly = doc['temperature_polynomial']
    assert poly['order'] == 1 and 8.0 < poly['span_k'] < 8.5
    assert '15 K' in poly['note']
    for entry in doc['selected'] + doc['findings']:
        assert not any(name.startswith(('bias_temp_coeff2', 'sf_temp_coeff2'))
                       for name in entry['parameters'])
    assert 'up to 0 s' not in report.markdown(diagnosis)


@pytest.mark.skipif(not os.path.exists(MPU), reason='real data not present')
def test_real_mpu6050_z_verdict_agrees_with_its_stated_numbers():
    from gyro_emulator.analysis.diagnose import diagnose, load_measured, to_json

    diagnosis = diagnose(load_measured(MPU, axis='z', static=True))
    doc = to_json(diagnosis)
    res = doc['residual']
    failed = vd._failed(res)
    assert (doc['verdict'] == 'unexplained') == (failed is not None)
    if failed:
        assert f'exceeds what noise alone reaches {failed}' in res['message']
    assert 'largest share' not in res['message']
    page = report.markdown(diagnosis)
    assert 'samples within' not in page and 'from all 44930 samples' in page
    follows = vd.follows(res)
    for text in doc['experiments']:
        assert 'remaining structure follows' not in text or follows is not None


def _cand(effect_id, significant=True):
    """Return a scored candidate as the selection steps hold it (only what the rule reads)."""
    return type('Cand', (), {'effect': type('Effect', (), {'effect_id': effect_id}),
                             'significant': significant})


@pytest.mark.parametrize('r,twin_significant,expected', [
    (-0.999, True, ['scale_factor_temperature']),   # a cooling: the twin is named
    (0.90, True, []),                               # below PAIR_R: the record can tell
    (-0.999, False, []),                            # the twin was not established itself
])
def test_a_cause_in_time_names_its_temperature_twin_when_the_two_are_confounded(
        r, twin_significant, expected):
    chosen = _cand('scale_factor_time')
    steps = [([chosen, _cand('scale_factor_temperature', twin_significant),
               _cand('bias_time')], chosen), ([_cand('bias_step', False)], None)]
    confound = [{'a': 'time', 'b': 'temperature', 'correlation': r}]
    assert vd.confounded_twins(steps, confound) == [expected]


def test_the_bias_twins_pair_both_ways_and_other_causes_have_none():
    first, second = _cand('bias_temperature'), _cand('g_sensitivity')
    steps = [([first, _cand('bias_time')], first), ([second, _cand('bias_time')], second)]
    confound = [{'a': 'temperature', 'b': 'time', 'correlation': 0.97}]
    assert vd.confounded_twins(steps, confound) == [['bias_time'], []]


def test_the_terminal_says_when_an_interval_stops_at_the_searched_range():
    # a delay pinned at the grid's end (-0.05 s): the report and JSON said so, the
    # terminal printed a 15 us wide interval as if the data gave it
    from gyro_emulator.analysis.diagnose.diagnosis import Parameter
    method = ('profile likelihood; its low end at the edge of the searched range: the '
              'interval may reach beyond it')
    pinned = Parameter(value=-0.05, sigma=3.9e-6, unit='s', meaning='output delay',
                       interval=(-0.05, -0.049985), method=method)
    assert report.parameter_text(pinned) == (
        '-0.05 [-0.05, -0.049985] s (95 %, profile; its low end at the edge of the searched '
        'range)')
    both = Parameter(value=0.0, sigma=1.0, unit='s', meaning='', interval=(-1.0, 1.0),
                     method=method.replace('its low end', 'its low and high end'))
    assert report.parameter_text(both).endswith('its low and high end at the edge of the '
                                                'searched range)')
    closed = Parameter(value=0.012, sigma=1e-4, unit='s', meaning='', interval=(0.0118, 0.0122),
                       method='profile likelihood')
    assert report.parameter_text(closed) == '0.012 [0.0118, 0.0122] s (95 %, profile)'
