"""The one profile protocol: every kind gives 3-axis samples; one function per idea."""

import math

from gyro_emulator.emulation import profiles, scenario
from gyro_emulator.emulation.recorded_profile import RecordedProfile
from gyro_emulator.emulation.run_profile import samples_with_force
from gyro_emulator.emulation.truth.drawn import draw_profile, SAMPLED_PROFILES
import numpy as np
import pytest

#: Times asked of every kind: unordered, repeated, before the start and after the end.
TIMES_S = np.array([3.0, 0.0, 0.5, 0.5, 17.25, -1.0, 1e4, 42.0])


def _recorded():
    t = np.array([0.0, 0.1, 0.2, 0.2, 0.3, 0.9, 1.0])
    rate = np.column_stack([np.zeros(7), np.linspace(0.0, 0.6, 7), np.ones(7)])
    accel = np.tile(profiles.LEVEL_ACCEL_M_S2, (7, 1))
    return RecordedProfile('log.csv', t, rate, np.linspace(20.0, 26.0, 7), accel)


def _kinds():
    yaml_profile = profiles.profile_from_mapping({'segments': [
        {'duration_s': 2.0, 'rate_deg_s': 10.0, 'temp_c': 20.0},
        {'duration_s': 4.0, 'rate_deg_s': [[0, 0, 0], [5, 0, 90]], 'temp_c': [20.0, 40.0]}]})
    rng = np.random.default_rng(4)
    return {
        **{f'scripted {name}': profiles.make_profile(name, 30.0) for name in
           profiles.PROFILE_NAMES},
        'scripted yaml': yaml_profile,
        **{f'sampled {name}': draw_profile(name, rng, 0.5, levels=3, duration_s=3600.0)
           for name in SAMPLED_PROFILES},
        'recorded': _recorded(),
        'scenario': scenario.parse_scenario({'axis': [0, 1, 0], 'segments': [
            {'duration_s': 1.0, 'rate_rpm': 10.0, 'temp_c': 30.0},
            {'duration_s': 2.0, 'rate_deg_s': -5.0, 'temp_c': 40.0}]}),
    }


@pytest.mark.parametrize('kind', sorted(_kinds()))
def test_every_kind_gives_3_axis_samples_on_the_times_asked(kind):
    profile = _kinds()[kind]
    assert isinstance(profile, profiles.Profile)
    assert profile.duration_s > 0.0 and isinstance(profile.name, str)
    s = profile.samples(TIMES_S)
    assert s.rate_rad_s.shape == (len(TIMES_S), 3)
    assert s.temp_c.shape == (len(TIMES_S),)
    if s.accel_m_s2 is None:    # left to the motion: the applied acceleration, then the force
        assert s.linear_accel_m_s2.shape == (len(TIMES_S), 3)
        assert np.all(np.isfinite(s.linear_accel_m_s2))
        force = samples_with_force(profile, np.sort(TIMES_S[TIMES_S >= 0.0])).accel_m_s2
        assert force.shape == (np.count_nonzero(TIMES_S >= 0.0), 3)
        assert np.all(np.isfinite(force))
    else:
        assert s.accel_m_s2.shape == (len(TIMES_S), 3)
        assert np.all(np.isfinite(s.accel_m_s2))
    for values in (s.rate_rad_s, s.temp_c):
        assert np.all(np.isfinite(values))
    # the same time gives the same sample, wherever it is asked
    assert np.array_equal(s.rate_rad_s[2], s.rate_rad_s[3])
    assert np.array_equal(profile.samples(TIMES_S[:1]).temp_c, s.temp_c[:1])


def test_a_sampled_profile_gives_its_own_samples_exactly_and_is_linear_between():
    prof = draw_profile('lab', np.random.default_rng(2), 2.0, levels=3)
    s = prof.samples(prof.time_s)
    assert np.array_equal(s.rate_rad_s, prof.rate_rad_s)
    assert np.array_equal(s.temp_c, prof.temp_c)
    assert np.array_equal(s.accel_m_s2, prof.accel_m_s2)
    own = prof.own_samples(10, 20)
    assert np.array_equal(own.temp_c, prof.temp_c[10:20])
    mid = prof.samples(prof.time_s[:-1] + 0.25)       # a quarter of the 0.5 s interval
    np.testing.assert_allclose(mid.temp_c, 0.5 * prof.temp_c[:-1] + 0.5 * prof.temp_c[1:],
                               atol=1e-9)
    assert prof.rate_rad_s.shape == (len(prof.time_s), 3)
    assert not prof.rate_rad_s[:, :2].any()           # the truth's part senses z


def test_a_sampled_profile_refuses_a_wrong_shape():
    t = np.arange(4.0)
    with pytest.raises(ValueError, match=r'SampledProfile.rate_rad_s has shape \(4,\): '
                                         r'expected \(4, 3\)'):
        profiles.SampledProfile('x', t, np.zeros(4), np.full(4, 25.0), np.zeros((4, 3)))


def test_scripted_and_sampled_static_agree():
    scripted = profiles.static_profile(100.0, 31.0)
    sampled = profiles.static_profile(100.0, 31.0, sample_rate_hz=4.0)
    assert isinstance(scripted, profiles.ScriptedProfile)
    assert isinstance(sampled, profiles.SampledProfile)
    assert len(sampled.time_s) == 400 and sampled.max_rate_rad_s == 0.0
    a, b = samples_with_force(scripted, sampled.time_s), sampled.samples(sampled.time_s)
    for name in ('rate_rad_s', 'temp_c', 'accel_m_s2'):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_scripted_and_sampled_temperature_ramp_agree():
    knots = ((0.0, 25.0), (60.0, 25.0), (600.0, 70.0), (660.0, 70.0), (1200.0, 25.0))
    scripted = profiles.temperature_ramp(knots, rate_deg_s=30.0)
    sampled = profiles.temperature_ramp(knots, rate_deg_s=30.0, sample_rate_hz=2.0)
    assert [s.duration_s for s in scripted.segments] == [60.0, 540.0, 60.0, 540.0]
    assert scripted.duration_s == 1200.0 and sampled.time_s[-1] == 1199.5
    a, b = samples_with_force(scripted, sampled.time_s), sampled.samples(sampled.time_s)
    np.testing.assert_allclose(a.temp_c, b.temp_c, rtol=0.0, atol=1e-9)
    np.testing.assert_array_equal(a.rate_rad_s, b.rate_rad_s)
    assert a.rate_rad_s[0, 2] == pytest.approx(math.radians(30.0))
    np.testing.assert_array_equal(a.accel_m_s2, b.accel_m_s2)


def test_scripted_and_sampled_paper_rate_steps_agree():
    args = {'dwell_s': 30.0, 'temps_c': (25.0, 45.0), 'rates_rpm': profiles.PAPER_RATES_RPM,
            'ramp_k_min': 20.0}
    scripted = profiles.paper_rate_steps(**args)
    # 4 dwells, the 60 s ramp at rest, 4 dwells
    assert len(scripted.segments) == 9 and scripted.duration_s == pytest.approx(300.0)
    for transition_s in (0.0, 2.0):
        sampled = profiles.paper_rate_steps(**args, transition_s=transition_s,
                                            sample_rate_hz=5.0)
        t = sampled.time_s
        a, b = scripted.samples(t), sampled.samples(t)
        np.testing.assert_allclose(a.temp_c, b.temp_c, rtol=0.0, atol=1e-9)
        changes = np.array([30.0, 60.0, 90.0, 120.0, 180.0, 210.0, 240.0, 270.0])
        away = np.min(np.abs(t[:, None] - changes[None, :]), axis=1) >= transition_s
        np.testing.assert_allclose(a.rate_rad_s[away], b.rate_rad_s[away], rtol=0.0,
                                   atol=1e-12)
        assert b.rate_rad_s[:, 2].max() == pytest.approx(40.0 * 2.0 * math.pi / 60.0)


def test_the_built_in_profiles_are_the_ideas():
    steps = profiles.make_profile('steps', 50.0, 31.0)
    assert steps == profiles.paper_rate_steps(10.0, (31.0,), profiles.STEP_LEVELS_RPM,
                                              name='steps')
    assert profiles.make_profile('static', 5.0, 31.0) == profiles.static_profile(5.0, 31.0)
    ramp = profiles.make_profile('temp-ramp', 60.0)
    assert ramp == profiles.temperature_ramp(((0.0, 25.0), (60.0, 85.0)))
    assert (ramp.name, steps.name) == ('temp-ramp', 'steps')


def test_the_drawn_paper_profile_is_the_papers_grid():
    prof = draw_profile('paper', np.random.default_rng(0), 0.1)
    soaks = np.unique(np.round(prof.temp_c[np.diff(prof.temp_c, append=0.0) == 0.0], 6))
    assert set(profiles.PAPER_TEMPS_C) <= set(soaks)
    rpm = np.round(prof.rate_rad_s[:, 2] * 60.0 / (2.0 * math.pi), 9)
    assert set(profiles.PAPER_RATES_RPM) <= set(rpm)


def test_a_scenario_is_a_scripted_profile_of_labelled_constant_steps():
    played = scenario.parse_scenario({'axis': [0, 0, 2], 'segments': [
        {'duration_s': 1.0, 'rate_rpm': 10.0, 'temp_c': 30.0, 'settle_s': 0.5},
        {'duration_s': 2.0, 'rate_deg_s': -5.0, 'temp_c': 40.0}]})
    assert [s.label for s in played.steps] == ['10 RPM', '-5 deg/s']
    assert played.profile.segments == played.steps and played.duration_s == 3.0
    s = played.samples(np.array([0.5, 1.5]))
    np.testing.assert_allclose(s.rate_rad_s[:, 2], [10.0 * 2.0 * math.pi / 60.0,
                                                    math.radians(-5.0)])
    np.testing.assert_array_equal(s.temp_c, [30.0, 40.0])
    assert played.rate_along_axis_rad_s(played.steps[1]) == pytest.approx(math.radians(-5.0))


def test_a_recorded_profile_is_sampled_on_its_own_times():
    rec = _recorded()
    assert isinstance(rec, profiles.SampledProfile)
    assert rec.sample_period_s == pytest.approx(0.1) and rec.duration_s == pytest.approx(1.1)
    s = rec.samples(np.array([0.05, 0.6]))
    np.testing.assert_allclose(s.temp_c, [20.5, 24.5])


@pytest.mark.parametrize('key, value, match', [
    ('rate_deg_s', [1e300, 0, 0], r'Segment.rate_start_rad_s = \(1.74\d*e\+298, 0.0, 0.0\) is out '
                                  r'of range: allowed 3 numbers in \[-1000, 1000\] rad/s'),
    ('rate_rad_s', [[0, 0, 0], [0, 0, -1000.5]], r'Segment.rate_end_rad_s = \(0.0, 0.0, '
                                                 r'-1000.5\) is out of range'),
    ('linear_accel_m_s2', [0, 0, 1e300], r'Segment.linear_accel_m_s2 = \(0.0, 0.0, 1e\+300\) is '
                                         r'out of range: allowed 3 numbers in \[-999900, '
                                         r'999900\] m/s\^2'),
    ('accel_m_s2', [0, 0, -2e6], r'Segment.accel_m_s2 = \(0.0, 0.0, -2000000.0\) is out of '
                                 r'range: allowed 3 numbers in \[-1e\+06, 1e\+06\] m/s\^2'),
])
def test_a_profile_vector_beyond_what_the_readers_and_the_model_take_is_named(key, value, match):
    """A profile's rate within the record rule (its bag reads back), a force the model takes."""
    mapping = {'segments': [{'duration_s': 1.0, 'rate_deg_s': [0, 0, 0], key: value}]}
    if key == 'rate_rad_s':
        del mapping['segments'][0]['rate_deg_s']
    with pytest.raises(ValueError, match=f'profile: segment 1: {match}') as info:
        profiles.profile_from_mapping(mapping)
    assert '\n' not in str(info.value)
    name = 'rate_rad_s' if key.startswith('rate') else key
    top = {'rate_rad_s': 1000.0, 'linear_accel_m_s2': 999900.0, 'accel_m_s2': 1e6}[name]
    edge = {'segments': [{'duration_s': 1.0, 'rate_rad_s': [0, 0, 0], name: [0.0, 0.0, -top]}]}
    profile = profiles.profile_from_mapping(edge)               # the edge itself is taken
    samples = samples_with_force(profile, np.array([0.0, 0.5]))
    assert np.all(np.isfinite(samples.rate_rad_s))
