"""
The emulated twin of a measured part: its noise model, and the round trip back to the log.

The IEEE Std 952 terms are what an estimator needs; the emulator can do a
little more. Its bias instability is a sum of Gauss-Markov terms across a
band of correlation times (:mod:`gyro_emulator.sensor.noise`), so a floor
that falls again at long tau (bias fluctuations with correlation times up
to some T_max) is within its reach. :func:`emulator_fit` fits the
emulator's own Allan model, white + flicker(band) + rate random walk, to
the measured curves over the taus the IEEE fit used, with one band for all
axes (the preset has one): T_max is the flat band (three times the longest
tau) unless a shorter one lowers the weighted sum of squares by more than
:data:`BAND_IMPROVEMENT` (the same weights as the IEEE fit, with its model
discrepancy).

:func:`check_noise` is the round trip: it simulates the fitted preset with
``gyro_emulator.emulation.simulate`` (what ``simulate --config fitted.yaml``
runs) for several seeds at the log's rate and length, and compares the mean
Allan deviation of the simulated records with the log's at every octave tau
from 0.1 s to a tenth of the record. :func:`check_thermal` simulates a
thermal preset along the log's temperature and compares the bias of each
group of samples with the log's.
"""

from dataclasses import dataclass, replace

from gyro_emulator.analysis import allan
from gyro_emulator.analysis.allan import fit as fitting
from gyro_emulator.analysis.calibrate import thermal
from gyro_emulator.emulation import profiles, simulate
from gyro_emulator.sensor import noise as sensor_noise
from gyro_emulator.units import AXES
import numpy as np

#: Gauss-Markov terms per decade of the twin's flicker model.
PER_DECADE = 2.0
#: Weighted sum of squares a shorter flicker band must save to be used.
BAND_IMPROVEMENT = 10.0
#: Round-trip tolerance on the Allan deviation (relative).
ADEV_TOLERANCE = 0.10


def flicker_avar_per_b2(taus_s, band_s, per_decade=PER_DECADE):
    """Allan variance of the emulator's flicker model per unit B^2 (sum of Gauss-Markov terms)."""
    corr = sensor_noise.flicker_corr_times_s(band_s, per_decade)
    unit = sensor_noise.flicker_unit_variance(corr)
    return sum(sensor_noise.gauss_markov_avar(q, t, taus_s) for q, t in zip(unit, corr))


def emulator_design(taus_s, band_s):
    """Columns of the emulator's Allan variance for (N^2, B^2, K^2): white, flicker(band), walk."""
    taus = np.asarray(taus_s, dtype=float)
    return np.column_stack([1.0 / taus, flicker_avar_per_b2(taus, band_s), taus / 3.0])


@dataclass(frozen=True)
class EmulatorFit:
    """
    The twin's noise: one flicker band, and (N, B, K) per axis in rad/s units.

    ``flat_band_s`` is the band that keeps B flat over the taus used;
    ``band_s`` the one chosen; ``saving`` the weighted sum of squares it
    saved over the flat band (0 when the flat band is kept).
    """

    band_s: tuple
    flat_band_s: tuple
    per_axis: dict
    saving: float

    def adev(self, axis, taus_s, lsb_rad_s=0.0, rate_hz=None):
        """Return the twin's expected Allan deviation, rad/s (quantisation as white noise)."""
        n, b, k = self.per_axis[axis]
        extra = 0.0 if not lsb_rad_s or rate_hz is None else lsb_rad_s ** 2 / 12.0 / rate_hz
        theta = np.array([n ** 2 + extra, b ** 2, k ** 2])
        return np.sqrt(emulator_design(taus_s, self.band_s) @ theta)


def _axis_cost(item, band):
    fit = item.fit
    sel = (item.result.taus_s >= fit.tau_range_s[0] * (1 - 1e-9))
    taus = item.result.taus_s[sel]
    log_avar = fitting.log_avar_unbiased(item.result.adev[sel] ** 2, item.result.edf[sel])
    var = 2.0 / np.maximum(item.result.edf[sel], 1.0) + (2.0 * fit.misfit) ** 2
    a = emulator_design(taus, band)
    start = np.array([max(fit.arw_rad_s_sqrt_hz ** 2, 1e-30),
                      max(fit.bias_instability_rad_s ** 2, 1e-30),
                      max(fit.rrw_rad_s_sqrt_s ** 2, 1e-30)])
    theta, cost = fitting.log_nnls(a, [0, 1, 2], log_avar, var, start)
    return theta, cost


def emulator_fit(calibration, flat_band_s):
    """
    Fit the twin's noise model to every axis (module docstring).

    ``flat_band_s`` is the band that keeps B flat over the taus used (the
    preset's default); a shorter upper end is tried on a grid of 8 per decade.
    """
    lsb2 = calibration.lsb_rad_s ** 2 / 12.0 / calibration.rate_hz
    lo, hi = flat_band_s
    candidates = [hi] + list(np.logspace(np.log10(max(10.0, 30.0 * lo)), np.log10(hi), int(
        8 * np.log10(hi / max(10.0, 30.0 * lo))) + 1)[:-1])
    results = []
    for upper in candidates:
        band = (lo, float(upper))
        fits = {item.axis: _axis_cost(item, band) for item in calibration.axes}
        results.append((sum(c for _, c in fits.values()), band, fits))
    flat_cost = results[0][0]
    best = min(results, key=lambda r: r[0])
    if flat_cost - best[0] < BAND_IMPROVEMENT:
        best = results[0]
    cost, band, fits = best
    # the log's white noise includes its quantisation (LSB^2 / 12 per sample),
    # which the twin adds back with its own quantiser
    per_axis = {axis: (float(np.sqrt(max(theta[0] - lsb2, 0.0))), float(np.sqrt(theta[1])),
                       float(np.sqrt(theta[2]))) for axis, (theta, _) in fits.items()}
    return EmulatorFit(band_s=band, flat_band_s=(lo, hi), per_axis=per_axis,
                       saving=float(flat_cost - cost))


def octave_taus(rate_hz, duration_s, start_s=0.1):
    """Octave taus start_s 2^k up to a tenth of the record, rounded to whole samples."""
    taus = start_s * 2.0 ** np.arange(0, 40)
    taus = taus[taus <= duration_s / 10.0 * (1 + 1e-9)]
    m = np.unique(np.maximum(np.round(taus * rate_hz), 1))
    return m / rate_hz


@dataclass(frozen=True)
class NoiseCheck:
    """
    Round trip of a noise preset against its log.

    ``taus_s`` the octave taus; per axis: ``measured`` (AllanResult of the
    log), ``simulated`` (AllanResults, one per seed), ``twin`` (their mean
    deviation), ``ratio`` (twin / measured - 1), ``passed`` (|ratio| <= 10 %
    at every tau) and ``consistent`` (at every tau within 10 % or inside the
    log's own 95 % interval: where a 2 h log cannot pin its Allan deviation
    to 10 %, a perfect twin cannot match it to 10 % either). ``accel`` is
    the same check of the accelerometer (None: not checked).
    """

    taus_s: np.ndarray
    seeds: tuple
    measured: dict
    simulated: dict
    twin: dict
    ratio: dict
    passed: dict
    consistent: dict
    accel: object = None


def _verdicts(taus, seeds, measured, simulated):
    """Return the :class:`NoiseCheck` of measured and simulated Allan deviations per axis."""
    twin = {axis: np.mean([r.adev for r in runs], axis=0) for axis, runs in simulated.items()}
    ratio = {axis: twin[axis] / measured[axis].adev - 1.0 for axis in twin}
    passed = {axis: bool(np.all(np.abs(r) <= ADEV_TOLERANCE)) for axis, r in ratio.items()}
    consistent = {}
    for axis, r in ratio.items():
        lo, hi = allan.confidence_interval(measured[axis].adev, measured[axis].edf, 0.95)
        inside = (twin[axis] >= lo) & (twin[axis] <= hi)
        consistent[axis] = bool(np.all((np.abs(r) <= ADEV_TOLERANCE) | inside))
    return NoiseCheck(taus_s=taus, seeds=tuple(range(1, seeds + 1)), measured=measured,
                      simulated={k: tuple(v) for k, v in simulated.items()}, twin=twin,
                      ratio=ratio, passed=passed, consistent=consistent)


def _longest_span_s(calibrations):
    """
    Return the span every axis's Allan deviation can use, s: its longest stretch without a gap.

    A log split by gaps (or by what screening set aside) gives an axis's
    Allan deviation only up to taus its longest segment holds; octave taus up
    to a tenth of the whole span would ask the log for taus it has not got.
    The shortest such stretch over the axes of ``calibrations`` (the gyro's,
    and the accelerometer's when checked), never more than the log's span.
    """
    span_s = calibrations[0].duration_s
    for cal in calibrations:
        for a in cal.axes:
            if a.segments:
                span_s = min(span_s, (max(len(s) for s in a.segments) - 1) / cal.rate_hz)
    return span_s


def check_noise(calibration, config, seeds=8, progress=None, accel=None):
    """
    Simulate ``config`` (preset name, YAML path or SensorConfig) and compare with the log.

    Each seed is one ``simulate`` run of the log's length at its rate; the
    twin's Allan deviation is the mean over the seeds (a single run scatters
    by its own chi-squared interval, which the plot shows). ``accel``, the
    log's accelerometer calibration, is compared with the same runs'
    accelerometer output at the same taus (:attr:`NoiseCheck.accel`).
    """
    if not (isinstance(seeds, int) and 1 <= seeds <= 64):
        raise ValueError(f'seeds = {seeds!r} is out of range: allowed 1 .. 64')
    span_s = _longest_span_s([calibration] + ([] if accel is None else [accel]))
    taus = octave_taus(calibration.rate_hz, span_s)
    if len(taus) < 2:
        raise ValueError(f'{calibration.source}: {span_s:.1f} s (its longest stretch without '
                         'a gap) is too short for octave taus from 0.1 s to a tenth of it: '
                         'allowed >= 2 s')
    channels = [(calibration, 'gyro_rad_s')] + ([] if accel is None else [(accel, 'accel_m_s2')])
    measured = [{a.axis: allan.overlapping_adev(list(a.segments), cal.rate_hz, taus=taus)
                 for a in cal.axes} for cal, _ in channels]
    simulated = [{a.axis: [] for a in cal.axes} for cal, _ in channels]
    duration = calibration.duration_s + 1.0 / calibration.rate_hz
    for seed in range(1, seeds + 1):
        _, _, batch = simulate.run_simulation(config, 'static', duration, calibration.rate_hz,
                                              seed=seed)
        for (cal, output), runs in zip(channels, simulated):
            for a in cal.axes:
                runs[a.axis].append(allan.overlapping_adev(
                    getattr(batch, output)[:, AXES.index(a.axis)], calibration.rate_hz,
                    taus=taus))
        if progress is not None:
            progress(seed, seeds)
    checks = [_verdicts(taus, seeds, m, s) for m, s in zip(measured, simulated)]
    return replace(checks[0], accel=checks[1] if accel is not None else None)


def log_profile(fit):
    """Return a static profile whose ambient follows the log's group temperatures."""
    g = next(iter(fit.groups.values()))
    times = np.concatenate(([0.0], g.time_s))
    temps = np.concatenate(([g.temp_c[0]], g.temp_c))
    zero = (0.0, 0.0, 0.0)
    segments = [profiles.Segment(float(t1 - t0), zero, zero, float(a), float(b))
                for t0, t1, a, b in zip(times[:-1], times[1:], temps[:-1], temps[1:])
                if t1 > t0]
    return profiles.ScriptedProfile('thermal-log', tuple(segments))


#: Largest rms of the group-mean z of a thermal twin that is within the noise.
THERMAL_RMS_Z = 1.5


@dataclass(frozen=True)
class ThermalCheck:
    """
    Round trip of a thermal preset: per axis the twin's group means against the log's.

    ``twin`` (rad/s) are the simulated group means at the log's group times;
    ``z`` their differences from the log's means over the expected scatter
    (the log's residual about its fit and the twin's own standard error);
    ``slope`` (log, twin, combined standard error) in rad/s/K; ``passed``
    when the rms of z is at most :data:`THERMAL_RMS_Z` and the slopes agree
    within 2 standard errors.
    """

    twin: dict
    twin_sem: dict
    z: dict
    slope: dict
    passed: dict


def check_thermal(fit, log, config, seed=1):
    """Simulate ``config`` along the log's temperature and compare bias against temperature."""
    first = next(iter(log.axes))
    time_s = log.axes[first][0]
    rate_hz = 1.0 / log.axis_timing(first).median_step_s
    duration = float(time_s[-1]) + 2.0 / rate_hz
    _, _, batch = simulate.run_simulation(config, log_profile(fit), duration, rate_hz, seed=seed)
    index = {'x': 0, 'y': 1, 'z': 2}
    out = {'twin': {}, 'twin_sem': {}, 'z': {}, 'slope': {}, 'passed': {}}
    for axis, g in fit.groups.items():
        t_axis = log.axes[axis][0]
        samples = np.clip(np.round(t_axis * rate_hz).astype(int), 0, len(batch.gyro_rad_s) - 1)
        sim = batch.gyro_rad_s[samples, index[axis]]
        means = np.array([np.mean(sim[a:b]) for a, b in g.bounds])
        sems = np.array([np.std(sim[a:b], ddof=1) / np.sqrt(b - a) for a, b in g.bounds])
        sigma = np.sqrt(fit.residual_rms[axis] ** 2 + sems ** 2)
        z = (means - g.rate_rad_s) / sigma
        dtemp = g.temp_c - fit.temp_ref_c
        log_c, log_e, _ = thermal.polyfit_stats(dtemp, g.rate_rad_s, 1)
        sim_c, sim_e, _ = thermal.polyfit_stats(dtemp, means, 1)
        err = float(np.hypot(log_e[1], sim_e[1]))
        out['twin'][axis], out['twin_sem'][axis], out['z'][axis] = means, sems, z
        out['slope'][axis] = (float(log_c[1]), float(sim_c[1]), err)
        out['passed'][axis] = bool(np.sqrt(np.mean(z ** 2)) <= THERMAL_RMS_Z
                                   and abs(sim_c[1] - log_c[1]) <= 2.0 * err)
    return ThermalCheck(**out)
