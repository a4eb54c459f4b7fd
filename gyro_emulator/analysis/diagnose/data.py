"""
Measured data for ``diagnose``: the CSV contract and its decimated view.

The CSV has a header row. Columns: ``time_s``; ``rate_cmd_rad_s`` (the
applied true rate, e.g. from a rate table; or ``rate_{x,y,z}_rad_s`` as
``simulate`` writes, read on the gyro column's axis; a record of a part at
rest may leave it out when the caller says so, ``static=True``); ``temp_c`` (the
temperature reading; optional: without it the temperature causes are not
testable); ``gyro_rad_s`` or, with ``axis``, ``gyro_<axis>_rad_s`` (the
measured output). Optional: ``accel_x_m_s2``, ``accel_y_m_s2``,
``accel_z_m_s2`` (all three or none). Other columns are ignored. A bag has
its topics mapped onto these roles (:func:`bag_topics`). Either is read
by :func:`gyro_emulator.recording.record.load_record`; :func:`measured`
turns the :class:`~gyro_emulator.recording.record.Record` into
:class:`MeasuredData`.

Fitting runs on bin means (:class:`Frame`): the samples are grouped in
contiguous bins of equal duration and every regressor is the mean of its
exact sample-level value over the bin (rate, rate^2, rate^3, the delayed rate
through a cumulative sum, acceleration). A least-squares fit on such means,
weighted by the sample count, is unbiased: it drops only the within-bin
variation of the regressors. Slow quantities (temperature, time, anything
that depends only on them) are taken at the bin means; a 0.3 s bin changes
the temperature by < 0.02 K on a 3 K/min ramp. Samples set aside (outliers,
:mod:`.screening`) are left out of the bins and of every fit.
"""

import copy
from dataclasses import dataclass

from gyro_emulator.emulation.recorded_profile import commanded_specific_force
from gyro_emulator.recording import csvio
from gyro_emulator.recording.record import DEFAULT_TOPICS, load_record
from gyro_emulator.units import AXES
from gyro_emulator.validation import check_record_values
import numpy as np
from scipy.interpolate import CubicSpline, PchipInterpolator
from scipy.signal import lfilter, lfilter_zi

#: Shapes of the applied rate between its samples (:meth:`Prepared.reshaped`): the
#: fits' linear interpolation, and the two classical smooth reconstructions.
RATE_SHAPES = ('linear', 'pchip', 'cubic')

REQUIRED_COLUMNS = ('time_s', 'rate_cmd_rad_s', 'temp_c', 'gyro_rad_s')
ACCEL_COLUMNS = ('accel_x_m_s2', 'accel_y_m_s2', 'accel_z_m_s2')

#: Most CSV rows diagnose holds: a longer record is read in blocks and averaged over
#: time bins to at most this many (:mod:`gyro_emulator.recording.binning`), so that
#: memory stays bounded (about 1.2 kB per row at the peak of the screening).
MAX_ROWS = 1_000_000
#: Largest number of bins fits run on (see the module docstring).
DEFAULT_MAX_BINS = 12000
#: Window of the centred temperature slope estimate, s.
TEMP_RATE_WINDOW_S = 30.0
#: Step of the uniform grid the temperature filters run on, at most, s.
TEMP_GRID_STEP_S = 0.5
#: Most points of that grid (11.6 days at 0.5 s): a longer record takes a coarser
#: one, still far finer than its bins (:data:`DEFAULT_MAX_BINS`).
TEMP_GRID_MAX_POINTS = 2_000_000


@dataclass(frozen=True)
class MeasuredData:
    """
    One measured record in the diagnose contract, SI units.

    Attributes
    ----------
    time_s : numpy.ndarray
        Sample times, s, non-decreasing (a repeated stamp, from a logger's
        clock resolution, is accepted; time going back is an error).
    rate_cmd_rad_s : numpy.ndarray
        Applied (true) rate about the sense axis, rad/s.
    temp_c : numpy.ndarray or None
        Temperature reading, deg C; None when the record has none.
    gyro_rad_s : numpy.ndarray
        Measured gyro output, rad/s.
    accel_m_s2 : numpy.ndarray or None
        Linear acceleration, shape (n, 3), m/s^2; None when not recorded.
    source : str
        Where the data came from (file name), for reports.
    recovery : tuple of str
        What a damaged source lost (e.g. a bag's corrupt chunks); () if sound.

    """

    time_s: np.ndarray
    rate_cmd_rad_s: np.ndarray
    temp_c: np.ndarray
    gyro_rad_s: np.ndarray
    accel_m_s2: np.ndarray = None
    source: str = ''
    recovery: tuple = ()

    def __post_init__(self):
        """Check shapes, finiteness, monotonic time and the physical limits of the values."""
        n = len(np.asarray(self.time_s))
        arrays = {'time_s': self.time_s, 'rate_cmd_rad_s': self.rate_cmd_rad_s,
                  'temp_c': self.temp_c, 'gyro_rad_s': self.gyro_rad_s}
        for name, value in arrays.items():
            if value is None and name == 'temp_c':
                continue
            arr = np.asarray(value, dtype=float)
            if arr.ndim != 1 or len(arr) != n:
                raise ValueError(
                    f'MeasuredData.{name}: expected {n} values, got shape '
                    f'{arr.shape}')
            bad = ~np.isfinite(arr)
            if np.any(bad):
                i = int(np.flatnonzero(bad)[0])
                raise ValueError(
                    f'MeasuredData.{name} = {float(arr[i])!r} at sample {i} is not a '
                    'finite number')
            object.__setattr__(self, name, arr)
        if n < 20:
            raise ValueError(
                f'MeasuredData: {n} samples is too few: allowed >= 20')
        if self.accel_m_s2 is not None:
            acc = np.asarray(self.accel_m_s2, dtype=float)
            if acc.shape != (n, 3) or not np.all(np.isfinite(acc)):
                raise ValueError(
                    f'MeasuredData.accel_m_s2: expected {n} x 3 finite values, '
                    f'got shape {acc.shape}')
            object.__setattr__(self, 'accel_m_s2', acc)
        step = np.diff(self.time_s)
        if np.any(step < 0.0):
            i = int(np.flatnonzero(step < 0.0)[0])
            raise ValueError(
                f'MeasuredData.time_s is not monotonic: sample {i + 1} has '
                f'time_s = {float(self.time_s[i + 1])!r} after '
                f'{float(self.time_s[i])!r}')
        if self.time_s[-1] <= self.time_s[0]:
            raise ValueError('MeasuredData.time_s spans no time: allowed '
                             'last > first')
        self._check_limits()

    def _check_limits(self):
        """Raise ValueError naming the first value beyond its physical limits, and the row."""
        for name, kind in (('rate_cmd_rad_s', 'rate'), ('gyro_rad_s', 'rate'), ('temp_c', 'temp')):
            if getattr(self, name) is not None:     # the one rule of every command
                check_record_values('MeasuredData', name, getattr(self, name), kind)

    @property
    def rows(self):
        """Return the number of samples."""
        return len(self.time_s)

    @property
    def has_accel(self):
        """Return whether acceleration columns are present."""
        return self.accel_m_s2 is not None

    @property
    def has_temp(self):
        """Return whether a temperature reading is present."""
        return self.temp_c is not None


#: The CSV columns diagnose reads (any others may hold anything).
COLUMNS = REQUIRED_COLUMNS + ('gyro_rad_s',) + tuple(f'gyro_{a}_rad_s' for a in AXES) \
    + tuple(f'rate_{a}_rad_s' for a in AXES) + ACCEL_COLUMNS
#: Default topic mapping of a bag (the emulator's inputs and output).
DEFAULT_BAG_TOPICS = {'rate': DEFAULT_TOPICS['rate'], 'temp': DEFAULT_TOPICS['temp'],
                      'gyro': DEFAULT_TOPICS['output'], 'accel': DEFAULT_TOPICS['accel']}


def _check_axis(axis):
    if axis is not None and axis not in AXES:
        raise ValueError(f"diagnose.axis = {axis!r} is not allowed: choose one of 'x', 'y', 'z'")


def bag_topics(rate_topic=None, temp_topic=None, gyro_topic=None, accel_topic=None):
    """
    Return the bag topic of each role diagnose reads (defaults :data:`DEFAULT_BAG_TOPICS`).

    The acceleration is read from ``cmd/linear_acceleration`` when the bag
    has it and ``accel_topic`` is None; ``'none'`` ignores it. It is the
    applied acceleration (gravity excluded) where the bag says so: the
    specific force then comes from the attitude integrated from the rate
    (:func:`~gyro_emulator.emulation.recorded_profile.commanded_specific_force`).
    """
    return {'gyro': gyro_topic or DEFAULT_BAG_TOPICS['gyro'],
            'rate': rate_topic or DEFAULT_BAG_TOPICS['rate'],
            'temp': temp_topic or DEFAULT_BAG_TOPICS['temp'], 'accel': accel_topic}


def load_measured(path, rate_topic=None, temp_topic=None, gyro_topic=None, accel_topic=None,
                  axis=None, static=False):
    """
    Read a measured record (CSV or bag) into the diagnose contract: :func:`measured` of it.

    Parameters
    ----------
    path : str
        CSV file (``.gz`` for gzip) with a header row (module docstring), or
        a bag directory or ``.mcap`` file
        (:func:`gyro_emulator.recording.record.load_record`).
    rate_topic, temp_topic, gyro_topic, accel_topic : str, optional
        A bag's topics (:func:`bag_topics`).
    axis : str, optional
        'x', 'y' or 'z': see :func:`measured`.
    static : bool
        The part was at rest: the applied rate is zero when a CSV has no
        ``rate_cmd_rad_s`` column.

    Returns
    -------
    MeasuredData

    Raises
    ------
    ValueError
        A required column is missing, a value is not numeric or not finite,
        or time goes back; the message names the column and the row.

    """
    _check_axis(axis)
    record = load_record(path, bag_topics(rate_topic, temp_topic, gyro_topic, accel_topic),
                         only=COLUMNS, max_rows=MAX_ROWS)
    return measured(record, axis, static)


def measured(record, axis=None, static=False):
    """
    Return the :class:`MeasuredData` of a record (a MeasuredData is returned as it is).

    A CSV's (or a synthetic record's) measured output is
    ``gyro_<axis>_rad_s`` when ``axis`` is given and the record has it, else
    ``gyro_rad_s``; the applied rate is ``rate_cmd_rad_s``, or the column
    of the same axis among ``rate_{x,y,z}_rad_s`` (as ``simulate`` writes);
    without either the applied rate is zero when ``static``. A bag's gyro
    topic sets the sample times (a repeated stamp is dropped); the applied
    rate about ``axis`` (default 'z'), the temperature and the acceleration
    are interpolated linearly onto them, and samples outside the span of any
    input topic are dropped.
    """
    if isinstance(record, MeasuredData):
        return record
    _check_axis(axis)
    if record.is_bag:
        return _from_bag(record, axis or 'z')
    return _from_columns(record, axis, static)


def _gyro_column(record, axis):
    """Return the name of the measured-output column (see :func:`measured`)."""
    columns = {c: a for a, c in record.gyro_sources.items()}
    if axis is not None and f'gyro_{axis}_rad_s' in columns:
        return f'gyro_{axis}_rad_s'
    if 'gyro_rad_s' in columns:
        return 'gyro_rad_s'
    per_axis = [c for c in csvio.GYRO_AXES if c in columns]
    if per_axis and axis is None:
        raise ValueError(f'{record.path}: no gyro_rad_s column; choose an axis (--axis) to '
                         f'read one of {", ".join(per_axis)}')
    raise ValueError(f'{record.path}: missing required column gyro_rad_s'
                     + (f' (or gyro_{axis}_rad_s)' if axis else '')
                     + f'; the file has {", ".join(_file_columns(record))}')


def _file_columns(record):
    """Return every column of a CSV record's file (those diagnose did not read too)."""
    return record.names if record.is_bag else csvio.column_names(record.path)


def _from_columns(record, axis=None, static=False):
    """Return the MeasuredData of a CSV or synthetic record (see :func:`measured`)."""
    path = record.path
    gyro = _gyro_column(record, axis)
    if record.rate is None and not static:
        raise ValueError(f'{path}: missing required column rate_cmd_rad_s (the applied rate; '
                         'or rate_x_rad_s, rate_y_rad_s and rate_z_rad_s as simulate writes); '
                         'for a part at rest give --static')
    accel = [c for c in ACCEL_COLUMNS if c in record.names]
    if accel and len(accel) != 3:
        raise ValueError(
            f'{path}: acceleration needs all of {", ".join(ACCEL_COLUMNS)}; '
            f'found only {", ".join(accel)}')
    n = len(record.time_s)
    by_column = {c: a for a, c in record.gyro_sources.items()}
    # the applied rate about the gyro column's own axis (a single column: ``axis``)
    sense = (axis or 'z') if gyro == csvio.GYRO_SINGLE else by_column[gyro]
    return MeasuredData(
        time_s=record.time_s,
        rate_cmd_rad_s=np.zeros(n) if record.rate is None else record.rate.axis(sense),
        temp_c=None if record.temp is None else record.temp.values,
        gyro_rad_s=record.gyro[by_column[gyro]],
        accel_m_s2=None if record.accel is None else record.accel.values,
        source=str(path) + (f' ({gyro})' if gyro != 'gyro_rad_s' else ''),
        recovery=record.recovery)


def _from_bag(record, axis):
    """Return the MeasuredData of a bag record on its gyro's times (see :func:`measured`)."""
    path = record.path
    t_gyro = record.gyro_stamp_ns
    if len(t_gyro) < 20:
        raise ValueError(f'bag {path}: topic {record.topics["gyro"]} has '
                         f'{len(t_gyro)} messages: allowed >= 20')
    keep = np.r_[True, np.diff(t_gyro) > 0]
    t, gyro = record.time_s[keep], record.gyro[axis][keep]
    inside = np.ones(len(t), bool)
    series = {}
    for role in ('rate', 'temp', 'accel'):
        channel = getattr(record, role)
        if channel is None:
            continue
        ts = channel.time_s
        values = channel.values if role == 'accel' else channel.axis(axis)[:, None]
        inside &= (t >= ts[0]) & (t <= ts[-1])
        series[role] = np.column_stack(
            [np.interp(t, ts, values[:, k]) for k in range(values.shape[1])])
    if record.linear_accel is not None:     # applied: gravity turned in from the attitude
        ts = record.linear_accel.time_s
        inside &= (t >= ts[0]) & (t <= ts[-1])
        series['accel'] = commanded_specific_force(record, t)
    if inside.sum() < 20:
        raise ValueError(f'bag {path}: fewer than 20 output samples lie '
                         'within the span of the input topics')
    accel = series['accel'][inside] if 'accel' in series else None
    return MeasuredData(time_s=t[inside] - t[inside][0],
                        rate_cmd_rad_s=series['rate'][inside, 0],
                        temp_c=series['temp'][inside, 0],
                        gyro_rad_s=gyro[inside], accel_m_s2=accel,
                        source=str(path), recovery=record.recovery)


def write_measured_csv(path, data):
    """Write ``data`` (MeasuredData, or a Record: :func:`measured`) in the diagnose contract."""
    data = measured(data)
    columns = {'time_s': data.time_s, 'rate_cmd_rad_s': data.rate_cmd_rad_s}
    fmt = ['%.6f', '%.9g']
    if data.has_temp:
        columns['temp_c'] = data.temp_c
        fmt.append('%.5f')
    columns['gyro_rad_s'] = data.gyro_rad_s
    fmt.append('%.9g')
    if data.has_accel:
        columns.update(zip(ACCEL_COLUMNS, data.accel_m_s2.T))
        fmt += ['%.6g'] * 3
    csvio.write_csv(path, columns, fmt)


class Frame:
    """
    Regressors of a record at one resolution: samples or bin means.

    Both resolutions expose the same attributes, so the models in
    :mod:`gyro_emulator.analysis.diagnose.effects` are written once: ``time_s``,
    ``rate`` (mean rate), ``rate2``, ``rate3`` (means of rate^2, rate^3),
    ``temp_c``, ``accel`` (n x 3 or None), ``gyro``, ``weight`` (samples per
    row). Slow quantities are computed on the bins and mapped to samples with
    :meth:`slow`.
    """

    def __init__(self, prepared, level, index=None):
        self.record = prepared
        self.bins = prepared
        self.level = level
        self.index = index
        self.bin_index = None if index is None else prepared.sample_bin_all[index]

    def __len__(self):
        """Return the rows at this resolution."""
        return len(self.time_s)

    def slow(self, values_on_bins):
        """Map a slow quantity computed on the bins to this resolution."""
        if self.level == 'bins':
            return values_on_bins
        return np.asarray(values_on_bins)[self.bin_index]

    def delayed_rate(self, delay_s):
        """Return the applied rate delayed by ``delay_s`` (the record's rate shape)."""
        if self.level == 'bins':
            return self.record.delayed_rate(delay_s, 'bins')
        return self.record.rate_at(self.record.data.time_s[self.index] - delay_s)

    def rate_derivative(self):
        """Return d(rate)/dt, rad/s^2: per sample (central differences), or its bin means."""
        if self.level == 'bins':
            return self.record.bin_mean(self.record.rate_derivative_all)
        return self.record.rate_derivative_all[self.index]

    def lagged_temp_c(self, tau_s):
        """Return the temperature through a first-order lag ``tau_s``."""
        return self.slow(self.record.lagged_temp_on_bins(tau_s))

    def temp_rate_c_s(self):
        """Return the smoothed temperature slope dT/dt, K/s."""
        return self.slow(self.record.temp_rate_on_bins)


class Prepared:
    """
    A record ready for fitting: samples, bins and shared temperature filters.

    The applied rate between its samples is taken as linear
    (:attr:`rate_shape`); :meth:`reshaped` gives the record with another
    shape of :data:`RATE_SHAPES`, for what depends on it (a delay shorter
    than the rate's changes: :mod:`.intervals`).

    Parameters
    ----------
    data : MeasuredData
        The record.
    max_bins : int
        Upper bound on the number of bins (see the module docstring).
    keep : numpy.ndarray of bool, optional
        Samples to use (False: set aside, :mod:`.screening`); all when None.
    fill_temp_c : float
        Temperature assumed when the record has no reading, deg C.

    """

    #: the applied rate between its samples: one of :data:`RATE_SHAPES`
    rate_shape = 'linear'

    def __init__(self, data, max_bins=DEFAULT_MAX_BINS, keep=None, fill_temp_c=25.0):
        self.data = data
        t = data.time_s
        keep = np.ones(len(t), bool) if keep is None else np.asarray(keep, bool)
        self.keep = keep
        dt = np.diff(t)
        self.dt_s = float(np.median(dt[dt > 0.0]))
        self.duration_s = float(t[-1] - t[0] + self.dt_s)
        bin_s = max(self.dt_s, self.duration_s / max_bins)
        # contiguous bins of equal duration over the whole record; bins with
        # no kept sample (gaps, set-aside stretches) are dropped
        raw = np.floor((t - t[0]) / bin_s + 1e-9).astype(np.int64)
        starts = np.flatnonzero(np.r_[True, raw[1:] != raw[:-1]])
        ends = np.r_[starts[1:], len(t)]
        counts = np.add.reduceat(keep.astype(float), starts)
        used = counts > 0
        self.bin_s = bin_s
        self.starts, self.ends = starts[used], ends[used]
        self.bin_start_s = t[self.starts]
        counts = counts[used]
        # set-aside samples alone in their raw bin map to the bin before (the
        # first bin when none is before: set aside from the record's start) for
        # slow quantities, but belong to no bin's sums
        raw_to_bin = np.maximum(np.cumsum(used) - 1, 0)
        raw_of_sample = np.repeat(np.arange(len(starts)), ends - starts)
        self.sample_bin_all = raw_to_bin[raw_of_sample]
        self._in_a_bin = used[raw_of_sample]
        self.sample_bin = self.sample_bin_all[keep]
        r = data.rate_cmd_rad_s
        temp = data.temp_c if data.has_temp else np.full(len(t), float(fill_temp_c))
        w = keep.astype(float)

        def mean(x):
            xw = x * (w if np.ndim(x) == 1 else w[:, None])
            sums = np.add.reduceat(xw, starts, axis=0)[used]
            return sums / (counts if np.ndim(x) == 1 else counts[:, None])

        self._cum_rate = np.r_[0.0, np.cumsum(r)]
        self.temp_all_c = temp
        self._rate_derivative = None
        self.samples = self.sample_frame(np.flatnonzero(keep))
        self.binned = self._frame(
            'bins', mean(t), mean(r), mean(r * r), mean(r ** 3), mean(temp),
            None if data.accel_m_s2 is None else mean(data.accel_m_s2),
            mean(data.gyro_rad_s), counts)
        # uniform grid for the temperature filters (exact on that grid)
        step = max(min(TEMP_GRID_STEP_S, max(bin_s, self.dt_s)),
                   self.duration_s / TEMP_GRID_MAX_POINTS)
        tb = self.binned.time_s
        self.grid_t = np.arange(tb[0], tb[-1] + step, step)
        self.grid_temp = np.interp(self.grid_t, self.binned.time_s,
                                   self.binned.temp_c)
        self.grid_step_s = step
        self.temp_rate_on_bins = self._temp_rate()
        self._lag_cache = {}

    @property
    def rate_derivative_all(self):
        """d(rate)/dt at every sample of the record (central differences), rad/s^2."""
        if self._rate_derivative is None:
            d = self.data
            self._rate_derivative = np.gradient(d.rate_cmd_rad_s, d.time_s) if np.all(
                np.diff(d.time_s) > 0.0) else np.zeros(d.rows)
        return self._rate_derivative

    def reshaped(self, shape):
        """
        Return this record with the applied rate ``shape`` between samples (None: unknown).

        ``shape`` one of :data:`RATE_SHAPES`: ``linear`` (the fits'), ``pchip``
        (monotone piecewise cubic, Fritsch & Carlson 1980: no overshoot) or
        ``cubic`` (the not-a-knot cubic spline). The copy shares the samples
        and bins and keeps its own cache of the quantities that depend on
        the shape. None where the time stamps do not increase strictly (a
        smooth interpolant needs them to).
        """
        if shape not in RATE_SHAPES:
            raise ValueError(f'shape = {shape!r} is not allowed: choose one of '
                             f'{", ".join(RATE_SHAPES)}')
        if shape == self.rate_shape:
            return self
        t = self.data.time_s
        if shape != 'linear' and not np.all(np.diff(t) > 0.0):
            return None
        other = copy.copy(self)
        other.rate_shape = shape
        other.__dict__.pop('_effect_cache', None)
        other.__dict__.pop('_interpolant', None)
        for name in ('binned', 'samples'):
            frame = copy.copy(getattr(self, name))
            frame.record = frame.bins = other
            setattr(other, name, frame)
        return other

    def rate_at(self, times_s):
        """Return the applied rate at ``times_s`` in the rate shape, held past the ends."""
        t, r = self.data.time_s, self.data.rate_cmd_rad_s
        if self.rate_shape == 'linear':
            return np.interp(times_s, t, r)
        f = self.__dict__.get('_interpolant')
        if f is None:
            # PCHIP's harmonic mean of neighbouring slopes divides by slopes that may be
            # tiny or 0 (a hold); it takes 0 there itself, the division only warns
            with np.errstate(divide='ignore', over='ignore', invalid='ignore'):
                f = PchipInterpolator(t, r) if self.rate_shape == 'pchip' else CubicSpline(t, r)
            self._interpolant = f
        return f(np.clip(times_s, t[0], t[-1]))

    def bin_mean(self, values_all):
        """Mean over the kept samples of each bin of a per-sample array (whole record)."""
        w = self.keep.astype(float)
        sums = np.bincount(self.sample_bin_all, weights=values_all * w,
                           minlength=len(self.binned.weight))
        return sums / self.binned.weight

    def sample_frame(self, index):
        """Return a sample-level :class:`Frame` of the samples at ``index`` (kept or not)."""
        d = self.data
        r = d.rate_cmd_rad_s[index]
        return self._frame('samples', d.time_s[index], r, r * r, r ** 3,
                           self.temp_all_c[index],
                           None if d.accel_m_s2 is None else d.accel_m_s2[index],
                           d.gyro_rad_s[index], np.ones(len(index)), index)

    def _frame(self, level, t, r, r2, r3, temp, accel, gyro, weight, index=None):
        f = Frame(self, level, index)
        f.time_s, f.rate, f.rate2, f.rate3 = t, r, r2, r3
        f.temp_c, f.accel, f.gyro, f.weight = temp, accel, gyro, weight
        return f

    def _temp_rate(self):
        """Centred difference of the gridded temperature over the window."""
        half = max(1, int(round(0.5 * TEMP_RATE_WINDOW_S / self.grid_step_s)))
        g = self.grid_temp
        if len(g) < 3:
            return np.zeros(len(self.binned.time_s))
        idx = np.arange(len(g))
        lo = np.clip(idx - half, 0, len(g) - 1)
        hi = np.clip(idx + half, 0, len(g) - 1)
        slope = (g[hi] - g[lo]) / ((hi - lo) * self.grid_step_s)
        return np.interp(self.binned.time_s, self.grid_t, slope)

    def lagged_temp_on_bins(self, tau_s):
        """
        First-order lag of the temperature, on the bins, deg C.

        tau dT_s/dt = T - T_s, solved exactly on the uniform grid for a
        temperature linear between grid points:
        T_s[k] = a T_s[k-1] + (1 - c) T[k] + (c - a) T[k-1], a = exp(-h/tau),
        c = tau (1 - a) / h; the filter starts in equilibrium.
        """
        key = float(tau_s)
        if key in self._lag_cache:
            return self._lag_cache[key]
        h = self.grid_step_s
        a = np.exp(-h / tau_s)
        c = tau_s * (1.0 - a) / h
        u = self.grid_temp
        b_coef, a_coef = [1.0 - c, c - a], [1.0, -a]
        y, _ = lfilter(b_coef, a_coef, u,
                       zi=lfilter_zi(b_coef, a_coef) * u[0])
        out = np.interp(self.binned.time_s, self.grid_t, y)
        if len(self._lag_cache) > 256:
            self._lag_cache.clear()
        self._lag_cache[key] = out
        return out

    def delayed_rate(self, delay_s, level):
        """
        Return the applied rate delayed by ``delay_s``, at a resolution.

        Samples: linear interpolation in time. Bins: the bin mean of the same
        interpolant over the kept samples, from cumulative sums over the
        whole record (exact for uniform sampling) less the set-aside samples.
        In another rate shape (:meth:`reshaped`): that interpolant at each
        sample, averaged over each bin's kept samples.
        """
        r = self.data.rate_cmd_rad_s
        if level == 'samples':
            return self.samples.delayed_rate(delay_s)
        if self.rate_shape != 'linear':
            return self.bin_mean(self.rate_at(self.data.time_s - delay_s))
        shift = delay_s / self.dt_s
        m = int(np.floor(shift))
        f = shift - m
        n = len(r)
        cum = self._cum_rate

        def window_sum(lag):
            # sum over bin samples of r[i - lag], indices clamped to the record
            lo = self.starts - lag
            hi = self.ends - lag
            total = cum[np.clip(hi, 0, n)] - cum[np.clip(lo, 0, n)]
            before = np.clip(np.minimum(hi, 0) - lo, 0, None)
            after = np.clip(hi - np.maximum(lo, n), 0, None)
            return total + before * r[0] + after * r[-1]

        total = (1.0 - f) * window_sum(m) + f * window_sum(m + 1)
        dropped = np.flatnonzero(~self.keep & self._in_a_bin)
        if len(dropped):
            idx = np.clip(dropped - m, 0, n - 1), np.clip(dropped - m - 1, 0, n - 1)
            values = (1.0 - f) * r[idx[0]] + f * r[idx[1]]
            total = total - np.bincount(self.sample_bin_all[dropped], weights=values,
                                        minlength=len(total))
        return total / self.binned.weight
