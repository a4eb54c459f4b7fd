"""
Thermal calibration: zero-rate bias against die temperature, from a static log.

The log (:func:`thermal_log`, from loaded
:class:`gyro_emulator.recording.record.Record` s) is a CSV with ``time_s``,
``temp_c`` and ``gyro_rad_s`` or ``gyro_{x,y,z}_rad_s``, or several
one-axis CSVs (x, y, z in the order given), or a bag with an Imu topic and
a sensor_msgs/Temperature topic (default ``imu/temperature``, the die
temperature). The samples are
averaged in groups (:func:`group_means`): the bursts of a log with gaps, or
windows of ``window_s`` of a continuous one. The bias is a polynomial in
(T - T_ref), T_ref the middle of the logged range (PX4's TREF), fitted to
the group means by least squares (:func:`fit_thermal`).

The rule (what data can support which polynomial)
-------------------------------------------------
* Order k needs a temperature span of at least :data:`MIN_SPAN_K` [k] kelvin
  (5, 15 and 25 K for orders 1, 2 and 3) and at least k + 3 distinct group
  temperatures (group means :data:`DISTINCT_K` or more apart): k + 1
  coefficients and two degrees of freedom to judge them.
* The order is the highest the rule allows up to the one asked for (3), then
  lowered while its top coefficient is within 3 standard errors of zero (the
  errors from the scatter of the group means about the fit).
* Data that cannot support order 1 are refused with a message naming the
  span and the count and what is needed.

When temperature and time move together (|correlation| > 0.9 over the
groups) a drift in time cannot be told from a temperature effect, and the
fit says so.

The accelerometer's offset against temperature is the same fit on its axes
(:func:`accel_thermal_log`, a :class:`ThermalLog` of ``sense`` ACCEL, m/s^2):
at rest each axis reads its share of gravity plus its bias, and gravity, a
constant, goes into the constant term. At one attitude a sensitivity that
changes with temperature moves that share of gravity too, and reads as an
offset change: the coefficients hold for the attitude of the log.
"""

from dataclasses import dataclass, field, replace
import os

from gyro_emulator.analysis import outliers
from gyro_emulator.analysis.allan import analyse as allan_record
from gyro_emulator.analysis.calibrate.noise import detect_lsb
from gyro_emulator.analysis.sense import ACCEL, GYRO
from gyro_emulator.recording import csvio
from gyro_emulator.recording.record import CSV_COLUMNS, DEFAULT_TOPICS
from gyro_emulator.units import AXES
from gyro_emulator.validation import MODEL_TEMP_RANGE_C
import numpy as np

#: Smallest temperature span (K) for each polynomial order.
MIN_SPAN_K = {1: 5.0, 2: 15.0, 3: 25.0}
#: Group temperatures closer than this (K) count as one.
DISTINCT_K = 0.25
#: Highest order PX4 and ArduPilot store.
MAX_ORDER = 3
#: A top coefficient within this many standard errors of zero is dropped.
SIGNIFICANCE = 3.0
#: |corr(temperature, time)| above this: temperature and time are confounded.
CONFOUNDED = 0.9
#: Least robust scale of a temperature, K: a die temperature has no noise of its
#: own, so a sample is an outlier when it jumps 6 x 0.2 = 1.2 K off its neighbours'
#: local mean (a 60 K/min ramp moves that mean 1 K at the end of a stretch).
TEMP_SCALE_FLOOR_K = 0.2


@dataclass(frozen=True)
class ThermalLog:
    """
    Static samples with their die temperature: per axis (time_s, temp_c, rate_rad_s).

    Built from loaded records by :func:`thermal_log` (the gyro) or
    :func:`accel_thermal_log` (the accelerometer: ``sense`` ACCEL, the
    samples in m/s^2); it reads no file. ``temp_columns[axis]`` names where
    its temperature came from; ``records[axis]`` is the record the axis came
    from, whose timing (:meth:`axis_timing`) every step reads.
    """

    sources: tuple
    axes: dict
    columns: dict
    temp_columns: dict = field(default_factory=dict)
    records: dict = field(default_factory=dict)
    sense: object = GYRO

    def axis_timing(self, axis):
        """Return the :class:`gyro_emulator.recording.timing.Timing` of ``axis``'s record."""
        if self.sense is ACCEL:
            return self.records[axis].accel_timing()
        return self.records[axis].timing()


#: CSV columns a thermal log must have (:func:`gyro_emulator.recording.record.load_record`).
REQUIRED_COLUMNS = ('time_s', 'temp_c')


def bag_topics(topic=None, temperature_topic=None):
    """Return the bag topic of each role a thermal log reads: the Imu and the die temperature."""
    return {'gyro': topic, 'imu_accel': topic, 'die_temp': temperature_topic}


def _bag_axes(rec):
    """
    Per-axis (time_s, temp_c, rate) of a bag record, its temperature on the gyro's times.

    Returns the axes, their columns, their temperature sources and their record.
    """
    if rec.temp is None:
        raise ValueError(f'{rec.path}: no sensor_msgs/Temperature topic (default '
                         f'{DEFAULT_TOPICS["die_temp"]}): name one with '
                         '--temperature-topic')
    if len(rec.temp.time_s) < 2:
        raise ValueError(f'{rec.path}: {rec.topics["temp"]} has {len(rec.temp.time_s)} '
                         'messages: need >= 2')
    temp_c = np.interp(rec.time_s, rec.temp.time_s, rec.temp.values)
    return ({a: (rec.time_s, temp_c, rate) for a, rate in rec.gyro.items()},
            dict(rec.gyro_sources), {a: f'{rec.path}: {rec.temp.source}' for a in rec.gyro},
            dict.fromkeys(rec.gyro, rec))


def thermal_log(recs):
    """
    Return the :class:`ThermalLog` of loaded records: one 3-axis CSV or bag, or one-axis CSVs.

    One-axis CSVs are taken as x, y, z in the order given.
    """
    paths = tuple(r.path for r in recs)
    if not recs or len(recs) > 3:
        raise ValueError(f'thermal log: {len(recs)} files given: give one 3-axis file or '
                         'one to three one-axis files (x, y, z in that order)')
    if len(recs) == 1 and recs[0].is_bag:
        return ThermalLog(paths, *_bag_axes(recs[0].require_gyro()))
    _refuse_repeated(paths)
    axes, columns, temps, records = {}, {}, {}, {}
    for i, rec in enumerate(recs):
        path = rec.path
        if rec.is_bag:
            raise ValueError(f'{path}: a bag must be the only thermal log given')
        found = rec.require_gyro().gyro_sources
        if len(found) > 1 and len(recs) > 1:
            raise ValueError(f'{path}: has {len(found)} gyro axes: give it alone')
        for named, name in found.items():
            axis = AXES[i] if name == csvio.GYRO_SINGLE else named
            if axis in axes:
                raise ValueError(f'{path}: axis {axis} is given twice ({columns[axis]})')
            axes[axis] = (rec.time_s, rec.temp.values, rec.gyro[named])
            columns[axis] = f'{path}:{name}'
            temps[axis] = f'{path}: {rec.temp.source}'
            records[axis] = rec
    return ThermalLog(paths, axes, columns, temps, records)


def _refuse_repeated(paths):
    """Refuse a file given twice (as two axes), through a link or another spelling too."""
    for i, path in enumerate(paths):
        for j, other in enumerate(paths[:i]):
            try:
                same = os.path.samefile(path, other)
            except OSError:
                same = os.path.realpath(path) == os.path.realpath(other)
            if same:
                raise ValueError(f'thermal log: {path} is given twice (as axes {AXES[j]} and '
                                 f'{AXES[i]}): give one file per axis, x, y, z in that order')


def accel_thermal_log(recs):
    """
    Return the accelerometer's :class:`ThermalLog` (``sense`` ACCEL) of loaded records.

    One 3-axis CSV with ``accel_{x,y,z}_m_s2`` columns, or a bag whose Imu
    carries ``linear_acceleration``; ValueError saying why not otherwise
    (the reason a thermal export gives for leaving the accelerometer out).
    """
    if len(recs) != 1:
        raise ValueError('the accelerometer needs one 3-axis log (one-axis files carry no '
                         'accelerometer)')
    rec = recs[0]
    if rec.accel is None:
        raise ValueError(f'{rec.path} has no accelerometer ({", ".join(CSV_COLUMNS["accel"])} '
                         "columns, or an Imu's linear_acceleration)")
    temp = rec.temp
    if temp is None or len(temp.time_s) < 2:
        raise ValueError(f'{rec.path}: no temperature for the accelerometer')
    times = rec.accel.time_s
    temp_c = np.interp(times, temp.time_s, temp.values)
    axes = {a: (times, temp_c, rec.accel_axis(a)[0]) for a in AXES}
    return ThermalLog((rec.path,), axes, {a: f'{rec.path}:{rec.accel_axis(a)[1]}' for a in AXES},
                      dict.fromkeys(AXES, f'{rec.path}: {temp.source}'),
                      dict.fromkeys(AXES, rec), ACCEL)


@dataclass(frozen=True)
class Groups:
    """Group means of one axis: time_s, temp_c, rate (rad/s), its standard error, count."""

    time_s: np.ndarray
    temp_c: np.ndarray
    rate_rad_s: np.ndarray
    sem_rad_s: np.ndarray
    count: np.ndarray
    bounds: tuple
    how: str


def _windows(time_s, a, b, window_s):
    """
    Index bounds of the windows of ``window_s`` over samples a..b (3 or more samples each).

    At most one window per sample is ever made: a stretch longer than its
    samples' count of windows is cut where samples are.
    """
    if (time_s[b - 1] - time_s[a]) / window_s > b - a:
        index = np.floor((time_s[a:b] - time_s[a]) / window_s)
        cuts = a + np.flatnonzero(np.r_[True, index[1:] != index[:-1], True])
        return [(int(lo), int(hi)) for lo, hi in zip(cuts[:-1], cuts[1:]) if hi - lo >= 3]
    edges = np.arange(time_s[a], time_s[b - 1] + window_s, window_s)
    idx = a + np.searchsorted(time_s[a:b], edges)
    return [(int(lo), int(hi)) for lo, hi in zip(idx[:-1], idx[1:]) if hi - lo >= 3]


def group_means(timing, temp_c, rate, window_s=60.0, keep=None):
    """
    Average a static log in groups: its bursts, or windows of ``window_s``.

    ``timing`` is the :class:`gyro_emulator.recording.timing.Timing` of the
    samples' stamps: its segments are the bursts. Bursts (3 or more, none
    longer than two windows) are the groups of a log taken in bursts;
    otherwise each contiguous stretch is cut into windows (a continuous log,
    or one with a few logging gaps).

    Only the samples ``keep`` marks (default all) count; a group with fewer
    than 3 of them is left out. The standard error of each mean is the
    sample standard deviation over sqrt(count): it treats the samples
    within a group as independent.
    """
    time_s = timing.time_s
    bounds = [(a, b) for a, b in timing.bounds if b - a >= 3]
    how = f'{len(bounds)} bursts'
    long = [time_s[b - 1] - time_s[a] > 2.0 * window_s for a, b in bounds]
    if len(bounds) < 3 or any(long):
        # a continuous log, or one with logging gaps: windows within each stretch
        stretches = len(bounds)
        bounds = [w for a, b in bounds for w in _windows(time_s, a, b, window_s)]
        how = f'{len(bounds)} windows of {window_s:g} s' + (
            f' in {stretches} stretches' if stretches > 1 else '')
    keep = np.ones(len(rate), bool) if keep is None else np.asarray(keep, bool)
    rows, used = [], []
    for a, b in bounds:
        k = keep[a:b]
        if np.count_nonzero(k) < 3:
            continue
        r = rate[a:b][k]
        rows.append((np.mean(time_s[a:b][k]), np.mean(temp_c[a:b][k]), np.mean(r),
                     np.std(r, ddof=1) / np.sqrt(len(r)), len(r)))
        used.append((a, b))
    if not rows:
        raise ValueError('thermal log: no group of 3 or more samples')
    stats = np.array(rows)
    return Groups(stats[:, 0], stats[:, 1], stats[:, 2], stats[:, 3],
                  stats[:, 4].astype(int), tuple(used), how)


def distinct_temperatures(temps_c, resolution_k=DISTINCT_K):
    """Count group temperatures at least ``resolution_k`` apart (greedy over sorted)."""
    count, last = 0, -np.inf
    for value in np.sort(np.asarray(temps_c, dtype=float)):
        if value - last >= resolution_k:
            count, last = count + 1, value
    return count


def allowed_order(span_k, distinct, requested=MAX_ORDER):
    """Highest polynomial order the rule allows (module docstring); ValueError below 1."""
    for order in range(min(int(requested), MAX_ORDER), 0, -1):
        if span_k >= MIN_SPAN_K[order] and distinct >= order + 3:
            return order
    needs = '; '.join(f'order {k}: {MIN_SPAN_K[k]:g} K and {k + 3}' for k in (1, 2, 3))
    raise ValueError(f'thermal log spans {span_k:.2f} K with {distinct} distinct temperatures '
                     f'({DISTINCT_K:g} K apart): too little to fit bias against temperature '
                     f'(need, for {needs})')


def newey_west_lags(count):
    """Newey-West lag count for ``count`` observations: floor(4 (count / 100)^(2/9))."""
    return int(np.floor(4.0 * (count / 100.0) ** (2.0 / 9.0)))


def polyfit_stats(dtemp, values, order):
    """
    Least squares in ascending powers of dtemp: (coefficients, standard errors, residuals).

    The group means follow each other in time and their residuals share
    the part's slow wander (bias instability, random walk), so they are not
    independent: each standard error is the larger of the ordinary one and
    the Newey-West (HAC) one (statsmodels, Bartlett kernel,
    :func:`newey_west_lags` lags, small-sample correction), the groups taken
    in the order given (time).
    """
    design = np.vander(np.asarray(dtemp, dtype=float), order + 1, increasing=True)
    values = np.asarray(values, dtype=float)
    coef, _, _, _ = np.linalg.lstsq(design, values, rcond=None)
    resid = values - design @ coef
    dof = max(len(values) - order - 1, 1)
    scale = float(np.sum(resid ** 2) / dof)
    err = np.sqrt(np.maximum(np.diag(scale * np.linalg.pinv(design.T @ design)), 0.0))
    lags = newey_west_lags(len(values))
    if lags >= 1 and dof >= 3:
        # statsmodels costs 0.5 s (3.8 s cold); `calibrate check-noise` loads this
        # module (through plots) without fitting anything.
        import statsmodels.api as sm

        hac = sm.OLS(values, design).fit(cov_type='HAC', cov_kwds={
            'maxlags': lags, 'use_correction': True})
        err = np.maximum(err, np.asarray(hac.bse, dtype=float))
    return coef, err, resid


@dataclass(frozen=True)
class ThermalFit:
    """
    Bias against temperature, per axis: polynomial in (T - temp_ref_c), rad/s per K^k.

    ``coefficients[axis]`` ascending powers (order + 1 values), ``errors``
    their standard errors, ``groups[axis]`` the group means, ``residual_rms``
    the scatter of the group means about the fit and ``group_noise`` their
    typical standard error (rad/s); ``notes`` what a user must know;
    ``set_aside[axis]`` the spikes and motion left out of the group means
    (:class:`gyro_emulator.analysis.outliers.SetAside`). The white noise
    ``arw_rad_s_sqrt_hz[axis]`` (N, rad/s/sqrt(Hz)) and the grid
    ``lsb_rad_s`` of the samples are None until :func:`with_white_noise`
    adds them (what the ``preset`` export needs beside the polynomial).
    ``data_temp_c`` is the (lowest, highest) temperature of the samples kept
    and ``data_rate_rad_s[axis]`` the same of their rates: the range
    :func:`check_export` holds a file to. ``sense`` is what the samples are
    (:mod:`gyro_emulator.analysis.sense`): for the accelerometer every value
    above is in m/s^2 units, ``gyro_scale`` is ``--accel-scale`` and
    ``median`` holds each axis's median group mean (the level PX4's own
    tool takes off the accelerometer's offset polynomial).
    """

    sources: tuple
    columns: dict
    temp_ref_c: float
    temp_min_c: float
    temp_max_c: float
    order: int
    order_reason: str
    coefficients: dict
    errors: dict
    groups: dict
    residual_rms: dict
    group_noise: dict
    span_k: float
    distinct_temps: int
    correlation: float
    grouping: str
    gyro_scale: float
    notes: tuple
    set_aside: dict = field(default_factory=dict)
    arw_rad_s_sqrt_hz: dict = None
    lsb_rad_s: float = None
    data_temp_c: tuple = None
    data_rate_rad_s: dict = None
    sense: object = GYRO
    median: dict = None

    @property
    def groups_temp_c(self):
        """Group temperatures of the first axis, deg C."""
        return next(iter(self.groups.values())).temp_c

    def bias(self, axis, temp_c, clamp=True):
        """Fitted bias of ``axis`` at ``temp_c`` (clamped to the logged range, as PX4 does)."""
        t = np.asarray(temp_c, dtype=float)
        if clamp:
            t = np.clip(t, self.temp_min_c, self.temp_max_c)
        return np.polynomial.polynomial.polyval(t - self.temp_ref_c, self.coefficients[axis])


def _order_for(groups, temp_ref, order):
    """Lower ``order`` while the top coefficient of any axis is insignificant."""
    for k in range(order, 0, -1):
        significant = []
        for g in groups.values():
            coef, err, _ = polyfit_stats(g.temp_c - temp_ref, g.rate_rad_s, k)
            significant.append(abs(coef[k]) > SIGNIFICANCE * err[k])
        if any(significant) or k == 1:
            return k, significant
    return 1, []


#: Temperature units a column is mistaken for: (name, offset, scale, the fix);
#: value x scale + offset is deg C.
TEMP_UNITS = (('kelvin', -273.15, 1.0, 'subtract 273.15'),
              ('millidegrees C', 0.0, 1e-3, 'divide by 1000'))


def screen_temperature(time_s, temp_c, dt_s, threshold=outliers.THRESHOLD, what='temp_c'):
    """
    Set aside the temperatures beyond physical limits, then the jumps (a SetAside).

    The limits are the physics model's, :data:`gyro_emulator.validation.MODEL_TEMP_RANGE_C`,
    the rule ``diagnose`` applies; the jumps are those of
    :func:`gyro_emulator.analysis.outliers.screen_at_rest`, at least 6 x
    :data:`TEMP_SCALE_FLOOR_K` off the neighbours. A column mostly beyond
    the limits is an error that names the unit it seems to be in.
    """
    try:
        return outliers.screen_at_rest(time_s, temp_c, dt_s, threshold, what,
                                       MODEL_TEMP_RANGE_C, 'C', TEMP_SCALE_FLOOR_K,
                                       'temperature jumps')
    except ValueError as exc:
        low, high = MODEL_TEMP_RANGE_C
        middle = float(np.median(temp_c))
        hints = [f'looks like {name}: {how}' for name, offset, scale, how in TEMP_UNITS
                 if low <= middle * scale + offset <= high]
        raise ValueError('; '.join([str(exc)] + hints[:1])) from None


def _screen(log, gyro_scale, threshold):
    """
    Leave out stuck axes, and find each other axis's spikes and motion, and temperature jumps.

    Returns (the log without its stuck or saturated axes, their gyro and
    their temperature :class:`gyro_emulator.analysis.outliers.SetAside` per
    axis, notes on the axes left out); with no axis left, ValueError.
    """
    screened, temps, notes = {}, {}, []
    for axis, (t, temp, rate) in log.axes.items():
        rate_hz = log.axis_timing(axis).rate_hz
        try:
            outliers.check_not_held(rate, rate_hz, _axis_name(log.sense, axis))
        except outliers.HeldOutput as exc:
            notes.append(f'{exc}: left out')
            continue
        screened[axis] = outliers.screen_at_rest(t, rate * gyro_scale, 1.0 / rate_hz, threshold,
                                                 log.columns.get(axis, f'axis {axis}'),
                                                 log.sense.limits, log.sense.unit)
        temps[axis] = screen_temperature(t, temp, 1.0 / rate_hz, threshold,
                                         log.temp_columns.get(axis, 'temp_c'))
    if not screened:
        raise ValueError('thermal log: no axis to fit: ' + '; '.join(notes))
    kept = replace(log, axes={a: log.axes[a] for a in screened},
                   columns={a: log.columns[a] for a in screened})
    return kept, screened, temps, notes


def _axis_name(sense, axis):
    return f'axis {axis}' if sense is GYRO else f'{sense.name} axis {axis}'


def _screen_notes(log, screened, temps):
    """Return notes on what was set aside: per axis its gyro, per temperature column its own."""
    notes = [f'{_axis_name(log.sense, a)}: {v.describe()}' for a, v in screened.items()
             if v.count or v.note]
    said = set()
    for axis, v in temps.items():
        column = log.temp_columns.get(axis, 'temp_c')
        if (v.count or v.note) and column not in said:
            said.add(column)
            notes.append(f'{column}: {v.describe()}')
    return notes


def _kept_ranges(log, keep, gyro_scale):
    """Return the (lowest, highest) kept temperature, deg C, and per axis the kept rates'."""
    temps = np.concatenate([temp[keep[a]] for a, (_, temp, _) in log.axes.items()])
    rates = {}
    for axis, (_, _, rate) in log.axes.items():
        kept = rate[keep[axis]] * gyro_scale
        rates[axis] = (float(np.min(kept)), float(np.max(kept)))
    return (float(np.min(temps)), float(np.max(temps))), rates


def fit_thermal(log, order=MAX_ORDER, window_s=60.0, gyro_scale=1.0,
                outlier_threshold=outliers.THRESHOLD):
    """
    Fit bias against temperature for every axis of ``log`` (module docstring).

    Parameters
    ----------
    log : ThermalLog
        From :func:`read_thermal_log`.
    order : int
        Highest polynomial order wanted (1 to 3).
    window_s : float
        Group length of a log without gaps, s.
    gyro_scale : float
        Factor applied to the logged rates first (a known scale error; the
        accelerometer's: ``--accel-scale``, 9.80665 for a log in g).
    outlier_threshold : float
        Spikes and motion beyond this many robust standard deviations of
        their neighbours are left out of the group means (``math.inf``: keep
        every sample).

    Returns
    -------
    ThermalFit

    """
    if order not in (1, 2, 3):
        raise ValueError(f'order = {order!r} is not allowed: choose 1, 2 or 3')
    if not (np.isfinite(window_s) and 1.0 <= window_s <= 86400.0):
        raise ValueError(f'window_s = {window_s!r} is out of range: allowed [1, 86400] s')
    if not (np.isfinite(gyro_scale) and 0.01 <= gyro_scale <= 100.0):
        raise ValueError(f'{log.sense.scale_option[2:].replace("-", "_")} = {gyro_scale!r} is '
                         'out of range: allowed [0.01, 100]')
    log, screened, temp_screened, skipped = _screen(log, gyro_scale, outlier_threshold)
    keep = {a: screened[a].keep & temp_screened[a].keep for a in screened}
    groups = {a: group_means(log.axis_timing(a), temp, rate * gyro_scale, window_s, keep=keep[a])
              for a, (_, temp, rate) in log.axes.items()}
    # the range the fit covers: group means (a glitch in the temperature column
    # moves one group's mean a little, not TMIN or TMAX)
    temps = np.concatenate([g.temp_c for g in groups.values()])
    t_min, t_max = float(np.min(temps)), float(np.max(temps))
    first = next(iter(groups.values()))
    span = float(np.ptp(first.temp_c))
    distinct = distinct_temperatures(first.temp_c)
    rule = allowed_order(span, distinct, order)
    temp_ref = 0.5 * (t_min + t_max)
    chosen, significant = _order_for(groups, temp_ref, rule)
    reason = (f'the rule allows order {rule} for {span:.2f} K and {distinct} distinct '
              f'temperatures (1: {MIN_SPAN_K[1]:g} K, 2: {MIN_SPAN_K[2]:g} K, 3: '
              f'{MIN_SPAN_K[3]:g} K)')
    if chosen < rule:
        reason += f'; higher terms within {SIGNIFICANCE:g} standard errors of zero: order {chosen}'
    coefs, errs, rms, noise = {}, {}, {}, {}
    for axis, g in groups.items():
        coef, err, resid = polyfit_stats(g.temp_c - temp_ref, g.rate_rad_s, chosen)
        coefs[axis], errs[axis] = coef, err
        rms[axis] = float(np.sqrt(np.mean(resid ** 2)))
        noise[axis] = float(np.sqrt(np.mean(g.sem_rad_s ** 2)))
    corr = float(np.corrcoef(first.temp_c, first.time_s)[0, 1]) if span > 0 else 0.0
    notes = _notes(coefs, errs, rms, noise, corr, chosen, significant, gyro_scale, log.sense)
    notes += _screen_notes(log, screened, temp_screened)
    notes += skipped
    data_temp, data_rate = _kept_ranges(log, keep, gyro_scale)
    return ThermalFit(sources=log.sources, columns=log.columns, temp_ref_c=temp_ref,
                      temp_min_c=t_min, temp_max_c=t_max, order=chosen, order_reason=reason,
                      coefficients=coefs, errors=errs, groups=groups, residual_rms=rms,
                      group_noise=noise, span_k=span, distinct_temps=distinct,
                      correlation=corr, grouping=first.how, gyro_scale=float(gyro_scale),
                      notes=tuple(notes), set_aside=screened, data_temp_c=data_temp,
                      data_rate_rad_s=data_rate, sense=log.sense,
                      median={a: float(np.median(g.rate_rad_s)) for a, g in groups.items()})


def _notes(coefs, errs, rms, noise, corr, order, significant, gyro_scale, sense=GYRO):
    notes = []
    if abs(corr) > CONFOUNDED:
        notes.append(f'temperature and time are confounded (correlation {corr:+.3f} over the '
                     'groups): a drift in time (warm-up, bias instability, random walk) cannot '
                     'be told apart from a temperature effect in this log; the coefficients '
                     'hold for other runs only if the bias does not drift at constant '
                     'temperature')
    for axis in coefs:
        if rms[axis] > 2.0 * noise[axis]:
            notes.append(f'{_axis_name(sense, axis)}: the group means scatter about the fit by '
                         f'{rms[axis] / noise[axis]:.1f}x their own noise: drift or structure '
                         'that temperature does not explain')
        if order == 1 and abs(coefs[axis][1]) <= SIGNIFICANCE * errs[axis][1]:
            notes.append(f'{_axis_name(sense, axis)}: its slope is within {SIGNIFICANCE:g} '
                         'standard errors of zero: no measurable temperature dependence over '
                         'this span')
    if gyro_scale != 1.0:
        what = 'rates' if sense is GYRO else f'{sense.name} samples'
        notes.append(f'the logged {what} were multiplied by {gyro_scale:g} first '
                     f'({sense.scale_option})')
    return notes


#: A written bias may leave the kept rates' range by this many times its width.
EXPORT_RATE_MARGIN = 1.0


def check_export(fit, what='the thermal calibration'):
    """
    Refuse (ValueError) a fit whose file would hold values the data cannot give.

    Every value written (TREF, TMIN, TMAX, the coefficients, the residual)
    must be finite; TMIN and TMAX within the kept samples' temperatures;
    and the bias the polynomial predicts over [TMIN, TMAX] within the kept
    rates' range widened by :data:`EXPORT_RATE_MARGIN` times its width each
    side (group means are means of those samples: a polynomial far outside
    them is a bad fit, not a bias). The message names the axis, the value
    and the limit.
    """
    values = [('TREF', fit.temp_ref_c), ('TMIN', fit.temp_min_c), ('TMAX', fit.temp_max_c)]
    for axis, coef in fit.coefficients.items():
        values += [(f'axis {axis} coefficient {k}', float(c)) for k, c in enumerate(coef)]
        values.append((f'axis {axis} residual rms', fit.residual_rms[axis]))
    for name, value in values:
        if not np.isfinite(value):
            raise ValueError(f'refusing to write {what}: {name} = {value!r} is not finite')
    if fit.data_temp_c is None:
        return
    low, high = fit.data_temp_c
    for name, value in values[1:3]:
        if not low - 1e-9 * abs(low) <= value <= high + 1e-9 * abs(high):
            raise ValueError(f'refusing to write {what}: {name} = {value:.6g} C is outside '
                             f'the kept temperatures [{low:.6g}, {high:.6g}] C')
    temps = np.linspace(fit.temp_min_c, fit.temp_max_c, 101)
    for axis in fit.coefficients:
        r_low, r_high = fit.data_rate_rad_s[axis]
        margin = EXPORT_RATE_MARGIN * (r_high - r_low)
        bias = fit.bias(axis, temps)
        worst = int(np.argmax(np.maximum(r_low - margin - bias, bias - r_high - margin)))
        if not r_low - margin <= bias[worst] <= r_high + margin:
            unit, kept = fit.sense.unit, 'rates' if fit.sense is GYRO else 'values'
            raise ValueError(
                f'refusing to write {what}: {_axis_name(fit.sense, axis)}: the fit predicts a '
                f'bias of {bias[worst]:.6g} {unit} at {temps[worst]:.2f} C, outside the kept '
                f'{kept} [{r_low:.6g}, {r_high:.6g}] {unit} widened by {EXPORT_RATE_MARGIN:g} x '
                'their range each side')


def px4_offset(params, axis, temp_c, prefix='TC_G0'):
    """
    Offset PX4 subtracts: X0 + X1 d + X2 d^2 + X3 d^3, d = clip(T, TMIN, TMAX) - TREF.

    ``params`` maps PX4 names to values (``TC_G0_TREF``, ``TC_G0_X1_0``, ...);
    ``prefix`` ``TC_A0`` reads the accelerometer's.
    """
    i = AXES.index(axis)
    t = np.clip(np.asarray(temp_c, dtype=float), params[f'{prefix}_TMIN'],
                params[f'{prefix}_TMAX'])
    d = t - params[f'{prefix}_TREF']
    return sum(params[f'{prefix}_X{k}_{i}'] * d ** k for k in range(4))


@dataclass(frozen=True)
class Compensation:
    """Group-mean bias before and after a correction (std, peak-to-peak, rad/s) and its slope."""

    before_std: float
    after_std: float
    before_ptp: float
    after_ptp: float
    held_out_std: float
    slope_rad_s_k: float
    slope_error: float


def compensation_check(fit, params, axis):
    """
    Apply a PX4 thermal correction to the log's group means of ``axis``.

    Before/after spread of the group means; ``held_out_std`` is the spread
    when each group is corrected by a fit that left it out (same order); the
    slope of the corrected means against temperature and its standard error
    say whether the residual is flat.
    """
    g = fit.groups[axis]
    after = g.rate_rad_s - px4_offset(params, axis, g.temp_c)
    coef, err, _ = polyfit_stats(g.temp_c - fit.temp_ref_c, after, 1)
    held = []
    for i in range(len(g.temp_c)):
        keep = np.arange(len(g.temp_c)) != i
        c, _, _ = polyfit_stats(g.temp_c[keep] - fit.temp_ref_c, g.rate_rad_s[keep], fit.order)
        held.append(g.rate_rad_s[i] - np.polynomial.polynomial.polyval(
            g.temp_c[i] - fit.temp_ref_c, c))
    return Compensation(before_std=float(np.std(g.rate_rad_s)), after_std=float(np.std(after)),
                        before_ptp=float(np.ptp(g.rate_rad_s)), after_ptp=float(np.ptp(after)),
                        held_out_std=float(np.std(held)), slope_rad_s_k=float(coef[1]),
                        slope_error=float(err[1]))


def white_noise_of(log, axis, gyro_scale=1.0):
    """(N of one axis from its samples, its unit/sqrt(Hz); sample rate, Hz): IEEE Std 952 fit."""
    rate = log.axes[axis][2]
    rate_hz, segments, _, _ = allan_record.screened_segments(
        log.axis_timing(axis), rate * gyro_scale, sense=log.sense)
    _, found = allan_record.identify(segments, rate_hz)
    return found.arw_rad_s_sqrt_hz, rate_hz


def with_white_noise(fit, log):
    """
    Return ``fit`` with each axis's white noise N and the samples' LSB, from the log's samples.

    N is the IEEE Std 952 fit of :func:`white_noise_of` (the logged rates
    times ``fit.gyro_scale``); the LSB is the median of the axes' grids
    (:func:`gyro_emulator.analysis.calibrate.noise.detect_lsb`), 0 unless
    every axis has one.
    """
    noise = {a: white_noise_of(log, a, fit.gyro_scale)[0] for a in fit.coefficients}
    steps = [detect_lsb(log.axes[a][2] * fit.gyro_scale) for a in fit.coefficients]
    lsb = float(np.median(steps)) if all(s > 0 for s in steps) else 0.0
    return replace(fit, arw_rad_s_sqrt_hz=noise, lsb_rad_s=lsb)
