"""
The emulator node recording its own inputs, outputs and truth (``record_dir``).

:class:`SelfRecorder` writes into a rosbag2 MCAP bag
(:class:`gyro_emulator.recording.bag.BagWriter`), with the node clock as log
time:

* what the node publishes (``imu/data_raw``, ``imu/temperature``, the
  ``~/truth/*`` topics) as it publishes it: a tap on the node's output stage
  (:attr:`gyro_emulator.ros.outputs.OutputStage.tap`) hands over each
  serialized message, so every published sample is in the bag, also the
  last ones before a stop (a subscription to its own topics lost those
  still in flight when the node shut down: 5 of 1411 once); each topic is
  stored with its publisher's QoS;
* what it receives (its command inputs) and ``/diagnostics`` (also other
  nodes' reports) through raw (still serialised) subscriptions: what any
  subscriber receives. They are best effort, which matches reliable and
  best-effort publishers alike.

``record_dir`` names the bag directory; if it exists and is not empty, the bag
goes into a new ``gyro_emulator_<date>_<time>`` directory inside it. The node owns
the recorder: the bag is finished when the node is destroyed
(``destroy_node`` calls :meth:`SelfRecorder.finish`) or the process exits
(SIGINT, SIGTERM); chunks are flushed every 0.5 s, so after SIGKILL
``gyro-emulator bag repair`` recovers all but the last half second.

A write error (a full disk, a file-size limit) stops the recording, never
the node: one ERROR line in the log, :attr:`SelfRecorder.error` for
``/diagnostics`` (level ERROR), and the bag keeps every chunk flushed before
the error (``gyro-emulator bag repair`` finishes it).
"""

import atexit
import datetime
import functools
import os
import sys

from gyro_emulator.recording import bag, topics
from gyro_emulator.ros import codec
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy


def bag_path(record_dir, now=None):
    """Return the bag directory for ``record_dir`` (a new subdirectory if it is in use)."""
    record_dir = os.path.abspath(os.path.expanduser(record_dir))
    if os.path.isdir(record_dir) and os.listdir(record_dir):
        stamp = (now or datetime.datetime.now()).strftime('%Y%m%d_%H%M%S')
        candidate = os.path.join(record_dir, f'gyro_emulator_{stamp}')
        suffix = 1
        while os.path.exists(candidate):
            candidate = os.path.join(record_dir, f'gyro_emulator_{stamp}_{suffix}')
            suffix += 1
        return candidate
    return record_dir


class SelfRecorder:
    """
    Record a gyro emulator node's inputs, outputs and truth into a bag.

    Parameters
    ----------
    node : rclpy.node.Node
        The emulator node (its parameters ``rate_source``, ``sensor_config``,
        ``seed``, ``rate_hz`` and ``frame_id`` are stored in the bag's
        custom_data, and its fully qualified name as ``node``: with ``seed``
        -1 the seed comes from that name, so ``replay`` finds it).
    outputs : gyro_emulator.ros.outputs.OutputStage
        The node's output stage, tapped for what the node publishes.
    record_dir : str
        Bag directory (see :func:`bag_path`).
    flush_interval_s : float
        Longest time a message waits in memory, s.

    """

    def __init__(self, node, outputs, record_dir, flush_interval_s=bag.DEFAULT_FLUSH_INTERVAL_S):
        self.node = node
        custom = {'generator': 'gyro_emulator node record_dir',
                  'node': node.get_fully_qualified_name(), **topics.ACCEL_CMD_MEANING}
        for name in ('sensor_config', 'seed', 'rate_hz', 'rate_source', 'frame_id'):
            if node.has_parameter(name):
                custom[name] = str(node.get_parameter(name).value)
        try:
            self.writer = bag.BagWriter(bag_path(record_dir), custom_data=custom,
                                        flush_interval_s=flush_interval_s)
        except OSError as exc:
            raise ValueError(f'record_dir = {record_dir!r}: cannot write a bag there '
                             f'({exc.strerror or exc}): allowed a writable directory') from None
        self.path = self.writer.path
        self.finished = False
        self.error = None
        self.counts = {}
        self._channels = {}             # publisher -> (topic, channel id), for the tap
        for pub, entry in outputs.sample_publishers():
            topic = pub.topic_name
            self._channels[pub] = (topic, self.writer.add_topic(
                topic, entry.type_name, qos_profiles=[codec.qos_to_profile(pub.qos_profile)]))
            self.counts[topic] = 0
        rate_source = custom.get('rate_source', 'angular_velocity')
        qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                         reliability=ReliabilityPolicy.BEST_EFFORT)
        offered = [codec.qos_to_profile(qos)]
        self._subscriptions = []
        rate_input = topics.RATE_INPUTS.get(rate_source, topics.RATE_CMD)
        received = [rate_input] + [t for t in topics.NODE_TOPICS
                                   if t.direction == 'in' and t not in topics.RATE_INPUTS.values()]
        for entry in received + [topics.DIAGNOSTICS]:
            type_name = entry.type_name
            topic = node.resolve_topic_name(entry.name)
            cid = self.writer.add_topic(topic, type_name, qos_profiles=offered)
            self.counts[topic] = 0
            self._subscriptions.append(node.create_subscription(
                codec.message_class(type_name), topic,
                functools.partial(self._on_message, topic, cid), qos, raw=True))
        outputs.tap = self._on_published
        self._timer = node.create_timer(0.1, self._flush_if_due)
        atexit.register(self.finish)
        node.get_logger().info(f'recording inputs, outputs and truth to {self.path}')

    def _on_message(self, topic, cid, data):
        if self.finished:
            return
        try:
            self.writer.write(cid, data, self.node.get_clock().now().nanoseconds)
        except OSError as exc:
            self._stop(exc)
            return
        self.counts[topic] += 1

    def _on_published(self, pub, data):
        """Write what the node just published (the output stage's tap)."""
        self._on_message(*self._channels[pub], data)

    def _flush_if_due(self):
        if self.finished:
            return
        try:
            self.writer.flush_if_due()
        except OSError as exc:
            self._stop(exc)

    def _stop(self, exc):
        """Stop recording after a write error; the node runs on."""
        self.finished = True
        self._timer.cancel()
        self.error = (f'cannot write {self.path} ({exc.strerror or exc}): recording '
                      f'stopped after {sum(self.counts.values())} messages; recover the bag '
                      f'with: gyro-emulator bag repair {self.path}')
        self.node.get_logger().error(self.error)
        try:
            self.writer.finish()             # closes the file; the summary may not fit
        except OSError:
            pass
        self._unregister()

    def finish(self):
        """Finish the bag (summary, footer, metadata.yaml). Safe to call twice."""
        if self.finished:
            return
        self.finished = True
        try:
            self.writer.finish()
        except OSError as exc:
            self.error = (f'cannot finish {self.path} ({exc.strerror or exc}); recover the '
                          f'bag with: gyro-emulator bag repair {self.path}')
            print(f'[gyro_emulator] recording: {self.error}', file=sys.stderr)
        self._unregister()

    def _unregister(self):
        try:
            atexit.unregister(self.finish)
        except Exception:  # noqa: B902 - interpreter shutting down
            pass
