"""The driver's attitude, specific force and accelerometer channel (no ROS)."""

import dataclasses
import math

from gyro_emulator.emulation.driver import parameters
from gyro_emulator.emulation.driver.attitude import AttitudeState, initial_attitude
from gyro_emulator.physics import kinematics
from gyro_emulator.units import STANDARD_GRAVITY_M_S2 as G
import numpy as np
import pytest
from test_driver import Log, make, node_values, PERIOD_NS, T0_NS, ticks


def test_a_default_driver_senses_gravity_on_z_with_a_noisy_accelerometer_and_its_covariance():
    driver, _, _ = make()
    out = ticks(driver, 0, 400)
    assert all(o.accel.true_specific_force_m_s2 == (0.0, 0.0, G) for o in out)
    assert all(o.attitude_wxyz == kinematics.LEVEL_WXYZ and o.accel_shown for o in out)
    sigma = np.asarray(driver.model.accel_white_noise_sigma_m_s2)
    assert np.all(sigma > 0)
    want = np.zeros(9)
    want[[0, 4, 8]] = sigma ** 2
    assert out[0].accel.covariance == tuple(want.tolist())
    accel = np.array([o.accel.accel_m_s2 for o in out])
    assert np.all(np.std(accel, axis=0) > 0)                    # noisy, not the truth
    assert np.allclose(np.mean(accel, axis=0), (0.0, 0.0, G), atol=6 * sigma.max())


def test_the_gyro_samples_are_those_of_the_gyro_model_beside_the_accelerometer():
    # the ImuModel's gyro is bit for bit the GyroModel of the same seed (test_driver offline)
    from test_driver import offline, rates
    driver, _, _ = make()
    out = ticks(driver, 0, 120)
    model = offline(driver)
    want = [model.step((0.0, 0.0, 0.0), 25.0, (0.0, 0.0, G)) for _ in range(120)]
    assert rates(out) == [tuple(s.gyro_rad_s.tolist()) for s in want]


def turn_about_x(**overrides):
    """Turn 90 deg about x in 1 s (200 samples at pi/2 rad/s), then hold still."""
    driver, inbox, _ = make(command_timeout_s=0.0, **overrides)
    inbox.push('rate', T0_NS, (0.5 * math.pi, 0.0, 0.0))
    inbox.push('rate', T0_NS + 200 * PERIOD_NS, (0.0, 0.0, 0.0))
    return driver, ticks(driver, 0, 400)


def test_a_90_degree_turn_about_x_moves_gravity_from_z_to_y():
    driver, out = turn_about_x(noise_enabled=False)
    before, after = out[0].accel.true_specific_force_m_s2, out[250].accel.true_specific_force_m_s2
    assert before == (0.0, 0.0, G)
    assert after == pytest.approx((0.0, G, 0.0), abs=1e-9)
    # the attitude is the exact integral: 90 deg about x
    half = math.sqrt(0.5)
    assert out[200].attitude_wxyz == pytest.approx((half, half, 0.0, 0.0), abs=1e-12)
    assert all(o.attitude_wxyz == out[200].attitude_wxyz for o in out[200:])
    # the accelerometer follows (noise off: its output is the specific force)
    assert out[250].accel.accel_m_s2 == pytest.approx((0.0, G, 0.0), abs=1e-9)
    # gravity turns smoothly: |f| stays g all along the turn
    norms = [np.linalg.norm(o.accel.true_specific_force_m_s2) for o in out]
    assert np.allclose(norms, G, rtol=1e-12)


def test_the_attitude_is_kinematics_propagate_of_the_true_rates():
    driver, inbox, _ = make(command_timeout_s=0.0, noise_enabled=False)
    rates = [(0.3, -0.2, 0.5), (0.0, 0.7, 0.0), (-0.4, 0.1, 0.9)]
    for i, rate in enumerate(rates):
        inbox.push('rate', T0_NS + 50 * i * PERIOD_NS, rate)
    out = ticks(driver, 0, 150)
    held = np.array([o.gyro.true_rate_rad_s for o in out])
    path, _ = kinematics.propagate(kinematics.LEVEL_WXYZ, held, PERIOD_NS * 1e-9)
    assert np.allclose([o.attitude_wxyz for o in out], path, atol=1e-12)
    force = kinematics.specific_force(path)
    assert np.allclose([o.accel.true_specific_force_m_s2 for o in out], force, atol=1e-9)


def test_the_specific_force_is_the_applied_acceleration_minus_gravity_in_the_sensor_frame():
    driver, inbox, _ = make(gravity_m_s2=3.72076, initial_attitude_rpy_rad=[0.0, 0.5, 0.0])
    inbox.push('linear_acceleration', 0, (1.0, -2.0, 0.5))
    out = ticks(driver, 0, 3)
    q = kinematics.from_roll_pitch_yaw(0.0, 0.5, 0.0)
    want = np.array((1.0, -2.0, 0.5)) + 3.72076 * kinematics.gravity_up_in_body(q)
    assert np.allclose(out[-1].accel.true_specific_force_m_s2, want, atol=1e-12)
    assert np.allclose(out[-1].attitude_wxyz, q, atol=1e-15)
    # pitched up 0.5 rad: gravity reads -g sin(0.5) on x and g cos(0.5) on z
    assert want[0] == pytest.approx(1.0 - 3.72076 * math.sin(0.5))


def test_the_g_sensitivity_sees_the_same_specific_force():
    g_sens = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.01, 0.0]      # z rate per m/s^2 on y
    values = node_values(sensor_config='paper', noise_enabled=False, command_timeout_s=0.0)
    from gyro_emulator.emulation.driver.commands import CommandInbox
    from gyro_emulator.emulation.driver.core import Driver
    from gyro_emulator.sensor.config import load_sensor_config
    inbox = CommandInbox()
    driver = Driver(values, load_sensor_config('paper'), 7, log=Log(), commands=inbox,
                    sensor_values={**parameters.sensor_param_values(load_sensor_config('paper')),
                                   'sensor.g_sensitivity_rad_s_m_s2': g_sens})
    driver.start(T0_NS)
    inbox.push('rate', T0_NS, (0.5 * math.pi, 0.0, 0.0))
    inbox.push('rate', T0_NS + 200 * PERIOD_NS, (0.0, 0.0, 0.0))
    out = ticks(driver, 0, 300)
    # level: no y force, no z bias from it; after the turn g on y gives 0.01 g rad/s on z
    shift = out[250].gyro.bias_rad_s[2] - out[0].gyro.bias_rad_s[2]
    assert shift == pytest.approx(0.01 * G, rel=1e-6)


@pytest.mark.parametrize('value, match', [
    (0.0, r'gravity_m_s2 = 0.0 is out of range: allowed \(0, 100\]'),
    (100.5, r'gravity_m_s2 = 100.5 is out of range: allowed \(0, 100\]'),
    (float('nan'), r'gravity_m_s2 = nan is out of range: allowed \(0, 100\]'),
    (-9.8, r'gravity_m_s2 = -9.8 is out of range'),
])
def test_a_bad_gravity_is_refused_in_one_line(value, match):
    with pytest.raises(ValueError, match=match) as info:
        parameters.check_value(parameters.NODE_SPECS['gravity_m_s2'], value)
    assert '\n' not in str(info.value)
    with pytest.raises(ValueError, match='gravity_m_s2'):
        AttitudeState(kinematics.LEVEL_WXYZ, value)


@pytest.mark.parametrize('value, match', [
    ([float('nan'), 0.0, 0.0], r'initial_attitude_rpy_rad.x = nan is out of range'),
    ([0.0, float('inf'), 0.0], r'initial_attitude_rpy_rad.y = inf is out of range'),
    ([0.0, 0.0, 7.0], r'initial_attitude_rpy_rad.z = 7.0 is out of range: allowed '
                      r'\[-6.28319, 6.28319\]'),
    ([0.0, 0.0], r'initial_attitude_rpy_rad = \[0.0, 0.0\] is not three numbers'),
])
def test_a_bad_initial_attitude_is_refused_in_one_line(value, match):
    with pytest.raises(ValueError, match=match):
        parameters.check_value(parameters.NODE_SPECS['initial_attitude_rpy_rad'], value)
    if len(value) != 3 or not all(math.isfinite(v) for v in value):
        with pytest.raises(ValueError, match='initial_attitude_rpy_rad'):
            initial_attitude(value)


def test_the_accelerometer_can_be_marked_absent_at_start_and_at_run_time():
    driver, _, _ = make(publish_linear_acceleration=False)
    assert not any(o.accel_shown for o in ticks(driver, 0, 5))
    driver.apply(driver.prepare([('publish_linear_acceleration', True)]), T0_NS)
    assert all(o.accel_shown for o in ticks(driver, 5, 5))
    with pytest.raises(ValueError, match='publish_linear_acceleration = 1 is not allowed'):
        driver.prepare([('publish_linear_acceleration', 1)])


def test_a_non_finite_acceleration_or_attitude_is_withheld():
    driver, _, log = make()
    stepper = driver._stepper
    real = stepper.step
    calls = [0]

    def step(*args):
        sample = real(*args)
        calls[0] += 1
        if calls[0] == 3:
            value = np.array(sample.accel_m_s2)
            value[1] = np.nan
            return dataclasses.replace(sample, accel_m_s2=value)
        return sample
    stepper.step = step
    out = ticks(driver, 0, 5)
    assert [(o.sample_ns - T0_NS) // PERIOD_NS for o in out] == [0, 1, 3, 4]
    assert driver.book.nonfinite == 1
    assert 'acceleration (' in log.text() and 'not published' in log.text()
    assert all(np.isfinite(o.accel.accel_m_s2).all() for o in out)


def test_a_clock_jump_back_keeps_the_attitude_and_restarts_its_time_line():
    driver, inbox, _ = make(command_timeout_s=0.0, noise_enabled=False)
    inbox.push('rate', T0_NS, (0.5 * math.pi, 0.0, 0.0))
    out = ticks(driver, 0, 100)                  # 45 deg about x so far
    q = out[-1].attitude_wxyz
    back = driver.tick(T0_NS - 10 * PERIOD_NS)   # the clock jumped back
    assert back and back[0].attitude_wxyz == q   # no step across the jump
    assert all(math.isfinite(v) for o in back for v in o.attitude_wxyz)


def test_the_one_sample_forms_are_the_batch_forms_bit_for_bit():
    rng = np.random.default_rng(5)
    q = kinematics.from_roll_pitch_yaw(*rng.uniform(-3, 3, 3))
    for _ in range(20):
        rate, dt = tuple(rng.normal(0, 2, 3)), float(rng.uniform(0, 0.01))
        accel = tuple(rng.normal(0, 5, 3))
        _, want = kinematics.propagate(q, [rate], dt)
        got = kinematics.step(q, rate, dt)
        assert np.allclose(got, want, rtol=0, atol=1e-15)   # propagate renormalises q first
        assert kinematics.specific_force_one(tuple(got), accel, 3.7) == \
            tuple(kinematics.specific_force(got, accel, 3.7).tolist())
        q = got


def _fields(out):
    """Every number of each output that depends on the model and the attitude, as bytes."""
    return [np.array([*o.gyro.rate_rad_s, *o.gyro.true_rate_rad_s, *o.gyro.bias_rad_s,
                      *o.gyro.scale_factor, *o.accel.accel_m_s2,
                      *o.accel.true_specific_force_m_s2, *o.attitude_wxyz, o.die_temp_c,
                      o.stamp_ns, o.sample_ns]).tobytes() for o in out]


def _tilt_and_turn(driver, inbox):
    """Tick turns about x, y and z held 60-300 samples, a changing acceleration, late ticks."""
    pushes = [(0, 'rate', (0.5 * math.pi, 0.0, 0.0)), (70, 'rate', (0.0, -0.3, 0.0)),
              (180, 'linear_acceleration', (0.5, 0.0, -0.2)), (400, 'rate', (0.2, 0.1, 0.9)),
              (700, 'rate', (0.0, 0.0, 0.0)), (760, 'rate', (-0.8, 0.0, 0.0)),
              (900, 'linear_acceleration', (0.0, 0.0, 0.0)), (1000, 'temperature', 31.0)]
    for k, name, value in pushes:
        inbox.push(name, T0_NS + k * PERIOD_NS, value)
    out = []
    for k in range(1400):
        if k % 97 in (1, 2):                 # a late timer: the next tick takes a burst
            continue
        out += driver.tick(T0_NS + k * PERIOD_NS + (PERIOD_NS // 3 if k % 131 == 0 else 0))
    return out


def test_blocks_on_the_forecast_attitude_equal_a_step_per_sample_bit_for_bit():
    # block_samples 1: the model steps every sample and the attitude is integrated per
    # sample; 50: gravity turning with a held rate runs the model in blocks
    outputs, calls = {}, {}
    for block in (1, 50):
        driver, inbox, _ = make(command_timeout_s=0.0, block_samples=block)
        outputs[block] = _fields(_tilt_and_turn(driver, inbox))
        calls[block] = driver.situation(0)['model_calls'], driver.situation(0)['model_rewinds']
    assert len(outputs[1]) == len(outputs[50]) > 1300
    assert outputs[50] == outputs[1]
    assert calls[1][0] == len(outputs[1])
    assert calls[50][0] < 0.3 * len(outputs[50]) and calls[50][1] > 0


def test_the_forecast_attitude_is_the_per_sample_integral_bit_for_bit():
    state = AttitudeState(kinematics.LEVEL_WXYZ, G, lambda ns, n: [ns + k * 1000 for k in
                                                                   range(1, n + 1)])
    alone = AttitudeState(kinematics.LEVEL_WXYZ, G)
    rate, accel = (0.4, -0.1, 0.3), (0.1, 0.0, 0.0)
    for k in range(200):
        if k == 130:
            rate = (0.0, 0.2, 0.0)           # off the forecast: it is dropped
        got = state.advance(k * 1000, rate), state.specific_force(accel)
        want = alone.advance(k * 1000, rate), alone.specific_force(accel)
        assert np.array([*got[0], *got[1]]).tobytes() == \
            np.array([*want[0], *want[1]]).tobytes(), k
        if k % 40 == 10:
            assert state.forces(50)[0] == got[1]


@pytest.mark.parametrize('source', ['default', 'command'])
def test_every_acceleration_the_node_accepts_keeps_the_model_running(source):
    """The top of each acceleration range plus the largest gravity is a force the model takes."""
    top = parameters.NODE_SPECS['default_linear_acceleration_m_s2'].high
    assert parameters.NODE_SPECS['max_abs_accel_m_s2'].high == top
    assert parameters.NODE_SPECS['default_linear_acceleration_m_s2'].low == -top
    gravity = parameters.NODE_SPECS['gravity_m_s2'].high
    for sign, rpy in ((1.0, [0.0, 0.0, 0.0]), (-1.0, [math.pi, 0.0, 0.0])):
        # gravity's reading adds to the applied acceleration: level +g on z, upside down -g
        applied = [0.0, 0.0, sign * top]
        if source == 'default':
            driver, _, log = make(default_linear_acceleration_m_s2=applied,
                                  gravity_m_s2=gravity, initial_attitude_rpy_rad=rpy)
        else:
            driver, inbox, log = make(max_abs_accel_m_s2=top, gravity_m_s2=gravity,
                                      initial_attitude_rpy_rad=rpy)
            inbox.push('linear_acceleration', 0, tuple(applied))
        out = ticks(driver, 0, 20)
        assert len(out) == 20, log
        force = np.array([o.accel.true_specific_force_m_s2 for o in out])
        assert np.allclose(force[:, 2], sign * (top + gravity), rtol=1e-12, atol=0.0)
        assert np.all(np.isfinite([o.accel.accel_m_s2 for o in out]))
