"""Damaged and hostile bags: detected, counted and said, never lost silently (issue 26)."""

import os
import resource
import shutil
import struct
import subprocess
import sys
import time

from conftest import ROOT
from gyro_emulator.recording import bag, cdr, record
from gyro_emulator.recording.mcap_writer import McapFileWriter
import numpy as np
import pytest
import yaml

IMU = 'sensor_msgs/msg/Imu'
TOPIC = '/imu/data_raw'
T0_NS = 1_700_000_000_000_000_000


def _write(path, count=2000, chunk_size=8192):
    """Write a 200 Hz Imu bag with small chunks; return its .mcap path."""
    stamps = T0_NS + np.arange(count, dtype=np.int64) * 5_000_000
    values = np.random.default_rng(5).normal(size=(count, len(cdr.LAYOUTS[IMU].fields)))
    with bag.BagWriter(path, chunk_size=chunk_size, custom_data={'seed': '3'}) as writer:
        writer.add_topic(TOPIC, IMU)
        writer.write_batches([(TOPIC, cdr.encode(IMU, stamps, values, 'imu'), stamps)])
    return os.path.join(path, os.path.basename(path) + '_0.mcap')


@pytest.fixture(scope='module')
def original(tmp_path_factory):
    """Return a sound bag and its messages read back (log times and payloads)."""
    path = str(tmp_path_factory.mktemp('integrity') / 'orig')
    _write(path)
    return path, _messages(path)


def _messages(path, tolerant=False):
    return [(m.log_time_ns, m.data) for m in bag.BagReader(path, tolerant).messages()]


def _copy(original, tmp_path, name='case'):
    target = str(tmp_path / name)
    shutil.copytree(original[0], target)
    os.rename(os.path.join(target, 'orig_0.mcap'), os.path.join(target, f'{name}_0.mcap'))
    meta = os.path.join(target, 'metadata.yaml')
    with open(meta, encoding='utf-8') as handle:
        text = handle.read().replace('orig_0.mcap', f'{name}_0.mcap')
    with open(meta, 'w', encoding='utf-8') as handle:
        handle.write(text)
    return target, os.path.join(target, f'{name}_0.mcap')


def _summary(mcap_path):
    from mcap.reader import make_reader
    with open(mcap_path, 'rb') as handle:
        return make_reader(handle).get_summary()


def _cli(*args, **kwargs):
    return subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=120,
                          env={**os.environ, 'PYTHONPATH': ROOT}, **kwargs)


def _one_line(text):
    return text.strip() and '\n' not in text.strip() and 'Traceback' not in text


def test_a_zeroed_chunk_header_is_counted_by_info_readers_and_repair(original, tmp_path):
    path, mcap_path = _copy(original, tmp_path)
    chunks = sorted(_summary(mcap_path).chunk_indexes, key=lambda c: c.chunk_start_offset)
    victim = chunks[len(chunks) // 2]
    with open(mcap_path, 'r+b') as handle:
        handle.seek(victim.chunk_start_offset)
        handle.write(bytes(64))
    times = np.array([t for t, _ in original[1]])
    lost = int(np.sum((times >= victim.message_start_time)
                      & (times <= victim.message_end_time)))
    assert lost > 0
    # bag info: a corrupt-chunk line with its count, and the loss
    info = _cli('bag', 'info', path)
    assert info.returncode == 0 and 'Traceback' not in info.stderr
    assert f'{lost} messages (' in info.stdout and f'Messages lost:    {lost} of' in info.stdout
    # readers: the Record's recovery notes count what is missing
    rec = record.load_record(path)
    assert len(rec.time_s) == len(times) - lost
    assert any(f'{lost} messages of' in note for note in rec.recovery), rec.recovery
    assert any(f'read {len(times) - lost} of the {len(times)}' in n for n in rec.recovery)
    # repair: never "complete"; says how many are gone; the rest are the original's
    report = bag.repair_bag(path)
    text = report.describe()
    assert report.lost_messages == lost and f'{lost} messages lost' in text
    assert 'complete,' not in text
    kept = [m for m in original[1] if not victim.message_start_time <= m[0]
            <= victim.message_end_time]
    assert _messages(path) == kept


@pytest.mark.parametrize('where', [0.0, 0.15, 0.3, 0.5, 0.7, 0.85, 0.97, 1.0])
def test_a_bit_flip_in_the_summary_is_caught_by_its_crc(original, tmp_path, where):
    path, mcap_path = _copy(original, tmp_path)
    data = bytearray(open(mcap_path, 'rb').read())
    summary_start = struct.unpack_from('<Q', data, len(data) - 8 - 20)[0]
    at = min(summary_start + int(where * (len(data) - 8 - summary_start)), len(data) - 9)
    data[at] ^= 0x10
    open(mcap_path, 'wb').write(bytes(data))
    with pytest.raises(ValueError) as caught:
        bag.BagReader(path).read_arrays(TOPIC)
    assert _one_line(str(caught.value)) and 'bag repair' in str(caught.value)
    tolerant = bag.BagReader(path, tolerant=True)
    assert any('rebuilt from the data section' in p or 'footer' in p
               for p in tolerant.problems), tolerant.problems
    assert list(tolerant.topics) == [TOPIC]
    assert _messages(path, tolerant=True) == original[1]
    report = bag.repair_bag(path)
    assert report.rewritten and report.message_count == len(original[1])
    assert list(bag.BagReader(path).topics) == [TOPIC] and _messages(path) == original[1]


@pytest.mark.parametrize('head', [b'XXXXXXXX', bytes(8), b'\x89MCAP1\r\n'])
def test_a_damaged_leading_magic_is_said_and_repair_makes_a_file_rosbags_reads(
        original, tmp_path, head):
    from rosbags.rosbag2 import Reader
    path, mcap_path = _copy(original, tmp_path)
    with open(mcap_path, 'r+b') as handle:
        handle.write(head)
    with pytest.raises(Exception):      # what the consumers do with it
        with Reader(path) as reader:
            list(reader.messages())
    with pytest.raises(ValueError) as caught:
        bag.BagReader(path).read_arrays(TOPIC)
    assert _one_line(str(caught.value)) and 'bag repair' in str(caught.value)
    info = _cli('bag', 'info', path)
    assert info.returncode == 0 and 'the leading MCAP magic is damaged' in info.stdout
    assert f'run: gyro-emulator bag repair {path}' in info.stdout
    assert _messages(path, tolerant=True) == original[1]
    report = bag.repair_bag(path)
    assert report.rewritten and report.message_count == len(original[1])
    assert 'complete,' not in report.describe()
    with open(mcap_path, 'rb') as handle:
        assert handle.read(8) == b'\x89MCAP0\r\n'
    with Reader(path) as reader:
        assert len(list(reader.messages())) == len(original[1])
    assert _messages(path) == original[1]


def test_a_file_that_is_not_mcap_at_either_end_is_still_refused(tmp_path):
    path = tmp_path / 'not.mcap'
    path.write_bytes(b'XXXXXXXX' + bytes(100))
    with pytest.raises(ValueError, match='is not an MCAP file'):
        bag.repair_bag(str(path))


def test_summary_damage_gives_one_line_from_every_command(original, tmp_path):
    path, mcap_path = _copy(original, tmp_path)
    summary = _summary(mcap_path)
    offset = min(c.chunk_start_offset for c in summary.chunk_indexes)
    data = bytearray(open(mcap_path, 'rb').read())
    summary_start = struct.unpack_from('<Q', data, len(data) - 8 - 20)[0]
    at = data.index(struct.pack('<Q', offset), summary_start)
    data[at + 3] ^= 0x40           # the first chunk index now points past the file
    open(mcap_path, 'wb').write(bytes(data))
    for args in (('bag', 'info', path), ('allan', path, '--axis', 'z'),
                 ('bag', 'repair', path)):
        out = _cli(*args)
        assert 'Traceback' not in out.stderr and out.returncode == 0, (args, out.stderr)
        assert 'summary CRC mismatch' in out.stdout + out.stderr, args


def test_a_chunk_written_twice_without_summary_is_dropped_and_counted(original, tmp_path):
    path, mcap_path = _copy(original, tmp_path)
    chunks = sorted(_summary(mcap_path).chunk_indexes, key=lambda c: c.chunk_start_offset)
    data = open(mcap_path, 'rb').read()
    twice = chunks[3]
    block = data[twice.chunk_start_offset:chunks[4].chunk_start_offset]
    end = chunks[-1].chunk_start_offset + chunks[-1].chunk_length + \
        chunks[-1].message_index_length
    with open(mcap_path, 'wb') as handle:
        handle.write(data[:chunks[4].chunk_start_offset] + block
                     + data[chunks[4].chunk_start_offset:end])
    repeated = len([t for t, _ in original[1]
                    if twice.message_start_time <= t <= twice.message_end_time])
    reader = bag.BagReader(path, tolerant=True)
    assert reader.message_count == len(original[1])
    assert any(f'dropped {repeated} repeated messages' in p for p in reader.problems)
    assert _messages(path, tolerant=True) == original[1]
    report = bag.repair_bag(path)
    assert report.message_count == len(original[1])
    assert f'dropped {repeated} repeated messages' in report.describe()
    assert _messages(path) == original[1]


def test_overlapping_message_sequences_are_dropped(tmp_path):
    stamps = T0_NS + np.arange(300, dtype=np.int64) * 5_000_000
    payloads = cdr.encode(IMU, stamps, np.zeros((300, 37)), 'imu')
    path = str(tmp_path / 'overlap')
    os.makedirs(path)
    writer = McapFileWriter(os.path.join(path, 'overlap_0.mcap'), chunk_size=1 << 20)
    channel = writer.add_channel(TOPIC, writer.add_schema(IMU, bag.message_definition(IMU)))
    for first, last in ((0, 200), (100, 300)):       # 100..199 written twice
        for i in range(first, last):
            writer.write(channel, payloads[i], stamps[i], sequence=i)
        writer.flush()
    writer.finish()
    reader = bag.BagReader(path, tolerant=True)
    got = reader.read_arrays(TOPIC).log_time_ns
    np.testing.assert_array_equal(got, stamps)
    assert any('dropped 100 repeated messages' in p for p in reader.problems)
    report = bag.repair_bag(path)
    assert report.message_count == 300 and report.lost_messages == 0
    assert 'dropped 100 repeated messages' in report.describe()


def test_a_file_listed_twice_is_read_once(original, tmp_path):
    path, _ = _copy(original, tmp_path)
    meta_path = os.path.join(path, 'metadata.yaml')
    meta = yaml.safe_load(open(meta_path))
    files = meta['rosbag2_bagfile_information']['relative_file_paths']
    meta['rosbag2_bagfile_information']['relative_file_paths'] = files * 2
    yaml.safe_dump(meta, open(meta_path, 'w'))
    rec = record.load_record(path)
    assert len(rec.time_s) == len(original[1])
    assert any('more than once: read once' in n for n in rec.recovery)


@pytest.mark.parametrize('value', ['../../../../etc/passwd', '/etc/passwd', 'sub/../../x.yaml'])
def test_a_sensor_config_outside_the_bag_is_refused(original, tmp_path, value):
    from gyro_emulator.analysis.replay.run import bag_config
    path, _ = _copy(original, tmp_path)
    meta_path = os.path.join(path, 'metadata.yaml')
    meta = yaml.safe_load(open(meta_path))
    meta['rosbag2_bagfile_information']['custom_data'] = {'sensor_config': value}
    yaml.safe_dump(meta, open(meta_path, 'w'))
    with pytest.raises(ValueError, match='outside the bag directory') as caught:
        bag_config(bag.BagReader(path))
    assert _one_line(str(caught.value)) and 'root:' not in str(caught.value)
    inside = os.path.join(path, 'mine.yaml')
    meta['rosbag2_bagfile_information']['custom_data'] = {'sensor_config': 'mine.yaml'}
    yaml.safe_dump(meta, open(meta_path, 'w'))
    assert bag_config(bag.BagReader(path)) == os.path.realpath(inside)


@pytest.mark.parametrize('meta, match', [
    ('rosbag2_bagfile_information: 5\n', 'rosbag2_bagfile_information is 5'),
    ('rosbag2_bagfile_information: [1, 2]\n', r'is \[1, 2\] \(list\)'),
    ('rosbag2_bagfile_information: {relative_file_paths: 5}\n', 'relative_file_paths is 5'),
    ('rosbag2_bagfile_information: {relative_file_paths: [3]}\n', r'relative_file_paths\[0\]'),
    ('rosbag2_bagfile_information: {custom_data: [1, 2]}\n', 'custom_data is'),
    ('rosbag2_bagfile_information: {custom_data: {a: [1]}}\n', 'custom_data'),
    ('rosbag2_bagfile_information: {files: 7}\n', 'files is 7'),
    ('rosbag2_bagfile_information: {version: x}\n', 'version is'),
    ('[1, 2\n', 'malformed YAML'),
    ('x: &a [1]\ny: *a\n', 'alias'),
])
def test_hostile_metadata_is_one_line(original, tmp_path, meta, match):
    path, _ = _copy(original, tmp_path)
    with open(os.path.join(path, 'metadata.yaml'), 'w') as handle:
        handle.write(meta)
    with pytest.raises(ValueError, match=match) as caught:
        bag.BagReader(path)
    assert _one_line(str(caught.value))
    report = bag.repair_bag(path)            # repair regenerates it
    assert report.message_count == len(original[1]) and any('ignored' in n
                                                            for n in report.notes)
    assert _messages(path) == original[1]


def test_a_yaml_alias_bomb_is_refused_fast(original, tmp_path):
    path, _ = _copy(original, tmp_path)
    lines = ['rosbag2_bagfile_information:', '  custom_data:',
             '    a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for i in range(1, 10):
        lines.append(f'    a{i}: &a{i} [' + ', '.join([f'*a{i - 1}'] * 9) + ']')
    with open(os.path.join(path, 'metadata.yaml'), 'w') as handle:
        handle.write('\n'.join(lines) + '\n')
    begin = time.monotonic()
    with pytest.raises(ValueError, match='alias'):
        bag.BagReader(path)
    assert time.monotonic() - begin < 2.0


def _interrupted(original, tmp_path, keep_tmp):
    """Leave the state a kill between the two renames of an older repair left."""
    path, mcap_path = _copy(original, tmp_path)
    with open(mcap_path, 'r+b') as handle:       # damaged: no summary
        handle.truncate(os.path.getsize(mcap_path) - 100)
    scratch = str(tmp_path / 'scratch')
    shutil.copytree(path, scratch)
    bag.repair_bag(scratch, backup=False)
    os.replace(mcap_path, mcap_path + '.orig')
    if keep_tmp:
        shutil.copy(os.path.join(scratch, 'case_0.mcap'), mcap_path + '.repair-tmp')
    return path, mcap_path


@pytest.mark.parametrize('keep_tmp', [True, False])
def test_a_repair_killed_between_its_renames_is_recovered(original, tmp_path, keep_tmp):
    path, mcap_path = _interrupted(original, tmp_path, keep_tmp)
    info = _cli('bag', 'info', path)
    assert info.returncode == 0 and 'interrupted repair' in info.stdout, info.stderr
    report = bag.repair_bag(path)
    assert os.path.exists(mcap_path) and 'restored it from' in report.describe()
    assert _messages(path) == original[1][:len(_messages(path))]
    assert len(_messages(path)) > 0.9 * len(original[1])
    assert not os.path.exists(mcap_path + '.repair-tmp')


def test_a_repair_hitting_the_file_size_limit_leaves_no_temp_file(original, tmp_path):
    path, mcap_path = _copy(original, tmp_path)
    with open(mcap_path, 'r+b') as handle:
        handle.truncate(os.path.getsize(mcap_path) - 100)
    before = open(mcap_path, 'rb').read()
    limit = 64 * 1024

    def small_files():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    out = _cli('bag', 'repair', path, preexec_fn=small_files)
    assert out.returncode != 0 and _one_line(out.stderr), out.stderr
    assert sorted(os.listdir(path)) == ['case_0.mcap', 'metadata.yaml']
    assert open(mcap_path, 'rb').read() == before


def _chunk_stream(rng, count):
    """Yield (chunk, messages): tiny chunks overlapping in time, some repeating earlier ones."""
    from types import SimpleNamespace
    from mcap.records import Message
    made, seq = [], 0
    for k in range(count):
        size = 300 if k == count // 2 else int(rng.integers(1, 5))     # one large chunk
        messages = []
        for _ in range(size):
            if made and rng.random() < 0.15:
                messages.append(made[int(rng.integers(len(made)))])      # a repeat
            else:
                seq += 1
                t = 1000 * k + int(rng.integers(0, 20_000))                # overlapping times
                messages.append(Message(channel_id=1 + seq % 2, sequence=seq, log_time=t,
                                        publish_time=t, data=bytes(rng.integers(0, 256, 8))))
        made.extend(messages)
        times = [m.log_time for m in messages]
        data = b''.join(m.data for m in messages) + k.to_bytes(4, 'little')
        yield SimpleNamespace(message_start_time=min(times), message_end_time=max(times),
                              uncompressed_size=len(data), compression='', data=data), messages


@pytest.mark.parametrize('seed', range(5))
def test_the_small_chunk_screen_drops_exactly_what_the_full_comparison_drops(seed):
    """Tiny chunks are screened by one set of keys: the same messages kept as without it."""
    from gyro_emulator.recording.scan import Repeats
    screened, full = Repeats(), Repeats()
    full._small_keys = None                                       # the comparison alone
    known, dropped = set(), 0
    for chunk, messages in _chunk_stream(np.random.default_rng(seed), 400):
        got, want = screened.drop(chunk, messages), full.drop(chunk, messages)
        assert got == want
        # a message equal to an earlier one is dropped, and no other
        ids = [(m.channel_id, m.sequence, m.log_time, m.publish_time, m.data) for m in messages]
        assert [(m.channel_id, m.sequence, m.log_time, m.publish_time, m.data)
                for m in got[0]] == [i for i in ids if i not in known]
        known.update(ids)
        dropped += got[1]
    assert dropped > 100 and screened._small_keys is None    # repeats met; a large chunk seen


def test_bag_info_says_where_metadata_yaml_counts_other_messages_than_the_files(
        original, tmp_path):
    # rosbags and ros2 bag info report metadata.yaml's counts; bag info showed
    # the files' without a word, and did not point to repair, which rewrites it
    path, _ = _copy(original, tmp_path)
    meta = os.path.join(path, 'metadata.yaml')
    info = _cli('bag', 'info', path)
    assert 'Notice' not in info.stdout and 'repair' not in info.stdout, info.stdout
    with open(meta, encoding='utf-8') as handle:
        doc = yaml.safe_load(handle)
    doc['rosbag2_bagfile_information']['message_count'] = 99999
    doc['rosbag2_bagfile_information']['topics_with_message_count'][0]['message_count'] = 7
    with open(meta, 'w', encoding='utf-8') as handle:
        yaml.safe_dump(doc, handle)
    from pathlib import Path

    from rosbags.rosbag2 import Reader

    with Reader(Path(path)) as reader:
        assert reader.message_count == 99999           # what a rosbags user is told
    info = _cli('bag', 'info', path)
    assert info.returncode == 0 and 'Traceback' not in info.stderr
    assert ('metadata.yaml counts 99999 messages, the files hold 2000' in info.stdout
            and f'metadata.yaml counts 7 messages on {TOPIC}, the files hold 2000' in info.stdout
            and f'run: gyro-emulator bag repair {path}' in info.stdout), info.stdout
    bag.repair_bag(path)
    info = _cli('bag', 'info', path)
    assert 'Notice' not in info.stdout, info.stdout
    with Reader(Path(path)) as reader:
        assert reader.message_count == 2000
