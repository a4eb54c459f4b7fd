"""A record's timing (rate, segments, missing samples) is worked out once and carried."""

from dataclasses import replace

from gyro_emulator.analysis.allan import analyse
from gyro_emulator.analysis.calibrate import noise, thermal
from gyro_emulator.recording import timing
from gyro_emulator.recording.record import Record
import numpy as np
import pytest


@pytest.fixture
def counted(monkeypatch):
    """Count the times stamps are read for their median step, segments and drops."""
    calls = []
    real = timing._median_step_and_segments

    def count(time_s, gap_factor):
        calls.append(len(time_s))
        return real(time_s, gap_factor)
    monkeypatch.setattr(timing, '_median_step_and_segments', count)
    return calls


def _static(n=60_000, rate_hz=100.0, seed=3, drop=0.0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate_hz
    keep = rng.random(n) >= drop
    gyro = rng.standard_normal((n, 3)) * 1e-3
    return Record.from_arrays(t[keep], gyro[keep], path='static')


def test_timing_facts_of_stamps_with_a_gap_and_drops():
    t = np.r_[np.arange(100) * 0.02, 100.0 + np.arange(50) * 0.02]
    t = np.delete(t, [10, 20, 21])       # 3 samples lost inside the first segment
    found = timing.timing_of(t)
    assert found.rate_hz == pytest.approx(50.0) and found.median_step_s == pytest.approx(0.02)
    assert found.bounds == ((0, 97), (97, 147)) and found.missing == 3
    assert found.gap_factor == timing.GAP_FACTOR and found.time_s is not None
    values = np.arange(147.0)
    assert [len(s) for s in found.segments(values)] == [97, 50]
    assert [len(s) for s in found.segments(values, min_samples=60)] == [97]
    assert found.kept(np.ones(len(t), bool)) is found
    keep = np.arange(len(t)) >= 5
    assert found.kept(keep).bounds == timing.timing_of(t[keep]).bounds
    with pytest.raises(ValueError, match='need >= 2'):
        timing.timing_of([1.0])


def test_a_record_works_its_timing_out_once_per_gap_factor(counted):
    record = _static(2000)
    first = record.timing()
    assert record.timing() is first and record.timing(3) is first and len(counted) == 1
    wide = record.timing(10.0)
    assert wide is not first and wide.gap_factor == 10.0 and len(counted) == 2
    moved = replace(record, time_s=record.time_s * 2.0)
    assert moved.timing().rate_hz == pytest.approx(first.rate_hz / 2.0)      # not carried over
    assert record == replace(record)                                       # no part of equality


def test_calibrate_noise_and_allan_read_the_records_timing(counted):
    """Three axes, one timing (it was worked out 7 times: 2 per axis, 1 for the missing note)."""
    record = _static(drop=0.01)
    cal = noise.calibrate_noise(record)
    assert len(cal.axes) == 3 and len(counted) == 1
    assert cal.rate_hz == pytest.approx(100.0) and 'missing between stamps' in cal.timing[0]
    info, _, _ = analyse.analyse_record(record, 'y')
    assert len(counted) == 1                             # the record carries it
    assert info['timing'] == list(cal.timing) and info['sample_rate_hz'] == cal.rate_hz


def test_a_stretch_cut_out_is_the_one_new_timing(counted):
    """Set-aside stretches longer than FILL_MAX_S split the record: the kept samples' timing."""
    record = _static(n=120_000)
    rate = record.gyro['x'].copy()
    rate[50_000:53_000] += 0.5 * np.sin(np.arange(3000) * 0.2)    # 30 s of motion
    rate_hz, segments, screened, handled = analyse.screened_segments(record.timing(), rate)
    assert handled['cut'] >= 3000 and len(segments) == 2 and len(counted) == 2
    assert rate_hz == pytest.approx(100.0)


def test_thermal_fit_and_its_noise_read_one_timing_per_record(counted):
    """Three axes of one file: one timing (it was worked out 12 times)."""
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 7200.0, 0.1)
    temp = 10.0 + 40.0 * t / t[-1]
    gyro = (0.003 + 1e-4 * (temp - 30.0))[:, None] + rng.standard_normal((len(t), 3)) * 1e-3
    record = Record.from_arrays(t, gyro, temp_c=temp, path='ramp')
    log = thermal.thermal_log([record])
    fit = thermal.with_white_noise(thermal.fit_thermal(log, 1), log)
    assert set(fit.coefficients) == {'x', 'y', 'z'} and len(counted) == 1
    assert log.axis_timing('z') is record.timing()
    assert 1.0 / log.axis_timing('x').median_step_s == pytest.approx(10.0)
