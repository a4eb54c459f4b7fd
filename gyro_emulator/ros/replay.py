"""
``replay``: republish a bag's topics with their original timing.

``ros2 run gyro_emulator replay BAG [--rate R] [--loop] [--clock [HZ]]``

Each message is published, serialised bytes untouched, when the wall clock
reaches ``start + (log_time - first_log_time) / rate``; the QoS of each
publisher is the first profile recorded for its topic (``--reliable`` forces
reliable delivery). With ``--clock`` the bag time at the current instant,
``first_log_time + (now - start) * rate``, is published on ``/clock``
(rosgraph_msgs/Clock) at HZ, so nodes with ``use_sim_time`` follow the bag
(``--wait-for-subscribers`` then also waits for a ``/clock`` subscriber).
``--loop`` starts over at the end (the bag clock jumps back, as rosbag2 does).
During ``--delay`` the ``/clock`` holds the first instant replayed, so a node
that matched late still starts there (:meth:`Player.hold_clock`).

Bags the recorder could not finish (SIGKILL) are read tolerantly: what was
recovered is replayed and the loss is reported. A topic whose message type is
not installed is skipped with a warning (as ``ros2 bag play`` does) unless
``--topics`` names it: then it is a one-line error.

``cmd/linear_acceleration`` is the applied acceleration (gravity excluded):
the node adds gravity from its attitude. A bag written when that topic held
the specific force (its ``custom_data`` lacks ``cmd_linear_acceleration:
applied``) would have the node count gravity twice: replaying that topic is
refused with one line that names the ``--topics`` to replay instead
(:func:`check_accel_meaning`).
"""

import argparse
import sys
import time

from gyro_emulator.interrupts import SignalFlag
from gyro_emulator.recording import bag, topics as table
from gyro_emulator.ros import codec, program, spinning
from gyro_emulator.units import NS_PER_S
import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import InvalidTopicNameException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock

#: Longest single sleep while waiting for a message, s (keeps /clock and signals live).
MAX_SLEEP_S = 0.05
#: Options in seconds, each at least 0: flag -> (default, help).
SECONDS_OPTIONS = {
    '--start-offset': (0.0, 'skip the first S seconds of the bag'),
    '--delay': (0.0, 'wait S seconds before the first message (with --clock, /clock '
                'holds the first instant meanwhile)'),
    '--wait-for-subscribers': (0.0, 'wait up to S seconds until every publisher has a '
                               'subscriber'),
}


def build_parser():
    """Return the ``replay`` argument parser."""
    parser = argparse.ArgumentParser(
        prog='replay', description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('bag', metavar='BAG', help='bag directory or .mcap file')
    parser.add_argument('-r', '--rate', type=float, default=1.0,
                        help='playback speed factor (default: %(default)s)')
    parser.add_argument('-l', '--loop', action='store_true', help='start over at the end')
    parser.add_argument('--clock', nargs='?', type=float, const=40.0, default=None,
                        metavar='HZ', help='publish the bag time on /clock at HZ '
                        '(default when given: 40)')
    parser.add_argument('--topics', nargs='+', default=None, metavar='TOPIC',
                        help='only replay these topics (default: all)')
    parser.add_argument('--remap', nargs='+', default=[], metavar='FROM:=TO',
                        help='publish topic FROM as TO')
    program.add_seconds_options(parser, SECONDS_OPTIONS)
    parser.add_argument('--reliable', action='store_true',
                        help='publish reliably whatever QoS was recorded')
    return parser


def _check(opts):
    if not opts.rate > 0 or opts.rate > 1000:
        raise ValueError(f'--rate = {opts.rate} is out of range: allowed (0, 1000]')
    if opts.clock is not None and not 0 < opts.clock <= 10000:
        raise ValueError(f'--clock = {opts.clock} is out of range: allowed (0, 10000] Hz')
    for flag in SECONDS_OPTIONS:
        program.check_seconds(flag, getattr(opts, flag[2:].replace('-', '_')))
    if opts.topics is not None:     # a topic named twice is replayed (and counted) once
        opts.topics = list(dict.fromkeys(opts.topics))
    remap = {}
    for rule in opts.remap:
        source, sep, target = rule.partition(':=')
        if not sep or not source or not target:
            raise ValueError(f'--remap {rule!r} is not FROM:=TO')
        if remap.get(source, target) != target:
            raise ValueError(f'--remap {source}:={remap[source]} and --remap {rule}: two names '
                             f'for {source}; give one rule per topic')
        remap[source] = target
    for source in remap:            # it was ignored without a word
        if opts.topics is not None and source not in opts.topics:
            raise ValueError(f'--remap {source}:={remap[source]}: {source} is not replayed '
                             f'(--topics {" ".join(opts.topics)}); add it to --topics or '
                             'drop the rule')
    return remap


def start_time_ns(reader, topics, offset_s, loop=False):
    """
    Return the bag time replay starts from, refusing a selection without a message.

    ``topics`` (None: all) from ``offset_s`` after the bag's first message
    must hold a message: an offset past the bag's last message, or topics
    without a message from it on, is a one-line ValueError, as every command
    refuses an empty selection (an empty topic, a CSV without data rows).
    With ``loop``, a bag whose messages are all at one instant is refused:
    it would be published as fast as the loop turns.
    """
    chosen = sorted(reader.topics) if topics is None else list(topics)
    if any(t not in reader.topics for t in chosen):
        return reader.start_time_ns     # refused by the Player, naming the bag's topics
    if not sum(reader.topics[t].message_count for t in chosen):
        raise ValueError(f'nothing to replay: bag {reader.path} has no message on '
                         f'{", ".join(chosen) or "any topic"}')
    span_s = reader.duration_ns / NS_PER_S
    if offset_s > span_s:
        raise ValueError(f'--start-offset = {offset_s} is past the end of bag {reader.path}: '
                         f'its messages span {span_s:.9g} s; allowed [0, {span_s:.9g}] s')
    start_ns = reader.start_time_ns + int(round(offset_s * NS_PER_S))
    if offset_s > 0 and topics is not None and not _any_message(reader, chosen, start_ns):
        raise ValueError(f'--start-offset = {offset_s} leaves no message of {", ".join(chosen)} '
                         f'to replay: the last comes before it (bag {reader.path} spans '
                         f'{span_s:.9g} s)')
    if loop and not (reader.end_time_ns > start_ns if topics is None
                     else _any_message(reader, chosen, start_ns + 1)):
        raise ValueError(f'--loop: the messages to replay of bag {reader.path} are all at one '
                         'instant: a loop would publish them as fast as it can; replay them '
                         'once, without --loop')
    return start_ns


def _any_message(reader, topics, start_ns):
    """Return whether ``topics`` of ``reader`` have a message at or after ``start_ns``."""
    return next(iter(reader.messages(topics, start_ns=start_ns)), None) is not None


def check_accel_meaning(reader, topics=None, remap=None):
    """
    Refuse to replay an older bag's acceleration commands (module docstring): ValueError.

    ``topics`` are the topics to replay (None: all); a Vector3Stamped topic
    named (or remapped to) ``*/cmd/linear_acceleration`` with messages, in a
    bag whose ``custom_data`` does not mark it applied, is refused.
    """
    if table.accel_commands_applied(reader.custom_data):
        return
    chosen = sorted(reader.topics) if topics is None else list(topics)
    key = table.ACCEL_CMD.name
    for name in chosen:
        info = reader.topics.get(name)
        target = (remap or {}).get(name, name).lstrip('/')
        if info is None or not info.message_count or info.type_name != table.VECTOR3_STAMPED \
                or not (target == key or target.endswith('/' + key)):
            continue
        others = ' '.join(t for t in chosen if t != name) or '(none)'
        raise ValueError(f'{name} of {reader.path} holds the specific force (gravity '
                         'included: the bag has no custom_data cmd_linear_acceleration: '
                         'applied); the node adds gravity itself and would count it twice: '
                         f'replay without it, --topics {others}')


class Player:
    """
    Publish a bag's messages on a node with their recorded timing.

    Parameters
    ----------
    node : rclpy.node.Node
        Owner of the publishers.
    reader : gyro_emulator.recording.bag.BagReader
        The bag.
    topics : list of str, optional
        Topics to replay (default all).
    remap : dict of str to str
        Published name of a recorded topic.
    rate : float
        Playback speed factor.
    clock_hz : float, optional
        Publish ``/clock`` at this rate.
    reliable : bool
        Force reliable publishers.
    stop : gyro_emulator.interrupts.SignalFlag, optional
        Set to stop between two messages (the signal handlers set it).

    """

    def __init__(self, node, reader, topics=None, remap=None, rate=1.0, clock_hz=None,
                 reliable=False, stop=None):
        self.node = node
        self.reader = reader
        self.topics = sorted(reader.topics) if topics is None else list(topics)
        self.rate = rate
        self.clock_period_s = None if clock_hz is None else 1.0 / clock_hz
        self.publishers = {}
        self._targets = {}
        self.published = 0
        #: Set by SIGINT/SIGTERM; checked between messages, so a signal never
        #: lands between a publish and its count.
        self.stop = SignalFlag() if stop is None else stop
        remap = remap or {}
        for name in sorted(set(remap) - set(reader.topics)):
            raise ValueError(f'--remap {name}:={remap[name]}: topic {name} is not in bag '
                             f'{reader.path}: topics are {", ".join(sorted(reader.topics))}')
        for name in list(self.topics):
            info = reader.topics.get(name)
            if info is None:
                raise ValueError(f'topic {name} is not in bag {reader.path}: topics are '
                                 f'{", ".join(sorted(reader.topics))}')
            message_class = self._message_class(name, info.type_name, topics is None)
            if message_class is None:
                continue
            profiles = info.qos_profiles
            qos = codec.profile_to_qos(profiles[0], depth=100) if profiles else \
                QoSProfile(depth=100)
            if reliable:
                qos.reliability = ReliabilityPolicy.RELIABLE
            target = remap.get(name, name)
            self._check_target(name, target, info.type_name, remap)
            try:
                self.publishers[name] = node.create_publisher(message_class, target, qos)
            except InvalidTopicNameException as exc:
                reason = str(exc).splitlines()[0].replace('Invalid topic name: ', '')
                reason = reason.rstrip(':')
                if name not in remap:       # the bag's own name (another tool wrote it)
                    raise ValueError(f'topic {name!r} of bag {reader.path} is not a ROS topic '
                                     f'name: {reason}; publish it as another with --remap '
                                     f'{name}:=NEW_NAME, or choose the topics with '
                                     '--topics') from None
                raise ValueError(f'--remap {name}:={target}: {target!r} is not a ROS topic '
                                 f'name: {reason}') from None
        self.clock_publisher = None
        if self.clock_period_s is not None:
            self._clock_msg = Clock()
            self.clock_publisher = node.create_publisher(
                Clock, '/clock', QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))

    def _check_target(self, name, target, type_name, remap):
        """Refuse two topics of different types published on one name (a ``--remap``)."""
        other = self._targets.setdefault(target, name)
        other_type = self.reader.topics[other].type_name
        if other_type != type_name:
            rules = ' and '.join(f'--remap {n}:={remap[n]}' for n in (other, name) if n in remap)
            raise ValueError(f'{rules}: {target} would carry {other} ({other_type}) and {name} '
                             f'({type_name}): a topic has one type; remap one elsewhere or '
                             'leave it out of --topics')

    def _message_class(self, name, type_name, skip):
        """
        Return the class of topic ``name``'s type, or None when it is skipped.

        A type that is not installed skips its topic with a warning when every
        topic is replayed (``skip``, as ``ros2 bag play`` does), and is a
        one-line error for a topic the user named with ``--topics``.
        """
        try:
            return codec.message_class(type_name)
        except ValueError as exc:
            if not skip:
                raise ValueError(f'--topics {name}: {exc}') from None
            self.topics.remove(name)
            if not self.topics:
                raise ValueError(f'no topic of bag {self.reader.path} has an installed '
                                 f'message type ({name}: {exc})') from None
            self.node.get_logger().warning(
                f'skipping topic {name}: {exc} (choose the topics with --topics)')
            return None

    def count(self):
        """Return the number of messages of the topics replayed (the bag's counts)."""
        return sum(self.reader.topics[name].message_count for name in self.topics)

    def wait_for_subscribers(self, timeout_s):
        """
        Wait until every publisher has a subscriber; return True if they all do.

        With ``/clock``, that one too: a node with ``use_sim_time`` then
        sees the bag's first instant (its first sample is there).
        """
        deadline = time.monotonic() + timeout_s
        publishers = dict(self.publishers)
        if self.clock_publisher is not None:
            publishers['/clock'] = self.clock_publisher
        while rclpy.ok() and not self.stop.is_set():
            missing = [n for n, p in publishers.items() if p.get_subscription_count() < 1]
            if not missing:
                return True
            if time.monotonic() >= deadline:
                self.node.get_logger().warning(
                    f'no subscriber on {", ".join(missing)} after {timeout_s} s; replaying')
                return False
            time.sleep(0.05)
        return False

    def wait_for_acks(self, timeout_s):
        """Wait until reliable subscribers acknowledged everything published."""
        for publisher in self.publishers.values():
            publisher.wait_for_all_acked(Duration(nanoseconds=int(timeout_s * NS_PER_S)))

    def hold_clock(self, bag_time_ns, duration_s):
        """
        Wait ``duration_s`` (or until stopped), ``/clock`` held at ``bag_time_ns`` (if published).

        A node with ``use_sim_time`` starts its samples at the first ``/clock``
        it sees; on a loaded machine its side of discovery, or its first
        ``/clock`` callback, can come after the writer saw its subscription
        (a loaded CI run heard a node only from 0.56 s into the bag on).
        Held at the bag's first instant, ``/clock`` gives it that instant
        whenever it matches within the delay.
        """
        if self.clock_publisher is None:
            self.stop.wait(duration_s)
            return
        deadline = time.monotonic() + duration_s
        while not self.stop.is_set() and rclpy.ok():
            self._publish_clock(bag_time_ns)
            left = deadline - time.monotonic()
            if left <= 0.0:
                return
            self.stop.wait(min(left, self.clock_period_s))

    def _publish_clock(self, bag_time_ns):
        msg = self._clock_msg
        msg.clock.sec, msg.clock.nanosec = divmod(int(bag_time_ns), NS_PER_S)
        self.clock_publisher.publish(msg)

    def play_once(self, start_ns):
        """Replay the messages from bag time ``start_ns`` once; return the count."""
        count = 0
        wall_start = time.monotonic()
        next_clock = wall_start
        scale = 1.0 / (self.rate * NS_PER_S)
        for item in self.reader.messages(self.topics, start_ns=start_ns):
            due = wall_start + (item.log_time_ns - start_ns) * scale
            while True:
                now = time.monotonic()
                if self.clock_publisher is not None and now >= next_clock:
                    self._publish_clock(start_ns + (now - wall_start) * self.rate * NS_PER_S)
                    next_clock += self.clock_period_s
                    if next_clock < now:
                        next_clock = now + self.clock_period_s
                if now >= due:
                    break
                if self.stop.is_set() or not rclpy.ok():
                    return count
                wake = due if self.clock_publisher is None else min(due, next_clock)
                time.sleep(min(MAX_SLEEP_S, max(0.0, wake - now)))
            self.publishers[item.topic].publish(item.data)
            count += 1
            self.published += 1
            if self.stop.is_set():
                break
        return count


def main(args=None):
    """Replay a bag until its end (or forever with ``--loop``) or SIGINT/SIGTERM."""
    argv, opts = program.parse_arguments(build_parser(), 'replay', args)
    with program.Run('replay') as run:
        remap = _check(opts)
        reader = bag.BagReader(opts.bag, tolerant=True)
        check_accel_meaning(reader, opts.topics, remap)
        start_ns = start_time_ns(reader, opts.topics, opts.start_offset, opts.loop)
        for note in reader.problems:
            print(f'replay: warning: incomplete bag, {note}', file=sys.stderr)
        # Signals only set a flag: the loop stops between messages and the final
        # count is exact (rclpy's handler would raise in the middle of a step).
        rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
        stop = SignalFlag()
        spinning.flag_signals(stop)
        run.node = Node('gyro_replay')
        player = Player(run.node, reader, opts.topics, remap, opts.rate, opts.clock,
                        opts.reliable, stop)
        run.on_exit(lambda: print(f'replay: published {player.published} messages',
                                  flush=True))
        _play(player, opts, reader, start_ns)
    return run.status


def _play(player, opts, reader, start_ns):
    """Wait as asked, then replay from ``start_ns`` once (or until stopped with ``--loop``)."""
    if opts.wait_for_subscribers > 0:
        player.wait_for_subscribers(opts.wait_for_subscribers)
    if opts.delay > 0:              # SIGINT or SIGTERM ends the wait (they set stop)
        player.hold_clock(start_ns, opts.delay)
    if start_ns > reader.start_time_ns:
        left_s = (reader.end_time_ns - start_ns) / NS_PER_S
        player.node.get_logger().info(
            f'replaying {opts.bag} from {opts.start_offset:g} s on (the last {left_s:.3f} s of '
            f'its {reader.duration_ns / NS_PER_S:.3f} s; {player.count()} messages in all) '
            f'at rate {opts.rate}')
    else:
        player.node.get_logger().info(
            f'replaying {player.count()} messages of {opts.bag} at rate {opts.rate}')
    while rclpy.ok() and not player.stop.is_set():
        player.play_once(start_ns)
        if not opts.loop:
            break
    # Also when stopped: what was published reaches reliable subscribers before
    # the publishers go (the count printed is what they received).
    player.wait_for_acks(2.0)


if __name__ == '__main__':
    sys.exit(main())
