"""
Bag write/read throughput for sensor_msgs/Imu, beside rosbags on the same data.

Usage: ./dev.sh shell, then ``python bench/bench_bag.py [--messages N]``
(``--messages 20000 --repeat 1`` for a quick run).

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
on the same payloads and the same file.

The MCAP file table sets our hand-written crash-safe writer
(``McapFileWriter``) beside the ``mcap`` library's own ``mcap.writer.Writer``
on one file each: the same payloads, schema, channel, zstd chunks of
``DEFAULT_CHUNK_SIZE`` bytes and the library's default indexes and summary.
Ours also flushes every closed chunk to the operating system (crash safety);
the library's zstd level is its default (not settable), ours is 1.

Every row gives messages per wall second and per CPU second of this process
(``time.process_time``), from the fastest of ``--repeat`` runs.

``--tiny-chunks N`` compares instead the same messages (an Imu topic and a
truth topic whose stamps run 100 ms ahead, as a node's latency puts them) in
normal chunks and in N tiny ones (one message of each topic a chunk, chunks
overlapping in time): ``bag info`` (open, info, verify) and the read
``allan`` does (``read_arrays``), best of ``--repeat``, and their ratio
(target: tiny within 5x of normal).
"""

import argparse
from dataclasses import dataclass
from functools import lru_cache
import os
import shutil
import subprocess
import sys
import tempfile
import time

from gyro_emulator.recording import bag, cdr
import numpy as np

IMU = 'sensor_msgs/msg/Imu'
TOPIC = '/imu/data_raw'
FRAME_ID = 'imu_link'


@dataclass(frozen=True)
class Inputs:
    """The messages every path writes: times, field values and CDR payloads."""

    stamps_ns: np.ndarray
    values: np.ndarray
    payloads: list
    stamp_list: list

    @property
    def count(self):
        """Return the number of messages."""
        return len(self.payloads)


def make_inputs(count):
    """Return ``count`` Imu messages 5 ms apart with seeded random fields."""
    stamps_ns = 1_700_000_000_000_000_000 + np.arange(count, dtype=np.int64) * 5_000_000
    values = np.random.default_rng(0).normal(size=(count, len(cdr.LAYOUTS[IMU].fields)))
    payloads = cdr.encode(IMU, stamps_ns, values, FRAME_ID)
    return Inputs(stamps_ns, values, payloads, stamps_ns.tolist())


def best_rates(count, func, repeat):
    """Return (messages per wall s, per CPU s) of the fastest of ``repeat`` calls."""
    best_wall_s, best_cpu_s = float('inf'), float('inf')
    for _ in range(repeat):
        wall_s, cpu_s = time.perf_counter(), time.process_time()
        func()
        wall_s, cpu_s = time.perf_counter() - wall_s, time.process_time() - cpu_s
        if wall_s < best_wall_s:
            best_wall_s, best_cpu_s = wall_s, cpu_s
    return count / best_wall_s, count / max(best_cpu_s, 1e-9)


def print_row(label, rates, note=''):
    """Print one table row: label, messages per wall s and per CPU s, a note."""
    print(f'  {label:<58} {rates[0]:>10,.0f} {rates[1]:>10,.0f}   {note}'.rstrip())


@lru_cache(maxsize=1)
def typestore():
    """Return rosbags' ROS 2 Jazzy type store, built once and outside the timings."""
    from rosbags.typesys import get_typestore, Stores
    return get_typestore(Stores.ROS2_JAZZY)


# -- write paths -------------------------------------------------------------------------
def write_bytes(path, inputs):
    """Write the ready payloads to a bag (the recorder's raw path)."""
    with bag.BagWriter(path) as writer:
        cid = writer.add_topic(TOPIC, IMU)
        write = writer.write
        for data, t in zip(inputs.payloads, inputs.stamp_list):
            write(cid, data, t)


def write_rclpy(path, inputs):
    """Update, serialise with rclpy and write one Imu message per sample."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu
    msg = Imu()
    msg.header.frame_id = FRAME_ID
    av = msg.angular_velocity
    gyro = inputs.values[:, cdr.LAYOUTS[IMU].columns('angular_velocity')].tolist()
    with bag.BagWriter(path) as writer:
        cid = writer.add_topic(TOPIC, IMU)
        write = writer.write
        for t, (x, y, z) in zip(inputs.stamp_list, gyro):
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t, 1_000_000_000)
            av.x, av.y, av.z = x, y, z
            write(cid, serialize_message(msg), t)


def write_numpy(path, inputs):
    """Encode the arrays with ``cdr.encode`` and write them as one batch."""
    with bag.BagWriter(path) as writer:
        writer.add_topic(TOPIC, IMU)
        payloads = cdr.encode(IMU, inputs.stamps_ns, inputs.values, FRAME_ID)
        writer.write_batches([(TOPIC, payloads, inputs.stamps_ns)])


def write_rosbags(path, inputs):
    """Write the ready payloads with rosbags' Writer (version 9, MCAP)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection(TOPIC, IMU, typestore=typestore())
        write = writer.write
        for data, t in zip(inputs.payloads, inputs.stamp_list):
            write(conn, t, data)


def write_mcap_file_writer(path, inputs):
    """Write the ready payloads to one MCAP file with our ``McapFileWriter``."""
    writer = bag.McapFileWriter(path + '.mcap', compression='zstd',
                                chunk_size=bag.DEFAULT_CHUNK_SIZE)
    schema_id = writer.add_schema(IMU, bag.message_definition(IMU))
    cid = writer.add_channel(TOPIC, schema_id)
    write = writer.write
    for seq, (data, t) in enumerate(zip(inputs.payloads, inputs.stamp_list)):
        write(cid, data, t, t, seq)
    writer.finish()


def write_mcap_library(path, inputs):
    """Write the ready payloads to one MCAP file with ``mcap.writer.Writer``."""
    from mcap.writer import CompressionType, Writer
    with open(path + '.mcap', 'wb') as stream:
        writer = Writer(stream, chunk_size=bag.DEFAULT_CHUNK_SIZE,
                        compression=CompressionType.ZSTD)
        writer.start(profile='ros2', library='mcap')
        schema_id = writer.register_schema(IMU, 'ros2msg',
                                           bag.message_definition(IMU).encode())
        cid = writer.register_channel(TOPIC, 'cdr', schema_id)
        add = writer.add_message
        for seq, (data, t) in enumerate(zip(inputs.payloads, inputs.stamp_list)):
            add(cid, log_time=t, data=data, publish_time=t, sequence=seq)
        writer.finish()


def bench_writes(inputs, work, repeat):
    """Print the bag write table and the MCAP file writer table."""
    paths = iter(os.path.join(work, f'w{i}') for i in range(1_000_000))

    def rates(func):
        return best_rates(inputs.count, lambda: func(next(paths), inputs), repeat)

    print(f'\nWRITE a bag {"messages/s":>53} {"msg/CPU-s":>10}')
    rosbags = rates(write_rosbags)
    for label, func in (('bytes  (recorder: raw payloads)', write_bytes),
                        ('rclpy  (serialize_message + write)', write_rclpy),
                        ('numpy  (cdr.encode arrays + write)', write_numpy)):
        ours = rates(func)
        print_row(f'bag.BagWriter {label}', ours, f'{ours[0] / rosbags[0]:5.2f}x rosbags')
    print_row('rosbags Writer v9 mcap (same payloads)', rosbags)
    print(f'\nWRITE one MCAP file, zstd chunks of {bag.DEFAULT_CHUNK_SIZE} bytes, same payloads')
    library = rates(write_mcap_library)
    ours = rates(write_mcap_file_writer)
    print_row('bag.McapFileWriter (ours, crash-safe)', ours,
              f'{ours[0] / library[0]:5.2f}x wall, {ours[1] / library[1]:5.2f}x CPU of mcap')
    print_row('mcap.writer.Writer (the mcap library)', library)


# -- read paths --------------------------------------------------------------------------
def read_functions(path, count):
    """Return {name: function} reading the bag at ``path`` of ``count`` Imu messages."""
    from rclpy.serialization import deserialize_message
    from rosbags.rosbag2 import Reader
    from sensor_msgs.msg import Imu
    reader = bag.BagReader(path)
    deserialize = typestore().deserialize_cdr

    def read_numpy():
        arrays = reader.read_arrays(TOPIC)
        assert arrays.decoded.values.shape == (count, len(cdr.LAYOUTS[IMU].fields))

    def read_bytes():
        assert sum(1 for _ in reader.messages(TOPIC)) == count

    def read_rclpy():
        for item in reader.messages(TOPIC):
            deserialize_message(item.data, Imu)

    def read_mcap_ros2():
        for _ in reader.decoded_messages(TOPIC):
            pass

    def read_rosbags(decode):
        with Reader(path) as rosbag:
            for conn, _, raw in rosbag.messages():
                if decode:
                    deserialize(raw, conn.msgtype)

    return {'numpy': read_numpy, 'bytes': read_bytes, 'rclpy': read_rclpy,
            'mcap_ros2': read_mcap_ros2, 'rosbags': lambda: read_rosbags(True),
            'rosbags_raw': lambda: read_rosbags(False)}


def bench_reads(inputs, work, repeat):
    """Write one bag of the payloads and print the read table."""
    path = os.path.join(work, 'read')
    write_bytes(path, inputs)
    size = os.path.getsize(os.path.join(path, 'read_0.mcap'))
    reads = read_functions(path, inputs.count)

    def rates(name, times=repeat):
        return best_rates(inputs.count, reads[name], times)

    print(f'\nREAD one {size / 1e6:.1f} MB file (zstd chunks) {"messages/s":>26} '
          f'{"msg/CPU-s":>10}')
    decoded, raw = rates('rosbags'), rates('rosbags_raw')
    for label, name, ref, times in (
            ('numpy  (read_arrays: decoded columns)', 'numpy', decoded, repeat),
            ('rclpy  (messages + deserialize_message)', 'rclpy', decoded, repeat),
            ('mcap_ros2 (decoded_messages)', 'mcap_ros2', decoded, 1),
            ('bytes  (messages, no decoding)', 'bytes', raw, repeat)):
        ours = rates(name, times)
        kind = 'decoded' if ref is decoded else 'raw'
        print_row(f'bag.BagReader {label}', ours, f'{ours[0] / ref[0]:5.2f}x rosbags {kind}')
    print_row('rosbags Reader + deserialize_cdr (decoded)', decoded)
    print_row('rosbags Reader messages (raw)', raw)


def write_pairs(path, count, chunk_size, offset_ns=100_000_000):
    """Write ``count`` Imu messages and as many truth messages ``offset_ns`` earlier."""
    vector = 'geometry_msgs/msg/Vector3Stamped'
    stamps = 1_700_000_000_000_000_000 + np.arange(count, dtype=np.int64) * 5_000_000
    rng = np.random.default_rng(1)
    imu = cdr.encode(IMU, stamps + offset_ns,
                     1e-3 * rng.standard_normal((count, len(cdr.LAYOUTS[IMU].fields))), FRAME_ID)
    truth = cdr.encode(vector, stamps,
                       1e-3 * rng.standard_normal((count, len(cdr.LAYOUTS[vector].fields))),
                       FRAME_ID)
    with bag.BagWriter(path, chunk_size=chunk_size) as writer:
        writer.add_topic(TOPIC, IMU)
        writer.add_topic('/gyro_emulator/truth/rate', vector)
        for k in range(count):
            writer.write('/gyro_emulator/truth/rate', truth[k], int(stamps[k]))
            writer.write(TOPIC, imu[k], int(stamps[k] + offset_ns))


def bench_tiny_chunks(chunks, repeat):
    """Time bag info and the allan read on normal and on tiny chunks; print the ratios."""
    work = tempfile.mkdtemp(prefix='bench_bag_tiny_')
    try:
        paths = {'normal': os.path.join(work, 'normal'), 'tiny': os.path.join(work, 'tiny')}
        write_pairs(paths['normal'], chunks, bag.DEFAULT_CHUNK_SIZE)
        write_pairs(paths['tiny'], chunks, 300)
        times = {}
        for kind, path in paths.items():
            def info():
                reader = bag.BagReader(path, tolerant=True)
                reader.info_text()
                reader.verify()

            def read():
                bag.BagReader(path, tolerant=True).read_arrays(TOPIC)
            for label, func in (('bag info', info), ('allan read', read),
                                ('gyro-emulator bag info', _command('bag', 'info', path)),
                                ('gyro-emulator allan', _command('allan', path, '--topic',
                                                                 TOPIC))):
                times[kind, label] = min(_timed(func) for _ in range(repeat))
        from mcap.reader import make_reader
        with open(os.path.join(paths['tiny'], 'tiny_0.mcap'), 'rb') as handle:
            count = len(make_reader(handle).get_summary().chunk_indexes)
        print(f'{chunks} Imu + {chunks} truth messages; tiny: {count} chunks overlapping in '
              f'time; best of {repeat} (the commands: whole processes, as a user runs them)')
        for label in ('bag info', 'allan read', 'gyro-emulator bag info', 'gyro-emulator allan'):
            normal, tiny = times['normal', label], times['tiny', label]
            print(f'  {label:24s}  normal {normal:6.2f} s   tiny {tiny:6.2f} s   '
                  f'{tiny / normal:4.1f}x (target <= 5x)')
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _command(*args):
    """Return a function that runs ``gyro-emulator ARGS`` in a child process."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

    def run():
        subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', *args], check=True,
                       stdout=subprocess.DEVNULL, env=dict(os.environ, PYTHONPATH=root))
    return run


def _timed(func):
    started = time.perf_counter()
    func()
    return time.perf_counter() - started


def main(argv=None):
    """Run the benchmark and print the tables."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--messages', type=int, default=200_000)
    parser.add_argument('--repeat', type=int, default=2)
    parser.add_argument('--tiny-chunks', type=int, default=None, metavar='N',
                        help='compare N tiny chunks with normal ones instead (e.g. 100000)')
    args = parser.parse_args(argv)
    if args.tiny_chunks:
        bench_tiny_chunks(args.tiny_chunks, args.repeat)
        return 0
    inputs = make_inputs(args.messages)
    typestore()
    print(f'{inputs.count} sensor_msgs/Imu messages ({len(inputs.payloads[0])} bytes each), '
          f'best of {args.repeat}; Python {sys.version.split()[0]}')
    work = tempfile.mkdtemp(prefix='bench_bag_')
    try:
        bench_writes(inputs, work, args.repeat)
        bench_reads(inputs, work, args.repeat)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print('\ntargets: write >= 80,000/s, read >= 100,000/s (numpy read path, rclpy write '
          'path)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
