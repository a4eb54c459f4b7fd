"""
``recorder``: record ROS 2 topics into a rosbag2-compatible MCAP bag.

``ros2 run gyro_emulator recorder -o DIR [--topics T ...] [--regex RE] [--all]``

Subscribes to the requested topics as they appear in the graph, with the
type and QoS their publishers offer (reliable only if every publisher is,
transient-local likewise, as rosbag2 adapts), and writes the serialised
messages untouched (``raw=True`` subscriptions: no deserialisation).
``log_time`` is the node clock at reception (sim time under
``use_sim_time``); ``publish_time`` is the middleware's source timestamp.

By default it records the emulator's inputs and outputs: ``cmd/angular_velocity``,
``cmd/temperature``, ``cmd/linear_acceleration``, ``imu/data_raw``,
``imu/temperature``, ``/diagnostics`` and every topic under the emulator
node's ``~/truth`` namespace. Its ``custom_data`` says that
``cmd/linear_acceleration`` is the applied acceleration, gravity excluded, as
the node takes it (``cmd_linear_acceleration: applied``,
:data:`gyro_emulator.recording.topics.ACCEL_CMD_MEANING`).

Crash safety: chunks are flushed at least every ``--flush-interval`` seconds
(a timer flushes even when messages stop), so SIGKILL loses at most that much;
SIGINT and SIGTERM finish the bag (summary, footer, metadata.yaml).

A write error (a full disk, a file-size limit) ends the run with one line
``recorder: error: cannot write ...`` and exit status 2; every chunk flushed
before it stays in the bag, which ``gyro-emulator bag repair`` finishes.
"""

import argparse
import datetime
import functools
import os
import re
import signal
import sys
import time

from gyro_emulator import outputs
from gyro_emulator.recording import bag, topics
from gyro_emulator.ros import codec, program
from gyro_emulator.ros.spinning import first_line, spin_once
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

#: The emulator's inputs and outputs, relative to the recorder's namespace.
DEFAULT_TOPICS = tuple(t.name for t in topics.RECORDED_BY_DEFAULT)
#: Name of the emulator node whose ``~/truth`` topics are recorded by default.
DEFAULT_EMULATOR_NODE = topics.NODE_NAME
#: The private namespace of the truth topics (``~/truth``).
TRUTH_PRIVATE_NAMESPACE = topics.TRUTH_RATE.name.rsplit('/', 1)[0]
#: How often the graph is searched for new topics, s.
DISCOVERY_PERIOD_S = 0.5
#: Options in seconds: flag -> (default, help).
SECONDS_OPTIONS = {
    '--duration': (None, 'stop after S seconds (default: until SIGINT/SIGTERM)'),
    '--flush-interval': (bag.DEFAULT_FLUSH_INTERVAL_S, 'flush to disk at least every S '
                         'seconds: what a SIGKILL can lose (default: %(default)s)'),
}


def adapted_qos(publisher_profiles, depth=100):
    """
    Return a subscription QoS compatible with every offered profile.

    Reliable only if all publishers are reliable, transient-local only if
    all are (rosbag2's adaptive QoS); keep-last ``depth``.

    Parameters
    ----------
    publisher_profiles : list of rclpy.qos.QoSProfile
        Profiles of the topic's publishers.
    depth : int
        Subscription history depth.

    """
    reliable = bool(publisher_profiles) and all(
        p.reliability == ReliabilityPolicy.RELIABLE for p in publisher_profiles)
    transient = bool(publisher_profiles) and all(
        p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in publisher_profiles)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE)


class TopicRecorder:
    """
    Subscribe a node to topics as they appear and write them into a bag.

    Parameters
    ----------
    node : rclpy.node.Node
        The node that owns the subscriptions and timers.
    writer : gyro_emulator.recording.bag.BagWriter
        Destination bag.
    topics : iterable of str
        Fully resolved topic names to record.
    regexes : iterable of str
        Also record topics whose resolved name matches one of these.
    record_all : bool
        Record every topic (except ``/rosout`` and parameter events).
    exclude : iterable of str
        Never record these resolved topic names.

    """

    IGNORED = ('/rosout', '/parameter_events')

    def __init__(self, node, writer, topics=(), regexes=(), record_all=False, exclude=()):
        self.node = node
        self.writer = writer
        self.topics = set(topics)
        self.regexes = [re.compile(r) for r in regexes]
        self.record_all = record_all
        self.exclude = set(exclude)
        self.subscriptions = {}
        self.counts = {}
        self.failed = False
        self._last_discovery = -1e9
        self._timer = node.create_timer(0.1, self._tick)
        self.discover()

    def wanted(self, name):
        """Return True if topic ``name`` should be recorded."""
        if name in self.exclude or name in self.subscriptions:
            return False
        if name in self.topics:
            return True
        if any(r.search(name) for r in self.regexes):
            return True
        return self.record_all and name not in self.IGNORED

    def _tick(self):
        try:
            self.writer.flush_if_due()
        except OSError as exc:
            self.failed = True
            raise _write_error(self.writer, exc) from None
        now = time.monotonic()
        if now - self._last_discovery >= DISCOVERY_PERIOD_S:
            self.discover()

    def discover(self):
        """Subscribe to every wanted topic that has a publisher now."""
        self._last_discovery = time.monotonic()
        for name, types in self.node.get_topic_names_and_types():
            if not self.wanted(name):
                continue
            if len(types) != 1:
                self.node.get_logger().warning(
                    f'not recording {name}: it has several types {types}')
                self.exclude.add(name)
                continue
            publishers = self.node.get_publishers_info_by_topic(name)
            if not publishers:
                continue
            type_name = types[0]
            try:
                msg_class = codec.message_class(type_name)
                profiles = [p.qos_profile for p in publishers]
                cid = self.writer.add_topic(
                    name, type_name,
                    qos_profiles=[codec.qos_to_profile(p) for p in profiles])
            except ValueError as exc:
                self.node.get_logger().warning(f'not recording {name}: {exc}')
                self.exclude.add(name)
                continue
            self.counts[name] = 0
            self.subscriptions[name] = self.node.create_subscription(
                msg_class, name, functools.partial(self._on_message, name, cid),
                adapted_qos(profiles), raw=True)
            self.node.get_logger().info(f'recording {name} [{type_name}]')

    def _on_message(self, name, cid, data, info):
        log_time = self.node.get_clock().now().nanoseconds
        publish = None
        if isinstance(info, dict):
            publish = info.get('source_timestamp') or None
        try:
            self.writer.write(cid, data, log_time, publish)
        except OSError as exc:
            self.failed = True
            raise _write_error(self.writer, exc) from None
        self.counts[name] += 1


def _write_error(writer, exc):
    """Return the one-line OSError of a failed bag write (a full disk)."""
    return OSError(f'cannot write {writer.path} ({exc.strerror or exc}): recording '
                   f'stopped after {writer.message_count} messages; recover the bag with: '
                   f'gyro-emulator bag repair {writer.path}')


def default_output():
    """Return rosbag2's default bag name for now: ``rosbag2_YYYY_MM_DD-HH_MM_SS``."""
    return datetime.datetime.now().strftime('rosbag2_%Y_%m_%d-%H_%M_%S')


def check_output(path, overwrite):
    """
    Return ``path`` once it can take the bag; refuse it in one line with the options' words.

    An existing empty directory takes it; a non-empty one only with
    ``--overwrite`` (which replaces the bag's files in it), a file never
    (:func:`gyro_emulator.outputs.check`).
    """
    empty = os.path.isdir(path) and not os.listdir(path)
    outputs.check([outputs.directory('--output', path)], overwrite=overwrite or empty)
    return path


def build_parser():
    """Return the ``recorder`` argument parser."""
    parser = argparse.ArgumentParser(
        prog='recorder', description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('-o', '--output', default=None, metavar='DIR',
                        help='bag directory to create (default: rosbag2_<date-time>)')
    parser.add_argument('--topics', nargs='+', default=None, metavar='TOPIC',
                        help='topics to record (default: the emulator inputs, outputs '
                             'and truth); relative names resolve in the recorder namespace')
    parser.add_argument('-e', '--regex', action='append', default=[], metavar='RE',
                        help='also record topics whose name matches RE (repeatable)')
    parser.add_argument('-a', '--all', action='store_true', help='record every topic')
    parser.add_argument('-x', '--exclude', nargs='+', default=[], metavar='TOPIC',
                        help='never record these topics')
    parser.add_argument('--emulator-node', default=DEFAULT_EMULATOR_NODE, metavar='NAME',
                        help='emulator node whose ~/truth topics are recorded by default '
                             '(default: %(default)s)')
    parser.add_argument('--compression', choices=bag.COMPRESSIONS, default='zstd',
                        help='MCAP chunk compression (default: %(default)s)')
    program.add_seconds_options(parser, SECONDS_OPTIONS)
    parser.add_argument('--overwrite', action='store_true',
                        help='replace an existing bag in the output directory')
    return parser


def requested_topics(node, opts):
    """
    Return the resolved topics to record and the regular expressions to match.

    Without ``--topics``: :data:`DEFAULT_TOPICS` and every topic under the
    ``~/truth`` namespace of the ``--emulator-node``; a ``~/`` name is
    resolved in that node's namespace.
    """
    emulator_ns = f'{node.get_namespace().rstrip("/")}/{opts.emulator_node}'
    requested = DEFAULT_TOPICS if opts.topics is None else opts.topics
    regexes = list(opts.regex)
    if opts.topics is None:
        truth_ns = emulator_ns + TRUTH_PRIVATE_NAMESPACE[1:]
        regexes.append('^' + re.escape(truth_ns) + '(/|$)')
    names = [resolve_topic(node, emulator_ns + t[1:] if t.startswith('~') else t, t,
                           '--topics') for t in requested]
    return names, regexes


def resolve_topic(node, name, given, option):
    """
    Return ``name`` resolved by ``node``, or raise ValueError naming ``option`` and ``given``.

    rcl refuses a name that is not a ROS topic name (a space, a ``!``, a
    repeated ``/``, an unknown ``{substitution}``) with an RCLError, a
    RuntimeError.
    """
    try:
        return node.resolve_topic_name(name)
    except RuntimeError as exc:
        reason = first_line(exc).replace('failed to resolve name: ', '')
        raise ValueError(f'{option} = {given!r} is not a ROS topic name: {reason}') from None


def check_regexes(regexes):
    """Raise ValueError for a ``--regex`` that is not a Python regular expression."""
    for text in regexes:
        try:
            re.compile(text)
        except re.error as exc:
            raise ValueError(f'--regex = {text!r} is not a regular expression ({exc}): '
                             'allowed a Python re pattern') from None


def _finish(writer, recorder):
    """Finish the bag and say what it holds (a second signal must not interrupt it)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if writer is None:
        return
    try:
        writer.finish()
    except OSError as exc:
        if recorder is not None and recorder.failed:
            return                      # already said: the write that failed
        print(f'recorder: error: cannot finish {writer.path} ({exc.strerror or exc}); '
              f'recover the bag with: gyro-emulator bag repair {writer.path}',
              file=sys.stderr, flush=True)
        return
    counts = ', '.join(f'{k}: {v}' for k, v in sorted(recorder.counts.items())) \
        if recorder is not None else ''
    print(f'recorder: wrote {writer.message_count} messages to {writer.path}'
          f'{" (" + counts + ")" if counts else ""}', flush=True)


def main(args=None):
    """Run the recorder until SIGINT/SIGTERM or ``--duration``; finish the bag."""
    argv, opts = program.parse_arguments(build_parser(), 'recorder', args)
    with program.Run('recorder') as run:
        program.check_seconds('--duration', opts.duration, low_open=True)
        program.check_seconds('--flush-interval', opts.flush_interval, low_open=True,
                              high=bag.MAX_FLUSH_INTERVAL_S)
        check_regexes(opts.regex)
        output = check_output(opts.output or default_output(), opts.overwrite)
        rclpy.init(args=argv)
        writer = recorder = None
        run.on_exit(lambda: _finish(writer, recorder))
        node = run.node = Node('gyro_recorder')
        # Every name is checked before the bag exists: a refused one leaves no bag behind.
        names, regexes = requested_topics(node, opts)
        excluded = [resolve_topic(node, t, t, '--exclude') for t in opts.exclude]
        writer = bag.BagWriter(output, compression=opts.compression,
                               flush_interval_s=opts.flush_interval, overwrite=opts.overwrite,
                               custom_data={'recorder': 'gyro_emulator recorder',
                                            **topics.ACCEL_CMD_MEANING})
        recorder = TopicRecorder(node, writer, names, regexes, opts.all, excluded)
        node.get_logger().info(f'recording to {writer.path}; waiting for '
                               f'{", ".join(sorted(names))}')
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        deadline = None if opts.duration is None else time.monotonic() + opts.duration
        while (deadline is None or time.monotonic() < deadline) and \
                spin_once(executor, 0.1):
            pass
    return run.status


if __name__ == '__main__':
    sys.exit(main())
