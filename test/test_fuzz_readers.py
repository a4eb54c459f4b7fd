"""
Random bytes and random truncations fed to the CSV and bag readers (issue 14).

Each case must end in data or in a one-line ValueError / OSError, never in
another exception. Seeded: the same cases every run.
"""

import gzip
import os
import shutil

from gyro_emulator.analysis.diagnose.data import load_measured
from gyro_emulator.recording import bag, cdr, csvio
import numpy as np
import pytest

IMU = 'sensor_msgs/msg/Imu'
CLEAN_ERRORS = (ValueError, OSError)


def _one_line(exc):
    text = str(exc)
    return text and '\n' not in text and 'Traceback' not in text


def _csv_bytes(rows=200):
    lines = ['time_s,rate_cmd_rad_s,temp_c,gyro_rad_s']
    lines += [f'{i * 0.01:.2f},0.1,25.0,{1e-4 * i:.6f}' for i in range(rows)]
    return ('\n'.join(lines) + '\n').encode()


def _mutations(data, rng, count):
    """Yield the intact data, then ``count`` damaged copies (truncated, flipped, random)."""
    yield data
    for k in range(count):
        buf = bytearray(data)
        kind = k % 4
        if kind == 0:
            yield bytes(buf[:int(rng.integers(0, len(buf)))])
        elif kind == 1:
            for _ in range(int(rng.integers(1, 20))):
                buf[int(rng.integers(0, len(buf)))] = int(rng.integers(0, 256))
            yield bytes(buf)
        elif kind == 2:
            start = int(rng.integers(0, len(buf)))
            size = int(rng.integers(1, 400))
            buf[start:start + size] = rng.integers(0, 256, size, dtype=np.uint8).tobytes()
            yield bytes(buf)
        else:
            yield rng.integers(0, 256, int(rng.integers(0, 3000)), dtype=np.uint8).tobytes()


@pytest.mark.parametrize('compressed', [False, True])
def test_csv_readers_end_in_data_or_one_line(tmp_path, compressed):
    rng = np.random.default_rng(14)
    data = _csv_bytes()
    if compressed:
        data = gzip.compress(data)
    outcomes = {'data': 0, 'error': 0}
    for i, damaged in enumerate(_mutations(data, rng, 200)):
        path = tmp_path / (f'case{i}.csv' + ('.gz' if compressed else ''))
        path.write_bytes(damaged)
        for reader in (lambda p: csvio.read_csv(p, required=('time_s',)), load_measured,
                       lambda p: csvio.read_gyro_csv(p)):
            try:
                reader(str(path))
                outcomes['data'] += 1
            except CLEAN_ERRORS as exc:
                assert _one_line(exc), repr(exc)
                outcomes['error'] += 1
    # the cases do exercise both outcomes
    assert outcomes['data'] > 0 and outcomes['error'] > 0, outcomes


def test_diagnose_refuses_duplicate_columns(tmp_path):
    path = tmp_path / 'dup.csv'
    path.write_text('time_s,rate_cmd_rad_s,temp_c,gyro_rad_s,temp_c\n0,0,25,0,26\n')
    with pytest.raises(ValueError, match='duplicate column.*temp_c'):
        load_measured(str(path))


def _small_bag(path):
    n = 300
    stamps = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 5_000_000
    values = np.random.default_rng(1).normal(size=(n, len(cdr.LAYOUTS[IMU].fields)))
    with bag.BagWriter(path, chunk_size=4096) as writer:
        writer.add_topic('/imu/data_raw', IMU)
        writer.write_batches([('/imu/data_raw', cdr.encode(IMU, stamps, values, 'imu'),
                               stamps)])
    return os.path.join(path, os.path.basename(path) + '_0.mcap')


def test_bag_reader_ends_in_data_or_one_line(tmp_path):
    rng = np.random.default_rng(41)
    source = _small_bag(str(tmp_path / 'src'))
    data = open(source, 'rb').read()
    outcomes = {'data': 0, 'error': 0}
    for i, damaged in enumerate(_mutations(data, rng, 240)):
        case = tmp_path / f'case{i}'
        case.mkdir()
        (case / f'case{i}_0.mcap').write_bytes(damaged)
        try:
            reader = bag.BagReader(str(case), tolerant=True)
            for topic in reader.topics:
                reader.read_arrays(topic)
            outcomes['data'] += 1
        except CLEAN_ERRORS as exc:
            assert _one_line(exc), repr(exc)
            outcomes['error'] += 1
        shutil.rmtree(case)
    assert outcomes['data'] > 0 and outcomes['error'] > 0, outcomes


def _corrupt_middle_chunk(mcap_path, fill=0xFF):
    """Overwrite the payload of the middle chunk; return its (start, end) log times."""
    from mcap.reader import make_reader
    with open(mcap_path, 'rb') as handle:
        chunks = make_reader(handle).get_summary().chunk_indexes
    index = chunks[len(chunks) // 2]
    with open(mcap_path, 'r+b') as handle:
        handle.seek(index.chunk_start_offset + 9 + index.chunk_length // 2)
        handle.write(bytes([fill]) * 64)
    return index.message_start_time, index.message_end_time, len(chunks)


@pytest.mark.parametrize('fill', [0xFF, 0x00])
def test_a_corrupt_chunk_is_detected_skipped_and_reported(tmp_path, fill):
    path = str(tmp_path / 'bag')
    mcap_path = _small_bag(path)
    intact = bag.BagReader(path).read_arrays('/imu/data_raw').log_time_ns
    start, end, chunks = _corrupt_middle_chunk(mcap_path, fill)
    assert chunks >= 3
    reader = bag.BagReader(path, tolerant=True)
    got = reader.read_arrays('/imu/data_raw').log_time_ns
    lost = intact[(intact >= start) & (intact <= end)]
    # exactly the corrupt chunk's messages are gone, and the reader says so
    np.testing.assert_array_equal(got, intact[(intact < start) | (intact > end)])
    assert len(lost) > 0 and len(reader.corrupt_chunks) == 1
    assert reader.corrupt_chunks[0]['start_ns'] == start
    assert any('corrupt chunk' in p for p in reader.problems)
    with pytest.raises(ValueError, match='corrupt chunk at byte .*CRC|corrupt chunk at byte'):
        bag.BagReader(path).read_arrays('/imu/data_raw')


def test_allan_on_a_bag_with_a_corrupt_chunk_warns_and_runs(tmp_path):
    import subprocess
    import sys
    from conftest import ROOT
    path = str(tmp_path / 'bag')
    _corrupt_middle_chunk(_small_bag(path))
    proc = subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', 'allan', path, '--axis',
                           'z'], capture_output=True, text=True, cwd=ROOT, timeout=120,
                          env=dict(os.environ, PYTHONPATH=ROOT))
    assert proc.returncode == 0, proc.stderr
    assert 'warning:' in proc.stderr and 'corrupt chunk' in proc.stderr, proc.stderr
    assert 'Traceback' not in proc.stderr


@pytest.mark.parametrize('rel', ['../outside_0.mcap', '/etc/passwd', 'sub/../../x.mcap'])
def test_metadata_paths_leaving_the_bag_are_refused(tmp_path, rel):
    import yaml
    path = str(tmp_path / 'bag')
    _small_bag(path)
    meta_path = os.path.join(path, 'metadata.yaml')
    meta = yaml.safe_load(open(meta_path))
    meta['rosbag2_bagfile_information']['relative_file_paths'] = [rel]
    yaml.safe_dump(meta, open(meta_path, 'w'))
    with pytest.raises(ValueError, match='outside the bag directory'):
        bag.BagReader(path)


@pytest.mark.parametrize('type_name', ['os/msg/System', 'subprocess/Popen',
                                       'sensor_msgs/msg/../Imu', 'builtins/msg/Exec',
                                       'rclpy/msg/Node'])
def test_untrusted_type_names_never_reach_an_arbitrary_import(type_name):
    from gyro_emulator.ros import codec
    with pytest.raises(ValueError, match='not understood|no .msg definition|not installed'):
        codec.message_class(type_name)


def test_bag_info_and_repair_report_a_corrupt_chunk_of_a_complete_bag(tmp_path):
    path = str(tmp_path / 'bag')
    start, end, _ = _corrupt_middle_chunk(_small_bag(path))
    reader = bag.BagReader(path, tolerant=True)
    corrupt, lost = reader.verify()
    assert len(corrupt) == 1 and (corrupt[0]['start_ns'], corrupt[0]['end_ns']) == (start, end)
    assert 0 < lost < reader.message_count
    report = bag.repair_bag(path)
    assert report.lost_messages == lost and len(report.corrupt) == 1
    assert 'corrupt chunk' in report.describe()
    repaired = bag.BagReader(path)
    assert repaired.message_count == reader.message_count - lost
    assert repaired.verify() == ([], 0)


def _quoted(path, names, rows, quoting):
    """Write ``rows`` under ``names`` with Python's csv module (pandas' quoting options)."""
    import csv
    with open(path, 'w', newline='', encoding='utf-8') as handle:
        writer = csv.writer(handle, quoting=quoting)
        writer.writerow(names)
        writer.writerows(rows)
    return str(path)


@pytest.mark.parametrize('quoting', ['QUOTE_NONNUMERIC', 'QUOTE_ALL'])
def test_standard_csv_quoting_reads_as_the_plain_file(tmp_path, capsys, quoting):
    import csv
    names = ['time_s', 'gyro_x_rad_s', 'gyro_y_rad_s', 'gyro_z_rad_s', 'temp_c']
    rng = np.random.default_rng(7)
    rows = np.column_stack([np.arange(2000) / 100.0, rng.normal(0.0, 1e-3, (2000, 3)),
                            np.full(2000, 25.0)]).tolist()
    plain = str(tmp_path / 'plain.csv')
    csvio.write_csv(plain, {n: np.array([r[i] for r in rows]) for i, n in enumerate(names)},
                    '%r')
    path = _quoted(tmp_path / 'quoted.csv', names, rows, getattr(csv, quoting))
    assert open(path).readline().startswith('"time_s","gyro_x_rad_s"')
    want = csvio.read_csv(plain, required=('time_s',))
    got = csvio.read_csv(path, required=('time_s',))
    assert list(got) == names
    for name in names:
        np.testing.assert_array_equal(got[name], want[name])
    blocks = list(csvio.iter_csv_blocks(path, required=('time_s',), block_rows=700))
    np.testing.assert_array_equal(np.concatenate([b[1]['time_s'] for b in blocks]),
                                  want['time_s'])
    from gyro_emulator import cli
    assert cli.main(['allan', path, '--axis', 'y']) == 0, capsys.readouterr().err


@pytest.mark.parametrize('text,message', [
    ('"time_s,gyro_rad_s\n0,1\n', r'row 1 \'"time_s,gyro_rad_s\' is not valid CSV \(unexpected '
                                  r'end of data\)'),
    ('"time_s"x,gyro_rad_s\n0,1\n', r'row 1 .* is not valid CSV'),
    ('"time_s","gyro_rad_s",""\n0,1,2\n', r'header row 1 has an empty column name'),
    ('"time_s","gyro_rad_s",gyro_rad_s\n0,1,2\n', r'duplicate column\(s\) gyro_rad_s'),
    ('"time_s","gyro_rad_s"\n"0","1"\n"0.01","1,5"\n', r'row 3, column gyro_rad_s: \'1,5\' is '
                                                       r'not a number'),
])
def test_bad_quoting_is_one_line_naming_the_row(tmp_path, text, message):
    path = tmp_path / 'bad.csv'
    path.write_text(text)
    with pytest.raises(ValueError, match=message) as caught:
        csvio.read_csv(str(path), required=('time_s',))
    assert _one_line(caught.value)
