"""
Timing of a record: increasing stamps, the nominal sample rate, segments and missing samples.

A step longer than ``gap_factor`` times the median positive step starts a
new segment (a gap in the record); within the segments, steps of whole
numbers of the nominal step are samples lost on the way
(:func:`dropped_samples`), unless they recur at a beat (a coarse clock).
Pure numpy: every reader of a record (:mod:`gyro_emulator.recording.record`,
:mod:`gyro_emulator.recording.csvio`) and every analysis use these rules.

:func:`timing_of` works the rate, the segments and the missing samples out
once, as a :class:`Timing`; a record carries its own
(:meth:`gyro_emulator.recording.record.Record.timing`), and ``allan``,
``calibrate noise``, ``calibrate thermal`` and ``diagnose`` read it from there.
"""

from dataclasses import dataclass

from gyro_emulator.validation import check_range, RECORD_TIME_LIMIT_S
import numpy as np


def check_increasing(time_s, what='time_s', strict=True):
    """Raise ValueError naming the first data row where ``time_s`` does not increase."""
    time_s = np.asarray(time_s, dtype=float)
    step = np.diff(time_s)
    bad = np.flatnonzero(step <= 0.0 if strict else step < 0.0)
    if len(bad):
        i = int(bad[0])
        hint = '' if not strict or np.any(step < 0.0) else ' (repeated timestamp)'
        raise ValueError(f'{what} does not increase at data row {i + 2}: '
                         f'{float(time_s[i + 1])!r} after {float(time_s[i])!r}{hint}')


#: Largest |time_s|, s: 317 years, past any epoch time in seconds (an epoch time in
#: ms, us or ns is 1.7e12, 1.7e15 or 1.7e18); the one limit of record times.
TIME_LIMIT_S = RECORD_TIME_LIMIT_S
#: Nominal (median) step allowed, s: 1 MHz to one sample an hour.
STEP_RANGE_S = (1e-6, 3600.0)
#: Units a time column is mistaken for, and what turns each into seconds.
TIME_UNITS = (('milliseconds', 1e3), ('microseconds', 1e6), ('nanoseconds', 1e9))
#: Epoch times in seconds from 2001 to 2096: a first stamp in this range, once
#: divided, names the unit.
EPOCH_RANGE_S = (1e9, 4e9)
#: A step in this range, once divided, names the unit (10 kHz to 1 Hz).
TYPICAL_STEP_S = (1e-4, 1.0)


def _power(factor):
    """Return 1e3, 1e6 or 1e9 as written by hand."""
    return f'{factor:.0e}'.replace('e+0', 'e')


def _unit_hint(first, step):
    """Name the units that would make ``first`` an epoch time or ``step`` a typical one."""
    for unit, factor in TIME_UNITS:
        if EPOCH_RANGE_S[0] <= abs(first) / factor <= EPOCH_RANGE_S[1]:
            return f'; looks like {unit} since the epoch: divide by {_power(factor)}'
    if step is None:
        return ''
    fits = [(u, f) for u, f in TIME_UNITS
            if TYPICAL_STEP_S[0] <= step / f <= TYPICAL_STEP_S[1]]
    if not fits:
        return ''
    return ('; looks like ' + ' or '.join(u for u, _ in fits) + ': divide by '
            + ' or '.join(_power(f) for _, f in fits))


#: A nominal step above this, s, is slower than an IMU logs: a note names the unit it may be.
SLOW_STEP_S = 1.0


def slow_step_note(time_s, step_s):
    """
    Name the unit a slow clock's stamps may be in, or return ''.

    A median step over :data:`SLOW_STEP_S` is allowed (a slow logger), but a
    100 Hz log stamped in milliseconds reads as 0.1 Hz: a noise density
    per sqrt(Hz) of the wrong rate is then sqrt(1e3) off, without an error.
    """
    if step_s <= SLOW_STEP_S:
        return ''
    hint = _unit_hint(float(np.asarray(time_s)[0]), step_s)
    return (f'the stamps give {1.0 / step_s:.3g} Hz (a median step of {step_s:.4g} s){hint} '
            '(a time column in another unit puts N and K off by the square root of its factor)'
            if hint else '')


def check_time_base(time_s, what='time_s'):
    """
    Raise ValueError unless ``time_s`` (increasing) is in seconds at a plausible rate.

    Every value within +-:data:`TIME_LIMIT_S` and the median positive step
    within :data:`STEP_RANGE_S`; the message names the data row, the value,
    the limit and the likely unit (an epoch time in ns: divide by 1e9).
    Checked before anything is sized from the duration or the rate.
    """
    t = np.asarray(time_s, dtype=float)
    if not len(t):
        return
    beyond = np.flatnonzero(~(np.abs(t) <= TIME_LIMIT_S))
    step = np.diff(t)
    positive = step[step > 0.0]
    median = float(np.median(positive)) if len(positive) else None
    if len(beyond):
        i = int(beyond[0])
        raise ValueError(f'{what}: data row {i + 1} is {float(t[i])!r}, beyond +-{TIME_LIMIT_S:g} '
                         f's (not seconds?){_unit_hint(t[i], median)}')
    low, high = STEP_RANGE_S
    if median is not None and not low <= median <= high:
        i = int(np.flatnonzero(step > 0.0)[0])
        raise ValueError(f'{what}: the median step is {median:.6g} s (data row {i + 2}: '
                         f'{float(t[i + 1])!r} after {float(t[i])!r}): allowed '
                         f'[{low:g}, {high:g}] s, 1 MHz to one sample an hour'
                         f'{_unit_hint(t[0], median)}')


#: Median and mean time step agreeing within this share: the median is the step.
STEP_AGREEMENT = 1e-3


#: A step longer than this many median steps starts a new segment (a gap).
GAP_FACTOR = 3.0


@dataclass(frozen=True, eq=False)
class Timing:
    """
    The timing of a record's stamps, worked out once (:func:`timing_of`).

    Attributes
    ----------
    time_s : numpy.ndarray
        The stamps, s, non-decreasing.
    gap_factor : float
        A step longer than this many median steps is a gap.
    median_step_s : float
        The median positive step, s.
    rate_hz : float
        Nominal sample rate, Hz: 1 / the median positive step, or 1 / the
        mean step within the segments when the two differ by more than
        :data:`STEP_AGREEMENT` (stamps rounded to a coarse clock or shared by
        a FIFO batch), or 1 / the step of the whole steps when samples are
        missing (:func:`dropped_samples`).
    bounds : tuple of (int, int)
        Start and stop index of each contiguous segment.
    missing : int
        Samples missing between stamps inside the segments (0 when no step
        reads as a drop).

    """

    time_s: np.ndarray
    gap_factor: float
    median_step_s: float
    rate_hz: float
    bounds: tuple
    missing: int

    def segments(self, values, min_samples=1):
        """Return ``values`` cut at the gaps: one array per segment of >= ``min_samples``."""
        values = np.asarray(values, dtype=float)
        return [values[a:b] for a, b in self.bounds if b - a >= min_samples]

    def kept(self, keep):
        """Return the :class:`Timing` of the samples ``keep`` marks (the same ``gap_factor``)."""
        keep = np.asarray(keep, bool)
        return self if keep.all() else timing_of(self.time_s[keep], self.gap_factor)


def timing_of(time_s, gap_factor=GAP_FACTOR):
    """
    Work out the :class:`Timing` of ``time_s``: nominal rate, segments, missing samples.

    A step longer than ``gap_factor`` times the median positive step
    starts a new segment (a gap in the record). The rate is 1 / that median,
    or, when the mean step within the segments differs from it by more than
    :data:`STEP_AGREEMENT`, the step of :func:`dropped_samples` (samples
    lost on the way) or else the mean step: stamps rounded to a coarse clock
    (a 416.7 Hz part stamped in whole milliseconds steps 2 and 3 ms, median
    2) or shared by a FIFO batch (steps 0, 0, 3 dt) have the right mean, not
    median. The samples missing inside the segments are counted even when so
    few are missing that the mean step agrees with the median.

    Raises ValueError when there are fewer than 2 stamps or no positive step.
    """
    t = np.asarray(time_s, dtype=float)
    median, within, bounds = _median_step_and_segments(t, gap_factor)
    lost = dropped_samples(within, median)
    dt = median
    mean = float(np.mean(within)) if len(within) else dt
    if mean > 0.0 and abs(mean / dt - 1.0) > STEP_AGREEMENT:
        dt = mean if lost is None else lost[1]
    return Timing(t, float(gap_factor), median, 1.0 / dt, tuple(bounds),
                  0 if lost is None else lost[0])


def _median_step_and_segments(time_s, gap_factor):
    """Return the median positive step, the steps within segments, and the segments."""
    t = np.asarray(time_s, dtype=float)
    check_range('timing', 'gap_factor', gap_factor, 1.0, None)
    if len(t) < 2:
        raise ValueError(f'time_s has {len(t)} samples: need >= 2')
    step = np.diff(t)
    positive = step[step > 0.0]
    if not len(positive):
        raise ValueError('time_s: no time step is positive')
    dt = float(np.median(positive))
    gap = step > gap_factor * dt
    cuts = np.flatnonzero(gap) + 1
    edges = np.concatenate(([0], cuts, [len(t)]))
    return dt, step[~gap], [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


#: Long steps off a whole number of nominal steps by more than this (median): not drops.
WHOLE_STEP_TOLERANCE = 0.25
#: More long steps than this share of all: a slower clock, not dropped samples.
MAX_LONG_STEP_SHARE = 0.5
#: Long steps whose spacings take two values this often recur at a beat (a coarse clock).
BEAT_SHARE = 0.9


def dropped_samples(step, dt):
    """
    Read steps as whole numbers of the nominal step with samples missing, or None.

    Samples lost on the way (a serial link, a USB buffer) leave steps of k
    whole nominal steps (k >= 2, k = the step / ``dt`` rounded) scattered
    among single ones. A faster part stamped by a coarse clock (900 Hz in
    whole milliseconds: steps of 1 and 2 ms) leaves the same two lengths,
    but its long steps recur at a beat: nearly all their spacings take one
    or two values. So the steps read as drops when none rounds to zero (a
    FIFO sharing a stamp is not a drop), at most
    :data:`MAX_LONG_STEP_SHARE` are long, the long ones lie within
    :data:`WHOLE_STEP_TOLERANCE` of whole numbers (median; stamps rounded to
    a clock leave 1.5 steps), and, when there are ten or more, fewer than
    :data:`BEAT_SHARE` of their spacings take the two commonest values
    (random losses spread them geometrically).

    Returns
    -------
    (int, float) or None
        The samples missing, sum(k - 1), and the step, sum(step) / sum(k);
        None when the steps are not drops.

    """
    step = np.asarray(step, dtype=float)
    whole = np.rint(step / dt)
    if not len(step) or np.any(whole < 1.0):
        return None
    long = np.flatnonzero(whole >= 2.0)
    if len(long) > MAX_LONG_STEP_SHARE * len(step):
        return None
    if len(long) and np.median(np.abs(step[long] / dt - whole[long])) > WHOLE_STEP_TOLERANCE:
        return None
    if len(long) >= 10:
        counts = np.sort(np.unique(np.diff(long), return_counts=True)[1])
        if np.sum(counts[-2:]) >= BEAT_SHARE * (len(long) - 1):
            return None
    return int(np.sum(whole - 1.0)), float(np.sum(step) / np.sum(whole))
