"""
Noise and effect estimated jointly: a local-level likelihood-ratio test on group means.

The residual's group means (a few hundred contiguous groups of samples,
:class:`.noise_model.SuperBins`) follow the structural model

    y_i = mu_i + x_i' beta + e_i,   e_i ~ N(0, sigma^2 / n_i),
    mu = a random walk of intensity K (rad/s/sqrt(s)) averaged over each group,

white noise of per-sample variance sigma^2 averaged over the group's n_i
samples plus a random walk (rate random walk, IEEE Std 952), the diffuse
level of Harvey (1989, Sec 2.3.1, 'llevel' in statsmodels'
``UnobservedComponents``). The level is removed by differencing, which is
the exact diffuse likelihood (Harvey 1989, Sec 3.4.3): the differences
d_i = y_i - y_{i-1} have a tridiagonal covariance, for a random walk
averaged over contiguous windows of lengths L_{i-1}, L_i separated by a gap
g_i (Allan-variance algebra: a walk averaged over two adjacent windows of
length tau differs by 2 K^2 tau / 3)::

    var d_i        = sigma^2 (1/n_i + 1/n_{i-1}) + K^2 ((L_{i-1} + L_i) / 3 + g_i)
    cov d_i, d_i+1 = -sigma^2 / n_i + K^2 L_i / 6

so the profile likelihood in (sigma^2, K^2), beta solved by generalised
least squares, costs one banded Cholesky per evaluation: exact for uneven
groups and gaps (which statsmodels' equally spaced, equal-variance model is
not) and about 100x faster than its Kalman filter, which makes the
parametric bootstrap affordable. The test's own check compares the
likelihood with statsmodels' on equal groups.

- :func:`fit_level`: the MLE of sigma^2 and K^2 (K^2 at most ``rw_cap``,
  the random walk the Allan deviation at short and middle averaging times
  allows, :func:`.noise_model.random_walk_cap`).
- :func:`lr_test`: the likelihood ratio of candidate columns given the
  nuisance columns, its asymptotic p (chi^2, q columns) and, where it can
  change the answer, the parametric-bootstrap Bartlett correction under the
  null MLE (:func:`simulate_differences`).
"""

from dataclasses import dataclass
import math
import warnings

import numpy as np
from scipy import linalg, optimize, stats

#: Bootstrap replicates of the Bartlett factor: the mean of N chi^2_1 draws has
#: a standard deviation of sqrt(2 / N), 0.09 at 256 (64 gave 0.18, and from one
#: fixed seed the same error on every record: a factor of 1.2 where the null
#: mean is 1.0 on the ADIS16405 cycles of bench/study_anchor.py).
N_BOOT = 256
#: Bartlett factors outside [C_LOW, C_HIGH] are not expected: the bootstrap
#: runs only when a factor within them could change the decision.
C_LOW, C_HIGH = 0.5, 2.5
#: Search range of log10(K^2 L / (sigma^2 / n)), the walk over one group
#: against the white noise of a group mean.
LOG_RATIO_RANGE = (-9.0, 4.0)
#: LAPACK's banded Cholesky factorisation and solve, double precision (:func:`_gls`).
_PBTRF, _PBTRS = linalg.get_lapack_funcs(('pbtrf', 'pbtrs'), (np.zeros(1),))


@dataclass(frozen=True)
class Groups:
    """
    The groups of a record: samples per group, kept duration and mean time.

    Attributes
    ----------
    count : numpy.ndarray
        Samples in each group (n_i > 0).
    length_s : numpy.ndarray
        Kept duration of each group, n_i dt, s.
    time_s : numpy.ndarray
        Mean time of each group (increasing), s.

    """

    count: np.ndarray
    length_s: np.ndarray
    time_s: np.ndarray

    def __post_init__(self):
        if len(self.count) < 8:
            raise ValueError(f'Groups: count has {len(self.count)} groups: allowed >= 8')
        if np.any(np.asarray(self.count) <= 0):
            raise ValueError('Groups: count must be > 0 in every group')
        if np.any(np.diff(self.time_s) <= 0.0):
            raise ValueError('Groups: time_s must increase')

    def bands(self):
        """Return the white and walk parts of the difference covariance: (A, B), banded."""
        inv = 1.0 / np.asarray(self.count, float)
        L = np.asarray(self.length_s, float)
        gap = np.maximum(np.diff(self.time_s) - 0.5 * (L[1:] + L[:-1]), 0.0)
        a = np.zeros((2, len(inv) - 1))
        b = np.zeros((2, len(inv) - 1))
        a[1] = inv[1:] + inv[:-1]
        b[1] = (L[1:] + L[:-1]) / 3.0 + gap
        a[0, 1:] = -inv[1:-1]
        b[0, 1:] = L[1:-1] / 6.0
        return a, b


@dataclass(frozen=True)
class LevelFit:
    """The MLE of one model: log-likelihood, white variance per sample, walk, coefficients."""

    loglike: float
    white_var_rad2_s2: float
    rw_var_rad2_s3: float
    beta: np.ndarray
    capped: bool


def _gls(dy, dx, band):
    """
    GLS of the differences on a banded covariance: (log det, weighted RSS, beta).

    LAPACK's banded Cholesky (``pbtrf``) and solve (``pbtrs``) are called
    directly, as ``scipy.linalg.cholesky_banded`` and ``cho_solve_banded``
    call them, without their per-call checks: the likelihood is evaluated
    some 30 000 times in one diagnosis, and those checks were most of its
    time. A non-finite input or a matrix that is not positive definite
    gives an infinite log det, as before.
    """
    rhs = np.column_stack([dy, dx])
    if not (np.isfinite(band).all() and np.isfinite(rhs).all()):
        return np.inf, np.inf, None
    chol, info = _PBTRF(band, lower=0)
    if info != 0:
        return np.inf, np.inf, None
    logdet = 2.0 * float(np.sum(np.log(chol[1])))
    sol, info = _PBTRS(chol, rhs, lower=0)
    if info != 0:
        return np.inf, np.inf, None
    if dx.shape[1]:
        gram = dx.T @ sol[:, 1:]
        beta = np.linalg.lstsq(gram, dx.T @ sol[:, 0], rcond=1e-12)[0]
        rss = float(dy @ sol[:, 0] - beta @ (dx.T @ sol[:, 0]))
    else:
        beta, rss = np.zeros(0), float(dy @ sol[:, 0])
    return logdet, max(rss, 1e-300), beta


def _profile(dy, dx, a, b, white, walk):
    """Log-likelihood of the differences at (white, walk), beta by GLS: (llf, beta)."""
    logdet, rss, beta = _gls(dy, dx, white * a + walk * b)
    return -0.5 * (len(dy) * math.log(2.0 * math.pi) + logdet + rss), beta


def _concentrated(dy, dx, a, b, ratio):
    """Log-likelihood at walk = ratio x white, the white variance at its MLE: (llf, white)."""
    logdet, rss, _ = _gls(dy, dx, a + ratio * b)
    m = len(dy)
    if not np.isfinite(logdet):
        return -np.inf, np.nan
    s2 = rss / m
    return -0.5 * (m * math.log(2.0 * math.pi * s2) + logdet + m), s2


def fit_level(y, x, groups, rw_cap=math.inf):
    """
    Maximum-likelihood local level with regression on the group means.

    Parameters
    ----------
    y : numpy.ndarray
        Group means of the residual, rad/s.
    x : numpy.ndarray
        Regressors on the groups, (groups, p), any units (a constant column
        is absorbed by the level and may be left in or out).
    groups : Groups
        Samples, durations and times of the groups.
    rw_cap : float
        Largest random-walk variance K^2 allowed, rad^2/s^3.

    Returns
    -------
    LevelFit
        K^2 at most ``rw_cap`` (``capped`` when the bound binds).

    """
    a, b = groups.bands()
    dy = np.diff(np.asarray(y, float))
    dx = np.diff(np.asarray(x, float).reshape(len(y), -1), axis=0)
    keep = np.sqrt(np.sum(dx * dx, axis=0)) > 1e-12 * max(1.0, float(np.max(np.abs(dx)))) \
        if dx.size else np.zeros(0, bool)
    dx = dx[:, keep]
    norms = np.sqrt(np.sum(dx * dx, axis=0))
    dx = dx / norms
    scale = float(np.median(groups.length_s)) * float(np.median(groups.count))
    with warnings.catch_warnings(), np.errstate(all='ignore'):
        warnings.simplefilter('ignore')
        lo, hi = LOG_RATIO_RANGE

        def neg(u):
            return -_concentrated(dy, dx, a, b, 10.0 ** u / scale)[0]

        res = optimize.minimize_scalar(neg, bounds=(lo, hi), method='bounded',
                                       options={'xatol': 1e-3})
        ratio = 10.0 ** float(res.x) / scale
        if neg(lo - 30.0) <= res.fun:                       # the boundary K = 0
            ratio = 0.0
        llf, white = _concentrated(dy, dx, a, b, ratio)
        walk, capped = ratio * white, False
        if walk > rw_cap:
            capped = True

            def neg_white(v):
                return -_profile(dy, dx, a, b, 10.0 ** v, rw_cap)[0]

            c = math.log10(max(white, 1e-300))
            res = optimize.minimize_scalar(neg_white, bounds=(c - 3.0, c + 3.0),
                                           method='bounded', options={'xatol': 1e-4})
            white, walk = 10.0 ** float(res.x), rw_cap
        llf, beta = _profile(dy, dx, a, b, white, walk)
    full = np.zeros(len(keep))
    full[keep] = beta / norms if beta is not None else 0.0
    return LevelFit(float(llf), float(white), float(walk), full, capped)


def simulate_differences(fit, groups, n_sim, rng):
    """
    Differences of group means drawn from a fitted null: (groups - 1, n_sim).

    Exact: d = C' z with C the banded Cholesky factor of the difference
    covariance (upper form, so d_i = c_{i-1,i} z_{i-1} + c_{i,i} z_i);
    the regression part is left out (the likelihood ratio does not depend
    on it).
    """
    a, b = groups.bands()
    chol = linalg.cholesky_banded(fit.white_var_rad2_s2 * a + fit.rw_var_rad2_s3 * b,
                                  lower=False)
    z = rng.standard_normal((chol.shape[1], n_sim))
    d = chol[1][:, None] * z
    d[1:] += chol[0][1:, None] * z[:-1]
    return d


@dataclass(frozen=True)
class LrResult:
    """A likelihood-ratio test: statistic, p-values and the fits."""

    lr: float
    df: int
    p_asymptotic: float
    p_value: float
    bartlett: float
    bootstrapped: bool
    null: LevelFit
    alt: LevelFit
    n_differences: int = 0

    @property
    def gain_predictive(self):
        """
        RMS gain of the one-step-ahead prediction of the group means: 1 - exp(-LR / 2m).

        The product of a Gaussian model's prediction-error variances is the
        determinant of its covariance, so at the MLE the likelihood ratio is
        m ln(g_null / g_alt), g the geometric mean prediction-error variance
        over the m differences: a held-out (predictive) gain on the group means.
        """
        return 1.0 - math.exp(-self.lr / (2.0 * max(self.n_differences, 1)))


def _lr(y, x0, x1, groups, rw_cap, null=None):
    null = null or fit_level(y, x0, groups, rw_cap)
    alt = fit_level(y, np.column_stack([x0, x1]), groups, rw_cap)
    return max(2.0 * (alt.loglike - null.loglike), 0.0), null, alt


def lr_test(y, x0, x1, groups, rng, rw_cap=math.inf, decide_at=None, n_boot=N_BOOT,
            null_sims=None, null=None):
    """
    Likelihood ratio of the candidate columns ``x1`` given the nuisance columns ``x0``.

    Parameters
    ----------
    y : numpy.ndarray
        Group means of the measured output (or residual), rad/s.
    x0, x1 : numpy.ndarray
        Nuisance and candidate columns on the groups, (groups, p) and (groups, q).
    groups : Groups
        The groups.
    rng : numpy.random.Generator
        Source of the bootstrap draws.
    rw_cap : float
        Largest random-walk variance of both models, rad^2/s^3.
    decide_at : float, optional
        The p-value threshold the caller applies: the bootstrap runs only
        when a Bartlett factor in [C_LOW, C_HIGH] could move p across it
        (always when None).
    n_boot : int
        Bootstrap replicates.
    null_sims : tuple or callable, optional
        (simulated differences, their null fits), or a function returning
        them, to reuse across candidates with the same null
        (:func:`bootstrap_nulls`); built from ``rng`` when None and needed.
    null : LevelFit, optional
        The null's fit, when already known.

    Returns
    -------
    LrResult
        p = chi^2_q survival of LR / c, c = mean bootstrap LR / q (Bartlett
        correction; Bartlett 1937, estimated by simulation as in Rocke 1989).

    """
    x0 = np.asarray(x0, float).reshape(len(y), -1)
    x1 = np.asarray(x1, float).reshape(len(y), -1)
    lr, null, alt = _lr(y, x0, x1, groups, rw_cap, null)
    q = x1.shape[1]
    p_asym = float(stats.chi2.sf(lr, q))
    need = decide_at is None or (stats.chi2.sf(lr / C_HIGH, q) >= decide_at
                                 > stats.chi2.sf(lr / C_LOW, q))
    if not need or n_boot == 0:
        return LrResult(lr, q, p_asym, p_asym, 1.0, False, null, alt, len(y) - 1)
    if callable(null_sims):
        null_sims = null_sims()
    sims, fits = null_sims if null_sims is not None else bootstrap_nulls(
        null, x0, groups, rng, rw_cap, n_boot)
    boot = []
    for j in range(sims.shape[1]):
        ys = np.r_[0.0, np.cumsum(sims[:, j])]
        boot.append(_lr(ys, x0, x1, groups, rw_cap, fits[j])[0])
    c = max(float(np.mean(boot)) / q, 1e-3)
    return LrResult(lr, q, p_asym, float(stats.chi2.sf(lr / c, q)), c, True, null, alt,
                    len(y) - 1)


def bootstrap_nulls(null, x0, groups, rng, rw_cap=math.inf, n_boot=N_BOOT):
    """Draw null records (differences) and fit the null to each, for :func:`lr_test`."""
    sims = simulate_differences(null, groups, n_boot, rng)
    fits = [fit_level(np.r_[0.0, np.cumsum(sims[:, j])], x0, groups, rw_cap)
            for j in range(n_boot)]
    return sims, fits
