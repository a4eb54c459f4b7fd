"""The diagnose CSV contract, bag input and the decimated view."""

from gyro_emulator.analysis.diagnose import data as dd
from gyro_emulator.analysis.diagnose import diagnose
from gyro_emulator.analysis.diagnose.data import (load_measured, MeasuredData, Prepared,
                                                  write_measured_csv)
import numpy as np
import pytest


def _record(n=400, dt=0.01, seed=0, accel=True):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    accel_m_s2 = rng.normal(size=(n, 3)) if accel else None
    return MeasuredData(time_s=t, rate_cmd_rad_s=np.sin(2 * np.pi * 0.7 * t),
                        temp_c=25.0 + 0.1 * t, gyro_rad_s=rng.normal(size=n),
                        accel_m_s2=accel_m_s2)


def test_csv_round_trip_with_and_without_accel(tmp_path):
    for accel in (True, False):
        rec = _record(accel=accel)
        path = tmp_path / f'r{accel}.csv'
        write_measured_csv(path, rec)
        back = load_measured(path)
        assert back.rows == rec.rows and back.has_accel == accel
        np.testing.assert_allclose(back.gyro_rad_s, rec.gyro_rad_s, rtol=1e-8)
        np.testing.assert_allclose(back.temp_c, rec.temp_c, atol=1e-5)


def test_extra_columns_ignored_and_any_column_order(tmp_path):
    path = tmp_path / 'x.csv'
    rows = ['note,gyro_rad_s,temp_c,time_s,rate_cmd_rad_s']
    rows += [f'a,{0.1 * i},{20 + i},{i * 0.5},{0.0}' for i in range(30)]
    path.write_text('\n'.join(rows) + '\n')
    rec = load_measured(path)
    assert rec.rows == 30 and not rec.has_accel
    assert rec.gyro_rad_s[3] == pytest.approx(0.3)
    assert rec.time_s[-1] == pytest.approx(14.5)


def _csv(tmp_path, header, lines):
    path = tmp_path / 'bad.csv'
    path.write_text(header + '\n' + '\n'.join(lines) + '\n')
    return path


GOOD = [f'{i * 0.1},0,25,0.001' for i in range(30)]


def test_missing_column_names_it(tmp_path):
    path = _csv(tmp_path, 'time_s,temp_c,gyro_rad_s', [f'{i},25,0' for i in range(30)])
    with pytest.raises(ValueError, match='missing required column rate_cmd_rad_s.*--static'):
        load_measured(path)
    path = _csv(tmp_path, 'time_s,rate_cmd_rad_s,temp_c,rate_dps',
                [f'{i},0,25,0' for i in range(30)])
    # the message lists the file's columns, also those diagnose does not read
    with pytest.raises(ValueError, match='missing required column gyro_rad_s; the file has '
                       'time_s, rate_cmd_rad_s, temp_c, rate_dps$'):
        load_measured(path)


def test_static_three_axis_log_without_temperature(tmp_path):
    # the layout of the ADIS16405 and MPU-6050 static logs
    path = _csv(tmp_path, 'time_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s',
                [f'{0.01 * i},{i},{10 * i},{100 * i}' for i in range(30)])
    with pytest.raises(ValueError, match='choose an axis.*gyro_x_rad_s, gyro_y_rad_s'):
        load_measured(path, static=True)
    with pytest.raises(ValueError, match='rate_cmd_rad_s'):
        load_measured(path, axis='y')
    rec = load_measured(path, axis='y', static=True)
    assert not rec.has_temp and not rec.has_accel
    np.testing.assert_array_equal(rec.gyro_rad_s, 10.0 * np.arange(30))
    np.testing.assert_array_equal(rec.rate_cmd_rad_s, 0.0)
    assert rec.source.endswith('(gyro_y_rad_s)')
    with pytest.raises(ValueError, match="diagnose.axis = 'w' is not allowed"):
        load_measured(path, axis='w', static=True)
    # without temperature the contract round trips without the column
    write_measured_csv(tmp_path / 'back.csv', rec)
    back = load_measured(tmp_path / 'back.csv')
    assert not back.has_temp and back.rows == 30


@pytest.mark.parametrize('row,line,message', [
    (4, '0.4,0,hot,0.001', r"row 6, column temp_c: 'hot' is not a number"),
    (7, '0.7,0,25,nan', 'data row 8, column gyro_rad_s: nan is not finite'),
    (10, '0.85,0,25,0.001', 'time_s does not increase at data row 11: 0.85'),
])
def test_a_bad_cell_names_column_and_row(tmp_path, row, line, message):
    lines = list(GOOD)
    lines[row] = line
    path = _csv(tmp_path, 'time_s,rate_cmd_rad_s,temp_c,gyro_rad_s', lines)
    with pytest.raises(ValueError, match=message):
        load_measured(path)


def test_a_repeated_stamp_is_accepted(tmp_path):
    lines = list(GOOD)
    lines[10] = '0.9,0,25,0.001'
    path = _csv(tmp_path, 'time_s,rate_cmd_rad_s,temp_c,gyro_rad_s', lines)
    assert load_measured(path).rows == 30


def test_partial_acceleration_columns_rejected(tmp_path):
    path = _csv(tmp_path, 'time_s,rate_cmd_rad_s,temp_c,gyro_rad_s,accel_x_m_s2',
                [line + ',0' for line in GOOD])
    with pytest.raises(ValueError, match='acceleration needs all of'):
        load_measured(path)


def test_out_of_model_temperature_rejected():
    rec = _record()
    with pytest.raises(ValueError, match=r'temp_c = .* at sample 0 \(data row 1\) is beyond '
                                         r'\[-60, 200\] C \(the physics model range'):
        MeasuredData(time_s=rec.time_s, rate_cmd_rad_s=rec.rate_cmd_rad_s,
                     temp_c=rec.temp_c + 300, gyro_rad_s=rec.gyro_rad_s)


def test_bin_means_and_delayed_rate_match_sample_level():
    rec = _record(n=5000, dt=0.01)
    prep = Prepared(rec, max_bins=300)
    b = prep.binned
    assert len(b) == 300 and np.sum(b.weight) == rec.rows
    i0, i1 = prep.starts[17], prep.ends[17]
    assert b.rate2[17] == pytest.approx(np.mean(rec.rate_cmd_rad_s[i0:i1] ** 2))
    for delay in (0.0, 0.0137, 0.05, -0.02):
        samples = prep.samples.delayed_rate(delay)
        means = np.add.reduceat(samples, prep.starts) / b.weight
        np.testing.assert_allclose(prep.binned.delayed_rate(delay)[1:-1],
                                   means[1:-1], atol=1e-12)


def test_set_aside_samples_leave_the_bins_exactly():
    rec = _record(n=3000, dt=0.01)
    keep = np.ones(rec.rows, bool)
    keep[[0, 17, 18, 901, 902, 903, 2999]] = False
    prep = Prepared(rec, max_bins=1500, keep=keep)
    b = prep.binned
    assert np.sum(b.weight) == keep.sum() and len(prep.samples) == keep.sum()
    means = np.bincount(prep.sample_bin, weights=rec.gyro_rad_s[keep]) / b.weight
    np.testing.assert_allclose(b.gyro, means, rtol=1e-12)
    for delay in (0.0, 0.0137, -0.02):
        samples = prep.samples.delayed_rate(delay)
        exact = np.bincount(prep.sample_bin, weights=samples) / b.weight
        np.testing.assert_allclose(b.delayed_rate(delay), exact, atol=1e-12)
    # a set-aside sample alone in its bin drops the bin, not a neighbour's sum
    alone = Prepared(rec, max_bins=rec.rows, keep=keep)
    assert len(alone.binned) == keep.sum()
    np.testing.assert_allclose(alone.binned.delayed_rate(0.005),
                               alone.samples.delayed_rate(0.005), atol=1e-12)


def test_samples_set_aside_from_the_start_map_into_the_first_bin():
    # the first raw bin holds only set-aside samples: they map to the first bin (there is
    # none before), belong to no bin's sums, and the bin means of every sample stay exact
    rec = _record(n=3000, dt=0.01)
    keep = np.ones(rec.rows, bool)
    keep[:5] = False
    prep = Prepared(rec, max_bins=1500, keep=keep)
    assert prep.sample_bin_all.min() == 0 and np.array_equal(prep.sample_bin_all[:5], [0] * 5)
    means = np.bincount(prep.sample_bin, weights=rec.gyro_rad_s[keep]) / prep.binned.weight
    np.testing.assert_allclose(prep.bin_mean(rec.gyro_rad_s), means, rtol=1e-12)
    rate = np.sin(rec.time_s)
    exact = np.bincount(prep.sample_bin, weights=rate[keep]) / prep.binned.weight
    np.testing.assert_allclose(prep.bin_mean(rate), exact, rtol=1e-12)


def test_thermal_lag_is_exact_on_a_ramp():
    n, dt, slope, tau = 20000, 0.05, 0.02, 60.0
    t = np.arange(n) * dt
    rec = MeasuredData(time_s=t, rate_cmd_rad_s=np.zeros(n), temp_c=20 + slope * t,
                       gyro_rad_s=np.zeros(n))
    prep = Prepared(rec, max_bins=2000)
    lagged = prep.lagged_temp_on_bins(tau)
    tb = prep.binned.time_s
    # the filter starts in equilibrium at the first bin
    exact = 20 + slope * (tb - tau * (1 - np.exp(-(tb - tb[0]) / tau)))
    np.testing.assert_allclose(lagged, exact, atol=1e-6)
    rate = prep.temp_rate_on_bins
    assert np.median(rate) == pytest.approx(slope, rel=1e-6)


def _write_bag(path, rec, with_accel=True):
    from gyro_emulator.recording import bag, cdr, topics
    stamps = np.round(1_700_000_000e9 + rec.time_s * 1e9).astype(np.int64)
    imu = cdr.layout_of('sensor_msgs/msg/Imu')
    values = np.zeros((rec.rows, len(imu.fields)))
    values[:, imu.index('angular_velocity.z')] = rec.gyro_rad_s
    vec = np.zeros((rec.rows, 3))
    vec[:, 2] = rec.rate_cmd_rad_s
    temp = np.column_stack([rec.temp_c, np.zeros(rec.rows)])
    # the applied acceleration (gravity excluded), as the bag's custom_data says: the
    # rate is about z, so the attitude keeps gravity on z and adds it back exactly
    applied = rec.accel_m_s2 - [0.0, 0.0, 9.80665] if with_accel else None
    with bag.BagWriter(str(path), custom_data=dict(topics.ACCEL_CMD_MEANING)) as writer:
        batches = []
        for topic, vals in (
                (topics.RATE_CMD, vec), (topics.TEMPERATURE_CMD, temp),
                (topics.IMU_OUT, values)) + (
                ((topics.ACCEL_CMD, applied),) if with_accel else ()):
            writer.add_topic(topic.bag_name, topic.type_name)
            batches.append((topic.bag_name, cdr.encode(topic.type_name, stamps, vals), stamps))
        writer.write_batches(batches)


def test_bag_input_maps_topics_onto_the_contract(tmp_path):
    pytest.importorskip('gyro_emulator.recording.bag')
    rec = _record(n=600, dt=0.02)
    _write_bag(tmp_path / 'run', rec)
    back = dd.load_measured(str(tmp_path / 'run'))
    assert back.rows == rec.rows and back.has_accel
    np.testing.assert_allclose(back.time_s, rec.time_s, atol=1e-9)
    np.testing.assert_allclose(back.rate_cmd_rad_s, rec.rate_cmd_rad_s, atol=1e-12)
    np.testing.assert_allclose(back.temp_c, rec.temp_c, atol=1e-12)
    np.testing.assert_allclose(back.gyro_rad_s, rec.gyro_rad_s, atol=1e-12)
    np.testing.assert_allclose(back.accel_m_s2, rec.accel_m_s2, atol=1e-12)
    no_accel = dd.load_measured(str(tmp_path / 'run'), accel_topic='none')
    assert not no_accel.has_accel
    with pytest.raises(ValueError, match="no topic 'imu/nope' for the gyro"):
        dd.load_measured(str(tmp_path / 'run'), gyro_topic='imu/nope')


def test_a_bag_with_a_corrupt_chunk_is_read_and_says_what_was_lost(tmp_path):
    from test_fuzz_readers import _corrupt_middle_chunk
    rec = _record(n=1500, dt=0.02)
    _write_bag(tmp_path / 'run', rec)
    clean = dd.load_measured(str(tmp_path / 'run'))
    assert clean.recovery == ()
    _corrupt_middle_chunk(str(tmp_path / 'run' / 'run_0.mcap'))
    back = dd.load_measured(str(tmp_path / 'run'))
    assert 0 < back.rows < rec.rows
    assert len(back.recovery) >= 1 and 'corrupt chunk' in back.recovery[0]


def test_one_loader_for_csv_and_bag(tmp_path):
    from gyro_emulator.recording import record, topics
    rec = _record(n=300, dt=0.02)
    write_measured_csv(tmp_path / 'run.csv', rec)
    _write_bag(tmp_path / 'run', rec)
    csv = record.load_record(tmp_path / 'run.csv', required=('time_s',))
    assert not csv.is_bag and csv.recovery == () and 'gyro_rad_s' in csv.names
    assert csv.gyro_sources == {'x': 'gyro_rad_s'} and csv.rate.source == 'rate_cmd_rad_s'
    loaded = record.load_record(tmp_path / 'run', {'gyro': topics.IMU_OUT.name})
    assert loaded.is_bag and record.is_bag(loaded.path)
    assert loaded.topics['gyro'] == topics.IMU_OUT.bag_name and len(loaded.time_s) == rec.rows
    np.testing.assert_allclose(loaded.gyro['z'], rec.gyro_rad_s)
    reader = record.open_bag(tmp_path / 'run')
    topic = record.find_topic(reader, 'gyro', topics.IMU_OUT.name)
    stream = record.read_stream(reader, topic)
    assert topic == topics.IMU_OUT.bag_name and len(stream) == rec.rows
    np.testing.assert_array_equal(np.diff(stream.times_ns) > 0, True)
    np.testing.assert_allclose(stream.field('angular_velocity')[:, 2], rec.gyro_rad_s)
    for path in (tmp_path / 'run.csv', tmp_path / 'run'):
        back = dd.load_measured(str(path))
        np.testing.assert_allclose(back.gyro_rad_s, rec.gyro_rad_s, rtol=1e-8)


def test_stamp_rule_log_time_when_every_stamp_is_zero():
    from gyro_emulator.recording import streams

    class Arrays:
        stamp_ns = np.zeros(3, dtype=np.int64)
        log_time_ns = np.array([30, 10, 20], dtype=np.int64)

    times, order = streams.stream_times_ns(Arrays())
    np.testing.assert_array_equal(times, [10, 20, 30])
    np.testing.assert_array_equal(order, [1, 2, 0])
    Arrays.stamp_ns = np.array([5, 0, 7], dtype=np.int64)
    times, _ = streams.stream_times_ns(Arrays())
    np.testing.assert_array_equal(times, [0, 5, 7])
    times, _ = streams.stream_times_ns(Arrays(), use_log_time=True)
    np.testing.assert_array_equal(times, [10, 20, 30])


def test_a_record_built_from_arrays_is_the_measured_data_it_holds():
    from gyro_emulator.recording.record import Record
    rec = _record(n=300, dt=0.02)
    built = Record.from_arrays(rec.time_s, rec.gyro_rad_s, rec.rate_cmd_rad_s, rec.temp_c,
                               rec.accel_m_s2, path='synthetic')
    back = dd.measured(built)
    assert back.source == 'synthetic' and back.rows == rec.rows and back.has_accel
    for name in ('time_s', 'rate_cmd_rad_s', 'temp_c', 'gyro_rad_s', 'accel_m_s2'):
        np.testing.assert_array_equal(getattr(back, name), getattr(rec, name))
    assert dd.measured(back) is back


def test_a_stuck_output_is_refused_in_one_line(tmp_path):
    # was LAPACK's 'DLASCL parameter 4' on stderr and 'SVD did not converge'
    t = np.arange(0.0, 60.0, 0.01)
    path = tmp_path / 'stuck.csv'
    np.savetxt(path, np.column_stack([t, 0 * t, 25 + 0 * t, 1e-3 + 0 * t]), delimiter=',',
               header='time_s,rate_cmd_rad_s,temp_c,gyro_rad_s', comments='')
    with pytest.raises(ValueError, match=r'gyro_rad_s = 0\.001 in all 6000 samples: a stuck'):
        diagnose(load_measured(str(path)))


def test_simulate_csv_is_read_on_the_gyro_axis(tmp_path):
    # simulate writes rate_{x,y,z}_rad_s beside gyro_{x,y,z}_rad_s: each axis's
    # applied rate pairs with that axis's output (a rate about z only here)
    from gyro_emulator.emulation.simulate import write_record
    path = str(tmp_path / 'sim.csv')
    write_record(path, 'paper', 'steps', 40.0, 25.0, seed=3)
    z = load_measured(path, axis='z')
    x = load_measured(path, axis='x')
    assert np.ptp(z.rate_cmd_rad_s) > 1.0 and np.all(x.rate_cmd_rad_s == 0.0)
    # the output follows the applied rate it is paired with (scale factor near 1)
    slope = np.polyfit(z.rate_cmd_rad_s, z.gyro_rad_s, 1)[0]
    assert slope == pytest.approx(1.0, abs=0.05)
    with pytest.raises(ValueError, match='choose an axis'):
        load_measured(path)
