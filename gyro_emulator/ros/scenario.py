"""
``ros2 run gyro_emulator scenario [PROFILE]``: play a rate/temperature profile.

A scenario is a YAML file of constant-input steps, written in the one
segment schema of :mod:`gyro_emulator.sensor.profiles` (a number as a rate
is along ``axis``). It publishes the step's
true rate on ``cmd/angular_velocity`` (geometry_msgs/Vector3Stamped, rad/s
along ``axis``) and its ambient temperature on ``cmd/temperature``
(sensor_msgs/Temperature) at ``publish_rate_hz``, so a lost message is
repaired at the next period. With ``--summary`` it also listens to
``imu/data_raw`` and ``imu/temperature`` and prints, per step, the commanded
and measured rate and the error in deg/s, averaged after ``settle_s``.

Profile keys (SI unless the name says otherwise)::

    name: paper_validation
    axis: [0.0, 0.0, 1.0]        # rate direction in the sensor frame
    publish_rate_hz: 50.0
    grid:                        # every rate at every temperature ...
      temps_c: [25.0, 45.0, 65.0, 85.0]
      rates_rpm: [0.0, 10.0, 20.0, 40.0]   # or rates_deg_s / rates_rad_s
      hold_s: 2.0                # duration of each step
      settle_s: 0.8              # start of each step left out of the summary
    segments:                    # ... and/or explicit steps, played after
      - {duration_s: 2.0, rate_deg_s: 60.0, temp_c: 25.0, settle_s: 0.5}
    node_parameters: {}          # parameters a runner should give the node
    faults:                      # injected while playing (sensor.faults schema)
      - {type: bias_step, axis: z, magnitude: 0.01, start_s: 3.0, duration_s: 1.0}

``node_parameters`` is what makes a compressed profile meaningful (e.g. a
short die thermal time constant); ``gyro_emulator.cli.main_job`` passes it on.
``faults`` is a fault schedule, times from the start of the profile: the
player sets the node's ``fault.*`` parameters through its parameter service
(atomically) up to :data:`FAULT_LEAD_S` ahead, with ``fault.start_s`` the
time left, so each fault starts on the node's clock within the latency of
that call. A fault replaces the one before, so it is sent no earlier than
:data:`FAULT_MARGIN_S` after that one ends (a fault that follows closer
starts that much late). After a last fault without an end the player clears
it.
"""

import argparse
from dataclasses import dataclass
import math
import os
import signal
import sys
import time
import warnings

from gyro_emulator.recording import topics
from gyro_emulator.resources import config_file, read_yaml
from gyro_emulator.ros.spinning import spin_once
from gyro_emulator.sensor import faults, profiles
from gyro_emulator.units import NS_PER_S

DEFAULT_PROFILE = 'scenario_paper_validation.yaml'
#: How a step's label writes the unit of each rate key of the segment schema.
RATE_LABELS = {'rate_rad_s': 'rad/s', 'rate_deg_s': 'deg/s', 'rate_rpm': 'RPM'}
#: How far ahead of its start a scheduled fault is sent to the node, s.
FAULT_LEAD_S = 0.5
#: How long after the previous fault's end the next is sent (it replaces it), s.
FAULT_MARGIN_S = 0.1


@dataclass(frozen=True)
class Step:
    """
    One constant-input step of a scenario: a constant :class:`Segment` along the axis.

    Attributes
    ----------
    duration_s : float
        Length of the step, s.
    rate_rad_s : float
        True rate along the profile axis, rad/s.
    temp_c : float
        Ambient temperature, deg C.
    settle_s : float
        Start of the step excluded from the summary, s.
    label : str
        Human-readable rate as written in the profile (e.g. ``10 RPM``).

    """

    duration_s: float
    rate_rad_s: float
    temp_c: float
    settle_s: float = 0.0
    label: str = ''

    @classmethod
    def from_segment(cls, where, segment, axis, label):
        """Return the step of a segment that holds its rate and temperature."""
        if segment.rate_start_rad_s != segment.rate_end_rad_s or \
                segment.temp_start_c != segment.temp_end_c:
            raise ValueError(f'{where}: a scenario step holds its rate and temp_c: give '
                             'numbers, not [start, end] ramps')
        return cls(segment.duration_s, sum(a * r for a, r in zip(axis, segment.rate_start_rad_s)),
                   segment.temp_start_c, segment.settle_s, label)


@dataclass(frozen=True)
class Profile:
    """A parsed profile: name, unit axis, publish rate, steps, node parameters, faults."""

    name: str
    axis: tuple
    publish_rate_hz: float
    steps: tuple
    node_parameters: dict
    faults: tuple = ()

    @property
    def duration_s(self):
        """Total length of the profile, s."""
        return sum(step.duration_s for step in self.steps)


def _number(where, key, value, low=None, high=None, low_open=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value):
        raise ValueError(f'{where}.{key} = {value!r} is not a finite number')
    if (low is not None and (value <= low if low_open else value < low)) or (
            high is not None and value > high):
        lo = '-inf' if low is None else f'{low:g}'
        hi = 'inf' if high is None else f'{high:g}'
        raise ValueError(f'{where}.{key} = {value!r} is out of range: allowed '
                         f'{"(" if low_open else "["}{lo}, {hi}]')
    return float(value)


def _rate(where, mapping, plural=False):
    names = {('rates_' + k[5:] if plural else k): k for k in profiles.RATE_UNITS}
    found = [n for n in names if n in mapping]
    if len(found) != 1:
        raise ValueError(f'{where}: give exactly one of {", ".join(names)}')
    return found[0], names[found[0]]


def _step(where, raw, axis):
    """Parse one step with the shared segment schema (``sensor.profiles.parse_segment``)."""
    if not isinstance(raw, dict):
        raise ValueError(f'{where} = {raw!r} must be a mapping')
    raw = profiles.canonical_segment(where, raw)
    key = _rate(where, raw)[0]
    value = _number(where, key, raw[key])
    if 'temp_c' not in raw:
        raise ValueError(f'{where}.temp_c = None is not a finite number')
    if 'duration_s' in raw:
        _number(where, 'duration_s', raw['duration_s'], 0.0, 86400.0, True)
    segment = profiles.parse_segment(where, raw, axis)
    return Step.from_segment(where, segment, axis, f'{value:g} {RATE_LABELS[key]}')


def _grid(where, raw, axis):
    if not isinstance(raw, dict):
        raise ValueError(f'{where} = {raw!r} must be a mapping')
    plural, key = _rate(where, raw, plural=True)
    raw = dict(raw)
    if 'temperatures_c' in raw and 'temps_c' not in raw:
        warnings.warn(f'{where}: temperatures_c is deprecated, write temps_c',
                      DeprecationWarning, stacklevel=3)
        raw['temps_c'] = raw.pop('temperatures_c')
    allowed = {'temps_c', 'hold_s', 'settle_s', plural}
    unknown = sorted(set(raw) - allowed)
    if unknown:
        raise ValueError(f'{where}: unknown key(s) {", ".join(unknown)}; allowed: '
                         f'{", ".join(sorted(allowed))}')
    temps, rates = raw.get('temps_c'), raw[plural]
    for name, values in (('temps_c', temps), (plural, rates)):
        if not isinstance(values, list) or not values:
            raise ValueError(f'{where}.{name} = {values!r} must be a non-empty list')
    hold = raw.get('hold_s')
    steps = []
    for temp in temps:
        for rate in rates:
            steps.append(_step(f'{where}[T={temp}, {plural}={rate}]', {
                'duration_s': hold, key: rate, 'temp_c': temp,
                'settle_s': raw.get('settle_s', 0.0)}, axis))
    return steps


def parse_profile(doc, source='profile'):
    """
    Build a :class:`Profile` from a parsed YAML mapping.

    Raises ValueError naming the key, the value and the allowed range.
    """
    if not isinstance(doc, dict):
        raise ValueError(f'{source}: expected a mapping, got {doc!r}')
    allowed = {'name', 'description', 'axis', 'publish_rate_hz', 'grid', 'segments',
               'node_parameters', 'faults'}
    unknown = sorted(set(doc) - allowed)
    if unknown:
        raise ValueError(f'{source}: unknown key(s) {", ".join(unknown)}; allowed: '
                         f'{", ".join(sorted(allowed))}')
    axis = profiles.unit_axis(source, doc.get('axis', list(profiles.DEFAULT_AXIS)))
    rate_hz = _number(source, 'publish_rate_hz', doc.get('publish_rate_hz', 50.0),
                      0.0, 1000.0, True)
    steps = []
    if 'grid' in doc:
        steps += _grid(f'{source}.grid', doc['grid'], axis)
    segments = doc.get('segments', [])
    if not isinstance(segments, list):
        raise ValueError(f'{source}.segments = {segments!r} must be a list')
    steps += [_step(f'{source}.segments[{i}]', s, axis) for i, s in enumerate(segments)]
    if not steps:
        raise ValueError(f'{source}: no steps (give grid and/or segments)')
    node_parameters = doc.get('node_parameters') or {}
    if not isinstance(node_parameters, dict):
        raise ValueError(f'{source}.node_parameters = {node_parameters!r} must be a mapping')
    schedule = faults.parse_schedule(f'{source}.faults', doc.get('faults'))
    return Profile(str(doc.get('name', os.path.basename(str(source)))),
                   axis, rate_hz, tuple(steps),
                   dict(node_parameters), schedule)


def default_profile_path():
    """Return the shipped paper-validation profile (see ``resources.config_dir``)."""
    return config_file(DEFAULT_PROFILE)


def load_scenario(path=None):
    """Read and parse a scenario YAML (default: the paper validation scenario)."""
    path = default_profile_path() if path is None else path
    return parse_profile(read_yaml(path), path)


# --- the summary -----------------------------------------------------------

@dataclass(frozen=True)
class StepResult:
    """Commanded vs measured for one step (rates along the axis, deg/s)."""

    step: Step
    commanded_deg_s: float
    measured_deg_s: float
    std_deg_s: float
    die_temp_c: float
    samples: int

    @property
    def error_deg_s(self):
        """Measured minus commanded rate, deg/s."""
        return self.measured_deg_s - self.commanded_deg_s


def summarize(profile, start_ns, imu, temps):
    """
    Average the output over each step's measurement window.

    Parameters
    ----------
    profile : Profile
        The profile that was played.
    start_ns : int
        Clock time at which the first step began, ns.
    imu : list of (int, tuple)
        (stamp ns, angular velocity (x, y, z) rad/s) of every Imu received.
    temps : list of (int, float)
        (stamp ns, die temperature deg C) of every Temperature received.

    Returns
    -------
    list of StepResult

    """
    import numpy as np

    stamps = np.array([s for s, _ in imu], dtype=np.int64)
    along = np.array([sum(a * w for a, w in zip(profile.axis, v)) for _, v in imu])
    t_stamps = np.array([s for s, _ in temps], dtype=np.int64)
    t_values = np.array([v for _, v in temps])
    results = []
    begin = start_ns
    for step in profile.steps:
        lo = begin + int(step.settle_s * 1e9)
        hi = begin + int(step.duration_s * 1e9)
        begin = hi
        sel = along[(stamps >= lo) & (stamps < hi)] if len(stamps) else along
        tsel = t_values[(t_stamps >= lo) & (t_stamps < hi)] if len(t_stamps) else t_values
        measured = float(np.degrees(sel.mean())) if len(sel) else float('nan')
        std = float(np.degrees(sel.std())) if len(sel) > 1 else float('nan')
        results.append(StepResult(
            step, math.degrees(step.rate_rad_s), measured, std,
            float(tsel.mean()) if len(tsel) else float('nan'), int(len(sel))))
    return results


def format_summary(results):
    """Return the summary table as text (one row per step)."""
    head = (f'{"step":>4} {"T_amb C":>8} {"T_die C":>8} {"rate":>10} {"cmd deg/s":>10} '
            f'{"meas deg/s":>11} {"err deg/s":>10} {"std deg/s":>10} {"n":>6}')
    lines = [head, '-' * len(head)]
    for i, r in enumerate(results):
        lines.append(
            f'{i:>4} {r.step.temp_c:>8.1f} {r.die_temp_c:>8.2f} '
            f'{r.step.label:>10} {r.commanded_deg_s:>10.3f} {r.measured_deg_s:>11.3f} '
            f'{r.error_deg_s:>+10.3f} {r.std_deg_s:>10.3f} {r.samples:>6d}')
    return '\n'.join(lines)


def results_json(profile, results):
    """Return the summary as a JSON-ready dict."""
    return {'profile': profile.name, 'axis': list(profile.axis), 'steps': [
        {'temperature_c': r.step.temp_c, 'rate': r.step.label,
         'commanded_deg_s': r.commanded_deg_s, 'measured_deg_s': r.measured_deg_s,
         'error_deg_s': r.error_deg_s, 'std_deg_s': r.std_deg_s,
         'die_temp_c': r.die_temp_c, 'samples': r.samples} for r in results]}


# --- the ROS side ----------------------------------------------------------

class ScenarioPlayer:
    """
    Publish a profile's commands from an rclpy node; optionally collect output.

    Parameters
    ----------
    node : rclpy.node.Node
        The node that owns publishers, subscriptions and the timer.
    profile : Profile
        What to play.
    collect : bool
        Subscribe to imu/data_raw and imu/temperature for :func:`summarize`.
    loop : bool
        Start over at the end instead of finishing.

    """

    def __init__(self, node, profile, collect=False, loop=False):
        from gyro_emulator.ros.codec import topic_class, topic_qos

        self.node = node
        self.profile = profile
        self.loop = loop
        self.rate_pub, self.temp_pub = (
            node.create_publisher(topic_class(topic), topic.name, topic_qos(topic))
            for topic in (topics.RATE_CMD, topics.TEMPERATURE_CMD))
        self._rate_msg = topic_class(topics.RATE_CMD)()
        self._temp_msg = topic_class(topics.TEMPERATURE_CMD)()
        self.imu, self.temps = [], []
        if collect:
            for topic, handler in ((topics.IMU_OUT, self._on_imu),
                                   (topics.DIE_TEMPERATURE_OUT, self._on_temp)):
                node.create_subscription(topic_class(topic), topic.name, handler,
                                         topic_qos(topic))
        self.start_ns = None
        self.done = False
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
            from rclpy.parameter_client import AsyncParameterClient
            self._fault_client = AsyncParameterClient(node, topics.NODE_NAME)

    def _on_imu(self, msg):
        v = msg.angular_velocity
        s = msg.header.stamp
        self.imu.append((s.sec * NS_PER_S + s.nanosec, (v.x, v.y, v.z)))

    def _on_temp(self, msg):
        s = msg.header.stamp
        self.temps.append((s.sec * NS_PER_S + s.nanosec, msg.temperature))

    def connected(self):
        """Return True once the emulator subscribes to both commands (and serves parameters)."""
        return self.rate_pub.get_subscription_count() > 0 and \
            self.temp_pub.get_subscription_count() > 0 and (
                self._fault_client is None or self._fault_client.services_are_ready())

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
        from rclpy.parameter import Parameter

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
        msg.vector.x, msg.vector.y, msg.vector.z = (a * step.rate_rad_s for a in ax)
        self.rate_pub.publish(msg)
        temp = self._temp_msg
        temp.header.stamp = stamp
        temp.temperature = step.temp_c
        self.temp_pub.publish(temp)

    def results(self):
        """Return the per-step :class:`StepResult` list of what was collected."""
        return summarize(self.profile, self.start_ns, self.imu, self.temps)


def play(profile, collect=True, wait_s=20.0, loop=False, progress=None, args=None):
    """
    Run a profile against a running emulator in a fresh rclpy context.

    Parameters
    ----------
    profile : Profile
        What to play.
    collect : bool
        Collect the emulator's output for the summary.
    wait_s : float
        How long to wait for the emulator to subscribe, s.
    loop : bool
        Repeat forever (until SIGINT).
    progress : callable or None
        Called with (step index, Step) when a step begins.
    args : list of str or None
        ROS arguments (e.g. ``['--ros-args', '-r', '__ns:=/gyro']``).

    Returns
    -------
    ScenarioPlayer
        With ``results()`` for the summary. Raises RuntimeError when the
        emulator never subscribes.

    """
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    context = rclpy.Context()
    rclpy.init(args=args, context=context)
    node = rclpy.create_node('gyro_scenario', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    player = ScenarioPlayer(node, profile, collect=collect, loop=loop)
    try:
        deadline = time.monotonic() + wait_s
        while not player.connected():
            if time.monotonic() > deadline:
                raise RuntimeError(
                    f'no emulator subscribed to {topics.RATE_CMD.name} and '
                    f'{topics.TEMPERATURE_CMD.name} (and served its parameters, for a '
                    f'fault schedule) within {wait_s:g} s (is '
                    f'`ros2 run gyro_emulator node` running on '
                    f'ROS_DOMAIN_ID={os.environ.get("ROS_DOMAIN_ID", "0")}?)')
            if not spin_once(executor, 0.05):
                raise ExternalShutdownException()
        if collect:
            deadline = time.monotonic() + wait_s
            while not player.imu and time.monotonic() < deadline:
                if not spin_once(executor, 0.05):
                    raise ExternalShutdownException()
        player.start()
        shown = None
        while not player.done:
            if not spin_once(executor, 0.05):
                raise ExternalShutdownException()
            index = player.current_step(node.get_clock().now().nanoseconds)
            if progress is not None and index is not None and index != shown:
                shown = index
                progress(index, profile.steps[index])
        deadline = time.monotonic() + 2.0
        while not player.faults_settled() and time.monotonic() < deadline:
            if not spin_once(executor, 0.05):
                break
    except (KeyboardInterrupt, ExternalShutdownException):
        player.done = True
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return player


def build_parser():
    """Return the ``scenario`` argument parser."""
    parser = argparse.ArgumentParser(
        prog='ros2 run gyro_emulator scenario',
        description='Play a rate/temperature profile onto the emulator cmd/ topics.')
    parser.add_argument('profile', nargs='?', default=None,
                        help='profile YAML (default: the paper validation profile)')
    parser.add_argument('--summary', action='store_true',
                        help='collect imu/data_raw and print commanded vs measured')
    parser.add_argument('--json', metavar='FILE', help='write the summary as JSON')
    parser.add_argument('--loop', action='store_true', help='repeat until Ctrl-C')
    parser.add_argument('--wait', type=float, default=20.0, metavar='S',
                        help='how long to wait for the emulator (default: %(default)s s)')
    return parser


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main(args=None):
    """Entry point of ``ros2 run gyro_emulator scenario``; returns the exit status."""
    from rclpy.utilities import remove_ros_args

    argv = sys.argv[1:] if args is None else list(args)
    opts = build_parser().parse_args(remove_ros_args(['scenario'] + argv)[1:])
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        profile = load_scenario(opts.profile)
        print(f'scenario {profile.name}: {len(profile.steps)} steps, '
              f'{profile.duration_s:g} s', flush=True)

        def progress(index, step):
            print(f'  step {index}: {step.label} at {step.temp_c:g} C for '
                  f'{step.duration_s:g} s', flush=True)

        player = play(profile, collect=opts.summary or bool(opts.json), wait_s=opts.wait,
                      loop=opts.loop, progress=progress, args=['scenario'] + argv)
    except (ValueError, RuntimeError, OSError) as exc:
        print(f'scenario: error: {exc}', file=sys.stderr)
        return 2
    for fault in player.faults_sent:
        print(f'  fault injected: {fault.describe()}', flush=True)
    for error in player.fault_errors:
        print(f'scenario: warning: the node refused {error}', file=sys.stderr)
    if opts.summary or opts.json:
        results = player.results()
        print(format_summary(results))
        if opts.json:
            import json
            with open(opts.json, 'w', encoding='utf-8') as handle:
                json.dump(results_json(profile, results), handle, indent=1)
    return 0


if __name__ == '__main__':
    sys.exit(main())
