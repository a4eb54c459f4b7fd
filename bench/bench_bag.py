"""
Bag write/read throughput for sensor_msgs/Imu, beside rosbags on the same data.

Usage: ./dev.sh shell, then ``python bench/bench_bag.py [--messages N]``.

Write paths (messages/s, including everything from the input shown to a
finished bag with metadata.yaml):

- ``rclpy``  an rclpy Imu message is updated, ``serialize_message``d and
  written (what a node recording its own output does);
- ``bytes``  already-serialised payloads are written (the recorder's raw
  subscriptions);
- ``numpy``  (N, 37) arrays are encoded with ``gyro_emulator.recording.cdr`` and written
  (``simulate --out``, replay output).

Read paths: ``numpy`` (``BagReader.read_arrays``: the chosen fast path),
``bytes`` (``BagReader.messages``), ``rclpy`` (bytes + ``deserialize_message``)
and ``mcap_ros2`` (``decoded_messages``, mcap-ros2-support's dynamic decoder).
The references are rosbags 0.11 (Writer version 9 / Reader + deserialize_cdr)
on the same payloads and the same file, and for writing also the ``mcap``
library's own ``mcap.writer.Writer`` (one MCAP file, zstd chunks of the same
size, no ``metadata.yaml`` and no flushing per chunk): the measure of what
our hand-written crash-safe writer (``McapFileWriter``) costs or saves. Best
of ``--repeat`` runs.
"""

import argparse
import os
import shutil
import sys
import tempfile
import time

from gyro_emulator.recording import bag, cdr
import numpy as np

IMU = 'sensor_msgs/msg/Imu'
TOPIC = '/imu/data_raw'


def best_rate(count, func, repeat):
    """Return the best messages/s of ``repeat`` calls of ``func``."""
    best = float('inf')
    for _ in range(repeat):
        start = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - start)
    return count / best


def main(argv=None):
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--messages', type=int, default=200_000)
    parser.add_argument('--repeat', type=int, default=2)
    args = parser.parse_args(argv)
    from mcap.writer import CompressionType, Writer as McapWriter
    from rclpy.serialization import deserialize_message, serialize_message
    from rosbags.rosbag2 import Reader, StoragePlugin, Writer
    from rosbags.typesys import get_typestore, Stores
    from sensor_msgs.msg import Imu

    n = args.messages
    rng = np.random.default_rng(0)
    stamps = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 5_000_000
    values = rng.normal(size=(n, 37))
    payloads = cdr.encode(IMU, stamps, values, 'imu_link')
    stamp_list = stamps.tolist()
    work = tempfile.mkdtemp(prefix='bench_bag_')
    counter = [0]

    def fresh(name):
        counter[0] += 1
        return os.path.join(work, f'{name}{counter[0]}')

    def write_bytes(path=None):
        with bag.BagWriter(path or fresh('bytes')) as writer:
            cid = writer.add_topic(TOPIC, IMU)
            write = writer.write
            for data, t in zip(payloads, stamp_list):
                write(cid, data, t)

    def write_rclpy():
        msg = Imu()
        msg.header.frame_id = 'imu_link'
        av = msg.angular_velocity
        gyro = values[:, 13:16].tolist()
        with bag.BagWriter(fresh('rclpy')) as writer:
            cid = writer.add_topic(TOPIC, IMU)
            write = writer.write
            for t, (x, y, z) in zip(stamp_list, gyro):
                msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t, 1_000_000_000)
                av.x, av.y, av.z = x, y, z
                write(cid, serialize_message(msg), t)

    def write_numpy():
        with bag.BagWriter(fresh('numpy')) as writer:
            writer.add_topic(TOPIC, IMU)
            writer.write_batches([(TOPIC, cdr.encode(IMU, stamps, values, 'imu_link'),
                                   stamps)])

    typestore = get_typestore(Stores.ROS2_JAZZY)

    def write_rosbags():
        with Writer(fresh('rosbags'), version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            conn = writer.add_connection(TOPIC, IMU, typestore=typestore)
            write = writer.write
            for data, t in zip(payloads, stamp_list):
                write(conn, t, data)

    def write_mcap_library():
        with open(fresh('mcap') + '.mcap', 'wb') as stream:
            writer = McapWriter(stream, chunk_size=bag.DEFAULT_CHUNK_SIZE,
                                compression=CompressionType.ZSTD)
            writer.start(profile='ros2', library='mcap')
            schema = writer.register_schema(IMU, 'ros2msg',
                                            bag.message_definition(IMU).encode())
            channel = writer.register_channel(TOPIC, 'cdr', schema)
            add = writer.add_message
            for seq, (data, t) in enumerate(zip(payloads, stamp_list)):
                add(channel, log_time=t, data=data, publish_time=t, sequence=seq)
            writer.finish()

    print(f'{n} sensor_msgs/Imu messages ({len(payloads[0])} bytes each), best of '
          f'{args.repeat}; Python {sys.version.split()[0]}')
    print('\nWRITE (messages/s)')
    rosbags_write = best_rate(n, write_rosbags, args.repeat)
    rows = [('bytes  (recorder: raw payloads)', best_rate(n, write_bytes, args.repeat)),
            ('rclpy  (serialize_message + write)', best_rate(n, write_rclpy, args.repeat)),
            ('numpy  (cdr.encode arrays + write)', best_rate(n, write_numpy, args.repeat))]
    for name, rate in rows:
        print(f'  gyro_emulator.recording.bag {name:<36} {rate:>10,.0f}   '
              f'{rate / rosbags_write:5.2f}x rosbags')
    print(f'  rosbags Writer v9 mcap (same payloads)                {rosbags_write:>10,.0f}')
    mcap_write = best_rate(n, write_mcap_library, args.repeat)
    print(f'  mcap.writer.Writer (same payloads, one file)          {mcap_write:>10,.0f}   '
          f'bytes path / mcap Writer: {rows[0][1] / mcap_write:.2f}x')

    path = os.path.join(work, 'read')
    write_bytes(path)
    size = os.path.getsize(os.path.join(path, 'read_0.mcap'))
    reader = bag.BagReader(path)

    def read_numpy():
        arrays = reader.read_arrays(TOPIC)
        assert arrays.decoded.values.shape == (n, 37)

    def read_bytes():
        count = 0
        for _ in reader.messages(TOPIC):
            count += 1
        assert count == n

    def read_rclpy():
        for item in reader.messages(TOPIC):
            deserialize_message(item.data, Imu)

    def read_mcap_ros2():
        for _ in reader.decoded_messages(TOPIC):
            pass

    def read_rosbags():
        with Reader(path) as rb:
            deserialize = typestore.deserialize_cdr
            for conn, _, raw in rb.messages():
                deserialize(raw, conn.msgtype)

    def read_rosbags_raw():
        with Reader(path) as rb:
            for _ in rb.messages():
                pass

    print(f'\nREAD (messages/s) of one {size / 1e6:.1f} MB file (zstd chunks)')
    rosbags_read = best_rate(n, read_rosbags, args.repeat)
    rosbags_raw = best_rate(n, read_rosbags_raw, args.repeat)
    reads = [('numpy  (read_arrays: decoded columns)', best_rate(n, read_numpy, args.repeat),
              rosbags_read),
             ('rclpy  (messages + deserialize_message)', best_rate(n, read_rclpy, args.repeat),
              rosbags_read),
             ('mcap_ros2 (decoded_messages)', best_rate(n, read_mcap_ros2, 1), rosbags_read),
             ('bytes  (messages, no decoding)', best_rate(n, read_bytes, args.repeat),
              rosbags_raw)]
    for name, rate, ref in reads:
        label = 'decoded' if ref is rosbags_read else 'raw'
        print(f'  gyro_emulator.recording.bag {name:<40} {rate:>10,.0f}   '
              f'{rate / ref:5.2f}x rosbags {label}')
    print(f'  rosbags Reader + deserialize_cdr (decoded)                 {rosbags_read:>10,.0f}')
    print(f'  rosbags Reader messages (raw)                              {rosbags_raw:>10,.0f}')
    print('\ntargets: write >= 80,000/s, read >= 100,000/s (numpy read path, rclpy write '
          'path)')
    shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
