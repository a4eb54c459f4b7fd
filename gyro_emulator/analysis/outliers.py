"""
Outliers in a rate record: logger spikes and handling motion, found and set aside.

A few samples no model should explain (a logger glitch, a bump of the
bench) can outweigh hours of data in a mean, a least-squares fit or an
Allan deviation. The pieces here find them in a residual (``diagnose``'s
nuisance residual, or a static log's rate itself):

1. :func:`local_high_pass`: a leave-one-out local least-squares fit over
   +-``half`` samples (a bias, and when a commanded rate is given, the rate
   at the previous, same and next sample) removes whatever changes slowly
   (bias instability, random walk, temperature) or follows the rate through
   short dynamics; the prediction error is divided by its standard error;
2. :func:`high_pass_flags`: that fit run twice, the second time with the
   samples beyond 4 robust sigma of the first down-weighted, so that a
   spike does not drag its neighbours' predictions; a sample is flagged
   beyond ``threshold`` robust standard deviations (:func:`robust_scale`:
   1.4826 x the median absolute deviation);
3. :func:`flag_segments`: flags closer than :data:`MERGE_S` are one
   stretch; a stretch of two or more samples (motion) is widened by
   :data:`MERGE_S` each side to cover its settling.

:func:`screen_at_rest` does all three, twice, on a record taken at rest
(``allan``, ``calibrate noise``, ``calibrate thermal``). Gaussian noise
crosses 6 sigma once in 5e8 samples, so a clean record loses nothing.
"""

from dataclasses import dataclass
import math

from gyro_emulator.validation import GYRO_LIMIT_RAD_S
import numpy as np

#: Robust standard deviations beyond which a sample is an outlier.
THRESHOLD = 6.0
#: Half width of the local high-pass window, s (at least LOCAL_MIN_SAMPLES).
LOCAL_HALF_S = 2.0
LOCAL_MIN_SAMPLES = 5
#: Flags closer than this are one stretch; a motion stretch is widened by it, s.
MERGE_S = 1.0
#: More than this share set aside: the record is not at rest, nothing is set aside.
MAX_FRACTION = 0.5


def moving_sum(v, half):
    """Sum over i-half..i+half (clipped to the array) of v, along axis 0."""
    c = np.concatenate([np.zeros((1,) + v.shape[1:]), np.cumsum(v, axis=0)])
    n = len(v)
    idx = np.arange(n)
    return c[np.minimum(idx + half + 1, n)] - c[np.maximum(idx - half, 0)]


def local_high_pass(r, rate, weight, half):
    """
    Leave-one-out local least squares of ``r`` on [1, rate[i-1], rate[i], rate[i+1]].

    Over +-half samples: a bias, a scale factor and any short linear
    dynamics (a delay or a filter within a sample) that hold locally; with
    ``rate`` None, the bias only (a record at rest). Moving sums of the
    weighted cross products give each sample's normal equations without the
    sample itself; a small ridge keeps a window of constant rate solvable (a
    ridge of 1e-6 of the diagonal). The prediction error is divided by
    sqrt(1 + x' G^-1 x), its standard deviation in units of the noise: a
    sample unlike its neighbours (the corner of a rate step) is predicted
    less well, and that is not an outlier.
    """
    if rate is None:
        total = moving_sum(weight, half) - weight
        level = (moving_sum(weight * r, half) - weight * r) / np.maximum(total, 1e-300)
        return (r - level) / np.sqrt(1.0 + 1.0 / np.maximum(total, 1e-300))
    prev = np.r_[rate[:1], rate[:-1]]
    nxt = np.r_[rate[1:], rate[-1:]]
    basis = np.column_stack([np.ones(len(r)), prev, rate, nxt])
    p = basis.shape[1]
    bw = basis * weight[:, None]
    gram = moving_sum(bw[:, :, None] * basis[:, None, :], half)
    gram -= bw[:, :, None] * basis[:, None, :]
    rhs = moving_sum(bw * r[:, None], half) - bw * r[:, None]
    diag = np.einsum('nii->ni', gram)
    ridge = 1e-6 * diag + 1e-9 * np.max(diag, axis=1, keepdims=True) + 1e-300
    gram[:, np.arange(p), np.arange(p)] += ridge
    # one factorisation per sample for both right-hand sides: G^-1 b and G^-1 x
    both = np.linalg.solve(gram, np.stack([rhs, basis], axis=2))
    lev = np.sum(basis * both[:, :, 1], axis=1)
    return (r - np.sum(basis * both[:, :, 0], axis=1)) / np.sqrt(1.0 + np.maximum(lev, 0.0))


def stretches(t, dt_s):
    """Return start and stop indices of the contiguous runs (a gap over 3 dt splits)."""
    cuts = np.flatnonzero(np.diff(t) > 3.0 * dt_s) + 1
    edges = np.r_[0, cuts, len(t)]
    return list(zip(edges[:-1], edges[1:]))


def robust_scale(h):
    """1.4826 x the median absolute deviation (the standard deviation for Gaussian data)."""
    sigma = 1.4826 * float(np.median(np.abs(h - np.median(h))))
    return sigma if sigma > 0.0 else (float(np.std(h)) or 1e-300)


def quantisation_step(values):
    """
    Return the output step of a quantised record (its LSB), or 0 for a continuous one.

    The smallest gap between distinct values, when at most one value in
    four is distinct (a quantised output repeats its levels; a continuous
    one does not).
    """
    levels = np.unique(values)
    if len(levels) < 2 or len(levels) > 0.25 * len(values):
        return 0.0
    return float(np.min(np.diff(levels)))


def clipped_scale(h, threshold=THRESHOLD, iterations=10):
    """
    Return the standard deviation of ``h`` without the values beyond ``threshold`` of it.

    Iterated until it no longer falls.

    For a quantised output, whose few levels make the median absolute
    deviation jump with the noise-to-LSB ratio, this is the consistent
    scale (Gaussian noise loses 2e-9 of its values at 6 sigma).
    """
    centre = float(np.median(h))
    sigma = float(np.std(h))
    for _ in range(iterations):
        inner = h[np.abs(h - centre) <= threshold * sigma]
        if len(inner) < 2:
            break
        new = float(np.std(inner))
        if new >= sigma * (1.0 - 1e-6):
            break
        sigma = new
    return sigma


def high_pass_flags(r, rate, keep, t, dt_s, threshold=THRESHOLD, floor=0.0):
    """
    Flag the samples of ``r`` that stand out from their neighbours (module docstring, 1-2).

    Parameters
    ----------
    r : numpy.ndarray
        The residual (or a rate at rest), per sample.
    rate : numpy.ndarray or None
        The commanded rate per sample (None: a bias-only local fit).
    keep : numpy.ndarray of bool
        Samples that may inform the local fits and the scale.
    t : numpy.ndarray
        Sample times, s (a gap of more than 3 dt splits the local fits).
    dt_s : float
        Sample interval, s.
    threshold : float
        Robust standard deviations.
    floor : float
        Least scale (for a quantised output: see :func:`screen_at_rest`).

    Returns
    -------
    (numpy.ndarray of bool, float, numpy.ndarray)
        The flags, the robust scale of the high-passed residual, and that
        residual (each stretch's own local fit).

    """
    half = max(LOCAL_MIN_SAMPLES, int(round(LOCAL_HALF_S / dt_s)))
    weight = keep.astype(float)
    h = np.zeros(len(r))
    for _ in range(2):
        for lo, hi in stretches(t, dt_s):
            h[lo:hi] = local_high_pass(r[lo:hi], None if rate is None else rate[lo:hi],
                                       weight[lo:hi], half)
        sigma = max(robust_scale(h[keep]), floor)
        u = np.abs(h) / (4.0 * sigma)
        weight = keep * np.where(u > 1.0, 1.0 / np.maximum(u, 1.0) ** 2, 1.0)
    return np.abs(h) > threshold * sigma, sigma, h


def flag_segments(flag, t, dt_s):
    """Group flags into stretches; widen multi-sample ones. Returns (set-aside mask, spans)."""
    idx = np.flatnonzero(flag)
    out = np.zeros(len(t), bool)
    spans = []
    if not len(idx):
        return out, spans
    breaks = np.flatnonzero(np.diff(t[idx]) > MERGE_S) + 1
    for group in np.split(idx, breaks):
        lo, hi = t[group[0]], t[group[-1]]
        if len(group) > 1:
            lo, hi = lo - MERGE_S, hi + MERGE_S + 0.5 * dt_s
            sel = (t >= lo) & (t <= hi)
        else:
            sel = np.zeros(len(t), bool)
            sel[group[0]] = True
        out |= sel
        spans.append((float(t[sel][0]), float(t[sel][-1]), int(sel.sum())))
    return out, spans


#: Identical consecutive samples over this long (s, and at least STUCK_MIN_SAMPLES)
#: make a held stretch: a stuck or saturated output, not noise.
STUCK_MIN_S = 1.0
STUCK_MIN_SAMPLES = 100
#: Share of the record in held stretches beyond which an axis is not usable.
STUCK_SHARE = 0.01


def held_share(values, rate_hz):
    """
    Return (share of samples in held stretches, the longest stretch's value).

    A held stretch is a run of identical consecutive samples of at least
    :data:`STUCK_MIN_S` and :data:`STUCK_MIN_SAMPLES`: a stuck or saturated
    output (a quantised output whose noise is about its LSB repeats a value
    for a handful of samples, never a hundred: 0.7^100 = 3e-16).
    """
    values = np.asarray(values, dtype=float)
    if len(values) < 2:
        return 0.0, float('nan')
    change = np.flatnonzero(values[1:] != values[:-1]) + 1
    starts = np.r_[0, change]
    lengths = np.diff(np.r_[starts, len(values)])
    held = lengths >= max(STUCK_MIN_SAMPLES, int(math.ceil(STUCK_MIN_S * rate_hz)))
    if not np.any(held):
        return 0.0, float('nan')
    longest = int(np.argmax(lengths))
    return float(np.sum(lengths[held])) / len(values), float(values[starts[longest]])


class HeldOutput(ValueError):
    """An output stuck, saturated or dead (:func:`check_not_held`): a part to leave out."""


def check_not_held(values, rate_hz, what):
    """Raise HeldOutput naming ``what`` when its output is stuck or saturated (held_share)."""
    share, value = held_share(values, rate_hz)
    if share > STUCK_SHARE:
        whole = 'holds one value' if share >= 1.0 else (
            f'holds one value for {100 * share:.3g} % of its samples')
        raise HeldOutput(f'{what} {whole} ({value:.9g}): a stuck, saturated or dead output '
                         '(or one quantised far more coarsely than its noise) has no noise to '
                         'identify; cut those samples or leave the axis out')


#: Window each side of a stretch set aside over which the levels are compared, s.
SHIFT_WINDOW_S = 10.0


def _window_means(time_s, values, keep, window_s):
    """Means of the kept samples in consecutive windows of ``window_s`` (empty ones left out)."""
    # the windows that hold samples, numbered in order: as many as the samples at
    # most, however long the gaps between them
    _, index = np.unique(np.floor((time_s[keep] - time_s[0]) / window_s), return_inverse=True)
    sums = np.bincount(index, weights=values[keep])
    counts = np.bincount(index)
    full = counts >= max(10, 0.5 * np.max(counts, initial=0))
    return sums[full] / counts[full]


def level_shifts(time_s, values, keep, spans, threshold=THRESHOLD, window_s=SHIFT_WINDOW_S):
    """
    Return the stretches across which the level steps: [(start_s, end_s, shift)].

    The mean of the kept samples within ``window_s`` after a stretch minus
    the mean within ``window_s`` before it (a shock that moved the bias, the
    bump itself set aside), judged against the robust spread of the
    differences of adjacent ``window_s`` means over the whole record (the
    record's own wander over that time, white noise included): beyond
    ``threshold`` of it, the level stepped.
    """
    time_s = np.asarray(time_s, dtype=float)
    values = np.asarray(values, dtype=float)
    means = _window_means(time_s, values, keep, window_s)
    if len(means) < 8:
        return []
    scale = robust_scale(np.diff(means))
    out = []
    for lo, hi, _ in spans:
        before = keep & (time_s >= lo - window_s) & (time_s < lo)
        after = keep & (time_s > hi) & (time_s <= hi + window_s)
        if np.count_nonzero(before) < 10 or np.count_nonzero(after) < 10:
            continue
        shift = float(np.mean(values[after]) - np.mean(values[before]))
        if abs(shift) > threshold * scale:
            out.append((lo, hi, shift))
    return out


@dataclass(frozen=True)
class SetAside:
    """
    What :func:`screen_at_rest` set aside.

    ``keep`` is True for the samples kept; ``spans`` lists each stretch set
    aside as (start_s, end_s, samples); ``sigma_rad_s`` is the robust scale
    of the high-passed rate; ``threshold`` the robust standard deviations
    (``math.inf``: screening off); ``note`` is set when nothing was set
    aside because too much would have been; ``outside`` counts the samples
    set aside, always, for lying beyond the physical ``limits`` (a bad cell:
    -1e308 in a gyro column), whose ``unit`` and ``cause`` (what the
    stretches are) the description names.
    """

    keep: np.ndarray
    spans: tuple
    sigma_rad_s: float
    threshold: float
    note: str = ''
    outside: int = 0
    limits: tuple = (-GYRO_LIMIT_RAD_S, GYRO_LIMIT_RAD_S)
    unit: str = 'rad/s'
    cause: str = 'spikes, motion'

    @property
    def count(self):
        """Return the number of samples set aside."""
        return int(len(self.keep) - np.count_nonzero(self.keep))

    @property
    def fraction(self):
        """Return the share of the samples set aside."""
        return self.count / max(len(self.keep), 1)

    def as_dict(self, max_spans=50):
        """JSON-ready form (the first ``max_spans`` stretches; a scale not worked out: null)."""
        doc = {'count': self.count, 'fraction': self.fraction,
               'stretches': len(self.spans),
               'spans': [list(s) for s in self.spans[:max_spans]],
               'sigma_rad_s': self.sigma_rad_s if math.isfinite(self.sigma_rad_s) else None,
               'threshold_sigma': None if math.isinf(self.threshold) else self.threshold,
               'note': self.note}
        if self.outside:
            doc['outside_limits'] = {'count': self.outside, 'limits': list(self.limits),
                                     'unit': self.unit}
        return doc

    def describe(self):
        """One line for a report: how many samples, in how many stretches, and when."""
        if self.outside:
            return self._describe_outside()
        if math.isinf(self.threshold):
            return 'outlier screening off: every sample kept'
        if not self.count:
            return (f'no sample beyond {self.threshold:g} robust sigma of its neighbours: '
                    f'nothing set aside{"; " + self.note if self.note else ""}')
        return (f'set aside {self.count} samples ({100 * self.fraction:.3g} %) in '
                f'{len(self.spans)} stretches beyond {self.threshold:g} robust sigma of '
                f'their neighbours ({self.cause}): {self._when()}')

    def _when(self):
        first = ', '.join(f'{lo:.1f}-{hi:.1f} s' if n > 1 else f'{lo:.2f} s'
                          for lo, hi, n in self.spans[:4])
        return first + (f' and {len(self.spans) - 4} more' if len(self.spans) > 4 else '')

    def _describe_outside(self):
        low, high = self.limits
        parts = [f'{self.outside} beyond the physical limits [{low:g}, {high:g}] {self.unit} '
                 '(bad cells)']
        if self.count > self.outside:
            parts.append(f'{self.count - self.outside} beyond {self.threshold:g} robust sigma '
                         f'of their neighbours ({self.cause})')
        tail = ('; outlier screening off: every other sample kept'
                if math.isinf(self.threshold) else f'; {self.note}' if self.note else '')
        return (f'set aside {self.count} samples ({100 * self.fraction:.3g} %) in '
                f'{len(self.spans)} stretches, {" and ".join(parts)}: {self._when()}{tail}')


def _quantised_floor(rate, time_s, dt_s, threshold):
    """Least scale of a quantised record (:func:`screen_at_rest`); 0 for a continuous one."""
    step = quantisation_step(rate)
    if step <= 0.0:
        return 0.0
    _, _, h = high_pass_flags(rate, None, np.ones(len(rate), bool), time_s, dt_s, threshold)
    return max(step / math.sqrt(12.0), clipped_scale(h, threshold))


def screen_at_rest(time_s, rate_rad_s, dt_s, threshold=THRESHOLD, what='the rate',
                   limits=(-GYRO_LIMIT_RAD_S, GYRO_LIMIT_RAD_S), unit='rad/s', floor=0.0,
                   cause='spikes, motion'):
    """
    Find the spikes and motion of a record taken at rest (module docstring).

    First the samples beyond the physical ``limits`` are set aside, always
    (bad cells; they are given the median of the rest, so that no fit sees
    them); more than :data:`MAX_FRACTION` of them is an error, naming the
    first. Then two passes of :func:`high_pass_flags` (the second without the
    first's flags in its fits and scale), then :func:`flag_segments`. A quantised
    output (:func:`quantisation_step`) takes as its scale at least the
    clipped standard deviation of its high-passed rate
    (:func:`clipped_scale`) and the quantisation noise LSB / sqrt(12): a part
    whose noise is about its LSB moves by whole LSBs, and that is no outlier. When more
    than :data:`MAX_FRACTION` of the record would go, it is not at rest:
    nothing else is set aside and ``note`` says so.

    Parameters
    ----------
    time_s, rate_rad_s : numpy.ndarray
        Sample times (s) and rates (rad/s).
    dt_s : float
        Sample interval, s.
    threshold : float
        Robust standard deviations (``math.inf``: set nothing aside but
        the samples beyond ``limits``).
    what : str
        The column, for the error.
    limits : (float, float)
        Physical limits of the values, in ``unit`` (default: a gyro's,
        :data:`gyro_emulator.validation.GYRO_LIMIT_RAD_S`).
    unit : str
        Unit of the values.
    floor : float
        Least robust scale (a quantity with no noise of its own, as a
        temperature: the smallest jump that is an outlier, over ``threshold``).
    cause : str
        What the stretches set aside are, for the description.

    Returns
    -------
    SetAside

    """
    time_s = np.asarray(time_s, dtype=float)
    rate, outside = _within_limits(np.asarray(rate_rad_s, dtype=float), limits, unit, what)
    n = len(rate)
    aside = {'outside': int(np.count_nonzero(outside)), 'limits': tuple(limits), 'unit': unit,
             'cause': cause}
    keep = ~outside
    spans = tuple(flag_segments(outside, time_s, dt_s)[1]) if aside['outside'] else ()
    if not math.isfinite(threshold) or n < 2 * LOCAL_MIN_SAMPLES + 1:
        return SetAside(keep, spans, float('nan'), threshold, **aside)
    flag = outside.copy()
    sigma = float('nan')
    floor = max(floor, _quantised_floor(rate, time_s, dt_s, threshold))
    for _ in range(2):
        new, sigma, _ = high_pass_flags(rate, None, ~flag, time_s, dt_s, threshold, floor)
        flag |= new
    drop, found = flag_segments(flag, time_s, dt_s)
    if drop.sum() > MAX_FRACTION * n:
        note = (f'{100 * drop.mean():.0f} % of the samples stand out from their neighbours: '
                'the record is not at rest, so nothing was set aside')
        return SetAside(keep, spans, sigma, threshold, note, **aside)
    return SetAside(~drop, tuple(found), sigma, threshold, **aside)


def _within_limits(values, limits, unit, what):
    """
    Return (values with those beyond ``limits`` set to the median of the rest, their mask).

    ValueError naming the first when more than :data:`MAX_FRACTION` are beyond.
    """
    low, high = limits
    outside = ~((values >= low) & (values <= high))
    count = int(np.count_nonzero(outside))
    if not count:
        return values, outside
    i = int(np.flatnonzero(outside)[0])
    if count > MAX_FRACTION * len(values):
        raise ValueError(f'{what}: {count} of {len(values)} values are beyond the physical '
                         f'limits [{low:g}, {high:g}] {unit} (the first at data row {i + 1}: '
                         f'{float(values[i])!r}): is the column in {unit}?')
    return np.where(outside, np.median(values[~outside]), values), outside
