"""
Noise calibration of a measured gyro log: the values an estimator or the emulator needs.

:func:`calibrate_noise` runs the IEEE Std 952 identification
(:func:`gyro_emulator.analysis.allan.identify`) on each axis of a static
log and keeps what the exporters need: N, B and K per axis with their
intervals, the tau range used, the log's sample rate, the value grid of
its samples (:func:`detect_lsb`, on
:func:`gyro_emulator.recording.record.grid_step`) and its mean.

Estimators model white noise and a bias random walk only. :func:`export_noise`
turns a calibration into those two numbers (continuous time, IEEE Std 952
units: N in rad/s/sqrt(Hz), K in rad/s^2/sqrt(Hz) = rad/s/sqrt(s)):

* a K the record does not resolve (lower 95 % bound zero) is exported as its
  upper bound, and said so: an estimator that believes its bias never walks
  is the failure to avoid;
* with several axes, each number is the largest over the axes;
* ``inflate`` multiplies N, B and K (and is written into every file).

The accelerometer's axes go through the same identification
(``calibrate_noise(..., sense=ACCEL)``, :mod:`gyro_emulator.analysis.sense`):
its samples in m/s^2, so N is in m/s^2/sqrt(Hz), B in m/s^2 and K in
m/s^3/sqrt(Hz). On a static log gravity is a constant: the Allan deviation
does not see it and the screening's local high-pass takes it out with the
bias. The magnitude of the mean says whether the columns are in m/s^2
(:func:`gravity_at_rest`).
"""

from dataclasses import dataclass, replace

from gyro_emulator import units
from gyro_emulator.analysis import allan, outliers
from gyro_emulator.analysis.allan import analyse as allan_record
from gyro_emulator.analysis.sense import ACCEL, GYRO
from gyro_emulator.recording.record import grid_step
from gyro_emulator.units import AXES
from gyro_emulator.validation import check_range
import numpy as np

#: Most distinct values a log may have for its grid to be looked for (grid_step).
GRID_MAX_UNIQUE = 200_000


@dataclass(frozen=True)
class AxisNoise:
    """
    The identification of one axis: its Allan deviation, fit, mean and segments.

    ``mean_rad_s`` is the mean of the kept samples in the channel's unit
    (rad/s for the gyro, m/s^2 for the accelerometer: :attr:`mean`);
    ``set_aside`` is the JSON form of the spikes and motion left out
    (:func:`gyro_emulator.analysis.allan.analyse.set_aside_summary`).
    """

    axis: str
    column: str
    result: object
    fit: object
    mean_rad_s: float
    segments: tuple = ()
    set_aside: dict = None

    @property
    def mean(self):
        """Return the mean of the kept samples, in the channel's SI unit."""
        return self.mean_rad_s


@dataclass(frozen=True)
class NoiseCalibration:
    """
    Noise calibration of a log.

    Attributes
    ----------
    source : str
        The log.
    rate_hz : float
        Its nominal sample rate, Hz.
    duration_s : float
        First to last sample, s.
    axes : tuple of AxisNoise
        One per calibrated axis.
    lsb_rad_s : float
        The grid the samples lie on (0: none found), in the channel's unit
        (rad/s; m/s^2 for the accelerometer).
    recovery : tuple of str
        What a damaged bag lost.
    skipped : tuple of str
        Axes left out, and why (a stuck, saturated or dead output).
    timing : tuple of str
        What the stamps say about the record (samples missing between them).
    sense : gyro_emulator.analysis.sense.Sense
        What the axes sense (:data:`~gyro_emulator.analysis.sense.GYRO` or
        :data:`~gyro_emulator.analysis.sense.ACCEL`).
    gravity_m_s2 : tuple or None
        The accelerometer's: the gravity it reads at rest, (x, y, z) m/s^2
        (:func:`gravity_at_rest`); None for the gyro.
    notes : tuple of str
        What the user must know about the channel (an accelerometer whose
        magnitude at rest is not near g; a scale applied).
    scale : float
        The factor the logged samples were multiplied by first.

    """

    source: str
    rate_hz: float
    duration_s: float
    axes: tuple
    lsb_rad_s: float = 0.0
    recovery: tuple = ()
    skipped: tuple = ()
    timing: tuple = ()
    sense: object = GYRO
    gravity_m_s2: tuple = None
    notes: tuple = ()
    scale: float = 1.0

    def axis(self, name):
        """Return the :class:`AxisNoise` of axis ``name``."""
        for item in self.axes:
            if item.axis == name:
                return item
        raise ValueError(f'{self.source}: axis {name!r} was not calibrated')

    @property
    def lsb(self):
        """Return the grid the samples lie on (0: none), in the channel's SI unit."""
        return self.lsb_rad_s

    def turn_on_bias(self, item):
        """
        Return the turn-on bias of :class:`AxisNoise` ``item``: its mean, less gravity on it.

        The gyro's is its mean (Earth's rate included). The accelerometer's
        is its mean minus the gravity :func:`gravity_at_rest` puts on the
        axis: with one attitude the bias along gravity is the magnitude's
        departure from g, and a bias across gravity cannot be told from a
        tilt (it is taken as none).
        """
        if self.gravity_m_s2 is None:
            return item.mean
        return item.mean - self.gravity_m_s2[AXES.index(item.axis)]

    @property
    def tau_range_s(self):
        """(shortest, longest) tau used by any axis, s."""
        lows = [a.fit.tau_range_s[0] for a in self.axes]
        highs = [a.fit.tau_range_s[1] for a in self.axes]
        return min(lows), max(highs)


def quantisation(rate, grid, unit='rad/s'):
    """
    Return an axis's LSB (or 0) and a warning when its grid is coarser than its noise (or None).

    The grid of :func:`gyro_emulator.recording.record.grid_step` is the LSB
    when it is below half the samples' standard deviation and there are at
    least 8 distinct values: the part's LSB or the precision the log was
    written with; either way the log's values are quantised to it. A coarser grid (any number of
    values: a few in a whole log is quantisation) is no LSB the noise sits
    on: the output is quantised more coarsely than its noise, rounding adds
    about LSB^2 / 12 per sample and, at this size, is not independent of
    the signal, so N describes the quantised output, not the sensor behind
    it (an LSB of 4 sigma read N 25 % high in a review). ``grid`` is the
    (step, distinct values) :func:`~gyro_emulator.recording.record.grid_step`
    found for ``rate``; ``unit`` that of the samples, for the warning.
    """
    step, distinct = grid
    with np.errstate(over='ignore', invalid='ignore'):  # a 1e308 sample: an infinite spread
        spread = float(np.std(rate))
    if step <= 0.5 * spread:
        return (step if distinct >= 8 else 0.0), None
    return 0.0, (f'the samples lie on a grid of {step:.4g} {unit}, coarser than half their '
                 f'spread ({spread:.4g} {unit}): the noise terms describe the quantised '
                 'output, not the sensor behind it (N can read well above the sensor)')


def detect_lsb(rate, max_unique=GRID_MAX_UNIQUE):
    """Quantisation step of a log: the grid its samples lie on, or 0 (:func:`quantisation`)."""
    return quantisation(rate, grid_step(rate, max_unique))[0]


#: A static accelerometer reads |f| = g within this share, else a note: a consumer
#: part's sensitivity and offset errors are a few % (the MPU-6050 log reads 9 % low).
GRAVITY_TOLERANCE = 0.15
#: Magnitudes at rest (in the log's unit) that say the columns are in g, not m/s^2.
IN_G = (0.5, 2.0)


#: The factors a logged channel may be multiplied by (``--accel-scale``), inclusive.
SCALE_RANGE = (1e-6, 1e6)


def check_scale(scale, name='accel_scale'):
    """Return ``scale``, a factor on the logged samples; ValueError outside :data:`SCALE_RANGE`."""
    return check_range('calibrate', name, scale, *SCALE_RANGE, low_open=False)


def gravity_at_rest(values, path, scale=1.0):
    """
    Return the gravity a static accelerometer reads, (x, y, z) m/s^2, and notes.

    ``values`` is the (n, 3) specific force of the log (m/s^2, after
    ``scale``). At rest it is gravity plus the bias: the attitude is taken
    as the direction of the mean (the median of each column, so that spikes
    do not move it) and gravity as standard, g = 9.80665 m/s^2, along it
    (local gravity differs by up to 0.3 %). A magnitude about 1 says the
    columns are in g: refused, naming ``--accel-scale``; one further than
    :data:`GRAVITY_TOLERANCE` from g gets a note (not static, or another
    unit or a scale error).
    """
    check_scale(scale)
    means = np.median(np.asarray(values, dtype=float), axis=0)
    size = float(np.linalg.norm(means))
    g = units.STANDARD_GRAVITY_M_S2
    low, high = IN_G
    if not np.isfinite(size) or size <= 0.0:
        raise ValueError(f'{path}: the accelerometer columns read {size!r} at rest: no gravity '
                         'to take the attitude from')
    if low <= size <= high:
        raise ValueError(f'{path}: the accelerometer reads {size:.4g} at rest, about 1: its '
                         f'columns look like g, not m/s^2 (give --accel-scale {g:g}'
                         + ('' if scale == 1.0 else f' instead of {scale:g}') + ')')
    notes = []
    if abs(size / g - 1.0) > GRAVITY_TOLERANCE:
        notes.append(f'the accelerometer reads {size:.4g} m/s^2 at rest, '
                     f'{100 * (size / g - 1):+.0f} % from g = {g:g}: is the log static, and in '
                     'm/s^2 (--accel-scale)? The turn-on bias takes the difference as a bias '
                     'along gravity')
    if scale != 1.0:
        notes.append(f'the logged accelerometer was multiplied by {scale:g} first (--accel-scale)')
    return tuple(float(v) for v in means * (g / size)), tuple(notes)


def _channel(record, sense, axes, gap_factor, scale):
    """Return (path, {axis: (samples, column)}, Timing) of the channel ``sense`` of a record."""
    if sense is GYRO:
        path = record.require_gyro().path
        names = tuple(record.gyro) if axes is None else tuple(axes)
        columns = {name: record.gyro_axis(name) for name in names}
        get_timing = record.timing
    else:
        path = record.path
        if record.accel is None:
            raise ValueError(f'{path}: no accelerometer (accel_{{x,y,z}}_m_s2 columns or an '
                             "Imu's linear_acceleration)")
        names = AXES if axes is None else tuple(axes)
        columns = {name: record.accel_axis(name) for name in names}
        get_timing = record.accel_timing
    if scale != 1.0:
        columns = {name: (values * scale, column) for name, (values, column) in columns.items()}
    try:
        return path, columns, get_timing(gap_factor)
    except ValueError as exc:
        raise ValueError(f'{path}: {exc}') from None


def calibrate_noise(record, axes=None, gap_factor=3.0, max_tau_fraction=0.25,
                    outlier_threshold=outliers.THRESHOLD, output=None, sense=GYRO, scale=1.0):
    """
    Identify the noise terms of each axis of a static log.

    Parameters
    ----------
    record : gyro_emulator.recording.record.Record
        The log (its gyro axes, or its accelerometer's).
    axes : sequence of str, optional
        Axes to calibrate (default: all the log has).
    gap_factor, max_tau_fraction : float
        As for ``gyro-emulator allan``; the record's timing at ``gap_factor``
        (:meth:`gyro_emulator.recording.record.Record.timing`, worked out
        once for all axes) is read, not worked out again.
    outlier_threshold : float
        Spikes and motion beyond this many robust standard deviations of
        their neighbours are set aside before the Allan deviation
        (:func:`gyro_emulator.analysis.allan.screened_segments`; ``math.inf``:
        keep every sample).
    output : numpy.ndarray, optional
        The quantised output the calibrated values were derived from (a
        residual is not on the output's grid): the LSB is that of
        ``output``, not of the axes.
    sense : gyro_emulator.analysis.sense.Sense
        The channel: :data:`~gyro_emulator.analysis.sense.GYRO` (default) or
        :data:`~gyro_emulator.analysis.sense.ACCEL` (the record's
        accelerometer, m/s^2; its gravity read by :func:`gravity_at_rest`).
    scale : float
        Multiply the logged samples by this first (``--accel-scale``: a log
        in g takes 9.80665).

    Returns
    -------
    NoiseCalibration

    """
    check_scale(scale, 'scale')
    path, columns, timing = _channel(record, sense, axes, gap_factor, scale)
    gravity, notes = None, ()
    if sense is ACCEL:
        gravity, notes = gravity_at_rest(record.accel.values * scale, path, scale)
    # What the record itself tells (values, timing, grids) first, then the analysis.
    grids = {name: grid_step(rate, GRID_MAX_UNIQUE) for name, (rate, _) in columns.items()}
    output_grid = None if output is None else grid_step(output, GRID_MAX_UNIQUE)
    found, rate_hz, steps = [], None, []
    skipped = []
    for name, (rate, column) in columns.items():
        what = f'axis {name}' if sense is GYRO else f'{sense.name} axis {name}'
        try:
            rate_hz, segments, screened, handled = allan.screened_segments(
                timing, rate, outlier_threshold, what, sense)
        except outliers.HeldOutput as exc:
            if len(columns) == 1:
                raise ValueError(f'{path}: {exc}') from None
            skipped.append(f'{exc}: left out')
            continue
        except ValueError as exc:
            raise ValueError(f'{path}: {exc}') from None
        result, fit = allan.identify(segments, rate_hz, max_tau_fraction)
        axis_lsb, coarse = quantisation(rate, grids[name], sense.unit)
        if coarse:
            fit = replace(fit, warnings=fit.warnings + (coarse,))
        found.append(AxisNoise(name, column, result, fit,
                               float(np.mean(rate[screened.keep])), tuple(segments),
                               allan_record.set_aside_summary(screened, handled, sense)))
        steps.append(axis_lsb)
    if not found:
        raise ValueError(f'{path}: no axis to calibrate: ' + '; '.join(skipped))
    lsb = float(np.median(steps)) if all(s > 0.0 for s in steps) else 0.0
    if output is not None:
        lsb = quantisation(output, output_grid, sense.unit)[0]
    return NoiseCalibration(source=str(path), rate_hz=float(rate_hz),
                            duration_s=float(timing.time_s[-1] - timing.time_s[0]),
                            axes=tuple(found), lsb_rad_s=lsb, recovery=record.recovery,
                            skipped=tuple(skipped),
                            timing=allan_record.timing_notes(timing),
                            sense=sense, gravity_m_s2=gravity, notes=notes, scale=float(scale))


@dataclass(frozen=True)
class ExportedNoise:
    """
    The white noise and bias random walk an estimator gets, continuous time.

    ``arw_rad_s_sqrt_hz`` (N) and ``rrw_rad_s_sqrt_s`` (K, = rad/s^2/sqrt(Hz))
    after ``inflate``; ``rrw_is_bound`` when K is an upper bound (the
    axis that gives it does not resolve it); ``per_axis`` maps each axis to its own (N, K)
    before inflation; ``note`` says how the numbers were chosen.
    """

    arw_rad_s_sqrt_hz: float
    rrw_rad_s_sqrt_s: float
    bias_instability_rad_s: float
    rrw_is_bound: bool
    inflate: float
    per_axis: dict
    note: str


def axis_values(item):
    """Return (N, B, K, K is a bound) of one axis, rad/s units; K bound when not resolved."""
    fit = item.fit
    if fit.resolved('rrw'):
        return fit.arw_rad_s_sqrt_hz, fit.bias_instability_rad_s, fit.rrw_rad_s_sqrt_s, False
    return (fit.arw_rad_s_sqrt_hz, fit.bias_instability_rad_s,
            max(fit.intervals['rrw'].high, fit.rrw_rad_s_sqrt_s), True)


def check_inflate(inflate):
    """Refuse an inflation factor of the exported figures outside [1, 1000] (ValueError)."""
    if not (np.isfinite(inflate) and 1.0 <= inflate <= 1000.0):
        raise ValueError(f'inflate = {inflate!r} is out of range: allowed [1, 1000]')


def export_noise(calibration, inflate=1.0):
    """Return the estimator's N and K (module docstring): largest over axes, x ``inflate``."""
    check_inflate(inflate)
    per_axis = {a.axis: axis_values(a) for a in calibration.axes}
    n = max(v[0] for v in per_axis.values())
    b = max(v[1] for v in per_axis.values())
    k = max(v[2] for v in per_axis.values())
    # K is a bound when the axis that gives it is: a resolved K above every bound is a value
    bound = any(v[3] and v[2] == k for v in per_axis.values())
    unresolved = ', '.join(a for a, v in per_axis.items() if v[3])
    parts = []
    if len(per_axis) > 1:
        parts.append('largest of the axes')
    if bound:
        parts.append(f'K not resolved on {unresolved}: its upper bound is used')
    elif unresolved:
        parts.append(f'K not resolved on {unresolved}: its upper bound is below the K used')
    if inflate != 1.0:
        parts.append(f'inflated x{inflate:g} on request')
    return ExportedNoise(arw_rad_s_sqrt_hz=n * inflate, rrw_rad_s_sqrt_s=k * inflate,
                         bias_instability_rad_s=b * inflate, rrw_is_bound=bound,
                         inflate=float(inflate),
                         per_axis={a: (v[0], v[2]) for a, v in per_axis.items()},
                         note='; '.join(parts))
