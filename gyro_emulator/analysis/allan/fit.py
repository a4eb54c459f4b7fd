"""
IEEE Std 952 noise identification from an Allan deviation.

The model has the five terms of IEEE Std 952 Annex C (Table C.1)::

    sigma^2(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln 2 / pi) B^2
                   + K^2 tau / 3 + R^2 tau^2 / 2

with Q (angle quantisation) in rad, N (angle random walk) in
rad/s/sqrt(Hz) = rad/sqrt(s), B (bias instability) in rad/s, K (rate random
walk) in rad/s/sqrt(s) and R (rate ramp) in rad/s^2; datasheet units come
from :mod:`gyro_emulator.units`.

The fit (:func:`fit_noise_terms`) works on the logarithm of the Allan
variance, by Gauss-Newton steps of non-negative least squares. Point i has
variance 2 / edf_i (the chi-squared law of the estimate) plus e^2, a model
discrepancy common to all points, set so that chi^2 per degree of freedom is
1. Where the curve follows the model e is 0 and the fit is weighted by the
equivalent degrees of freedom; where real data depart from the five terms
e caps every weight at 1 / e^2, so each decade of tau counts about equally
and thousands of degrees of freedom in the white region cannot outvote the
few that carry B and K (the region-wise balance of the IEEE Std 952
graphical method). Q and R are kept only when the data resolve them (their
lower 95 % bound is above zero), they carry at least a quarter of the Allan
variance somewhere in the fit range and they lower the weighted sum of
squares by at least 3.84
(a likelihood-ratio test at 95 %, which treats the taus as independent and
so favours the term: hence the other conditions). R must also show its
slope where the curve is precise (a local slope of +0.7 or more at
edf >= 20): a rate random walk over a finite record mimics a ramp at its
noisy long end, so a weaker ramp stays inside K.

Intervals (:class:`TermInterval`): each term's chi-squared interval at the
tau where it is best determined, NIST SP 1065 Sec 5.3 with the effective
degrees of freedom 2 / (2 / edf + e^2), transferred to the fitted value; a
term whose lower bound is zero, read at the taus up to a tenth of the
longest segment (:data:`RESOLVE_TAU_SHARE`), is reported as an upper bound
("not resolved") and its interval starts at zero. Read-offs
(:func:`readings`) are the IEEE Std 952 tangent lines of slope -1, -1/2,
0, +1/2 and +1 read at tau = sqrt(3), 1, the minimum, 3 and sqrt(2) s;
:func:`compare_readings` warns when the fitted curve and the measured
curve disagree at a read-off point.
"""

from dataclasses import dataclass, field, replace

from gyro_emulator import units
from gyro_emulator.analysis.allan.adev import local_slopes, pooled_edf
import numpy as np
from scipy import optimize, special, stats

#: Term names in model order, their Allan slopes and read-off tau (s).
TERMS = ('quantization', 'arw', 'bias_instability', 'rrw', 'rate_ramp')
SLOPES = {'quantization': -1.0, 'arw': -0.5, 'bias_instability': 0.0, 'rrw': 0.5,
          'rate_ramp': 1.0}
#: Terms kept only when the data resolve them.
OPTIONAL_TERMS = ('quantization', 'rate_ramp')
#: Q and R must carry this share of the Allan variance somewhere in the fit range.
MIN_SHARE = 0.25
#: Intervals are read where the term carries at least this share of the variance.
DOMINANT_SHARE = 0.5
#: R must show a local slope this steep where the curve has edf >= VISIBLE_EDF.
VISIBLE_SLOPE = 0.7
VISIBLE_EDF = 20.0
#: Q and R must lower the weighted sum of squares by this (chi^2_1 at 95 %).
LIKELIHOOD_RATIO = 3.84
#: Resolved from tau <= T/10 only: beyond, few averages give few dof (NIST SP 1065 Sec 5.3).
RESOLVE_TAU_SHARE = 0.1
#: A resolved K must cost this when removed: overlapping taus make 3.84 too lax (test_allan.py).
RRW_LIKELIHOOD_RATIO = 30.0
#: Default level of the term intervals (coverage measured in test_allan.py).
TERM_CI = 0.95
#: Level of the "resolved" decision (two-sided).
RESOLVED_LEVEL = 0.95
#: A read-off is identified when the local slope at its tau is this close to the term's.
READING_SLOPE_TOLERANCE = 0.15
#: The fitted curve disagrees with a read-off beyond this relative difference (and 2 sigma).
READING_DISAGREEMENT = 0.10
#: Model discrepancy (relative, in deviation) above which the fit is flagged.
MISFIT_WARNING = 0.10


def design(taus_s):
    """Return the Allan variance columns for (Q^2, N^2, B^2, K^2, R^2) (IEEE Std 952 C.1)."""
    t = np.asarray(taus_s, dtype=float)
    return np.column_stack([3.0 / t ** 2, 1.0 / t,
                            np.full(t.shape, units.FLICKER_FLOOR_PER_B ** 2), t / 3.0,
                            t ** 2 / 2.0])


def model_adev(taus_s, arw_rad_s_sqrt_hz, bias_instability_rad_s, rrw_rad_s_sqrt_s,
               quantization_rad=0.0, rate_ramp_rad_s2=0.0):
    """
    Allan deviation of the five IEEE Std 952 terms, rad/s.

    sqrt(3 Q^2/tau^2 + N^2/tau + (2 ln 2/pi) B^2 + K^2 tau/3 + R^2 tau^2/2)
    (IEEE Std 952 Annex C).
    """
    theta = np.array([quantization_rad, arw_rad_s_sqrt_hz, bias_instability_rad_s,
                      rrw_rad_s_sqrt_s, rate_ramp_rad_s2], dtype=float) ** 2
    return np.sqrt(design(taus_s) @ theta)


@dataclass(frozen=True)
class TermInterval:
    """
    Confidence interval of one term (SI units of the term).

    ``tau_s`` is where it was read (the tau that determines the term best);
    ``resolved`` is whether the lower 95 % bound is above zero.
    """

    low: float
    high: float
    tau_s: float
    resolved: bool


@dataclass(frozen=True)
class NoiseFit:
    """
    Fitted IEEE Std 952 gyro noise terms.

    Attributes
    ----------
    arw_rad_s_sqrt_hz : float
        N, angle random walk, rad/s/sqrt(Hz) (= rad/sqrt(s)).
    bias_instability_rad_s : float
        B, bias instability, rad/s (Allan floor 0.664 B).
    rrw_rad_s_sqrt_s : float
        K, rate random walk, rad/s/sqrt(s).
    taus_s : numpy.ndarray
        The averaging times used in the fit, s.
    quantization_rad : float
        Q, angle quantisation noise, rad (Allan deviation sqrt(3) Q / tau).
    rate_ramp_rad_s2 : float
        R, rate ramp, rad/s^2 (Allan deviation R tau / sqrt(2)).
    intervals : dict
        Term name -> :class:`TermInterval` at level ``ci``.
    ci : float
        Confidence level of ``intervals``.
    misfit : float
        Model discrepancy e: the relative scatter of the measured deviation
        about the model beyond its chi-squared scatter (0 = none).
    warnings : tuple of str
        What a user must know before trusting the numbers.
    band : gyro_emulator.analysis.allan.band.BandLimit or None
        The band-limited region left out (when the fit was told).
    readings : dict
        Term name -> :class:`Reading`, the read-offs over the fit's taus.

    """

    arw_rad_s_sqrt_hz: float
    bias_instability_rad_s: float
    rrw_rad_s_sqrt_s: float
    taus_s: np.ndarray
    quantization_rad: float = 0.0
    rate_ramp_rad_s2: float = 0.0
    intervals: dict = field(default_factory=dict)
    ci: float = 0.95
    misfit: float = 0.0
    warnings: tuple = ()
    band: object = None
    readings: dict = field(default_factory=dict)

    @property
    def arw_deg_sqrt_h(self):
        """N in deg/sqrt(h)."""
        return float(units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(self.arw_rad_s_sqrt_hz))

    @property
    def bias_instability_deg_h(self):
        """B in deg/h."""
        return float(units.rad_s_to_deg_h(self.bias_instability_rad_s))

    @property
    def rrw_deg_h_sqrt_h(self):
        """K in deg/h/sqrt(h)."""
        return float(units.rad_s_sqrt_s_to_rrw_deg_h_sqrt_h(self.rrw_rad_s_sqrt_s))

    @property
    def tau_range_s(self):
        """(shortest, longest) tau of the fit, s."""
        return float(self.taus_s[0]), float(self.taus_s[-1])

    def value(self, term):
        """Fitted value of ``term`` (one of :data:`TERMS`), SI units."""
        return float(self.coefficients()[TERMS.index(term)])

    def coefficients(self):
        """(Q, N, B, K, R) as an array, SI units."""
        return np.array([self.quantization_rad, self.arw_rad_s_sqrt_hz,
                         self.bias_instability_rad_s, self.rrw_rad_s_sqrt_s,
                         self.rate_ramp_rad_s2])

    def resolved(self, term):
        """Whether the data resolve ``term`` (lower 95 % bound above zero)."""
        interval = self.intervals.get(term)
        return bool(interval and interval.resolved)

    def adev(self, taus_s):
        """Model Allan deviation at ``taus_s``, rad/s."""
        return np.sqrt(design(taus_s) @ self.coefficients() ** 2)

    def term_adev(self, term, taus_s):
        """Allan deviation of one term alone at ``taus_s``, rad/s."""
        j = TERMS.index(term)
        return np.sqrt(design(taus_s)[:, j]) * self.coefficients()[j]


def _log_variance(edf):
    """Variance of ln(sigma^2) of an Allan variance with ``edf`` degrees of freedom: 2 / edf."""
    return 2.0 / np.maximum(np.asarray(edf, dtype=float), 1.0)


def log_avar_unbiased(avar, edf):
    """
    ln(sigma^2) less its chi-squared bias: E[ln(chi2_nu / nu)] = psi(nu/2) - ln(nu/2).

    The logarithm of an estimate with few degrees of freedom is low on
    average (by about 1 / edf); without this correction a log-domain fit
    underestimates the terms that live at long tau (K, R).
    """
    nu = np.maximum(np.asarray(edf, dtype=float), 1.0)
    return np.log(avar) - (special.digamma(nu / 2.0) - np.log(nu / 2.0))


def log_nnls(a, columns, log_avar, var, theta):
    """
    Minimise sum (ln avar - ln(A theta))^2 / var over theta >= 0.

    Gauss-Newton steps, each a non-negative least-squares problem, halved
    until the cost falls. ``a`` is the design (variance per unit theta),
    ``columns`` the columns used, ``theta`` the start; returns (theta, cost).
    """
    weight = 1.0 / np.sqrt(var)

    def cost(th):
        model = np.maximum(a[:, columns] @ th, 1e-300)
        return float(np.sum(((log_avar - np.log(model)) * weight) ** 2))

    current = cost(theta)
    for _ in range(60):
        model = np.maximum(a[:, columns] @ theta, 1e-300)
        target = model * (1.0 + log_avar - np.log(model))
        scale = weight / model
        proposal, _ = optimize.nnls(a[:, columns] * scale[:, np.newaxis], target * scale)
        step, new = 1.0, None
        while step > 1e-4:
            trial = theta + step * (proposal - theta)
            new = cost(trial)
            if new <= current:
                break
            step *= 0.5
        if new is None or new > current:
            break
        done = current - new <= 1e-10 * max(current, 1.0)
        theta, current = trial, new
        if done:
            break
    return theta, current


def discrepancy(resid, var0, dof):
    """Return the extra variance e^2 of ln(avar) giving chi^2 per dof = 1 (0 if below)."""
    if dof <= 0 or np.sum(resid ** 2 / var0) <= dof:
        return 0.0
    upper = float(np.sum(resid ** 2)) + 1.0
    return float(optimize.brentq(lambda e2: np.sum(resid ** 2 / (var0 + e2)) - dof,
                                 0.0, upper))


def _fit_columns(a, log_avar, var0, columns):
    """Fit the chosen columns; return (theta over all 5 terms, e^2)."""
    avar = np.exp(log_avar)
    start, _ = optimize.nnls(a[:, columns] / avar[:, np.newaxis], np.ones(len(avar)))
    theta, e2 = start, 0.0
    for _ in range(6):
        theta, _ = log_nnls(a, columns, log_avar, var0 + e2, theta)
        resid = log_avar - np.log(np.maximum(a[:, columns] @ theta, 1e-300))
        new_e2 = discrepancy(resid, var0, len(log_avar) - np.count_nonzero(theta))
        if abs(new_e2 - e2) <= 1e-3 * max(e2, 1e-6):
            e2 = new_e2
            break
        e2 = new_e2
    full = np.zeros(len(TERMS))
    full[columns] = theta
    return full, e2


def _point_bounds(avar, model, column, theta_j, var, level):
    """Chi-squared bounds on theta_j from each point alone (others held at the fit)."""
    edf = 2.0 / var
    lo = avar * edf / stats.chi2.ppf(0.5 + level / 2.0, edf)
    hi = avar * edf / stats.chi2.ppf(0.5 - level / 2.0, edf)
    others = model - column * theta_j
    point = (avar - others) / column
    return point, (lo - others) / column, (hi - others) / column


def term_interval(a, avar, theta, j, var, taus, level):
    """
    Interval of term j (variance coefficient theta_j) at ``level``, and where it was read.

    At every point where the term carries at least half of the model's
    variance, the chi-squared interval of the Allan variance (effective edf
    2 / var) bounds theta_j with the other terms held at their fitted values
    (where they are the minority, their error matters less); the narrowest
    such interval is shifted onto the fitted value. A term that dominates
    nowhere is read where its share is largest; a term fitted as zero gets
    an upper bound only. Returns (low, high, tau)
    of the coefficient sqrt(theta_j).
    """
    model = a @ theta
    point, lo, hi = _point_bounds(avar, model, a[:, j], theta[j], var, level)
    share = a[:, j] * theta[j] / np.maximum(model, 1e-300)
    width = np.where(share >= DOMINANT_SHARE, hi - lo, np.inf)
    i = int(np.argmin(width)) if np.any(np.isfinite(width)) else int(np.argmax(
        a[:, j] / np.maximum(model, 1e-300)))
    low = max(theta[j] - (point[i] - lo[i]), 0.0)
    high = max(theta[j] + (hi[i] - point[i]), theta[j])
    return float(np.sqrt(low)), float(np.sqrt(high)), float(taus[i])


def _intervals(a, avar, theta, var, taus, level, resolve_max_tau_s=np.inf):
    """
    Each term's interval, and whether it is resolved (:data:`RESOLVE_TAU_SHARE`).

    A term is resolved when its 95 % lower bound, read at the taus up to
    ``resolve_max_tau_s`` only, is above zero; an unresolved term's
    interval starts at zero (the data allow it to be absent).
    """
    var = np.broadcast_to(var, taus.shape)
    near = taus <= resolve_max_tau_s
    out = {}
    for j, name in enumerate(TERMS):
        low, high, tau = term_interval(a, avar, theta, j, var, taus, level)
        resolved = bool(np.any(near)) and term_interval(
            a[near], avar[near], theta, j, var[near], taus[near], RESOLVED_LEVEL)[0] > 0.0
        out[name] = TermInterval(low=low if resolved else 0.0, high=high, tau_s=tau,
                                 resolved=resolved)
    return out


#: NIST SP 1065 noise type (alpha) of each term, for the degrees of freedom.
_TERM_ALPHA = np.array([2, 0, -1, -2, -2])


def model_edf(result, taus_s, theta):
    """Equivalent dof at ``taus_s`` for the noise type the model says dominates there."""
    a = design(taus_s)
    alpha = _TERM_ALPHA[np.argmax(a * theta, axis=1)]
    m = np.round(np.asarray(taus_s) * result.rate_hz)
    return pooled_edf(result.segment_lengths or (result.n_samples,), m, alpha)


def _select(result, tau_range_s):
    taus = np.asarray(result.taus_s, dtype=float)
    sel = np.ones(len(taus), dtype=bool)
    if tau_range_s is not None:
        sel = (taus >= tau_range_s[0] * (1 - 1e-9)) & (taus <= tau_range_s[1] * (1 + 1e-9))
    sel &= np.asarray(result.adev) > 0.0
    if np.count_nonzero(sel) < 3:
        raise ValueError(f'fit_noise_terms: {np.count_nonzero(sel)} averaging times is too '
                         'few: need >= 3')
    return sel


def _cost(a, log_avar, var, theta):
    return float(np.sum((log_avar - np.log(np.maximum(a @ theta, 1e-300))) ** 2 / var))


def _unsupported(a, slopes, edf, log_avar, var, theta, intervals, columns):
    """Columns of the optional terms (Q, R) the data do not support (module docstring)."""
    share = a * theta / np.maximum(a @ theta, 1e-300)[:, np.newaxis]
    full = _cost(a, log_avar, var, theta)
    precise = edf >= VISIBLE_EDF
    out = []
    for term in OPTIONAL_TERMS:
        j = TERMS.index(term)
        if j not in columns:
            continue
        visible = term != 'rate_ramp' or bool(np.any(slopes[precise] >= VISIBLE_SLOPE))
        if not (intervals[term].resolved and np.max(share[:, j]) >= MIN_SHARE and visible):
            out.append(j)
            continue
        if _cost_without(a, log_avar, var, theta, columns, j) - full < LIKELIHOOD_RATIO:
            out.append(j)
    return out


def _cost_without(a, log_avar, var, theta, columns, j):
    """Weighted sum of squares of the fit refitted without column ``j``."""
    rest = [c for c in columns if c != j]
    sub, _ = log_nnls(a, rest, log_avar, var, np.maximum(theta[rest], 1e-300))
    without = np.zeros(len(TERMS))
    without[rest] = sub
    return _cost(a, log_avar, var, without)


def _random_walk_unsupported(a, log_avar, var, theta, columns, intervals):
    """
    Whether a resolved K fails :data:`RRW_LIKELIHOOD_RATIO` (then it is reported as a bound).

    K's interval holds the flicker level at its fitted value; the fit
    without K, N and B refitted, must also be clearly worse.
    """
    j = TERMS.index('rrw')
    if not intervals['rrw'].resolved or j not in columns:
        return False
    full = _cost(a, log_avar, var, theta)
    return _cost_without(a, log_avar, var, theta, columns, j) - full < RRW_LIKELIHOOD_RATIO


def _columns(terms):
    """Return the model columns of ``terms`` (None: all five); ValueError for a bad name."""
    if terms is None:
        return list(range(len(TERMS)))
    unknown = [t for t in terms if t not in TERMS]
    if unknown or not terms:
        raise ValueError(f'fit_noise_terms: terms = {tuple(terms)!r} is not allowed: a '
                         f'non-empty subset of {", ".join(TERMS)}')
    return sorted({TERMS.index(t) for t in terms})


def fit_noise_terms(result, tau_range_s=None, ci=None, terms=None):
    """
    Fit Q, N, B, K and R to an Allan deviation (IEEE Std 952; module docstring).

    Parameters
    ----------
    result : AllanResult
        From :func:`gyro_emulator.analysis.allan.overlapping_adev`.
    tau_range_s : tuple of float, optional
        Only use taus within [min, max], s (e.g. above the band-limited region
        of :mod:`gyro_emulator.analysis.allan.band`).
    ci : float, optional
        Level of the term intervals (default :data:`TERM_CI`, 95 %).
    terms : sequence of str, optional
        Fit only these terms (names of :data:`TERMS`), the others held at
        zero: e.g. N, B and K for a caller that models only white noise,
        flicker and random walk and must not see part of the curve go into
        a term it ignores. Default all five (Q and R kept only when the
        data support them).

    Returns
    -------
    NoiseFit
        N in rad/s/sqrt(Hz), B in rad/s, K in rad/s/sqrt(s), Q in rad, R in
        rad/s^2 (datasheet units via its properties), with intervals.

    """
    columns = _columns(terms)
    sel = _select(result, tau_range_s)
    taus = np.asarray(result.taus_s, dtype=float)[sel]
    avar = np.asarray(result.adev, dtype=float)[sel] ** 2
    a = design(taus)
    edf = np.asarray(result.edf, dtype=float)[sel]
    for _ in range(3):
        # the degrees of freedom follow the noise type the model says dominates
        log_avar = log_avar_unbiased(avar, edf)
        var0 = _log_variance(edf)
        theta, e2 = _fit_columns(a, log_avar, var0, columns)
        edf = model_edf(result, taus, theta)
    log_avar, var0 = log_avar_unbiased(avar, edf), _log_variance(edf)
    theta, e2 = _fit_columns(a, log_avar, var0, columns)
    level = TERM_CI if ci is None else float(ci)
    longest_s = max(result.segment_lengths or (result.n_samples,)) / result.rate_hz
    near = RESOLVE_TAU_SHARE * longest_s
    intervals = _intervals(a, avar, theta, var0 + e2, taus, level, near)
    slopes = local_slopes(taus, np.sqrt(avar))
    dropped = _unsupported(a, slopes, edf, log_avar, var0 + e2, theta, intervals, columns)
    if dropped:
        columns = [j for j in columns if j not in dropped]
        theta, e2 = _fit_columns(a, log_avar, var0, columns)
        intervals = _intervals(a, avar, theta, var0 + e2, taus, level, near)
    if _random_walk_unsupported(a, log_avar, var0 + e2, theta, columns, intervals):
        intervals = dict(intervals, rrw=replace(intervals['rrw'], low=0.0, resolved=False))
    q, n, b, k, r = np.sqrt(theta)
    misfit = float(np.sqrt(e2) / 2.0)
    warnings = []
    if misfit > MISFIT_WARNING:
        warnings.append(f'the curve departs from the IEEE Std 952 terms by about '
                        f'{100 * misfit:.0f} % rms beyond its statistical scatter: structure '
                        'the five terms do not describe; the intervals include it')
    return NoiseFit(arw_rad_s_sqrt_hz=float(n), bias_instability_rad_s=float(b),
                    rrw_rad_s_sqrt_s=float(k), taus_s=taus, quantization_rad=float(q),
                    rate_ramp_rad_s2=float(r), intervals=intervals, ci=level,
                    misfit=misfit, warnings=tuple(warnings))


#: Read-off rules: term -> (tau to read at, s; factor turning sigma(tau) into the term).
_READ_AT = {'quantization': (np.sqrt(3.0), lambda s, t: s * t / np.sqrt(3.0)),
            'arw': (1.0, lambda s, t: s * np.sqrt(t)),
            'bias_instability': (None, lambda s, t: s / units.FLICKER_FLOOR_PER_B),
            'rrw': (3.0, lambda s, t: s * np.sqrt(3.0 / t)),
            'rate_ramp': (np.sqrt(2.0), lambda s, t: s * np.sqrt(2.0) / t)}


@dataclass(frozen=True)
class Reading:
    """
    One IEEE Std 952 read-off: the tangent line of the term's slope.

    ``value`` (SI units of the term) is the lowest line of that slope that
    touches the curve; ``tau_s`` is where it touches; ``identified`` is
    whether the curve's own slope there is the term's (within 0.15): if not,
    the value is only an upper bound.
    """

    value: float
    tau_s: float
    slope: float
    identified: bool


def readings(taus_s, adev):
    """
    IEEE Std 952 read-offs of an Allan deviation (tangent lines; Annex C).

    Each term's value is the minimum over tau of sigma(tau) transformed by
    its line: Q = sigma tau / sqrt(3), N = sigma sqrt(tau), B = sigma / 0.664,
    K = sigma sqrt(3 / tau), R = sigma sqrt(2) / tau. Every other term only
    adds to sigma, so each read-off is an upper bound of the term, equal to
    it where the term dominates. N is read the classic way where the curve
    has a white region (local slope -1/2): sigma sqrt(tau) at the tau of
    that region closest to 1 s.
    """
    taus = np.asarray(taus_s, dtype=float)
    sig = np.asarray(adev, dtype=float)
    slopes = local_slopes(taus, sig, half_width=1)
    out = {}
    white = np.flatnonzero(np.abs(slopes - SLOPES['arw']) <= READING_SLOPE_TOLERANCE)
    for term in TERMS:
        values = _READ_AT[term][1](sig, taus)
        i = int(np.argmin(values))
        if term == 'arw' and len(white):
            # the classic reading: the -1/2 line through the white region, at 1 s
            i = int(white[np.argmin(np.abs(np.log(taus[white])))])
        interior = 0 < i < len(taus) - 1 or term != 'bias_instability'
        out[term] = Reading(value=float(values[i]), tau_s=float(taus[i]),
                            slope=float(slopes[i]), identified=bool(
                                abs(slopes[i] - SLOPES[term]) <= READING_SLOPE_TOLERANCE
                                and interior))
    return out


def compare_readings(fit, result, found):
    """
    Warnings where the fitted curve and the measured curve disagree at a read-off.

    At the tau of every identified read-off the fitted deviation is compared
    with the measured one; they disagree when they differ by more than 10 %
    and the fitted value lies outside the measured point's 99 % chi-squared
    interval (its own statistics, not widened by the model discrepancy: the
    question is whether the curve the fit draws passes through the point).
    99 %, not 95 %: the minimum of a curve is its lowest point by selection.
    At every read-off, identified or not, a fitted term whose own deviation
    alone is above that interval is a contradiction (each term is at most
    the total): the fit is pulled by structure the terms do not describe.
    """
    taus = np.asarray(result.taus_s, dtype=float)
    out = []
    for term, reading in found.items():
        i = int(np.argmin(np.abs(taus - reading.tau_s)))
        measured, fitted = float(result.adev[i]), float(fit.adev(taus[i:i + 1])[0])
        edf = max(float(result.edf[i]), 1.0)
        lo = measured * np.sqrt(edf / stats.chi2.ppf(0.995, edf))
        hi = measured * np.sqrt(edf / stats.chi2.ppf(0.005, edf))
        own = float(fit.term_adev(term, taus[i:i + 1])[0])
        if own > hi:
            out.append(f'the fitted {term} alone is {100 * (own / measured - 1):+.0f} % above '
                       f'the measured deviation at tau = {taus[i]:.3g} s, outside its 99 % '
                       'interval: the curve bends below the model there, so the fit is pulled '
                       'by something else (a warm-up or other trend, a step): check the start '
                       'of the log, trim it, and fit again')
            continue
        if not reading.identified:
            continue
        if abs(fitted / measured - 1.0) > READING_DISAGREEMENT and not lo <= fitted <= hi:
            out.append(f'fit and read-off disagree for {term} at tau = {taus[i]:.3g} s: the '
                       f'measured deviation is {100 * (measured / fitted - 1):+.0f} % from '
                       'the fitted curve, outside its 99 % interval')
    return out
