"""Kinematics in one place (issue 32): the attitude quaternion and the specific force."""

import math

from gyro_emulator.physics import kinematics
import numpy as np
import pytest

G = 9.80665


def test_a_level_part_at_rest_reads_plus_g_on_z():
    force = kinematics.specific_force(kinematics.LEVEL_WXYZ)
    assert np.array_equal(force, [0.0, 0.0, G])
    assert not np.signbit(force).any()          # +0, not -0


def test_a_90_degree_turn_about_x_moves_gravity_from_z_to_y():
    # REP 103: +90 deg about x turns the body's y axis up, so y reads +g
    _, after = kinematics.propagate(kinematics.LEVEL_WXYZ, [[math.pi / 2, 0.0, 0.0]], 1.0)
    np.testing.assert_allclose(kinematics.specific_force(after), [0.0, G, 0.0], rtol=0,
                               atol=1e-12)
    # the same 90 deg in 1000 steps, and as a roll angle
    _, stepped = kinematics.propagate(kinematics.LEVEL_WXYZ,
                                      np.tile([math.pi / 2, 0.0, 0.0], (1000, 1)), 1e-3)
    np.testing.assert_allclose(kinematics.specific_force(stepped), [0.0, G, 0.0], rtol=0,
                               atol=1e-12)
    rolled = kinematics.from_roll_pitch_yaw(math.pi / 2, 0.0, 0.0)
    np.testing.assert_allclose(kinematics.specific_force(rolled), [0.0, G, 0.0], rtol=0,
                               atol=1e-12)
    # pitch nose down (+90 deg about y): x points down, so x reads -g
    pitched = kinematics.from_roll_pitch_yaw(0.0, math.pi / 2, 0.0)
    np.testing.assert_allclose(kinematics.specific_force(pitched), [-G, 0.0, 0.0], rtol=0,
                               atol=1e-12)


def test_applied_acceleration_adds_in_the_body_frame_and_gravity_is_a_parameter():
    rolled = kinematics.from_roll_pitch_yaw(0.3, -0.2, 1.0)
    up = kinematics.gravity_up_in_body(rolled)
    force = kinematics.specific_force(rolled, [1.0, -2.0, 0.5], gravity_m_s2=3.71)
    np.testing.assert_allclose(force, np.array([1.0, -2.0, 0.5]) + 3.71 * up, rtol=0,
                               atol=1e-15)
    # R^T e_z is the world's up seen from the body: R (R^T e_z) = e_z
    np.testing.assert_allclose(kinematics.rotate_to_world(rolled, up), [0.0, 0.0, 1.0],
                               atol=1e-15)


@pytest.mark.parametrize('gravity', [0.0, -9.8, 100.0001, math.nan, math.inf, True, '9.8'])
def test_a_bad_gravity_is_refused_in_one_line(gravity):
    with pytest.raises(ValueError, match=r'gravity_m_s2 = .* is out of range: allowed '
                                         r'\(0, 100\] m/s\^2'):
        kinematics.specific_force(kinematics.LEVEL_WXYZ, gravity_m_s2=gravity)


@pytest.mark.parametrize('attitude', [(0, 0, 0, 0), (1, 0, 0), (2, 0, 0, 0),
                                      (math.nan, 0, 0, 1), 'level'])
def test_a_bad_attitude_is_refused_in_one_line(attitude):
    with pytest.raises(ValueError, match='attitude_wxyz = .* norm 1'):
        kinematics.AttitudeTrack(attitude)


def test_constant_rate_integration_matches_the_closed_form():
    omega = np.array([0.3, -0.2, 0.5])
    n, dt = 10_000, 1e-3
    path, after = kinematics.propagate((1.0, 0.0, 0.0, 0.0), np.tile(omega, (n, 1)), dt)
    speed = np.linalg.norm(omega)
    for k in (0, 1, 777, n - 1):
        angle = speed * k * dt
        exact = np.r_[math.cos(angle / 2), math.sin(angle / 2) * omega / speed]
        np.testing.assert_allclose(path[k], exact, rtol=0, atol=1e-12)
    angle = speed * n * dt
    np.testing.assert_allclose(after, np.r_[math.cos(angle / 2),
                                            math.sin(angle / 2) * omega / speed], atol=1e-12)


def test_the_norm_stays_one_over_a_million_steps():
    rng = np.random.default_rng(5)
    rate = rng.normal(0.0, 2.0, (1_000_000, 3))
    path, after = kinematics.propagate(kinematics.LEVEL_WXYZ, rate, 1e-3)
    norms = np.sqrt(np.sum(path * path, axis=1))
    assert np.max(np.abs(norms - 1.0)) < 1e-15 * 10
    assert abs(np.linalg.norm(after) - 1.0) < 1e-14


def test_batch_and_stateful_steps_agree_bit_for_bit_for_any_split():
    rng = np.random.default_rng(11)
    t = np.cumsum(rng.uniform(0.001, 0.02, 500))
    rate = rng.normal(0.0, 1.0, (500, 3))
    start = kinematics.from_roll_pitch_yaw(0.1, 0.2, -0.4)
    whole = kinematics.AttitudeTrack(start).at(t, rate)
    path, _ = kinematics.propagate(start, rate[:-1], np.diff(t))
    assert np.array_equal(whole[:-1], path)
    for seed in range(5):
        cuts = np.sort(np.random.default_rng(seed).choice(np.arange(1, 500), 6, replace=False))
        track = kinematics.AttitudeTrack(start)
        parts = []
        for a, b in zip(np.r_[0, cuts], np.r_[cuts, 500]):
            if b - a == 1:
                parts.append(track.step(t[a], rate[a])[None])
            else:
                parts.append(track.at(t[a:b], rate[a:b]))
        assert np.array_equal(np.vstack(parts), whole)


def test_rotation_about_z_keeps_gravity_exactly_on_z():
    rate = np.column_stack([np.zeros(2000), np.zeros(2000), np.linspace(-3.0, 5.0, 2000)])
    attitudes = kinematics.AttitudeTrack().at(np.arange(2000) * 0.01, rate)
    force = kinematics.specific_force(attitudes)
    assert np.array_equal(force, np.tile([0.0, 0.0, G], (2000, 1)))


def test_a_held_rate_in_one_call_equals_a_step_per_sample_bit_for_bit():
    q = kinematics.check_attitude(kinematics.from_roll_pitch_yaw(0.3, -0.2, 1.1))
    rate = (0.7, -0.4, 0.25)
    dt_s = np.array([0.005, 0.004999999, 0.005000001, 0.0, 0.01] * 20)
    path = kinematics.steps_held(q, rate, dt_s)
    one = q
    for k, dt in enumerate(dt_s):
        one = kinematics.step(one, rate, float(dt))
        assert path[k].tobytes() == one.tobytes(), k
    assert kinematics.steps_held(q, rate, np.empty(0)).shape == (0, 4)
