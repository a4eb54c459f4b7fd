"""The node's plain-Python parts: input rules, block stepper, parameters, profiles."""

from dataclasses import fields
import math
import os
import sys
import types

from gyro_emulator.emulation import profiles, scenario
from gyro_emulator.emulation.driver import commands, parameters
from gyro_emulator.emulation.driver.block_stepper import BlockStepper
from gyro_emulator.emulation.run_profile import samples_with_force
from gyro_emulator.physics import kinematics
from gyro_emulator.ros import params
from gyro_emulator.sensor import config as sensor_config
from gyro_emulator.sensor import model as sensor_model
import numpy as np
import pytest
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: Every term with a visible effect at 200 Hz (noise, lag, filter, LSB, g-sens).
RICH = {
    'electronics_noise_rad_s_sqrt_hz': 2e-4, 'bias_instability_rad_s': 2e-5,
    'rate_random_walk_rad_s_sqrt_s': 1e-5, 'thermal_time_constant_s': 0.2,
    'output_filter_hz': 40.0, 'lsb_rad_s': 1e-5, 'turn_on_bias_sigma_rad_s': 1e-3,
    'bias_temp_coeff_rad_s_k': 1e-5, 'g_sensitivity_rad_s_m_s2': 1e-4,
    'misalignment': ((0.0, 1e-3, 0.0), (0.0, 0.0, 2e-3), (-1e-3, 0.0, 0.0)),
    'mode_split_hz': (10.0, 20.0, 30.0), 'latency_s': 0.002}


def rich_config():
    return sensor_config.SensorConfig(**RICH)


# --- commands -----------------------------------------------------------------

LIMITS = commands.InputLimits(max_abs_rate_rad_s=10.0, max_abs_accel_m_s2=100.0,
                              temp_range_c=(-40.0, 120.0))


@pytest.mark.parametrize('values,reason', [
    ((float('nan'), 0.0, 0.0), 'non_finite_rate'),
    ((0.0, float('inf'), 0.0), 'non_finite_rate'),
    ((0.0, 0.0, -10.5), 'rate_too_large'),
])
def test_bad_rates_are_rejected_with_their_reason(values, reason):
    with pytest.raises(commands.InputRejected) as err:
        commands.check_rate(values, LIMITS)
    assert err.value.reason == reason
    assert 'angular_velocity.' in str(err.value)


def test_good_rate_passes_unchanged():
    assert commands.check_rate((1.0, -2.0, 10.0), LIMITS) == (1.0, -2.0, 10.0)


@pytest.mark.parametrize('temp,reason', [
    (float('nan'), 'non_finite_temperature'), (float('-inf'), 'non_finite_temperature'),
    (-273.15, 'below_absolute_zero'), (-500.0, 'below_absolute_zero')])
def test_impossible_temperatures_are_rejected(temp, reason):
    with pytest.raises(commands.InputRejected) as err:
        commands.check_temperature(temp, LIMITS)
    assert err.value.reason == reason


def test_temperature_outside_model_range_is_clamped_or_rejected_by_policy():
    assert commands.check_temperature(150.0, LIMITS) == (120.0, True)
    assert commands.check_temperature(-100.0, LIMITS) == (-40.0, True)
    assert commands.check_temperature(20.0, LIMITS) == (20.0, False)
    strict = commands.InputLimits(temp_range_c=(-40.0, 120.0), temperature_policy='reject')
    with pytest.raises(commands.InputRejected) as err:
        commands.check_temperature(150.0, strict)
    assert err.value.reason == 'temperature_out_of_range'
    assert '[-40, 120] C' in str(err.value)


def test_acceleration_limits():
    assert commands.check_acceleration((0.0, 0.0, 9.8), LIMITS) == (0.0, 0.0, 9.8)
    for values, reason in (((float('nan'),) * 3, 'non_finite_acceleration'),
                           ((0.0, 200.0, 0.0), 'acceleration_too_large')):
        with pytest.raises(commands.InputRejected) as err:
            commands.check_acceleration(values, LIMITS)
        assert err.value.reason == reason


def test_limits_are_validated():
    with pytest.raises(ValueError, match='temperature_policy'):
        commands.InputLimits(temperature_policy='ignore')
    with pytest.raises(ValueError, match='max_abs_rate_rad_s'):
        commands.InputLimits(max_abs_rate_rad_s=-1.0)


def test_command_applies_at_its_stamp_and_zero_stamp_means_on_receipt():
    stream = commands.CommandStream('rate', initial=0)
    lead = 10**9
    stream.offer(1, 200, now_ns=100, max_lead_ns=lead)
    assert stream.advance(150) == 0
    assert stream.advance(200) == 1
    stream.offer(2, 0, now_ns=300, max_lead_ns=lead)
    assert stream.advance(299) == 1 and stream.advance(300) == 2
    assert stream.accepted == 2
    assert stream.age_s(1300) == pytest.approx(1e-6)


def test_out_of_order_and_future_stamps_are_rejected():
    stream = commands.CommandStream('rate', initial=0)
    stream.offer(1, 500, now_ns=400, max_lead_ns=1000)
    with pytest.raises(commands.InputRejected) as err:
        stream.offer(3, 5000, now_ns=420, max_lead_ns=1000)
    assert err.value.reason == 'future_stamp'
    assert stream.advance(10**6) == 1
    # older than the command in force: out of order
    with pytest.raises(commands.InputRejected) as err:
        stream.offer(2, 499, now_ns=10**6, max_lead_ns=1000)
    assert err.value.reason == 'out_of_order'
    assert stream.accepted == 1
    stream.reset_clock()
    assert stream.offer(4, 10, now_ns=5, max_lead_ns=1000) is None


def test_a_future_stamped_command_does_not_block_the_stream():
    """Issue 14: one command stamped 0.45 s ahead once blocked all others for 0.45 s."""
    stream = commands.CommandStream('rate', initial=0)
    ms = 10**6
    stream.offer('ahead', 450 * ms, now_ns=0, max_lead_ns=1000 * ms)
    for k in range(1, 5):                       # the regular 10 ms stream goes on
        stream.offer(k, 10 * k * ms, now_ns=10 * k * ms, max_lead_ns=1000 * ms)
        assert stream.advance(10 * k * ms) == k
    assert stream.advance(449 * ms) == 4 and stream.advance(450 * ms) == 'ahead'
    with pytest.raises(commands.InputRejected, match='older than the command in force'):
        stream.offer(5, 440 * ms, now_ns=450 * ms, max_lead_ns=1000 * ms)


def test_queue_overflow_drops_the_oldest():
    stream = commands.CommandStream('rate', initial=0, capacity=3)
    dropped = [stream.offer(v, 100 + v, now_ns=0, max_lead_ns=10**6) for v in range(5)]
    assert dropped == [None, None, None, 'queue_overflow', 'queue_overflow']
    assert [v for _, v in stream.pending] == [2, 3, 4]


def _streams_state(cmds):
    return [(list(s.pending), s.value, s.accepted, s.newest_stamp_ns, s.applied_stamp_ns,
             s.last_arrival_ns) for s in cmds.streams]


def test_a_batch_of_commands_is_taken_as_each_in_turn(monkeypatch):
    """A node's batch (its inbox at a sample) gives what offering its commands one by one does."""
    rng = np.random.default_rng(11)
    limits = commands.InputLimits(max_stamp_lead_s=1e-3)
    made = []
    for _ in range(2):
        log = []
        made.append((commands.Commands(25.0, (0.0, 0.0, 9.8), 6, lambda e, log=log: log.append(
            (e.reason, str(e))), lambda *a, log=log: log.append(a)), log))
    (batched, log_b), (single, log_s) = made
    extend = commands.CommandStream.extend
    at_once = []
    monkeypatch.setattr(commands.CommandStream, 'extend',
                        lambda *a: at_once.append(extend(*a)) or at_once[-1])
    now, used, ms = 10**9, set(), 10**6
    for round_ in range(3000):
        name = ('rate', 'linear_acceleration')[int(rng.integers(2))]
        n = int(rng.integers(1, 9))
        offsets = np.sort(rng.integers(-8, 2, n)) if rng.random() < 0.8 else \
            rng.integers(-8, 2, n)                  # in order, mostly
        # 0: on receipt; +2 s: too far ahead
        stamps = [0 if rng.random() < 0.1 else
                  int(now + o * ms + (2000 * ms if rng.random() < 0.01 else 0))
                  for o in offsets]
        values = [tuple(rng.choice([rng.normal(), 1e9, float('nan'), 3],
                                   p=[0.97, 0.01, 0.01, 0.01]) for _ in range(3))
                  for _ in range(n)]
        batched.offer(name, stamps, values, now, limits)
        for stamp, value in zip(stamps, values):
            single.offer(name, [stamp], [value], now, limits)
        assert _streams_state(batched) == _streams_state(single), round_
        assert log_b == log_s, round_
        used.update(reason for reason, _ in log_b)
        now += int(rng.integers(0, 3)) * ms
        for cmds in (batched, single):
            cmds.rate.advance(now - ms)
            cmds.accel.advance(now - ms)
    # every path was taken: batches queued at once and one by one, each reason of refusal
    assert {'out_of_order', 'future_stamp', 'queue_overflow', 'non_finite_rate',
            'rate_too_large', 'non_finite_acceleration'} <= used
    assert 100 < sum(at_once) < len(at_once) - 100


def test_throttle_lets_one_line_per_period_and_counts_the_rest():
    now = [0.0]
    throttle = commands.Throttle(1.0, lambda: now[0])
    assert throttle('a') == 0
    assert throttle('a') is None and throttle('a') is None
    assert throttle('b') == 0
    now[0] = 1.5
    assert throttle('a') == 2


# --- block stepper ----------------------------------------------------------------

def _inputs_sequence(n, seed):
    """Return inputs held for 1 to 150 ticks, each change of rate, temp or accel."""
    rng = np.random.default_rng(seed)
    rates, temps, accels = [], [], []
    rate, temp, accel = (0.0, 0.0, 0.0), 25.0, None
    while len(rates) < n:
        u = rng.random()
        if u < 0.6:
            rate = tuple(rng.normal(size=3))
        elif u < 0.85:
            temp = float(rng.uniform(0.0, 80.0))
        else:
            accel = tuple(rng.normal(size=3) * 9.8)
        hold = int(rng.choice([1, 3, 20, 150]))
        rates += [rate] * hold
        temps += [temp] * hold
        accels += [accel] * hold
    return rates[:n], temps[:n], accels[:n]


@pytest.mark.parametrize('max_block', [1, 7, 64])
def test_block_stepper_equals_per_sample_step_bit_for_bit(max_block):
    config = rich_config()
    rates, temps, accels = _inputs_sequence(1500, seed=3)
    ref = sensor_model.GyroModel(config, 200.0, np.random.default_rng(11))
    stepper = BlockStepper(sensor_model.GyroModel(config, 200.0, np.random.default_rng(11)),
                           max_block)
    for i, (r, t, a) in enumerate(zip(rates, temps, accels)):
        if i == 700:
            changed = config.with_terms(quantization=False)
            ref.update_config(changed)
            stepper.update_config(changed)
        want = ref.step(r, t, a)
        got = stepper.step(r, t, a)
        for name in ('gyro_rad_s', 'true_rate_rad_s', 'bias_rad_s', 'scale_factor',
                     'saturated'):
            assert np.array_equal(getattr(got, name), getattr(want, name)), (i, name)
        assert got.die_temp_c == want.die_temp_c and \
            got.output_delay_s == want.output_delay_s
    if max_block > 1:  # blocks were used, and some were rewound
        assert stepper.model_calls < 0.9 * len(rates)
        assert stepper.rewinds > 0


def test_inputs_at_a_steady_pace_run_in_blocks_of_their_hold_bit_for_bit():
    # a simulator's commands: a new rate every 9-11 ticks; the blocks start at each change
    config = rich_config()
    ref = sensor_model.GyroModel(config, 200.0, np.random.default_rng(5))
    stepper = BlockStepper(sensor_model.GyroModel(config, 200.0, np.random.default_rng(5)), 50)
    rng = np.random.default_rng(2)
    count = 0
    for _ in range(120):
        rate = tuple(rng.normal(size=3))
        for _ in range(int(rng.integers(9, 12))):
            want, got = ref.step(rate, 25.0), stepper.step(rate, 25.0)
            assert got.gyro_rad_s.tobytes() == want.gyro_rad_s.tobytes(), count
            assert got.bias_rad_s.tobytes() == want.bias_rad_s.tobytes(), count
            count += 1
    assert stepper.model_calls < 0.35 * count       # one block per rate, a few singles
    # a rewind only when a hold is shorter than each of the last HOLDS_KEPT (8): p ~ 1.3 %
    assert stepper.rewinds < 0.05 * 120


def test_block_stepper_adapts_its_block_to_how_often_inputs_change():
    model = sensor_model.GyroModel(rich_config(), 200.0, np.random.default_rng(0))
    stepper = BlockStepper(model, 32)
    for k in range(200):
        stepper.step((0.01 * k, 0.0, 0.0), 25.0)
    assert stepper.block == 1
    for _ in range(200):
        stepper.step((1.0, 0.0, 0.0), 25.0)
    assert stepper.block == 32


# --- parameters ------------------------------------------------------------------

def test_shipped_defaults_define_every_node_parameter_and_validate():
    raw = params.load_params_file(os.path.join(ROOT, 'config', 'gyro_emulator.yaml'))
    assert sorted(raw) == sorted(parameters.NODE_SPECS)
    defaults = params.node_defaults(os.path.join(ROOT, 'config', 'gyro_emulator.yaml'))
    assert defaults['rate_hz'] == 200.0 and defaults['sensor_config'] == 'paper'


def test_node_and_simulate_share_one_gravity_default_and_a_driver_like_temperature_rate():
    """Issue 15: level and at rest, +1 g on z (REP 103) in both; imu/temperature at 1-10 Hz."""
    defaults = params.node_defaults()
    # The node senses gravity from its attitude: level, at rest, no applied acceleration.
    at_rest = kinematics.specific_force(
        kinematics.from_roll_pitch_yaw(*defaults['initial_attitude_rpy_rad']),
        defaults['default_linear_acceleration_m_s2'], defaults['gravity_m_s2'])
    assert at_rest.tolist() == list(profiles.LEVEL_ACCEL_M_S2)
    assert profiles.LEVEL_ACCEL_M_S2 == (0.0, 0.0, 9.80665)
    for name in profiles.PROFILE_NAMES:
        accel = samples_with_force(profiles.make_profile(name, 10.0),
                                   np.array([0.0, 5.0])).accel_m_s2
        assert np.array_equal(accel, np.tile(profiles.LEVEL_ACCEL_M_S2, (2, 1))), name
    assert 1.0 <= defaults['temperature_rate_hz'] <= 10.0
    assert defaults['seed'] == parameters.SEED_FROM_NAME and defaults['fault.type'] == 'none'


@pytest.mark.parametrize('value,match', [
    ([0.0, 0.0], 'is not three numbers'), ([0.0, True, 1.0], 'is not three numbers'),
    ([0.0, 0.0, float('nan')], r'default_linear_acceleration_m_s2.z = nan is out of range'),
    ('up', 'is not three numbers')])
def test_a_vector_parameter_is_three_finite_numbers(value, match):
    spec = parameters.NODE_SPECS['default_linear_acceleration_m_s2']
    with pytest.raises(ValueError, match=match):
        parameters.check_value(spec, value)
    assert parameters.check_value(spec, [0, 0, 9]) == [0.0, 0.0, 9.0]


def test_defaults_file_errors_name_the_problem(tmp_path):
    path = tmp_path / 'p.yaml'
    raw = params.load_params_file(os.path.join(ROOT, 'config', 'gyro_emulator.yaml'))
    raw['rate_hzz'] = 1.0
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': raw}}))
    with pytest.raises(ValueError, match='unknown parameter.*rate_hzz'):
        params.node_defaults(str(path))
    del raw['rate_hzz'], raw['seed']
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': raw}}))
    with pytest.raises(ValueError, match='missing parameter.*seed'):
        params.node_defaults(str(path))
    path.write_text('gyro: [1, 2')
    with pytest.raises(ValueError, match='malformed YAML') as caught:
        params.load_params_file(str(path))
    assert '\n' not in str(caught.value) and 'line 1, column 7' in str(caught.value)


@pytest.mark.parametrize('name,value,match', [
    ('rate_hz', 0.5, r'rate_hz = 0.5 is out of range: allowed \[1, 5000\]'),
    ('stale_rate_policy', 'freeze', 'choose one of zero, hold'),
    ('seed', 1.5, 'not an integer'),
    ('noise_enabled', 1, 'choose true or false'),
    ('frame_id', '', r"frame_id = '' is not allowed: a tf2 frame name \(not empty"),
    ('frame_id', '/imu_link', "frame_id = '/imu_link' is not allowed: a tf2 frame name"),
])
def test_check_value_names_parameter_value_and_range(name, value, match):
    with pytest.raises(ValueError, match=match):
        parameters.check_value(parameters.NODE_SPECS[name], value)


@pytest.mark.parametrize('frame', ['imu_link', 'base/imu', 'gyro_1_imu_link'])
def test_a_tf2_frame_name_is_taken_as_it_is(frame):
    assert parameters.check_value(parameters.NODE_SPECS['frame_id'], frame) == frame


def test_descriptors_carry_ranges_and_read_only():
    rate = params.descriptor(parameters.NODE_SPECS['rate_hz'])
    assert rate.read_only and rate.floating_point_range[0].to_value == 5000.0
    timeout = params.descriptor(parameters.NODE_SPECS['command_timeout_s'])
    assert not timeout.read_only and timeout.description
    assert all(spec.description for spec in parameters.NODE_PARAMS)


def test_every_sensor_field_has_a_description():
    names = [f.name for f in fields(sensor_config.SensorConfig)]
    assert sorted(set(names) - set(parameters.SENSOR_DESCRIPTIONS)) == []


@pytest.mark.parametrize('config', [sensor_config.SensorConfig(), rich_config(),
                                    rich_config().with_terms(latency=False)],
                         ids=['default', 'rich', 'rich_no_latency'])
def test_sensor_parameters_round_trip_to_the_same_config(config):
    values = parameters.sensor_param_values(config)
    assert all(isinstance(v, (bool, int, float, str, list)) for v in values.values())
    assert len(values['sensor.misalignment']) == 9
    assert math.isnan(values['sensor.initial_die_temp_c'])
    assert parameters.apply_sensor_params(config, values) == config


def test_sensor_parameter_errors_name_the_field():
    config = sensor_config.SensorConfig()
    with pytest.raises(ValueError, match='SensorConfig.lsb_rad_s'):
        parameters.apply_sensor_params(config, {'sensor.lsb_rad_s': [-1.0, 0.0, 0.0]})
    with pytest.raises(ValueError, match='unknown error term'):
        parameters.apply_sensor_params(config, {'sensor.terms.magic': True})
    changed = parameters.apply_sensor_params(config, {'sensor.lsb_rad_s': 1e-4,
                                                      'sensor.terms.quantization': False})
    assert changed.lsb_rad_s == (1e-4,) * 3 and not changed.terms.quantization


def test_without_noise_switches_off_only_noise_terms():
    quiet = parameters.without_noise(rich_config())
    for term in parameters.NOISE_TERMS:
        assert not getattr(quiet.terms, term)
    assert quiet.terms.thermal_lag and quiet.terms.quantization


# --- scenario profiles ------------------------------------------------------------

def test_shipped_paper_profile_is_the_papers_grid_and_short():
    profile = scenario.load_scenario(os.path.join(ROOT, 'config',
                                                  'scenario_paper_validation.yaml'))
    temps = sorted({s.temp_start_c for s in profile.steps})
    rpm = sorted({round(profile.rate_along_axis_rad_s(s) * 60.0 / (2.0 * math.pi), 9)
                  for s in profile.steps})
    assert temps[0] == 25.0 and temps[-1] == 85.0
    assert rpm == [0.0, 10.0, 20.0, 40.0]
    assert len(profile.steps) == len(temps) * 4
    assert 20.0 <= profile.duration_s <= 60.0
    assert all(0.0 < s.settle_s < s.duration_s for s in profile.steps)
    assert profile.axis == (0.0, 0.0, 1.0)


@pytest.mark.parametrize('doc,match', [
    ({'segments': [{'duration_s': 1.0, 'temp_c': 20.0}]}, 'exactly one of'),
    ({'segments': [{'duration_s': -1.0, 'rate_rpm': 1, 'temp_c': 20.0}]},
     'duration_s = -1.0 is out of range'),
    ({'segments': [{'duration_s': 1.0, 'rate_rpm': 1, 'temp_c': -300.0}]},
     'temp_start_c = -300.0 is out of range'),
    ({'axis': [0, 0, 0], 'segments': []}, 'zero vector'),
    ({'grid': {'temps_c': [], 'rates_rpm': [1], 'hold_s': 1.0}}, 'non-empty list'),
    ({'speed': 1}, 'unknown key.*speed'),
    ({}, 'no steps'),
])
def test_profile_errors_name_the_key(doc, match):
    with pytest.raises(ValueError, match=match):
        scenario.parse_scenario(doc)


def test_scenario_and_simulate_profiles_share_one_segment_schema():
    """The same segment mapping means the same rate, temperature and settle time."""
    seg = {'duration_s': 2.0, 'rate_rpm': 10.0, 'temp_c': 40.0, 'settle_s': 0.5}
    played = scenario.parse_scenario({'axis': [0, 1, 0], 'segments': [seg]})
    step = played.steps[0]
    segment = profiles.profile_from_mapping({'axis': [0, 1, 0], 'segments': [seg]}).segments[0]
    rate = played.rate_along_axis_rad_s(step)
    assert segment.rate_start_rad_s == pytest.approx((0.0, rate, 0.0))
    assert rate == pytest.approx(10.0 * 2.0 * math.pi / 60.0)
    assert (step.temp_start_c, step.settle_s) == (segment.temp_start_c, segment.settle_s)


def test_old_temperature_spelling_is_read_with_a_deprecation_warning():
    old = {'segments': [{'duration_s': 1.0, 'rate_rpm': 1, 'temperature_c': 30.0}]}
    with pytest.warns(DeprecationWarning, match='temperature_c is deprecated, write temp_c'):
        step = scenario.parse_scenario(old).steps[0]
    assert step.temp_start_c == 30.0
    with pytest.warns(DeprecationWarning, match='temperatures_c is deprecated'):
        grid = scenario.parse_scenario({'grid': {'temperatures_c': [20.0], 'rates_rpm': [0],
                                                 'hold_s': 1.0}})
    assert grid.steps[0].temp_start_c == 20.0


def test_a_scenario_step_refuses_a_ramp():
    with pytest.raises(ValueError, match='holds its rate and temp_c'):
        scenario.parse_scenario({'segments': [
            {'duration_s': 1.0, 'rate_rpm': 1, 'temp_c': [20.0, 30.0]}]})


def test_summary_averages_each_step_after_its_settle_time():
    profile = scenario.parse_scenario({'axis': [0, 0, 2], 'segments': [
        {'duration_s': 1.0, 'rate_deg_s': 10.0, 'temp_c': 20.0, 'settle_s': 0.5},
        {'duration_s': 1.0, 'rate_rad_s': 1.0, 'temp_c': 40.0, 'settle_s': 0.25}]})
    start = 5 * 10**9
    imu, temps = [], []
    for k in range(200):
        t = start + k * 10**7
        z = math.radians(99.0) if k < 50 else math.radians(11.0) if k < 100 else \
            (7.0 if k < 125 else 1.5)
        imu.append((t, (0.3, 0.0, z)))
        temps.append((t, 20.0 + 20.0 * (k >= 100)))
    first, second = scenario.summarize(profile, start, imu, temps)
    assert first.samples == 50 and first.measured_deg_s == pytest.approx(11.0)
    assert first.error_deg_s == pytest.approx(1.0) and first.die_temp_c == 20.0
    assert second.samples == 75
    assert second.measured_deg_s == pytest.approx(math.degrees(1.5))
    assert second.commanded_deg_s == pytest.approx(math.degrees(1.0))
    table = scenario.format_summary([first, second])
    assert '10 deg/s' in table and '+1.000' in table


def test_a_stopped_scenario_says_where_it_stopped():
    profile = scenario.parse_scenario({'segments': [
        {'duration_s': 2.0, 'rate_deg_s': 0.0, 'temp_c': 25.0},
        {'duration_s': 3.0, 'rate_deg_s': 10.0, 'temp_c': 25.0},
        {'duration_s': 1.0, 'rate_deg_s': 20.0, 'temp_c': 45.0}]})
    start = 7 * 10 ** 9
    note = scenario.interruption_note(profile, start, start + 2_500_000_000)
    assert note == ('interrupted at 2.5 s of 6 s, in step 2 of 3: steps 2-3 were not '
                    'finished (no samples where none was taken)')
    assert 'in step 3 of 3: step 3 was not finished' in scenario.interruption_note(
        profile, start, start + 5_500_000_000)
    assert scenario.interruption_note(profile, None, start) == (
        'interrupted before the first step: none of the 3 steps was played')
    results = scenario.summarize(profile, start, [(start + 10 ** 9, (0.0, 0.0, 0.0))], [])
    doc = scenario.results_json(profile, results, note)
    # A step without samples is null in the JSON and named, never a NaN.
    assert doc['interrupted'] == note and doc['steps'][2]['measured_deg_s'] is None
    assert doc['steps'][2]['die_temp_c'] is None and doc['steps'][2]['samples'] == 0
    assert doc['unmeasured'] == ('step 2 (10 deg/s at 25 C) and step 3 (20 deg/s at 45 C) '
                                 'got no Imu sample after their settle time')
    assert 'interrupted' not in scenario.results_json(profile, results)
    table = scenario.format_summary(results)
    assert 'nan' not in table and table.count('no samples') == 2


def test_the_scenario_player_checks_its_json_before_it_plays(tmp_path, capsys):
    """--json is never the profile, a folder that is a file, or an existing file unasked."""
    from gyro_emulator.ros import scenario as player
    profile = tmp_path / 'profile.yaml'
    profile.write_text('segments:\n  - {duration_s: 1, rate_deg_s: 0, temp_c: 25}\n')
    before = profile.read_bytes()
    link = tmp_path / 'link.yaml'
    link.symlink_to(profile)
    (tmp_path / 'a_file').write_text('x')
    (tmp_path / 'old.json').write_text('{}')
    for out, said in ((profile, 'is the input'), (link, 'is the input'),
                      (tmp_path / 'a_file' / 'x.json', 'is a file, not a folder'),
                      (tmp_path / 'old.json', 'exists: pass --overwrite')):
        # refused before ROS starts: no node is running, nothing is played
        assert player.main([str(profile), '--json', str(out), '--wait', '1']) == 2
        out_text, err = capsys.readouterr()
        assert out_text == '' and len(err.strip().splitlines()) == 1 and said in err, err
    assert profile.read_bytes() == before
    assert (tmp_path / 'old.json').read_text() == '{}'


def test_the_main_job_says_the_imu_rate_over_the_stamps_not_over_the_wall_time():
    from gyro_emulator.cli import main_job

    imu = [(10 ** 9 + k * 5_000_000, (0.0, 0.0, 0.0)) for k in range(6399)]
    assert main_job.samples_line(imu, 41.7) == (
        '6399 Imu samples over 32.0 s of stamps (200.0 Hz); 41.7 s wall with the node '
        'start-up')
    assert main_job.samples_line(imu[:1], 3.0) == (
        '1 Imu samples (3.0 s wall with the node start-up)')


# --- launch file and main job -----------------------------------------------------

def _stub_launch_modules(monkeypatch):
    """Stand-ins for launch/launch_ros (not on PyPI) that record their arguments."""
    made = {}

    def recorder(name):
        def make(*args, **kwargs):
            made.setdefault(name, []).append((args, kwargs))
            return (name, args, kwargs)
        return make
    modules = {
        'launch': {'LaunchDescription': recorder('LaunchDescription')},
        'launch.actions': {'DeclareLaunchArgument': recorder('DeclareLaunchArgument'),
                           'OpaqueFunction': recorder('OpaqueFunction')},
        'launch.substitutions': {'LaunchConfiguration': recorder('LaunchConfiguration')},
        'launch_ros': {}, 'launch_ros.actions': {'Node': recorder('Node')}}
    for name, attrs in modules.items():
        module = types.ModuleType(name)
        module.__dict__.update(attrs)
        monkeypatch.setitem(sys.modules, name, module)
    return made


def load_launch_file(monkeypatch, name):
    """Run ``launch/<name>`` against the stand-ins; return (what it made, the module)."""
    made = _stub_launch_modules(monkeypatch)
    monkeypatch.setenv('AMENT_PREFIX_PATH', sys.prefix)
    import importlib.util
    spec = importlib.util.spec_from_file_location(
        name.replace('.', '_'), os.path.join(ROOT, 'launch', name))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.generate_launch_description()
    return made, module


def test_launch_file_starts_the_node_executable_with_the_shipped_config(monkeypatch):
    made, _ = load_launch_file(monkeypatch, 'gyro_emulator.launch.py')
    (_, node_kwargs), = made['Node']
    assert node_kwargs['package'] == 'gyro_emulator' and node_kwargs['executable'] == 'node'
    declared = {args[0]: kwargs for args, kwargs in made['DeclareLaunchArgument']}
    assert declared['params_file']['default_value'].endswith(
        os.path.join('config', 'gyro_emulator.yaml'))
    assert set(declared) == {'params_file', 'namespace', 'use_sim_time'}


def test_a_main_job_interrupted_with_every_step_sampled_is_still_130(capsys):
    """A Ctrl-C late in the last step (a loaded machine): not 0, "all steps measured"."""
    import dataclasses

    from gyro_emulator.cli import main_job
    from gyro_emulator.emulation import scenario
    profile = scenario.parse_scenario({'name': 'long', 'grid': {
        'temps_c': [25.0], 'rates_rpm': [0.0, 40.0], 'hold_s': 4.0, 'settle_s': 0.3}})
    sampled = [scenario.StepResult(step, 0.0, 0.0, 0.1, 25.0, 1) for step in profile.steps]
    note = 'interrupted at 7.6 s of 8 s, in step 2 of 2: step 2 was not finished'
    assert main_job.verdict(sampled, note, 342, 'node.log') == (130,
                                                                f'the scenario was {note}')
    assert main_job.verdict(sampled, None, 342, 'node.log') == (
        0, 'all 2 steps measured (342 Imu samples)')
    empty = sampled[:1] + [dataclasses.replace(sampled[1], samples=0)]
    status, why = main_job.verdict(empty, None, 280, 'node.log')
    assert status == 1 and why.startswith('step 2 (40 RPM at 25 C) got no Imu sample')
    assert main_job.verdict(empty, note, 280, 'node.log')[0] == 130
    assert capsys.readouterr().err.count('main: error: step 2 (40 RPM') == 2


def test_main_job_physics_column_matches_the_paper_fig6():
    from gyro_emulator.cli import main_job
    from gyro_emulator.physics import paper
    temps, rate = paper.fig6_data(viscosity_law='constant')
    assert main_job.physics_error_deg_s(math.radians(60.0), 25.0) == pytest.approx(
        0.0, abs=1e-9)
    assert main_job.physics_error_deg_s(math.radians(60.0), temps[-1]) == pytest.approx(
        rate[-1] - 60.0, rel=1e-9)
    assert math.isnan(main_job.physics_error_deg_s(1.0, float('nan')))


# --- raw (pre-serialized) messages -------------------------------------------------

def _without_padding(payload, frame_id='gyro_frame'):
    """
    Return an Imu's CDR bytes with the alignment padding after its frame_id zeroed.

    The serializer does not clear the padding it skips (Fast-CDR leaves what
    the buffer held: 0xa1 once, 0xa5 another time), and no reader looks at it.
    """
    end = 4 + 4 + 4 + 4 + len(frame_id) + 1      # encapsulation, stamp, length, text, NUL
    aligned = 4 + -(-(end - 4) // 8) * 8          # the next float64 of the CDR body
    return payload[:end] + bytes(aligned - end) + payload[aligned:]


def test_patched_bytes_equal_serializing_the_same_message():
    from gyro_emulator.ros.rawmsg import RawMessage
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import Imu

    imu = Imu()
    imu.header.frame_id = 'gyro_frame'
    imu.orientation_covariance[0] = -1.0
    raw = RawMessage(imu, {'stamp': ('header.stamp', 'time'),
                           'rate': ('angular_velocity', 'vector3'),
                           'cov': ('angular_velocity_covariance', ('array', 9)),
                           'cov0': ('linear_acceleration_covariance', ('array', 1))})
    assert raw.raw
    rng = np.random.default_rng(5)
    for _ in range(20):
        stamp_ns = int(rng.integers(0, 2 ** 31)) * 10 ** 9 + int(rng.integers(0, 10 ** 9))
        rate = rng.normal(size=3).tolist()
        cov = rng.random(9).tolist()
        raw.set_stamp_ns('stamp', stamp_ns)
        raw.put('rate', *rate)
        raw.put('cov', *cov)
        raw.put('cov0', -1.0)
        want = Imu()
        want.header.frame_id = 'gyro_frame'
        want.header.stamp.sec, want.header.stamp.nanosec = divmod(stamp_ns, 10 ** 9)
        want.orientation_covariance[0] = -1.0
        want.angular_velocity.x, want.angular_velocity.y, want.angular_velocity.z = rate
        want.angular_velocity_covariance = cov
        want.linear_acceleration_covariance[0] = -1.0
        assert _without_padding(raw.payload()) == _without_padding(
            bytes(serialize_message(want)))
        back = deserialize_message(raw.payload(), Imu)
        assert back == want
        assert back.angular_velocity.y == rate[1] and back.header.frame_id == 'gyro_frame'


def test_raw_message_falls_back_to_the_message_when_a_slot_is_not_unique(monkeypatch):
    from gyro_emulator.ros import rawmsg
    from sensor_msgs.msg import Temperature

    # Every sentinel the same: the search finds it twice, so the bytes path is off.
    monkeypatch.setattr(rawmsg, '_sentinel', lambda index: 1.0)
    msg = Temperature()
    raw = rawmsg.RawMessage(msg, {'value': ('temperature', 'double'),
                                  'variance': ('variance', 'double')})
    assert not raw.raw
    raw.put('value', 42.5)
    assert raw.payload() is msg and msg.temperature == 42.5


# --- the node's fault state (emulation.fault_state) --------------------------------

def test_fault_state_moves_pending_active_ended_and_follows_a_jump_back():
    from gyro_emulator.emulation.driver.fault_state import FaultState
    from gyro_emulator.sensor import faults
    state = FaultState((8.0, 8.0, 8.0), np.random.default_rng(0))
    assert state.state == 'none' and state.changed
    state.changed = False
    ms = 1_000_000
    state.start(faults.Fault('stuck', 'x', 0.0, 0.01, 0.02), 100 * ms, (0.5, 0.0, 0.0))
    seen = []
    offset = 0
    for k in range(40):
        sample_ns = 100 * ms + k * ms + offset
        value, published, pinned = state.apply(sample_ns, np.array([1.0 + k, 2.0, 3.0]))
        if state.changed:
            seen.append((state.state, state.since_ns - 100 * ms))
            state.changed = False
        if k == 10:
            assert value == (10.0, 2.0, 3.0) and state.level == 2   # the sample before
        if k == 20:
            # A simulation reset 15 ms back: the fault's clock continues.
            offset = -15 * ms
            state.shift(offset)
            value, _, _ = state.apply(sample_ns + offset, np.array([99.0, 2.0, 3.0]))
            assert value[0] == 10.0
    # Ends 20 ms of fault time after it began: at k = 30, on the new time line.
    assert seen == [('pending', 0), ('active', 10 * ms), ('ended', 15 * ms)]
    assert published and pinned is None


def test_extended_terms_come_from_sensor_config_and_survive_the_parameters(tmp_path):
    """The extended terms are structural: read from the YAML, never a sensor.* parameter."""
    path = tmp_path / 'part.yaml'
    path.write_text('extended:\n  bias_step: {step_time_s: 2.0, bias_step_rad_s: 0.01}\n')
    base = sensor_config.load_sensor_config(str(path))
    values = parameters.sensor_param_values(base)
    assert not any(name.startswith('sensor.extended') for name in values)
    values['sensor.lsb_rad_s'] = [0.0, 0.0, 0.0]
    config = parameters.apply_sensor_params(base, values)
    assert config.extended == base.extended and config.extended.active() == ('bias_step',)
    with pytest.raises(ValueError, match='unknown error-model parameter'):
        parameters.apply_sensor_params(base, {'sensor.extended': 1.0})


def test_the_help_says_default_nodes_share_a_turn_on_bias_and_its_figure_is_true():
    """The node's --help: the default name's consumer part has z -7.92 deg/s of bias at start."""
    from gyro_emulator.ros import node_help
    from gyro_emulator.sensor.streams import seed_from_name

    text = ' '.join(node_help.help_text().split())
    assert 'every node of the same name is the same part' in text
    assert 'z -7.92 deg/s' in text and 'startup_bias_calibration' in text
    rng = np.random.default_rng(seed_from_name('/gyro_emulator'))
    model = sensor_model.GyroModel(sensor_config.load_sensor_config('consumer'), 200.0, rng)
    bias_z = math.degrees(model.step((0.0, 0.0, 0.0), 25.0, (0.0, 0.0, 9.80665)).bias_rad_s[2])
    assert f'{bias_z:+.2f}' == '-7.92'


def test_the_help_shows_each_range_as_the_check_takes_it():
    """An open bound is shown open: gravity 0 is refused, so the help says (0, 100]."""
    from gyro_emulator.ros import node_help

    text = ' '.join(node_help.help_text().split())
    ranged = [s for s in parameters.NODE_SPECS.values()
              if s.kind == 'double' and s.low is not None and not s.choices]
    assert any(s.low_open for s in ranged)
    for spec in ranged:
        shown = f'{"(" if spec.low_open else "["}{spec.low:g}, {spec.high:g}]'
        assert shown in text, spec.name
        if spec.low_open:
            with pytest.raises(ValueError, match=rf'{spec.name} = .* is out of range'):
                parameters.check_value(spec, spec.low)
            assert f'[{spec.low:g}, {spec.high:g}]' not in text, spec.name
        else:
            assert parameters.check_value(spec, spec.low) == spec.low


def test_a_rate_the_node_accepts_is_one_every_reader_of_its_bag_takes():
    """The largest max_abs_rate_rad_s is the record rule's rate: replay reads what it records."""
    from gyro_emulator.validation import check_record_values

    spec = parameters.NODE_SPECS['max_abs_rate_rad_s']
    assert parameters.check_value(spec, spec.high) == spec.high
    rows = np.array([[spec.high, -spec.high, 0.0]])
    assert check_record_values('/cmd/angular_velocity', 'vector', rows, 'rate') is rows
    with pytest.raises(ValueError, match=r'max_abs_rate_rad_s = .* is out of range'):
        parameters.check_value(spec, float(np.nextafter(spec.high, math.inf)))


def test_the_help_gives_an_open_lower_bound_as_the_node_checks_it():
    """gyro_emulator node refuses gravity_m_s2 = 0; its --help said [0, 100], now (0, 100]."""
    from gyro_emulator.ros import node_help

    text = ' '.join(node_help.help_text().split())
    assert '(default 9.80665; (0, 100], read-only)' in text
    with pytest.raises(ValueError, match=r'allowed \(0, 100\]'):
        kinematics.check_gravity(0.0, 'node')
    for spec in parameters.NODE_PARAMS:
        if spec.low_open:
            assert f'({spec.low:g}, {spec.high:g}]' in text, spec.name
