"""The sensor's sample clock under the node's timer (emulation.driver.sample_clock), no ROS."""

import subprocess
import sys
import threading

from gyro_emulator.emulation.driver.block_stepper import BlockStepper
from gyro_emulator.emulation.driver.sample_clock import MAX_GAP_S, SampleClock
from gyro_emulator.ros import gyro_array
from gyro_emulator.sensor.config import SensorConfig
from gyro_emulator.sensor.model import GyroModel
import numpy as np
import pytest

MS = 1_000_000


def run(clock, ticks_ns):
    """Return every (tick, Due) of a list of tick times."""
    return [(t, clock.due(t)) for t in ticks_ns]


def test_a_timer_in_step_hands_out_one_sample_per_tick_at_its_grid_time():
    clock = SampleClock(0.005)
    # A timer at 5 ms with a latency of 50-400 us (the first tick the latest).
    rng = np.random.default_rng(0)
    ticks = [10**9 + k * 5 * MS + int(rng.uniform(50e3, 400e3)) for k in range(400)]
    ticks[0] += 300_000
    out = run(clock, ticks)
    times = [t for _, due in out for t in due.times_ns]
    assert len(times) >= 399 and all(len(d.times_ns) <= 1 for _, d in out)
    assert all(t <= tick for tick, due in out for t in due.times_ns)   # never ahead of now
    assert np.all(np.diff(times) > 0)
    assert clock.dropped == 0 and clock.emitted == clock.due_total


def test_a_coarse_clock_gets_every_sample_at_its_own_time():
    """/clock every 10 ms or 20 ms at 200 Hz: 2 or 4 samples per tick, none lost."""
    for step_ms, per_tick in ((10, 2), (20, 4)):
        clock = SampleClock(0.005)
        out = run(clock, [k * step_ms * MS for k in range(1, 501)])
        times = [t for _, due in out for t in due.times_ns]
        assert [len(d.times_ns) for _, d in out[1:]] == [per_tick] * 499
        assert times == [step_ms * MS + 5 * MS * k for k in range(len(times))]
        assert clock.emitted_ratio == 1.0 and clock.dropped == 0
        assert clock.caught_up == 499 * (per_tick - 1)


def test_on_a_simulators_clock_the_grid_keeps_its_period_whatever_the_phase():
    """A drifting part (4.995 ms) on /clock steps of 10 ms: every interval one period."""
    clock = SampleClock(0.004995, follow_timer=False)
    out = run(clock, [k * 10 * MS for k in range(1, 2001)])
    times = np.array([t for _, due in out for t in due.times_ns])
    assert set(np.diff(times)) <= {4_995_000}
    assert len(times) == (20_000 - 10) * MS // 4_995_000 + 1 and clock.dropped == 0


def test_fifo_bursts_are_bounded_and_the_backlog_catches_up():
    clock = SampleClock(0.001, 'fifo', max_burst=8, depth=1000)
    clock.due(0)
    stall = clock.due(46 * MS)                        # a 46 ms stall at 1 kHz: 46 due
    assert len(stall.times_ns) == 8 and clock.backlog == 38
    sizes = [len(clock.due(46 * MS + k * MS).times_ns) for k in range(1, 8)]
    assert sizes == [8, 8, 8, 8, 8, 4, 1]           # 38 waiting, 1 more per tick
    assert clock.dropped == 0 and clock.backlog == 0 and clock.largest_burst == 8
    assert clock.emitted == clock.due_total == 54


def test_the_counts_another_thread_reads_are_replaced_whole_after_each_tick():
    clock = SampleClock(0.001, 'fifo', max_burst=8, depth=1000)
    clock.due(0)
    before = clock.counts
    clock.due(46 * MS)                                # 46 due, 8 out, 38 waiting
    assert before == {'overruns': 0, 'samples_due': 1, 'samples_caught_up': 0,
                      'samples_dropped': 0, 'emitted_ratio': 1.0, 'largest_burst': 1,
                      'backlog': 0, 'clock_restarts': 0}    # a held snapshot never moves
    now = clock.counts
    assert now['samples_due'] == clock.due_total == 47 and now['backlog'] == 38
    assert now['emitted_ratio'] == pytest.approx(9 / 47)
    clock.due(46 * MS)                                # the same instant: 8 more of the 38
    assert clock.counts['samples_due'] == 47 and clock.counts['backlog'] == 30
    assert clock.counts['emitted_ratio'] == pytest.approx(17 / 47)
    assert now['emitted_ratio'] == pytest.approx(9 / 47)


def test_fifo_overflow_and_drop_policy_count_what_they_drop():
    clock = SampleClock(0.001, 'fifo', max_burst=16, depth=20)
    clock.due(0)
    due = clock.due(100 * MS)                         # 100 due, depth 20: 80 dropped
    assert due.skipped == 80 and len(due.times_ns) == 16 and clock.backlog == 4
    assert due.times_ns[0] == 81 * MS
    dropper = SampleClock(0.001, 'drop')
    dropper.due(0)
    due = dropper.due(100 * MS)
    assert due.skipped == 99 and due.times_ns == (100 * MS,)
    assert dropper.dropped == 99 and dropper.emitted_ratio == pytest.approx(2 / 101)


def test_jumps_back_and_long_gaps_reanchor_the_grid():
    clock = SampleClock(0.005)
    clock.due(10**9)
    assert clock.due(10**9 + 5 * MS).times_ns == (10**9 + 5 * MS,)
    back = clock.due(5 * 10**8)
    assert back.restart == 'jump_back' and back.times_ns == (5 * 10**8,)
    gap = clock.due(5 * 10**8 + int((MAX_GAP_S + 1) * 1e9))
    assert gap.restart == 'gap' and len(gap.times_ns) == 1 and clock.restarts == 2


def test_a_new_period_applies_from_the_next_sample():
    clock = SampleClock(0.005)
    clock.due(0)
    clock.set_period(0.004)
    assert clock.due(12 * MS).times_ns == (5 * MS, 9 * MS)


def test_skipped_samples_move_the_model_as_steps_would():
    config = SensorConfig()
    a = BlockStepper(GyroModel(config, 200.0, np.random.default_rng(3)), 50)
    b = BlockStepper(GyroModel(config, 200.0, np.random.default_rng(3)), 1)
    rate, accel = (0.1, 0.0, -0.2), (0.0, 0.0, 9.8)
    a.skip(123, rate, 30.0, accel)
    for _ in range(123):
        b.step(rate, 30.0, accel)
    assert a.step(rate, 30.0, accel).gyro_rad_s.tobytes() == \
        b.step(rate, 30.0, accel).gyro_rad_s.tobytes()


def test_stamp_jitter_is_bounded_by_the_period_so_stamps_increase():
    """sensor.timestamp_jitter_s = 0.1 s (its allowed top) at 200 Hz."""
    config = SensorConfig(timestamp_jitter_s=0.1, latency_s=0.0)
    model = GyroModel(config, 200.0, np.random.default_rng(0))
    batch = model.run(np.zeros((20000, 3)), 25.0)
    delay = np.asarray(batch.output_delay_s)
    stamps = np.arange(20000) * model.sample_period_s + delay
    assert np.all(np.diff(stamps) > 0)
    assert delay.max() <= 0.45 * 0.005 + 1e-12 and delay.min() >= 0.0
    # A small jitter keeps its Gaussian spread (no clipping at 1e-4 s).
    small = GyroModel(SensorConfig(timestamp_jitter_s=1e-4, latency_s=0.001), 200.0,
                      np.random.default_rng(0)).run(np.zeros((20000, 3)), 25.0)
    assert np.std(small.output_delay_s) == pytest.approx(1e-4, rel=0.03)


@pytest.mark.parametrize('codes,stopped,status', [
    ([0, 0, 0], True, 0), ([130, 0, -2], True, 0), ([0, 143, -15], True, 0),
    ([0, 2, 0], True, 2), ([0, 1], False, 1), ([-9, 0], True, 137), ([130], False, 130)])
def test_the_array_status_after_a_stop_is_zero_unless_a_node_failed(codes, stopped, status):
    assert gyro_array.exit_status(codes, stopped) == status


def _child(code):
    """Start a Python child running ``code`` (SIGINT ignored: a node slow to end)."""
    return subprocess.Popen([sys.executable, '-c',
                             'import signal, time\n'
                             'signal.signal(signal.SIGINT, signal.SIG_IGN)\n' + code])


def test_the_array_waits_for_a_node_slow_to_end_and_a_second_stop_ends_it():
    """A node that ends on its own is waited for; a second Ctrl-C kills one that hangs."""
    slow = _child('time.sleep(2.0)')              # ends cleanly, on its own time
    assert gyro_array._wait_for_nodes([slow], stop=[2]) == [0]
    hung = _child('time.sleep(600)')
    stop = [2]
    threading.Timer(0.5, stop.append, args=(2,)).start()
    assert gyro_array._wait_for_nodes([hung], stop) == [-9]
