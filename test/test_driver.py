"""The node's driver without ROS (emulation.driver.core): inputs and times in, samples out."""

import dataclasses
import math

from gyro_emulator.emulation.driver import parameters
from gyro_emulator.emulation.driver.book import ERROR, OK, WARN
from gyro_emulator.emulation.driver.commands import CommandInbox
from gyro_emulator.emulation.driver.core import Driver
from gyro_emulator.resources import config_file, read_yaml
from gyro_emulator.sensor.config import ErrorTerms, load_sensor_config
from gyro_emulator.sensor.model import GyroModel
from gyro_emulator.units import NS_PER_S
import numpy as np
import pytest
import yaml

T0_NS = 1000 * NS_PER_S
PERIOD_NS = 5_000_000           # 200 Hz
LEVEL = (0.0, 0.0, 9.80665)


class Log:
    """A logger that keeps its lines: (level, text)."""

    def __init__(self):
        self.lines = []

    def info(self, text):
        self.lines.append(('info', text))

    def warning(self, text):
        self.lines.append(('warning', text))

    def error(self, text):
        self.lines.append(('error', text))

    def text(self):
        return '\n'.join(text for _, text in self.lines)


def node_values(**overrides):
    """Return the shipped node parameter defaults (config/gyro_emulator.yaml) with overrides."""
    doc = dict(read_yaml(config_file('gyro_emulator.yaml'))['/**']['ros__parameters'])
    for name, value in doc.pop('fault').items():     # nested, as rclpy reads it
        doc['fault.' + name] = value
    doc.update(overrides)
    return {spec.name: parameters.check_value(spec, doc[spec.name])
            for spec in parameters.NODE_PARAMS}


def make(sensor='paper', seed=7, follow_timer=False, **overrides):
    """Return (driver, inbox, log) on the sensor preset, 200 Hz unless overridden."""
    overrides.setdefault('sensor_config', sensor)
    values = node_values(**overrides)
    inbox, log = CommandInbox(), Log()
    driver = Driver(values, load_sensor_config(values['sensor_config']), seed,
                    follow_timer=follow_timer, log=log, commands=inbox)
    driver.start(T0_NS)
    return driver, inbox, log


def offline(driver, sensor='paper', seed=7, noise=True, rate_hz=200.0):
    """Return the GyroModel the driver's samples must equal (same seed, same config)."""
    config = load_sensor_config(sensor)
    config = config if noise else parameters.without_noise(config)
    return GyroModel(config, rate_hz, np.random.default_rng(seed))


def ticks(driver, first_k, count, step=1):
    """Tick the driver at T0 + k periods; return every output."""
    out = []
    for k in range(first_k, first_k + count * step, step):
        out += driver.tick(T0_NS + k * PERIOD_NS)
    return out


def rates(outputs):
    return [o.gyro.rate_rad_s for o in outputs]


# --- one sample per tick, equal to the offline model ------------------------------

def test_samples_equal_the_offline_model_with_commands_applied_at_their_stamps():
    driver, inbox, _ = make(command_timeout_s=0.0)
    inbox.push('rate', T0_NS + 10 * PERIOD_NS, (0.0, 0.0, 1.0))
    inbox.push('temperature', T0_NS + 30 * PERIOD_NS, 40.0)
    # 0: on receipt; applied acceleration: with gravity the specific force is (0, g, 0)
    inbox.push('linear_acceleration', 0, (0.0, 9.80665, -9.80665))
    out = ticks(driver, 0, 60)
    model = offline(driver)
    want = []
    for k in range(60):
        rate = (0.0, 0.0, 1.0) if k >= 10 else (0.0, 0.0, 0.0)
        temp = 40.0 if k >= 30 else 25.0
        want.append(model.step(rate, temp, (0.0, 9.80665, 0.0)))
    assert [o.sample_ns for o in out] == [T0_NS + k * PERIOD_NS for k in range(60)]
    assert rates(out) == [tuple(s.gyro_rad_s.tolist()) for s in want]
    assert all(np.array_equal(o.gyro.bias_rad_s, s.bias_rad_s) and
               np.array_equal(o.gyro.true_rate_rad_s, s.true_rate_rad_s) and
               o.die_temp_c == s.die_temp_c for o, s in zip(out, want))
    assert all(o.accel.true_specific_force_m_s2 == (0.0, 9.80665, 0.0) for o in out)
    assert all(o.accel_shown for o in out)        # the accelerometer is published by default


def test_the_covariance_is_the_white_noise_and_temperature_comes_every_nth_sample():
    driver, _, _ = make(temperature_rate_hz=10.0)
    out = ticks(driver, 0, 45)
    sigma = np.asarray(driver.model.white_noise_sigma_rad_s)
    cov = np.zeros(9)
    cov[[0, 4, 8]] = sigma ** 2
    assert out[0].gyro.covariance == tuple(cov.tolist())
    assert all(o.gyro.covariance is out[0].gyro.covariance for o in out)
    assert [k for k, o in enumerate(out) if o.temperature_due] == [19, 39]
    quiet, _, _ = make(noise_enabled=False)
    assert set(ticks(quiet, 0, 3)[0].gyro.covariance) == {0.0}


# --- stale commands ------------------------------------------------------------

@pytest.mark.parametrize('policy', ['zero', 'hold'])
def test_a_stale_rate_command_gives_zero_or_the_last_rate(policy):
    driver, inbox, _ = make(command_timeout_s=0.3, stale_rate_policy=policy)
    inbox.push('rate', 0, (0.2, 0.0, 0.0))
    out = ticks(driver, 0, 100)                     # 0.5 s, the command taken at k = 0
    true_x = [o.gyro.true_rate_rad_s[0] for o in out]
    assert true_x[:60] == [0.2] * 60                # stale once more than 0.3 s old
    assert true_x[61:] == [0.0 if policy == 'zero' else 0.2] * 39
    situation = driver.situation(T0_NS + 99 * PERIOD_NS)
    assert situation['stale'] and situation['stale_policy'] == policy
    inbox.push('rate', 0, (0.1, 0.0, 0.0))          # a fresh command ends it
    assert ticks(driver, 100, 1)[0].gyro.true_rate_rad_s[0] == 0.1
    assert not driver.situation(T0_NS + 100 * PERIOD_NS)['stale']


def test_without_a_timeout_a_rate_never_goes_stale():
    driver, inbox, _ = make(command_timeout_s=0.0)
    inbox.push('rate', 0, (0.2, 0.0, 0.0))
    out = ticks(driver, 0, 400)
    assert all(o.gyro.true_rate_rad_s[0] == 0.2 for o in out)


# --- bad inputs ----------------------------------------------------------------

def test_bad_commands_are_rejected_counted_and_logged_once_per_second():
    driver, inbox, log = make(max_stamp_lead_s=0.2)
    ticks(driver, 0, 1)
    inbox.push('rate', 0, (float('nan'), 0.0, 0.0))
    inbox.push('rate', 0, (1000.0, 0.0, 0.0))
    inbox.push('rate', 0, (2000.0, 0.0, 0.0))
    inbox.push('rate', T0_NS + 100 * NS_PER_S, (0.1, 0.0, 0.0))
    inbox.push('temperature', 0, 500.0)
    inbox.push('linear_acceleration', 0, (0.0, 1e9, 0.0))
    out = ticks(driver, 1, 1)
    rejected = driver.book.rejected
    assert (rejected['non_finite_rate'], rejected['rate_too_large'],
            rejected['future_stamp'], rejected['acceleration_too_large']) == (1, 2, 1, 1)
    assert driver.book.clamped['temperature_clamped'] == 1
    assert driver.situation(T0_NS)['ambient_temp_c'] == driver.limits.temp_range_c[1]
    assert out[0].gyro.true_rate_rad_s.tolist() == [0.0, 0.0, 0.0]
    text = log.text()
    assert text.count('input rejected (rate_too_large)') == 1   # the second is held back
    assert 'clamped to 200 C' in text


# --- catch-up, FIFO and drops ------------------------------------------------------

def test_a_late_tick_hands_out_a_bounded_burst_and_the_backlog_drains():
    driver, _, _ = make(max_burst_samples=8)
    first = ticks(driver, 0, 1)
    burst = driver.tick(T0_NS + 20 * PERIOD_NS)     # 20 samples came due
    assert len(burst) == 8 and driver.backlog == 12
    rest = driver.drain() + driver.drain()
    assert driver.backlog == 0 and driver.drain() == []
    out = first + burst + rest
    assert [o.sample_ns for o in out] == [T0_NS + k * PERIOD_NS for k in range(21)]
    model = offline(driver)
    assert rates(out) == [tuple(model.step((0.0,) * 3, 25.0, LEVEL).gyro_rad_s.tolist())
                          for _ in range(21)]
    counts = driver.situation(T0_NS + 20 * PERIOD_NS)
    assert (counts['samples_due'], counts['samples_caught_up'], counts['largest_burst'],
            counts['samples_dropped'], counts['backlog']) == (21, 17, 8, 0, 0)
    assert counts['emitted_ratio'] == 1.0


@pytest.mark.parametrize('policy,depth,published', [('fifo', 5, 5), ('drop', 1000, 1)])
def test_an_overflow_or_the_drop_policy_drops_and_counts_but_runs_the_model_through(
        policy, depth, published):
    driver, _, _ = make(overrun_policy=policy, fifo_depth_samples=depth, max_burst_samples=32)
    ticks(driver, 0, 1)
    out = driver.tick(T0_NS + 30 * PERIOD_NS)       # 30 samples came due
    dropped = 30 - published
    assert len(out) == published and driver.book.dropped == dropped
    assert [o.sample_ns for o in out] == [T0_NS + k * PERIOD_NS
                                          for k in range(31 - published, 31)]
    model = offline(driver)
    want = [model.step((0.0,) * 3, 25.0, LEVEL) for _ in range(31)]
    assert rates(out) == [tuple(s.gyro_rad_s.tolist()) for s in want[31 - published:]]
    assert driver.situation(T0_NS)['samples_dropped'] == dropped
    assert f'{dropped} dropped' in driver.summary()


def test_a_wall_clock_grid_moves_back_to_an_early_tick():
    driver, _, _ = make(follow_timer=True)
    ticks(driver, 0, 1)
    late = driver.tick(T0_NS + PERIOD_NS - 1_000_000)   # 1 ms early: the grid follows it
    assert [o.sample_ns for o in late] == [T0_NS + PERIOD_NS - 1_000_000]


# --- output delay and stamps -----------------------------------------------------

def test_the_stamp_is_the_sample_instant_plus_the_models_delay_jitter_clipped():
    driver, _, _ = make('consumer')                  # latency 1 ms, jitter 0.2 ms
    out = ticks(driver, 0, 400)
    model = offline(driver, 'consumer')
    delays = [model.step((0.0,) * 3, 25.0, LEVEL).output_delay_s for _ in range(400)]
    assert [o.stamp_ns - o.sample_ns for o in out] == [int(round(d * NS_PER_S))
                                                       for d in delays]
    offsets = np.array([o.stamp_ns - o.sample_ns for o in out]) - 1_000_000
    assert np.abs(offsets).max() <= 0.45 * PERIOD_NS and offsets.std() > 0
    assert np.all(np.diff([o.stamp_ns for o in out]) > 0)


def test_a_shorter_latency_set_at_run_time_never_moves_a_stamp_back():
    driver, _, _ = make()
    driver.apply(driver.prepare([('sensor.latency_s', 0.05)]), T0_NS)
    out = ticks(driver, 0, 20)
    assert out[0].stamp_ns == T0_NS + 50_000_000
    driver.apply(driver.prepare([('sensor.latency_s', 0.0)]), T0_NS + 20 * PERIOD_NS)
    out += ticks(driver, 20, 20)
    stamps = [o.stamp_ns for o in out]
    assert np.all(np.diff(stamps) > 0)
    assert stamps[20] == stamps[19] + 1
    clamped = driver.situation(T0_NS)['stamps_clamped']
    assert clamped == 10 and stamps[30] == out[30].sample_ns


# --- clock jumps ------------------------------------------------------------------

def test_a_clock_jump_back_reanchors_restarts_and_forgets_the_command_stamps():
    driver, inbox, log = make()
    ticks(driver, 0, 10)
    inbox.push('rate', T0_NS + 20 * PERIOD_NS, (0.5, 0.0, 0.0))
    ticks(driver, 10, 1)
    assert driver.situation(T0_NS)['commands_pending'] == 1
    back_ns = T0_NS - NS_PER_S
    out = driver.tick(back_ns)
    assert [o.sample_ns for o in out] == [back_ns]
    assert 'clock jumped back: command stamps forgotten, filters restarted' in log.text()
    situation = driver.situation(back_ns)
    assert situation['commands_pending'] == 0 and situation['clock_restarts'] == 1
    assert out[0].stamp_ns == back_ns               # stamps start again from the new time
    assert [o.sample_ns for o in driver.tick(back_ns + PERIOD_NS)] == [back_ns + PERIOD_NS]


def test_a_clock_jump_ahead_beyond_the_gap_restarts_without_running_the_gap():
    driver, _, log = make()
    ticks(driver, 0, 3)
    ahead_ns = T0_NS + 60 * NS_PER_S
    out = driver.tick(ahead_ns)
    assert [o.sample_ns for o in out] == [ahead_ns]
    assert 'the clock jumped ahead 59.990 s' in log.text()
    assert driver.situation(ahead_ns)['clock_restarts'] == 1 and driver.book.dropped == 0


# --- faults --------------------------------------------------------------------------

def test_a_stuck_fault_goes_pending_active_ended_and_repeats_the_last_output():
    driver, inbox, _ = make(command_timeout_s=0.0)
    inbox.push('rate', 0, (0.1, 0.2, 0.3))
    before = ticks(driver, 0, 10)
    change = driver.prepare([('fault.type', 'stuck'), ('fault.start_s', 0.02),
                             ('fault.duration_s', 0.05)])
    applied = driver.apply(change, T0_NS + 9 * PERIOD_NS)
    assert [(r.state, r.fault.kind) for r in applied.faults] == [('pending', 'stuck')]
    out = ticks(driver, 10, 20)
    changes = [(k, o.fault.state, o.fault.level) for k, o in enumerate(out)
               if o.fault is not None]
    assert changes == [(3, 'active', 2), (13, 'ended', 0)]
    stuck = [o.gyro.rate_rad_s for o in out[3:13]]
    assert stuck == [out[2].gyro.rate_rad_s] * 10     # the last output before it acts
    assert out[13].gyro.rate_rad_s != stuck[0] and before[-1].gyro.rate_rad_s != stuck[0]
    assert driver.situation(T0_NS)['fault.state'] == 'ended'


def test_a_dropout_publishes_nothing_and_a_new_fault_ends_the_one_it_replaces():
    driver, _, _ = make(temperature_rate_hz=200.0)
    driver.apply(driver.prepare([('fault.type', 'dropout')]), T0_NS)
    out = ticks(driver, 0, 5)
    assert [o.published for o in out] == [False] * 5
    assert not any(o.temperature_due for o in out)
    applied = driver.apply(driver.prepare([('fault.type', 'none')]), T0_NS + 5 * PERIOD_NS)
    assert [r.state for r in applied.faults] == ['ended', 'none']
    assert all(o.published and o.temperature_due for o in ticks(driver, 5, 3))


def test_the_start_reports_the_parameters_fault():
    values = node_values(**{'fault.type': 'bias_step', 'fault.magnitude': 0.01})
    log = Log()
    driver = Driver(values, load_sensor_config('paper'), 7, log=log)
    reports = driver.start(T0_NS)
    assert [r.state for r in reports] == ['none', 'pending']
    assert reports[-1].stamp_ns == T0_NS and 'fault set: bias_step' in log.text()


# --- the parameter transaction ------------------------------------------------------

@pytest.mark.parametrize('changes,match', [
    ([('stale_rate_policy', 'hold'), ('max_abs_rate_rad_s', -1.0)], 'max_abs_rate_rad_s'),
    ([('command_timeout_s', 1.0), ('sensor.output_filter_hz', 5000.0)], 'Nyquist'),
    ([('temperature_override_enabled', True), ('temperature_override_c', 199.0)],
     'temperature_override_c'),
    ([('noise_enabled', False), ('fault.type', 'bogus')], 'fault.type'),
])
def test_a_bad_set_is_refused_whole_and_nothing_changes(changes, match):
    driver, _, _ = make('consumer')
    values, limits, model = dict(driver.values), driver.limits, driver.model
    with pytest.raises(ValueError, match=match):
        driver.prepare(changes)
    assert driver.values == values and driver.limits is limits and driver.model is model


def test_a_good_set_applies_whole_and_a_clock_drift_moves_the_grid():
    driver, inbox, _ = make()
    ticks(driver, 0, 2)
    change = driver.prepare([('max_abs_rate_rad_s', 0.5), ('sensor.clock_drift_ppm', 1000.0),
                             ('overrun_policy', 'drop'), ('unknown.name', 1)])
    assert driver.values['max_abs_rate_rad_s'] == 100.0          # prepared, not applied
    applied = driver.apply(change, T0_NS + PERIOD_NS)
    assert applied.model_changed and applied.faults == ()
    assert driver.limits.max_abs_rate_rad_s == 0.5
    assert driver.values['overrun_policy'] == 'drop'
    assert driver.sample_period_s == pytest.approx(0.005 / 1.001)
    inbox.push('rate', 0, (0.6, 0.0, 0.0))                          # above the new limit
    # The next sample (T0 + 2 periods) was on the grid already; from it on, the new period.
    now_ns = T0_NS + 2 * PERIOD_NS + 98 * 4_995_005
    out = driver.tick(now_ns)
    assert driver.book.rejected['rate_too_large'] == 1
    assert [o.sample_ns for o in out] == [now_ns] and driver.book.dropped == 98


def test_a_set_without_a_model_change_keeps_the_model_and_the_fault():
    driver, _, _ = make()
    applied = driver.apply(driver.prepare([('publish_truth', False)]), T0_NS)
    assert not applied.model_changed and applied.faults == ()
    assert driver.values['publish_truth'] is False


# --- behind a simulator: one output per imu/ideal message ----------------------------

def imu_driver(**overrides):
    return make(input_source='imu', **overrides)


def test_one_output_per_message_stamped_at_its_stamp_with_the_rate_from_the_stamps():
    driver, _, log = imu_driver(temperature_rate_hz=1.0)
    dt = 4_000_000
    out = []
    for k in range(10):
        out += driver.ideal_imu(T0_NS + k * dt, (0.0, 0.0, 0.01 * k), (1.0, 0.0, 9.0))
    assert [o.sample_ns for o in out] == [o.stamp_ns for o in out] == \
        [T0_NS + k * dt for k in range(10)]
    # the simulator's acceleration is the specific force the accelerometer senses
    assert all(o.accel.true_specific_force_m_s2 == (1.0, 0.0, 9.0) and o.accel_shown
               for o in out)
    assert 'input rate 250 Hz from the imu/ideal stamps: model re-planned' in log.text()
    model = offline(driver)
    want = [model.step((0.0, 0.0, 0.0), 25.0, (1.0, 0.0, 9.0))]
    model.set_sample_rate(250.0)
    want += [model.step((0.0, 0.0, 0.01 * k), 25.0, (1.0, 0.0, 9.0)) for k in range(1, 10)]
    assert rates(out) == [tuple(s.gyro_rad_s.tolist()) for s in want]
    assert driver.situation(T0_NS)['input_rate_hz'] == pytest.approx(250.0)


def test_a_lost_message_runs_the_model_through_with_the_previous_input_held():
    driver, _, _ = imu_driver()
    dt = 5_000_000                                   # the nominal 200 Hz: no re-plan
    out = driver.ideal_imu(T0_NS, (0.1, 0.0, 0.0), LEVEL)
    out += driver.ideal_imu(T0_NS + dt, (0.2, 0.0, 0.0), LEVEL)
    out += driver.ideal_imu(T0_NS + 4 * dt, (0.3, 0.0, 0.0), LEVEL)    # two lost
    model = offline(driver)
    want = [model.step((0.1, 0.0, 0.0), 25.0, LEVEL), model.step((0.2, 0.0, 0.0), 25.0, LEVEL)]
    model.step((0.2, 0.0, 0.0), 25.0, LEVEL)
    model.step((0.2, 0.0, 0.0), 25.0, LEVEL)
    want.append(model.step((0.3, 0.0, 0.0), 25.0, LEVEL))
    assert rates(out) == [tuple(s.gyro_rad_s.tolist()) for s in want]
    assert driver.situation(T0_NS)['input_gap_samples'] == 2


def test_bad_messages_are_refused_and_the_input_clock_can_restart():
    driver, _, log = imu_driver()
    assert len(driver.ideal_imu(T0_NS, (0.0,) * 3, LEVEL)) == 1
    assert driver.ideal_imu(T0_NS, (0.0,) * 3, LEVEL) == []                # repeated stamp
    assert driver.ideal_imu(T0_NS + 10, (0.0,) * 3, LEVEL) == []           # 10 ns: too close
    assert driver.ideal_imu(T0_NS + PERIOD_NS, (float('nan'), 0.0, 0.0), LEVEL) == []
    rejected = driver.book.rejected
    assert (rejected['out_of_order'], rejected['stamp_spacing'],
            rejected['non_finite_rate']) == (1, 1, 1)
    back = driver.ideal_imu(T0_NS - NS_PER_S, (0.0,) * 3, LEVEL)
    assert [o.sample_ns for o in back] == [T0_NS - NS_PER_S]
    gap = driver.ideal_imu(T0_NS + 2 * NS_PER_S, (0.0,) * 3, LEVEL)
    assert len(gap) == 1
    text = log.text()
    assert 'the input clock jumped back' in text and 'a gap of 3.000 s' in text
    assert driver.situation(T0_NS)['input_restarts'] == 2


def test_a_rate_the_model_refuses_is_a_model_error_until_a_rate_fits():
    driver, _, log = imu_driver(sensor='consumer', rate_hz=250.0)    # 42 Hz output filter
    for k in range(3):
        driver.ideal_imu(T0_NS + k * 50_000_000, (0.0,) * 3, LEVEL)         # 20 Hz
    assert driver.book.model_errors == 2 and 'input rate 20 Hz refused' in log.text()
    assert driver.situation(T0_NS)['sample_period_s'] == pytest.approx(1 / 250.0)


def test_a_fault_set_behind_a_simulator_starts_at_the_last_input_stamp():
    driver, _, _ = imu_driver()
    driver.ideal_imu(T0_NS + 7, (0.0,) * 3, LEVEL)
    applied = driver.apply(driver.prepare([('fault.type', 'stuck')]), 123)
    assert applied.faults[-1].stamp_ns == T0_NS + 7


def test_the_command_inbox_names_its_streams():
    with pytest.raises(ValueError, match='rate, temperature, linear_acceleration'):
        CommandInbox().push('pressure', 0, 1.0)


# --- any clock jump: re-anchored, counted, said once ---------------------------------

def step_part(tmp_path, step_time_s=25.0):
    """Return the path of a part whose only term is a 0.5 rad/s bias step on x at step_time_s."""
    path = tmp_path / 'part.yaml'
    path.write_text(yaml.safe_dump({
        'terms': dict.fromkeys(ErrorTerms.names(), False),
        'extended': {'bias_step': {'step_time_s': step_time_s, 'bias_step_rad_s': 0.5}}}))
    return str(path)


def at_s(driver, *times_s):
    """Tick the driver at the given clock times (s); return the x rates."""
    return [o.gyro.rate_rad_s[0] for t in times_s for o in driver.tick(int(round(t * NS_PER_S)))]


@pytest.mark.parametrize('sensor', ['paper', 'step_part'])
def test_clock_jumps_of_1e9_s_ahead_and_back_keep_the_node_publishing(tmp_path, sensor):
    """A /clock from 10 s to epoch seconds (1.7e9 s) and +-1e9 s: no error, one sample each."""
    sensor = step_part(tmp_path) if sensor == 'step_part' else sensor
    driver, _, log = make(sensor)
    times = [10.0, 10.005, 1.7e9, 1.7e9 + 0.005, 1.7e9 - 1e9, 0.7e9 + 1e9, 10.0, 10.005]
    counts = [len(driver.tick(int(round(t * NS_PER_S)))) for t in times]
    assert counts == [1] * len(times)
    assert driver.book.clock_jumps == 4 and driver.book.model_errors == 0
    text = log.text()
    assert text.count('jumped') == 4 and 'the clock jumped ahead 1699999989.995 s' in text
    assert ('record time re-anchored' in text) == (sensor != 'paper')   # extended terms only
    assert 'clock jumped back: command stamps forgotten, filters restarted (1e+09 s back, ' \
           'to 700000000 s)' in text
    report = driver.report(1.0, driver.situation(0), check_rate=False)
    assert report.level == WARN and report.message.count('jumped') == 4
    assert dict(report.values)['clock_jumps'] == 4
    again = driver.report(1.0, driver.situation(0), check_rate=False)
    assert again.message == 'OK'                                       # said once


def test_the_record_time_is_reanchored_when_the_clock_jumps_out_of_its_reach(tmp_path):
    """The bias step at record time 25 s: off, then on 30 s after each re-anchoring."""
    driver, _, log = make(step_part(tmp_path))
    assert at_s(driver, 10.0, 40.0) == [0.0, 0.5]           # follows the clock: 30 s
    assert at_s(driver, 1.7e9, 1.7e9 + 30.0) == [0.0, 0.5]  # out of reach: re-anchored
    assert at_s(driver, 0.7e9, 0.7e9 + 20.0) == [0.0, 0.0]  # back before it: that instant
    situation = driver.situation(0)
    assert situation['record_time_reanchors'] == 1
    assert 'record time re-anchored at this sample (the clock at 1.7e+09 s' in log.text()


def test_a_jump_to_within_reach_of_record_start_clock_s_puts_the_record_time_on_it(tmp_path):
    origin_s = 1.7e9 - 100.0
    driver, _, log = make(step_part(tmp_path), record_start_clock_s=origin_s)
    assert at_s(driver, 10.0) == [0.0]          # the origin out of reach: the first sample
    assert 'record_start_clock_s = 1.7e+09 s is not used' in log.text()
    assert at_s(driver, 1.7e9 - 90.0) == [0.0]  # record time 10 s: before the step
    assert at_s(driver, 1.7e9 - 60.0) == [0.5]  # 40 s: after it
    assert 'record time re-anchored at record_start_clock_s' in log.text()


def test_behind_a_simulator_an_input_clock_jump_of_1e9_s_is_survived_and_counted():
    driver, _, log = imu_driver()
    stamps = [10 * NS_PER_S, 10 * NS_PER_S + PERIOD_NS, int(1.7e18), int(1.7e18) + PERIOD_NS,
              int(0.7e18), int(0.7e18) + PERIOD_NS]
    out = [o for t in stamps for o in driver.ideal_imu(t, (0.0,) * 3, LEVEL)]
    assert [o.sample_ns for o in out] == stamps
    assert driver.book.clock_jumps == 2 and driver.book.model_errors == 0
    assert 'a gap of 1699999989.995 s' in log.text()


# --- a non-finite sample is never published ------------------------------------------

def test_a_non_finite_sample_is_withheld_counted_logged_throttled_and_an_error():
    clock = [0.0]
    values = node_values(sensor_config='paper')
    log = Log()
    driver = Driver(values, load_sensor_config('paper'), 7, log=log,
                    monotonic=lambda: clock[0])
    driver.start(T0_NS)
    stepper = driver._stepper
    real = stepper.step
    bad = {3: ('gyro_rad_s', 0), 4: ('bias_rad_s', 2), 5: ('scale_factor', 1), 9: ('die', 0),
           10: ('delay', 0)}
    calls = [0]

    def step(*args):
        sample = real(*args)
        k, calls[0] = calls[0], calls[0] + 1
        if k not in bad:
            return sample
        field, axis = bad[k]
        if field in ('die', 'delay'):
            name = 'die_temp_c' if field == 'die' else 'output_delay_s'
            return dataclasses.replace(sample, **{name: float('nan')})
        value = np.array(getattr(sample, field), dtype=float)
        value[axis] = np.inf if k % 2 else np.nan
        return dataclasses.replace(sample, **{field: value})
    stepper.step = step
    out = ticks(driver, 0, 12)
    assert [(o.sample_ns - T0_NS) // PERIOD_NS for o in out] == [0, 1, 2, 6, 7, 8, 11]
    assert all(np.isfinite(o.gyro.rate_rad_s).all() and np.isfinite(o.die_temp_c) and
               np.isfinite(o.gyro.bias_rad_s).all() for o in out)
    assert driver.book.nonfinite == 5 and driver.book.samples == 7
    assert np.isfinite(driver.situation(0)['die_temp_c'])   # the last one shown: a good one
    errors = [text for level, text in log.lines if level == 'error']
    assert len(errors) == 1 and 'the model gave a non-finite sample (rate (inf' in errors[0]
    clock[0] = 2.0                                      # the throttle's second is over
    bad[12] = ('gyro_rad_s', 1)
    ticks(driver, 12, 1)
    errors = [text for level, text in log.lines if level == 'error']
    assert len(errors) == 2 and errors[1].endswith('(4 similar held back)')
    report = driver.report(1.0, driver.situation(0), check_rate=False)
    assert report.level == ERROR and '6 non-finite sample(s) withheld' in report.message
    assert dict(report.values)['nonfinite_samples'] == 6
    assert '6 non-finite withheld' in driver.summary()


# --- the start-up bias calibration ---------------------------------------------------

def pair(sensor='consumer', seed=7, calibration_s=1.0, **overrides):
    """Return (calibrating driver, plain driver, log of the first): same part, same seed."""
    cal, inbox, log = make(sensor, seed=seed, startup_bias_calibration=calibration_s,
                           **overrides)
    plain, plain_inbox, _ = make(sensor, seed=seed, **overrides)
    return cal, plain, (inbox, plain_inbox), log


def test_the_startup_calibration_removes_the_mean_of_its_window_and_keeps_the_truth():
    """The consumer preset (turn-on bias sigma 6.67 deg/s), 20 seeds: the bias is gone."""
    window = 200                                          # 1 s at 200 Hz
    for seed in range(20):
        cal, plain, _, log = pair(seed=seed)
        got, raw = ticks(cal, 0, 3 * window), ticks(plain, 0, 3 * window)
        assert rates(got[:window]) == rates(raw[:window])          # the window: uncorrected
        estimate = np.mean(rates(raw[:window]), axis=0)
        situation = cal.situation(0)
        assert situation['bias_calibration'] == 'applied'
        assert situation['bias_calibration.samples'] == window
        np.testing.assert_allclose([situation[f'bias_calibration.{a}_rad_s'] for a in 'xyz'],
                                   estimate, rtol=1e-12, atol=1e-15)
        after = np.array(rates(got[window:]))
        offset = np.array([situation[f'bias_calibration.{a}_rad_s'] for a in 'xyz'])
        assert np.array_equal(after, np.array(rates(raw[window:])) - offset)
        assert all(np.array_equal(a.gyro.bias_rad_s, b.gyro.bias_rad_s)
                   for a, b in zip(got, raw))                     # the truth keeps it
        # The turn-on bias (0.05-0.2 rad/s here) is gone: the corrected mean is within
        # 1e-3 rad/s, about ten standard errors of a 200-sample mean (1e-4 rad/s).
        assert np.abs(np.mean(rates(raw[window:]), axis=0)).max() > 0.01
        assert np.abs(after.mean(axis=0)).max() < 1e-3
    assert 'startup bias calibration over 1 s (200 samples): x ' in log.text()
    report = cal.report(1.0, cal.situation(0), check_rate=False)
    assert report.level == OK and 'startup bias calibration over 1 s' in report.message


def test_a_commanded_rate_in_the_window_keeps_the_estimate_off_the_output():
    cal, plain, (inbox, plain_inbox), log = pair(command_timeout_s=0.0)
    for box in (inbox, plain_inbox):
        box.push('rate', T0_NS + 100 * PERIOD_NS, (0.0, 0.0, 0.01))
    assert rates(ticks(cal, 0, 400)) == rates(ticks(plain, 0, 400))
    situation = cal.situation(0)
    assert situation['bias_calibration'] == 'not applied'
    assert situation['bias_calibration.moved'] == 'the commanded rate was not zero'
    assert 'not applied: the commanded rate was not zero; estimate x ' in log.text()
    report = cal.report(1.0, situation, check_rate=False)
    assert report.level == WARN and 'startup bias calibration over 1 s' in report.message


def test_motion_the_command_does_not_show_is_caught_by_the_spread():
    """A 0.05 rad/s bias step on x half way through the window (an uncommanded turn)."""
    fault = {'fault.type': 'bias_step', 'fault.axis': 'x', 'fault.magnitude': 0.05,
             'fault.start_s': 0.5}
    cal, plain, _, log = pair(**fault)
    assert rates(ticks(cal, 0, 400)) == rates(ticks(plain, 0, 400))
    moved = cal.situation(0)['bias_calibration.moved']
    assert moved.startswith('the spread says motion on x (0.02') and ' y' not in moved


@pytest.mark.parametrize('sensor', ['paper', 'consumer', 'tactical'])
def test_the_spread_test_has_no_false_alarms_at_rest(sensor):
    """60 parts per preset at rest, 0.5 s windows: every estimate applied (limit 3x rest)."""
    flagged = []
    for seed in range(60):
        cal, _, _ = make(sensor, seed=seed, startup_bias_calibration=0.5)
        ticks(cal, 0, 101)
        situation = cal.situation(0)
        if situation['bias_calibration'] != 'applied':
            flagged.append((seed, situation['bias_calibration.moved']))
    assert flagged == []


def test_without_noise_the_window_is_exact_and_behind_a_simulator_it_counts_periods():
    cal, _, _ = make('consumer', seed=3, startup_bias_calibration=0.25, noise_enabled=False,
                     input_source='imu')
    out = []
    for k in range(80):
        out += cal.ideal_imu(T0_NS + k * 4_000_000, (0.0,) * 3, LEVEL)   # 250 Hz
    situation = cal.situation(0)
    # 0.25 s of sample periods: the first at the nominal 200 Hz (5 ms), then 61 at
    # 250 Hz (4 ms) from the stamps: 0.249 s, within half a period of 0.25 s.
    assert situation['bias_calibration'] == 'applied'
    assert situation['bias_calibration.samples'] == 62
    assert len(set(rates(out[:62]))) == 1               # no noise: one value
    assert set(rates(out[62:])) == {(0.0, 0.0, 0.0)}


@pytest.mark.parametrize('source', ['/clock', 'imu/ideal'])
def test_off_the_wall_clock_no_sample_yet_is_a_warning_until_the_first(source):
    """use_sim_time without a /clock bridge (or no simulator yet): not an OK with 0 samples."""
    driver, _, _ = make()
    report = driver.report(1.0, driver.situation(0), check_rate=False, waiting_for=source)
    assert report.level == WARN and report.message == f'no sample yet: waiting for {source}'
    assert dict(report.values)['samples'] == 0
    assert len(driver.tick(10 * NS_PER_S)) == 1
    report = driver.report(1.0, driver.situation(0), check_rate=False, waiting_for=source)
    assert report.level == OK and report.message == 'OK'
    nothing = driver.report(1.0, driver.situation(0), check_rate=False, waiting_for=source)
    assert nothing.level == OK                # a paused simulation after samples: not said


def test_an_ideal_imu_without_acceleration_senses_gravity_and_marks_it_absent():
    """REP 145: an imu/ideal whose acceleration covariance[0] is -1 has none (values ignored)."""
    driver, _, _ = imu_driver()
    dt = 5_000_000                                   # the nominal 200 Hz: no re-plan
    out = driver.ideal_imu(T0_NS, (0.1, 0.0, 0.0), None)
    out += driver.ideal_imu(T0_NS + dt, (0.2, 0.0, 0.0), None)
    out += driver.ideal_imu(T0_NS + 3 * dt, (0.3, 0.0, 0.0), None)     # one lost
    assert len(out) == 3 and driver.book.model_errors == 0
    assert not any(o.accel_shown for o in out)       # nothing made up on imu/data_raw
    assert out[0].accel.true_specific_force_m_s2 == LEVEL
    # the model sensed gravity turning with the attitude integrated from the rates
    roll = [math.atan2(o.accel.true_specific_force_m_s2[1], o.accel.true_specific_force_m_s2[2])
            for o in out]
    # (each rate held until the next sample: 0.1 over dt, then 0.2 over the 2 dt to the third)
    assert roll == pytest.approx([0.0, 0.1 * dt * 1e-9, (0.1 + 0.2 * 2) * dt * 1e-9], abs=1e-12)
    shown = driver.ideal_imu(T0_NS + 4 * dt, (0.0, 0.0, 0.0), (0.0, 0.0, 9.0))
    assert shown[0].accel_shown and shown[0].accel.true_specific_force_m_s2 == (0.0, 0.0, 9.0)


def test_a_screened_parameter_set_is_said_once_and_changes_nothing():
    """A refused set on the log and in one report (WARN); a valid one says nothing."""
    driver, _, log = make()
    before = dict(driver.values)
    driver.screen([('command_timeout_s', 0.5)])
    assert 'refused' not in log.text()
    driver.screen([('command_timeout_s', -1.0), ('noise_enabled', False)])
    assert driver.values == before
    line = 'parameter set refused: command_timeout_s = -1.0 is out of range'
    assert line in log.text()
    report = driver.report(1.0, driver.situation(0), check_rate=False)
    assert report.level == WARN and line in report.message
    assert 'refused' not in driver.report(1.0, driver.situation(0), check_rate=False).message
