"""
Mutated bags, each read back against the original: a count or notice, or one line (issue 26).

Four mutations, seeded and bounded: zeroed byte ranges, bit flips in the
summary, chunks written twice (with and without the summary), and metadata
fields of the wrong type. For each mutated bag, the tolerant reader (what
allan, calibrate, diagnose and replay use), ``bag info``'s verify and
``bag repair`` must end in messages or in a one-line ValueError/OSError;
the messages read must be the original's (none invented, none repeated),
and any difference from the original must come with a notice. Repair never
reports more messages than were written.
"""

from collections import Counter
import os
import shutil
import struct

from gyro_emulator.recording import bag, cdr
import numpy as np
import pytest
import yaml

IMU = 'sensor_msgs/msg/Imu'
TEMP = 'sensor_msgs/msg/Temperature'
CLEAN_ERRORS = (ValueError, OSError)
WRONG_TYPES = (5, [1, 2], 'x', {'a': [1]}, 1.5, True, None, {'k': 'v'})
META_FIELDS = ('rosbag2_bagfile_information', 'relative_file_paths', 'custom_data', 'version',
               'files', 'topics_with_message_count', 'message_count')


def _write(path):
    count = 1200
    stamps = 1_700_000_000_000_000_000 + np.arange(count, dtype=np.int64) * 5_000_000
    rng = np.random.default_rng(26)
    values = rng.normal(size=(count, len(cdr.LAYOUTS[IMU].fields)))
    temps = np.column_stack([25 + rng.normal(size=count // 10), np.full(count // 10, 0.1)])
    with bag.BagWriter(path, chunk_size=6000, custom_data={'seed': '1'}) as writer:
        writer.add_topic('/imu/data_raw', IMU)
        writer.add_topic('/imu/temperature', TEMP)
        writer.write_batches([
            ('/imu/data_raw', cdr.encode(IMU, stamps, values, 'imu'), stamps),
            ('/imu/temperature', cdr.encode(TEMP, stamps[::10], temps, 'imu'), stamps[::10])])


def _read(path, tolerant):
    reader = bag.BagReader(path, tolerant=tolerant)
    messages = [(m.topic, m.log_time_ns, m.data) for m in reader.messages()]
    for topic in reader.topics:
        reader.read_arrays(topic)
    return reader, messages


def _one_line(exc):
    text = str(exc)
    return bool(text) and '\n' not in text and 'Traceback' not in text


def _mutate_zeros(data, rng, summary_start):
    buf = bytearray(data)
    start = int(rng.integers(8, len(buf)))
    size = int(rng.choice([4, 16, 64, 300]))
    buf[start:start + size] = bytes(len(buf[start:start + size]))
    return bytes(buf)


def _mutate_summary(data, rng, summary_start):
    buf = bytearray(data)
    for _ in range(int(rng.integers(1, 4))):
        at = int(rng.integers(summary_start, len(buf) - 8))
        buf[at] ^= 1 << int(rng.integers(0, 8))
    return bytes(buf)


def _mutate_duplicate(data, rng, summary_start, chunks):
    starts = sorted(c.chunk_start_offset for c in chunks) + [None]
    k = int(rng.integers(0, len(chunks)))
    end = starts[k + 1] or summary_start
    block = data[starts[k]:end]
    where = starts[int(rng.integers(k + 1, len(starts)))] or summary_start
    tail = data[where:] if rng.random() < 0.5 else data[where:summary_start]
    return data[:where] + block + tail


def _mutated(source_dir, rng, kind, chunks, summary_start, case_dir):
    shutil.copytree(source_dir, case_dir)
    mcap_path = os.path.join(case_dir, 'src_0.mcap')
    if kind == 'metadata':
        meta_path = os.path.join(case_dir, 'metadata.yaml')
        meta = yaml.safe_load(open(meta_path))
        field = META_FIELDS[int(rng.integers(0, len(META_FIELDS)))]
        value = WRONG_TYPES[int(rng.integers(0, len(WRONG_TYPES)))]
        if field == 'rosbag2_bagfile_information':
            meta[field] = value
        else:
            meta['rosbag2_bagfile_information'][field] = value
        yaml.safe_dump(meta, open(meta_path, 'w'))
        return
    data = open(mcap_path, 'rb').read()
    if kind == 'zeros':
        data = _mutate_zeros(data, rng, summary_start)
    elif kind == 'summary':
        data = _mutate_summary(data, rng, summary_start)
    else:
        data = _mutate_duplicate(data, rng, summary_start, chunks)
    open(mcap_path, 'wb').write(data)


def _check_subset(messages, original, notices, what):
    """Check the messages are the original's, each at most once, any difference noticed."""
    got, want = Counter(messages), Counter(original)
    assert not (got - want), f'{what}: {sum((got - want).values())} messages not written'
    if got != want:
        assert notices, f'{what}: {sum((want - got).values())} messages missing silently'


@pytest.mark.parametrize('kind,cases', [('zeros', 32), ('summary', 20), ('duplicate', 14),
                                        ('metadata', 20)])
def test_mutated_bags_say_what_they_lost(tmp_path, kind, cases):
    from mcap.reader import make_reader
    source = str(tmp_path / 'src')
    _write(source)
    _, original = _read(source, False)
    mcap_path = os.path.join(source, 'src_0.mcap')
    with open(mcap_path, 'rb') as handle:
        chunks = make_reader(handle).get_summary().chunk_indexes
    data = open(mcap_path, 'rb').read()
    summary_start = struct.unpack_from('<Q', data, len(data) - 8 - 20)[0]
    rng = np.random.default_rng({'zeros': 1, 'summary': 2, 'duplicate': 3, 'metadata': 4}[kind])
    outcomes = Counter()
    for i in range(cases):
        case = str(tmp_path / f'c{i}')
        _mutated(source, rng, kind, chunks, summary_start, case)
        try:
            reader, messages = _read(case, True)
            corrupt, lost = reader.verify()
            _check_subset(messages, original, reader.problems + corrupt + [lost] * bool(lost),
                          f'{kind} case {i}: read')
            outcomes['read'] += 1
        except CLEAN_ERRORS as exc:
            assert _one_line(exc), repr(exc)
            outcomes['error'] += 1
        try:
            report = bag.repair_bag(case, out_dir=case + '_fixed')
            assert report.message_count <= len(original), f'{kind} case {i}: repair invents'
            _, repaired = _read(case + '_fixed', False)
            text = report.describe()
            notices = [line for line in text.splitlines()
                       if any(w in line for w in ('lost', 'skipped', 'dropped', 'discarded',
                                                  'ignored', 'rebuilt', 'recovered'))]
            _check_subset(repaired, original, notices, f'{kind} case {i}: repair')
            outcomes['repaired'] += 1
        except CLEAN_ERRORS as exc:
            assert _one_line(exc), repr(exc)
        shutil.rmtree(case)
        shutil.rmtree(case + '_fixed', ignore_errors=True)
    assert outcomes['read'] > 0, outcomes
