"""
``ros2 run gyro_emulator scenario [PROFILE]``: play a rate/temperature profile.

The scenario file (its keys, its steps and the summary) is
:mod:`gyro_emulator.emulation.scenario`; this is its ROS edge. The player
publishes the step's
true rate on ``cmd/angular_velocity`` (geometry_msgs/Vector3Stamped, rad/s
along ``axis``) and its ambient temperature on ``cmd/temperature``
(sensor_msgs/Temperature) at ``publish_rate_hz``, so a lost message is
repaired at the next period. With ``--summary`` it also listens to
``imu/data_raw`` and ``imu/temperature`` and prints, per step, the commanded
and measured rate and the error in deg/s, averaged after ``settle_s``. It keeps every sample
(:data:`COLLECT_DEPTH`: a late node's catch-up bursts, and what comes while a
loaded machine holds the player back) and, after the last step, waits up to
:data:`DRAIN_S` for the node's samples of it.

Before the first step the player waits for the emulator itself: a node that
subscribes to both commands and publishes ``imu/data_raw`` (a recorder that
subscribes to the commands is not one), then for its first Imu sample, so
no step starts before the node runs, however long its start takes. It says
what it is still waiting for (:func:`play`'s ``waiting``) and gives up after
``wait_s`` with one line naming what never came.

A scenario's ``faults`` schedule (times from the start of the profile) is
played through the node's parameter service: the player sets the node's
``fault.*`` parameters (atomically) up to :data:`FAULT_LEAD_S` ahead, with
``fault.start_s`` the time left, so each fault starts on the node's clock
within the latency of that call. A fault replaces the one before, so it is sent no earlier than
:data:`FAULT_MARGIN_S` after that one ends (a fault that follows closer
starts that much late). After a last fault without an end the player clears
it.
"""

import argparse
import math
import os
import signal
import sys
import time

from gyro_emulator import atomic, outputs
from gyro_emulator.emulation.scenario import format_summary, interruption_note, \
    load_scenario, results_json, summarize, unmeasured
from gyro_emulator.interrupts import SignalFlag
from gyro_emulator.recording import topics
from gyro_emulator.ros.codec import topic_class, topic_qos
from gyro_emulator.ros.spinning import flag_signals, spin_once
from gyro_emulator.units import NS_PER_S
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args

#: How far ahead of its start a scheduled fault is sent to the node, s.
FAULT_LEAD_S = 0.5
#: How long after the previous fault's end the next is sent (it replaces it), s.
FAULT_MARGIN_S = 0.1
#: How often :func:`play` reports the wait for the emulator, s.
WAITING_REPORT_S = 1.0
#: How often the ``scenario`` command prints that it still waits, s.
WAITING_LINE_S = 5.0
#: History of the player's output subscriptions (best effort, which either
#: reliability the node offers serves). The sensor-data profile's 5 lost the
#: node's catch-up bursts (up to ``max_burst_samples``, 32, per tick) and
#: whatever came while a loaded machine held the player back: a node or a player
#: stopped for 0.6 s kept 44-50 of a step's 100 samples. 1000 is the node's own
#: FIFO depth (``fifo_depth_samples``).
COLLECT_DEPTH = 1000
#: Longest wait after the profile's end for the node's samples of its last step, s
#: (a node behind a loaded machine publishes them late, each with its own stamp).
DRAIN_S = 10.0


# --- the ROS side ----------------------------------------------------------

class ScenarioPlayer:
    """
    Publish a profile's commands from an rclpy node; optionally collect output.

    Parameters
    ----------
    node : rclpy.node.Node
        The node that owns publishers, subscriptions and the timer.
    profile : gyro_emulator.emulation.scenario.Scenario
        What to play.
    collect : bool
        Keep imu/data_raw and imu/temperature for :func:`summarize` (imu/data_raw
        is subscribed either way: its first sample says the emulator runs).
    loop : bool
        Start over at the end instead of finishing.

    Attributes
    ----------
    imu_received : int
        Imu messages received (kept or not).

    """

    def __init__(self, node, profile, collect=False, loop=False):
        self.node = node
        self.profile = profile
        self.loop = loop
        self.rate_pub, self.temp_pub = (
            node.create_publisher(topic_class(topic), topic.name, topic_qos(topic))
            for topic in (topics.RATE_CMD, topics.TEMPERATURE_CMD))
        self._rate_msg = topic_class(topics.RATE_CMD)()
        self._temp_msg = topic_class(topics.TEMPERATURE_CMD)()
        self.imu, self.temps = [], []
        self.imu_received = 0
        self.newest_imu_ns = None
        self._collect = collect
        deep = QoSProfile(depth=COLLECT_DEPTH, reliability=ReliabilityPolicy.BEST_EFFORT)
        node.create_subscription(topic_class(topics.IMU_OUT), topics.IMU_OUT.name,
                                 self._on_imu, deep)
        if collect:
            node.create_subscription(topic_class(topics.DIE_TEMPERATURE_OUT),
                                     topics.DIE_TEMPERATURE_OUT.name, self._on_temp, deep)
        self.start_ns = None
        self.done = False
        self.stop_ns = None          # set when interrupted (SIGINT, SIGTERM, shutdown)
        self._ends = []
        total = 0
        for step in profile.steps:
            total += int(step.duration_s * 1e9)
            self._ends.append(total)
        self._timer = None
        self.faults_sent = []
        self.fault_errors = []
        self._fault_next = 0
        self._fault_futures = []
        self._fault_client = None
        if profile.faults:
            self._fault_client = AsyncParameterClient(node, topics.NODE_NAME)

    def _on_imu(self, msg):
        self.imu_received += 1
        if not self._collect:
            return
        v = msg.angular_velocity
        s = msg.header.stamp
        stamp_ns = s.sec * NS_PER_S + s.nanosec
        self.imu.append((stamp_ns, (v.x, v.y, v.z)))
        if self.newest_imu_ns is None or stamp_ns > self.newest_imu_ns:
            self.newest_imu_ns = stamp_ns

    def _on_temp(self, msg):
        s = msg.header.stamp
        self.temps.append((s.sec * NS_PER_S + s.nanosec, msg.temperature))

    def emulator(self):
        """
        Return the fully qualified name of the emulator on the graph, or None.

        The emulator is a node that subscribes to both commands and publishes
        ``imu/data_raw`` (a recorder subscribes to the commands too, but
        publishes no Imu).
        """
        node = self.node

        def nodes(infos):
            return {(i.node_namespace, i.node_name) for i in infos}
        found = nodes(node.get_subscriptions_info_by_topic(self.rate_pub.topic_name)) \
            & nodes(node.get_subscriptions_info_by_topic(self.temp_pub.topic_name)) \
            & nodes(node.get_publishers_info_by_topic(node.resolve_topic_name(
                topics.IMU_OUT.name)))
        if not found:
            return None
        namespace, name = min(found)
        return namespace.rstrip('/') + '/' + name

    def missing(self):
        """Say what the player still waits for before the first step; None: nothing."""
        imu = self.node.resolve_topic_name(topics.IMU_OUT.name)
        if self.emulator() is None:
            return (f'no node yet subscribes to {self.rate_pub.topic_name} and '
                    f'{self.temp_pub.topic_name} and publishes {imu}')
        if self._fault_client is not None and not self._fault_client.services_are_ready():
            return 'its parameter service (for the fault schedule) is not up yet'
        if not self.imu_received:
            return f'its first {imu} sample has not come yet'
        return None

    def connected(self):
        """Return True once the emulator runs: on the graph, serving, its first sample in."""
        return self.missing() is None

    def last_step_in(self):
        """Return True once a collected Imu is stamped at or after the profile's end."""
        end_ns = self.start_ns + self._ends[-1]
        return self.newest_imu_ns is not None and self.newest_imu_ns >= end_ns

    def faults_settled(self):
        """Return True once the node has answered every fault sent."""
        return all(future.done() for future in self._fault_futures)

    def _send_faults(self, elapsed_s):
        """Send each scheduled fault once its time has come (FAULT_LEAD_S ahead)."""
        schedule = self.profile.faults
        while self._fault_next < len(schedule):
            index = self._fault_next
            fault = schedule[index]
            send_at = fault.start_s - FAULT_LEAD_S
            if index:
                send_at = max(send_at, schedule[index - 1].end_s + FAULT_MARGIN_S)
            if elapsed_s < send_at:
                return
            self._set_fault(fault.kind, fault.axis, fault.magnitude,
                            max(0.0, fault.start_s - elapsed_s), fault.duration_s)
            self.faults_sent.append(fault)
            self._fault_next += 1

    def _set_fault(self, kind, axis, magnitude, start_s, duration_s):
        values = (('fault.type', kind), ('fault.axis', axis), ('fault.magnitude', magnitude),
                  ('fault.start_s', start_s), ('fault.duration_s', duration_s))
        future = self._fault_client.set_parameters_atomically(
            [Parameter(name, value=value) for name, value in values])
        self._fault_futures.append(future)

        def check(done):
            result = done.result()
            if result is not None and not result.result.successful:
                self.fault_errors.append(f'fault {kind}: {result.result.reason}')
        future.add_done_callback(check)

    def start(self):
        """Begin the first step now and publish every 1 / publish_rate_hz."""
        self.start_ns = self.node.get_clock().now().nanoseconds
        self._publish()
        self._timer = self.node.create_timer(1.0 / self.profile.publish_rate_hz,
                                             self._publish)

    def current_step(self, now_ns):
        """Return the index of the step in force at ``now_ns`` (None after the end)."""
        elapsed = now_ns - self.start_ns
        if self.loop:
            elapsed %= self._ends[-1]
        for index, end in enumerate(self._ends):
            if elapsed < end:
                return index
        return None

    def _publish(self):
        now_ns = self.node.get_clock().now().nanoseconds
        index = self.current_step(now_ns)
        if self._fault_client is not None:
            self._send_faults((now_ns - self.start_ns) / NS_PER_S)
        if index is None:
            self.done = True
            self._timer.cancel()
            schedule = self.profile.faults
            if schedule and schedule[-1].duration_s == 0.0:
                self._set_fault('none', 'all', 0.0, 0.0, 0.0)
            return
        step = self.profile.steps[index]
        stamp = self.node.get_clock().now().to_msg()
        msg = self._rate_msg
        msg.header.stamp = stamp
        ax = self.profile.axis
        rate = self.profile.rate_along_axis_rad_s(step)
        msg.vector.x, msg.vector.y, msg.vector.z = (a * rate for a in ax)
        self.rate_pub.publish(msg)
        temp = self._temp_msg
        temp.header.stamp = stamp
        temp.temperature = step.temp_start_c
        self.temp_pub.publish(temp)

    def results(self):
        """Return the per-step :class:`StepResult` list of what was collected."""
        return summarize(self.profile, self.start_ns, self.imu, self.temps)

    @property
    def interrupted(self):
        """One line saying where the profile was stopped, or None when it ran to its end."""
        if self.stop_ns is None:
            return None
        return interruption_note(self.profile, self.start_ns, self.stop_ns)


def play(profile, collect=True, wait_s=120.0, loop=False, progress=None, args=None,
         waiting=None):
    """
    Run a profile against a running emulator in a fresh rclpy context.

    Parameters
    ----------
    profile : gyro_emulator.emulation.scenario.Scenario
        What to play.
    collect : bool
        Collect the emulator's output for the summary.
    wait_s : float
        Longest wait for the emulator (on the graph, then its first sample), s.
    loop : bool
        Repeat forever (until SIGINT).
    progress : callable or None
        Called with (step index, step: a constant Segment) when a step begins.
    args : list of str or None
        ROS arguments (e.g. ``['--ros-args', '-r', '__ns:=/gyro']``).
    waiting : callable or None
        Called with (seconds waited, what is missing) about every
        :data:`WAITING_REPORT_S` while the player waits for the emulator;
        it may raise RuntimeError to stop waiting (its emulator process died).

    Returns
    -------
    ScenarioPlayer
        With ``results()`` for the summary. Raises RuntimeError when the
        emulator is not running within ``wait_s``.

    """
    context = rclpy.Context()
    # SIGINT/SIGTERM only set a flag, read between spins (flag_signals)
    rclpy.init(args=args, context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('gyro_scenario', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    player = ScenarioPlayer(node, profile, collect=collect, loop=loop)
    stop = SignalFlag()
    previous = flag_signals(stop)
    try:
        _wait_for_emulator(player, executor, stop, wait_s, waiting)
        player.imu.clear()                  # what came before the first step
        player.temps.clear()
        player.start()
        shown = None
        while not player.done:
            _spin(executor, stop)
            index = player.current_step(node.get_clock().now().nanoseconds)
            if progress is not None and index is not None and index != shown:
                shown = index
                progress(index, profile.steps[index])
        if collect:
            _drain(player, executor, stop)
        deadline = time.monotonic() + 2.0
        while not player.faults_settled() and time.monotonic() < deadline:
            if stop.is_set() or not spin_once(executor, 0.05):
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        if not player.done:
            player.stop_ns = _now_ns(node)
        player.done = True
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    return player


def _wait_for_emulator(player, executor, stop, wait_s, waiting):
    """Spin until the emulator runs (:meth:`ScenarioPlayer.connected`); RuntimeError at wait_s."""
    began = time.monotonic()
    next_report = began + WAITING_REPORT_S
    while True:
        missing = player.missing()
        if missing is None:
            return
        now = time.monotonic()
        if now - began > wait_s:
            raise RuntimeError(
                f'no emulator within {wait_s:g} s: {missing} (is `ros2 run '
                f'gyro_emulator node` running on ROS_DOMAIN_ID='
                f'{os.environ.get("ROS_DOMAIN_ID", "0")}?)')
        if waiting is not None and now >= next_report:
            next_report += WAITING_REPORT_S
            waiting(now - began, missing)
        _spin(executor, stop)


def _drain(player, executor, stop):
    """Spin until the last step's samples are in (``last_step_in``), at most DRAIN_S."""
    deadline = time.monotonic() + DRAIN_S
    while not player.last_step_in() and time.monotonic() < deadline:
        _spin(executor, stop)


def _spin(executor, stop):
    """Spin once; raise KeyboardInterrupt on a signal, ExternalShutdownException once shut down."""
    if stop.is_set():
        raise KeyboardInterrupt
    if not spin_once(executor, 0.05):
        raise ExternalShutdownException()


def _now_ns(node):
    """Return the node's clock (the profile's time base), or the system clock once it is gone."""
    try:
        return node.get_clock().now().nanoseconds
    except Exception:           # the context is shut down: ROS time is system time then
        return time.time_ns()


def build_parser():
    """Return the ``scenario`` argument parser."""
    parser = argparse.ArgumentParser(
        prog='ros2 run gyro_emulator scenario',
        description='Play a rate/temperature profile onto the emulator cmd/ topics.')
    parser.add_argument('profile', nargs='?', default=None,
                        help='profile YAML (default: the paper validation profile)')
    parser.add_argument('--summary', action='store_true',
                        help='collect imu/data_raw and print commanded vs measured')
    parser.add_argument('--json', metavar='FILE', help='write the summary as JSON (checked '
                        'before the run: never the profile, an existing file only with '
                        '--overwrite; written whole or not at all)')
    parser.add_argument('--overwrite', action='store_true', help='replace an existing --json')
    parser.add_argument('--loop', action='store_true', help='repeat until Ctrl-C')
    parser.add_argument('--wait', type=float, default=120.0, metavar='S',
                        help='longest wait for the emulator node and its first sample '
                             '(default: %(default)s s)')
    return parser


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def waiting_printer(prefix, limit_s, every_s, stream=sys.stdout):
    """
    Return a ``waiting`` callback for :func:`play` that prints a line every ``every_s``.

    The line: ``<prefix>: waiting for the emulator node (12 s, at most 120 s): <what
    is missing>``.
    """
    said = [0]

    def waiting(elapsed_s, missing):
        if elapsed_s >= (said[0] + 1) * every_s:
            said[0] = int(elapsed_s // every_s)
            print(f'{prefix}: waiting for the emulator node ({elapsed_s:.0f} s, at most '
                  f'{limit_s:g} s): {missing}', file=stream, flush=True)
    return waiting


def main(args=None):
    """Entry point of ``ros2 run gyro_emulator scenario``; returns the exit status."""
    argv = sys.argv[1:] if args is None else list(args)
    opts = build_parser().parse_args(remove_ros_args(['scenario'] + argv)[1:])
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        return _run(opts, argv)
    finally:
        signal.signal(signal.SIGTERM, previous)     # a caller in-process keeps its own


def _run(opts, argv):
    """Play the scenario of the parsed options; return the exit status (see :func:`main`)."""
    try:
        if not 0.0 <= opts.wait < math.inf:
            raise ValueError(f'--wait = {opts.wait:g} is out of range: allowed [0, inf) s')
        outputs.check([outputs.file('--json', opts.json)], inputs=[opts.profile],
                      overwrite=opts.overwrite)
        profile = load_scenario(opts.profile)
        print(f'scenario {profile.name}: {len(profile.steps)} steps, '
              f'{profile.duration_s:g} s', flush=True)

        def progress(index, step):
            print(f'  step {index}: {step.label} at {step.temp_start_c:g} C for '
                  f'{step.duration_s:g} s', flush=True)

        player = play(profile, collect=opts.summary or bool(opts.json), wait_s=opts.wait,
                      loop=opts.loop, progress=progress, args=['scenario'] + argv,
                      waiting=waiting_printer('scenario', opts.wait, WAITING_LINE_S))
    except (ValueError, RuntimeError, OSError) as exc:
        print(f'scenario: error: {exc}', file=sys.stderr)
        return 2
    for fault in player.faults_sent:
        print(f'  fault injected: {fault.describe()}', flush=True)
    for error in player.fault_errors:
        print(f'scenario: warning: the node refused {error}', file=sys.stderr)
    if player.interrupted:
        print(f'scenario: {player.interrupted}', flush=True)
    if opts.summary or opts.json:
        results = player.results()
        print(format_summary(results))
        if opts.json:
            try:
                atomic.write_json(opts.json, results_json(profile, results, player.interrupted),
                                  indent=1)
            except OSError as exc:
                print(f'scenario: error: {exc}', file=sys.stderr)
                return 2
        missing = unmeasured(results)
        if missing:
            print(f'scenario: error: {missing}', file=sys.stderr)
            return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
