"""Spikes and motion set aside in records at rest: allan, calibrate noise and thermal."""

import math

from gyro_emulator import cli
from gyro_emulator.analysis import allan, outliers
from gyro_emulator.analysis.calibrate import noise as cal_noise, thermal
from gyro_emulator.emulation.truth.generator import make_truth
from gyro_emulator.recording import timing
from gyro_emulator.recording.record import load_record
import numpy as np
import pytest
from scipy import signal


def _read_log(paths):
    return thermal.thermal_log([load_record(p, required=thermal.REQUIRED_COLUMNS)
                                for p in paths])


RATE_HZ = 100.0


def _static_noise(rng, n, sigma=1e-3, rho=0.0, walk=2e-6, flicker=2e-4):
    """White (optionally AR(1)-filtered), a random walk and a slow Gauss-Markov wander, rad/s."""
    white = rng.standard_normal(n) * sigma
    if rho:
        white = signal.lfilter([math.sqrt(1 - rho ** 2)], [1.0, -rho], white)
    walk = np.cumsum(rng.standard_normal(n)) * walk
    phi = math.exp(-1.0 / (RATE_HZ * 300.0))
    wander = signal.lfilter([flicker * math.sqrt(1 - phi ** 2)], [1.0, -phi],
                            rng.standard_normal(n))
    return white + walk + wander + 0.01


def _bump(rng, n_samples, peak_rad_s):
    """Return a handling bump: band-limited motion under a half-sine window."""
    b, a = signal.butter(2, 3.0 / (0.5 * RATE_HZ))
    motion = signal.lfilter(b, a, rng.standard_normal(n_samples + 100))[100:]
    motion *= peak_rad_s / np.max(np.abs(motion))
    return motion * np.sin(np.pi * np.arange(n_samples) / n_samples)


@pytest.mark.parametrize('rho', [0.0, 0.6])
def test_clean_records_lose_nothing(rho):
    """False alarms: 40 seeded records of 50 000 samples at rest, white or filtered noise."""
    t = np.arange(50_000) / RATE_HZ
    lost = 0
    for seed in range(40):
        x = _static_noise(np.random.default_rng(seed), len(t), rho=rho)
        lost += outliers.screen_at_rest(t, x, 1.0 / RATE_HZ).count
    # 2e6 samples x 2e-9 (two-sided 6 sigma): 0.004 expected
    assert lost == 0


@pytest.mark.parametrize('noise_lsb', [0.2, 0.5, 1.0, 3.0])
def test_a_quantised_output_moving_by_whole_lsbs_is_not_an_outlier(noise_lsb):
    t = np.arange(100_000) / RATE_HZ
    lsb = 1e-3
    x = np.round(np.random.default_rng(7).standard_normal(len(t)) * noise_lsb) * lsb
    assert outliers.quantisation_step(x) == pytest.approx(lsb)
    assert outliers.screen_at_rest(t, x, 1.0 / RATE_HZ).count == 0
    # a real spike on the same grid still stands out
    x[5000] += 40 * lsb * max(noise_lsb, 1.0)
    found = outliers.screen_at_rest(t, x, 1.0 / RATE_HZ)
    assert found.count == 1 and found.spans[0][0] == pytest.approx(t[5000])


def test_spikes_and_a_bump_are_found_and_reported():
    rng = np.random.default_rng(11)
    t = np.arange(200_000) / RATE_HZ
    x = _static_noise(rng, len(t))
    where = rng.choice(np.arange(1000, len(t) - 1000), 60, replace=False)
    x[where] += rng.choice([-1, 1], 60) * rng.uniform(0.015, 0.3, 60)   # 15 to 300 sigma
    start = 120_000
    x[start:start + 400] += _bump(rng, 400, 0.2)                       # a 4 s bump
    found = outliers.screen_at_rest(t, x, 1.0 / RATE_HZ)
    assert np.all(~found.keep[where])
    # (two spikes less than 1 s apart also make a stretch: about 2 such pairs expected)
    bump = [s for s in found.spans if s[0] <= t[start + 200] <= s[1]]
    assert len(bump) == 1
    lo, hi, _ = bump[0]
    # the bump's visible part is inside the stretch, widened by 1 s for its settling
    assert lo <= t[start + 60] and hi >= t[start + 340]
    assert hi - lo < 4.0 + 2 * outliers.MERGE_S + 0.5
    assert found.fraction < 0.01          # 60 spikes, a 6 s stretch, a pair or two: not more
    line = found.describe()
    assert line.startswith(f'set aside {found.count} samples') and 'stretches' in line


def test_a_record_that_is_not_at_rest_is_left_alone_and_says_so():
    t = np.arange(20_000) / RATE_HZ
    rng = np.random.default_rng(3)
    x = _static_noise(rng, len(t)) + np.where(rng.random(len(t)) < 0.3, 0.5, 0.0)
    found = outliers.screen_at_rest(t, x, 1.0 / RATE_HZ)
    assert found.count == 0 and 'not at rest' in found.note


def test_the_noise_fit_survives_spikes_and_handling_motion():
    """The truth generator's lab outliers: N and B as on the clean record, 10x off without."""
    clean, _ = make_truth('none', 5, profile='static', sample_rate_hz=RATE_HZ,
                          duration_s=3600.0)
    dirty, truth = make_truth('none', 5, profile='static', sample_rate_hz=RATE_HZ,
                              duration_s=3600.0, outliers='spikes+motion')
    assert truth['outliers']['spikes'] > 0 and truth['outliers']['motion_s']
    fits = {}
    for name, rec, threshold in (('clean', clean, outliers.THRESHOLD),
                                 ('screened', dirty, outliers.THRESHOLD),
                                 ('kept', dirty, math.inf)):
        rate_hz, segments, found, handled = allan.screened_segments(
            rec.timing(), rec.gyro['x'], threshold=threshold)
        fits[name] = (allan.identify(segments, rate_hz)[1], found, handled)
    n_clean = fits['clean'][0].intervals['arw']
    n = fits['screened'][0].arw_rad_s_sqrt_hz
    assert fits['clean'][1].count == 0
    # the screened N inside the clean fit's 95 % interval, widened by the filled share
    share = fits['screened'][1].fraction
    assert n_clean.low * (1 - share) <= n <= n_clean.high
    assert fits['kept'][0].arw_rad_s_sqrt_hz > 3 * n
    spikes = truth['outliers']['spike_times_s']
    kept = fits['screened'][1].keep
    idx = np.searchsorted(dirty.time_s, spikes)
    assert np.mean(~kept[idx]) >= 0.9
    assert fits['screened'][2]['filled'] + fits['screened'][2]['cut'] == fits['screened'][1].count


def _thermal_log(path, outliers_kind):
    rec, truth = make_truth('bias_temperature', 4, profile='thermal_cycle', sample_rate_hz=10.0,
                            duration_s=20000.0, outliers=outliers_kind)
    with open(path, 'w', encoding='utf-8') as handle:
        handle.write('time_s,temp_c,gyro_rad_s\n')
        for row in zip(rec.time_s, rec.temp.values, rec.gyro['x']):
            handle.write('%.3f,%.5f,%.9g\n' % row)
    return str(path), truth


def test_thermal_fit_survives_spikes_and_motion(tmp_path):
    clean, _ = _thermal_log(tmp_path / 'clean.csv', None)
    dirty, truth = _thermal_log(tmp_path / 'dirty.csv', 'spikes+motion')
    ref = thermal.fit_thermal(_read_log([clean]))
    fit = thermal.fit_thermal(_read_log([dirty]))
    kept = thermal.fit_thermal(_read_log([dirty]), outlier_threshold=math.inf)
    slope, err = ref.coefficients['x'][1], ref.errors['x'][1]
    assert fit.order == ref.order
    assert abs(fit.coefficients['x'][1] - slope) < 3 * err
    assert fit.set_aside['x'].count >= truth['outliers']['spikes']
    assert any('set aside' in note for note in fit.notes)
    # every sample kept: the spikes swamp the group noise
    assert kept.group_noise['x'] > 5 * fit.group_noise['x']


def test_cli_reports_and_can_keep_every_sample(tmp_path, capsys):
    t = np.arange(60_000) / RATE_HZ
    x = _static_noise(np.random.default_rng(2), len(t))
    x[[1000, 20000, 40000]] += 0.2
    path = tmp_path / 'static.csv'
    np.savetxt(path, np.column_stack([t, x]), delimiter=',', header='time_s,gyro_rad_s',
               comments='', fmt='%.9g')
    assert cli.main(['allan', str(path), '--json', str(tmp_path / 'a.json')]) == 0
    assert 'set aside 3 samples' in capsys.readouterr().out
    assert cli.main(['allan', str(path), '--keep-outliers']) == 0
    assert 'outlier screening off' in capsys.readouterr().out
    out = tmp_path / 'imu.yaml'
    assert cli.main(['calibrate', 'noise', str(path), '--format', 'kalibr', '-o',
                     str(out)]) == 0
    assert '#   set aside 3 samples' in out.read_text()
    cal = cal_noise.calibrate_noise(load_record(str(path)))
    assert cal.axes[0].set_aside['count'] == 3 and cal.axes[0].set_aside['filled'] == 3


def test_a_stuck_or_saturated_axis_is_left_out_and_named(tmp_path):
    """A dead z axis (all 0) or one pinned at full scale: x and y calibrated, z named."""
    t = np.arange(120_000) / RATE_HZ
    rng = np.random.default_rng(4)
    x, y = _static_noise(rng, len(t)), _static_noise(rng, len(t))
    for name, z in (('dead', np.zeros(len(t))), ('pinned', np.full(len(t), 34.906585))):
        path = tmp_path / f'{name}.csv'
        temp = 20.0 + 20.0 * t / t[-1]
        np.savetxt(path, np.column_stack([t, x, y, z, temp]), delimiter=',', comments='',
                   header='time_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,temp_c', fmt='%.10g')
        cal = cal_noise.calibrate_noise(load_record(str(path)))
        assert [a.axis for a in cal.axes] == ['x', 'y']
        assert len(cal.skipped) == 1 and cal.skipped[0].startswith('axis z holds one value')
        with pytest.raises(ValueError, match='axis z holds one value'):
            cal_noise.calibrate_noise(load_record(str(path)), axes=('z',))
        fit = thermal.fit_thermal(_read_log([str(path)]))
        assert set(fit.coefficients) == {'x', 'y'}
        assert any('axis z holds one value' in note for note in fit.notes)
    # a noisy quantised output repeats a value for a few samples, never for a second
    q = np.round(np.random.default_rng(5).standard_normal(len(t)) * 0.4)
    assert outliers.held_share(q, RATE_HZ)[0] == 0.0


@pytest.mark.parametrize('stamping', ['milliseconds', 'fifo'])
def test_coarse_or_shared_timestamps_give_the_true_rate(stamping):
    """A 416.7 Hz part stamped in whole ms (steps 2 and 3 ms), or a FIFO of 3 per stamp."""
    rate_hz = 1000.0 / 2.4 if stamping == 'milliseconds' else 100.0
    n = 400_000 if stamping == 'milliseconds' else 60_000
    true_t = np.arange(n) / rate_hz
    t = (np.floor(true_t * 1000.0) / 1000.0 if stamping == 'milliseconds'
         else np.repeat(true_t[::3], 3)[:n])
    x = np.random.default_rng(6).standard_normal(n) * 1e-3
    found = timing.timing_of(t)
    got, segments = found.rate_hz, found.bounds
    assert got == pytest.approx(rate_hz, rel=1e-3) and len(segments) == 1
    _, fit = allan.identify([x], got)
    density = 1e-3 / math.sqrt(rate_hz)
    assert fit.intervals['arw'].low <= density <= fit.intervals['arw'].high


@pytest.mark.parametrize('share', [0.001, 0.01, 0.05, 0.2])
def test_dropped_samples_keep_the_nominal_rate_and_are_counted(share):
    """
    A 100 Hz part that lost a share of its samples at random (the helper's case).

    The mean step reads 83 Hz at 20 % loss, which put N 10 % high with a
    0.3 % interval: the rate stays 100 Hz and the samples missing inside the
    segments (1 or 2 in a row; 3 or more make a gap) are counted.
    """
    rng = np.random.default_rng(int(share * 1000))
    n = 200_000
    t = np.arange(n) / RATE_HZ + 7.0
    keep = rng.random(n) >= share
    found = timing.timing_of(t[keep])
    rate_hz, bounds = found.rate_hz, found.bounds
    assert rate_hz == pytest.approx(RATE_HZ, rel=1e-9)
    index = np.flatnonzero(keep)
    steps = np.diff(index)
    # a step of exactly 3 periods sits on the gap threshold: either side is right
    missing = found.missing
    assert np.sum(steps[steps <= 2] - 1) <= missing <= np.sum(steps[steps <= 3] - 1)
    assert 1 + np.sum(steps > 3) <= len(bounds) <= 1 + np.sum(steps > 2)


@pytest.mark.parametrize('rate_hz', [1200.0, 990.0, 900.0, 700.0, 1000.0 / 2.4, 333.3, 250.3])
def test_a_faster_part_on_a_millisecond_clock_is_not_read_as_dropped_samples(rate_hz):
    """Steps of 1 and 2 ms at a fixed beat (or 0 and 1, 2 and 3 ms): true rate, none missing."""
    t = np.floor(np.arange(300_000) / rate_hz * 1000.0) / 1000.0
    found = timing.timing_of(t)
    assert found.rate_hz == pytest.approx(rate_hz, rel=2e-3)
    assert found.missing == 0


def test_calibrate_noise_on_a_log_with_dropped_samples_gets_n_and_says_what_is_missing(
        tmp_path, capsys):
    """5 % of a 100 Hz log lost: N within its interval of the truth, and a timing warning."""
    rng = np.random.default_rng(41)
    n = 180_000
    t = np.arange(n) / RATE_HZ
    x = _static_noise(rng, n, flicker=0.0)
    keep = rng.random(n) >= 0.05
    path = tmp_path / 'lossy.csv'
    np.savetxt(path, np.column_stack([t[keep], x[keep]]), delimiter=',',
               header='time_s,gyro_x_rad_s', comments='', fmt='%.10g')
    cal = cal_noise.calibrate_noise(load_record(str(path)))
    assert cal.rate_hz == pytest.approx(RATE_HZ)
    arw = cal.axes[0].fit.intervals['arw']
    truth = 1e-3 / math.sqrt(RATE_HZ)
    assert arw.low <= truth <= arw.high
    assert len(cal.timing) == 1 and 'missing between stamps' in cal.timing[0]
    clean = tmp_path / 'clean.csv'
    np.savetxt(clean, np.column_stack([t, x]), delimiter=',', header='time_s,gyro_x_rad_s',
               comments='', fmt='%.10g')
    assert cal_noise.calibrate_noise(load_record(str(clean))).timing == ()


def test_a_shock_that_moves_the_bias_splits_the_record():
    """A 3 s bump after which the bias sits about 14 sigma (of 10 s means) higher: cut."""
    rng = np.random.default_rng(8)
    t = np.arange(360_000) / RATE_HZ
    x = _static_noise(rng, len(t), flicker=0.0)
    x[180_000:] += 1e-3
    x[179_800:180_100] += _bump(rng, 300, 0.3)
    rate_hz, segments, found, handled = allan.screened_segments(timing.timing_of(t), x)
    assert len(handled['level_shifts']) == 1
    assert handled['level_shifts'][0]['shift_rad_s'] == pytest.approx(1e-3, rel=0.3)
    assert len(segments) == 2 and handled['filled'] == 0
    # the same bump without the step is filled: one segment
    y = _static_noise(np.random.default_rng(8), len(t), flicker=0.0)
    y[179_800:180_100] += _bump(np.random.default_rng(9), 300, 0.3)
    _, segments, _, handled = allan.screened_segments(timing.timing_of(t), y)
    assert handled['level_shifts'] == [] and len(segments) == 1


def test_thermal_range_and_windows_survive_glitches_and_logging_gaps(tmp_path):
    """Three -40 C temperature reads and three logging gaps in a 10 -> 50 C ramp."""
    t = np.arange(0.0, 7200.0, 0.1)
    temp = 10.0 + 40.0 * t / t[-1]
    temp[[1000, 30000, 60000]] = -40.0
    rate = 0.003 + 1e-4 * (temp - 30.0) + np.random.default_rng(3).standard_normal(len(t)) * 1e-3
    keep = ~(((t > 1800) & (t < 1830)) | ((t > 3600) & (t < 3630)) | ((t > 5400) & (t < 5430)))
    path = tmp_path / 'ramp.csv'
    np.savetxt(path, np.column_stack([t[keep], temp[keep], rate[keep]]), delimiter=',',
               header='time_s,temp_c,gyro_rad_s', comments='', fmt='%.10g')
    fit = thermal.fit_thermal(_read_log([str(path)]))
    assert 'windows of 60 s in 4 stretches' in fit.grouping
    assert 10.0 <= fit.temp_min_c < 11.0 and 49.0 < fit.temp_max_c <= 50.0
    assert fit.span_k > 38.0


def test_a_warm_up_at_the_start_is_warned_and_clean_records_are_not():
    """A bias settling by 0.05 deg/s (300 s) in a 2 h log; 300 records without one stay quiet."""
    rng = np.random.default_rng(12)
    t = np.arange(720_000) / RATE_HZ
    x = _static_noise(rng, len(t), walk=2e-7, flicker=0.0) + 8.7e-4 * np.exp(-t / 300.0)
    _, fit = allan.identify([x], RATE_HZ)
    assert any('warm-up' in w for w in fit.warnings)
    warned = sum(allan.start_transient(_static_noise(np.random.default_rng(s), 60_000,
                                                     walk=(2e-6, 2e-5)[s % 2]), RATE_HZ)
                 is not None for s in range(300))
    assert warned == 0
