#!/usr/bin/env python3
"""
Study: which null would find a one-way staircase of soaks in real noise (issue 23).

The ADIS16405 y axis (``../shared/data/real``, the whole 2.8 h log as 10 Hz
block means) through the ``soaks`` profile (15 -> 55 C in five soaks) with
a bias tempco at a third of the datasheet figure: ``diagnose`` does not find
it (the strict xfail of ``test/test_diagnose_real_noise.py``). This study
takes the group means, the current model's columns and the candidate's
columns of ``diagnose``'s likelihood test (:mod:`.statespace`) for
``bias_temperature`` and compares nulls of the group means:

- white noise + random walk (what ``diagnose`` does), as reported;
- white + flicker (one Gauss-Markov term per decade, the same terms as the
  noise simulations) + random walk, the likelihood ratio Bartlett-corrected
  by a parametric bootstrap under the null's MLE and under the
  alternative's;
- the same, the null evaluated at the alternative's noise MLE (the noise
  measured on the candidate's own residual);
- the same, the noise known: fitted to the same stretch without the effect.

The flicker model has a dense covariance of the group differences (one
Cholesky factor per likelihood), which is why it is a study and not the
test. Prints LR, bootstrap factor and p for each.

Usage: python bench/study_null_soaks.py [--boot N] [--seed S] [--axis A] [--profile P] [--scale F]
"""

import argparse
import math
import os

import benchenv  # one core: pins the BLAS thread pools before numpy loads

from gyro_emulator.analysis.diagnose import diagnose, selection, to_json  # noqa: E402
from gyro_emulator.emulation.truth import injection as inj  # noqa: E402
from gyro_emulator.sensor import noise as sensor_noise  # noqa: E402
import numpy as np  # noqa: E402
from scipy import linalg, optimize, stats  # noqa: E402

REAL = benchenv.REAL
LOG = os.path.join(REAL, 'adis16405_static', 'adis16405_run1_100hz.csv.gz')
DEG = math.pi / 180.0


def _record(effects, seed, axis='y', profile='soaks'):
    """Return the test's record: the whole ADIS16405 log as 10 Hz block means, soaks."""
    rng = np.random.default_rng(seed)
    t, y, _ = inj.load_real(LOG, axis)
    t, y = inj.block_means(t, y, 10)
    return inj.inject(y, inj.profile(profile, t, rng), effects,
                      sf_error=float(rng.uniform(-5e-3, 5e-3)))


def _capture(record, effect_id='bias_temperature'):
    """Run diagnose; return its doc and the likelihood test's inputs for ``effect_id``."""
    seen = {}
    original = selection.Selector.state_space_test

    def hook(self, current, effect, m):
        res = original(self, current, effect, m)
        if effect.effect_id == effect_id and 'y' not in seen and res is not None:
            st = self._state_space_null(current)
            seen.update(y=st['y'], x0=st['x0'], groups=st['groups'],
                        x1=self._linear_columns(current, effect), lr=res)
        return res

    selection.Selector.state_space_test = hook
    try:
        doc = to_json(diagnose(record))
    finally:
        selection.Selector.state_space_test = original
    return doc, seen


def _dense(band):
    m = band.shape[1]
    out = np.diag(band[1])
    i = np.arange(m - 1)
    out[i, i + 1] = out[i + 1, i] = band[0, 1:]
    return out


class FlickerNull:
    """White + flicker + random walk on group means: covariance of the differences."""

    def __init__(self, groups):
        a, b = groups.bands()
        t, length = np.asarray(groups.time_s), np.asarray(groups.length_s)
        taus = sensor_noise.flicker_corr_times_s((float(np.median(np.diff(t))),
                                                  10.0 * float(t[-1] - t[0])))
        cov = np.zeros((len(t), len(t)))
        for tau, q in zip(taus, sensor_noise.flicker_unit_variance(taus)):
            s = np.sinh(length / (2 * tau)) / (length / (2 * tau))   # window averages
            c = q * np.exp(-np.abs(t[:, None] - t[None, :]) / tau) * np.outer(s, s)
            u = length / tau
            c[np.diag_indices(len(t))] = q * 2.0 / u ** 2 * (u - 1.0 + np.exp(-u))
            cov += c
        flick = cov[1:, 1:] - cov[1:, :-1] - cov[:-1, 1:] + cov[:-1, :-1]
        self.parts = [_dense(a), flick, _dense(b)]
        self.scale = [float(np.median(np.diag(p))) for p in self.parts]

    def _solve(self, y, x, cov):
        """Return (log det, GLS weighted RSS) of the differences under ``cov``."""
        dy, dx = np.diff(y), np.diff(x, axis=0)
        dx = dx[:, np.sqrt(np.sum(dx * dx, axis=0)) > 0.0]
        chol = linalg.cho_factor(cov, lower=True, check_finite=False)
        sol = linalg.cho_solve(chol, np.column_stack([dy, dx]), check_finite=False)
        rss = float(dy @ sol[:, 0])
        if dx.shape[1]:
            beta = np.linalg.lstsq(dx.T @ sol[:, 1:], dx.T @ sol[:, 0], rcond=1e-12)[0]
            rss -= float(beta @ (dx.T @ sol[:, 0]))
        return 2.0 * float(np.sum(np.log(np.diag(chol[0])))), rss

    def loglike(self, y, x, variances):
        """Gaussian log-likelihood of the differences at (white, flicker, walk), beta by GLS."""
        logdet, rss = self._solve(y, x, sum(v * p for v, p in zip(variances, self.parts)))
        return -0.5 * ((len(y) - 1) * math.log(2.0 * math.pi) + logdet + rss)

    def fit(self, y, x):
        """MLE of the three variances (white per sample, B^2, K^2): (loglike, variances)."""
        m = len(y) - 1

        def ratios(u):
            return [1.0] + [10.0 ** float(np.clip(w, -9.0, 4.0)) * self.scale[0] / s
                            for w, s in zip(u, self.scale[1:])]

        def neg(u):                     # the white variance concentrated out
            try:
                logdet, rss = self._solve(y, x, sum(
                    r * p for r, p in zip(ratios(u), self.parts)))
            except linalg.LinAlgError:
                return np.inf
            return 0.5 * (m * math.log(2.0 * math.pi * rss / m) + logdet + m)

        starts = [(-2.0, -3.0), (0.0, -3.0), (-2.0, -1.0), (0.0, -1.0), (-4.0, -5.0)]
        u0 = min(starts, key=lambda u: neg(np.asarray(u)))
        u = optimize.minimize(neg, u0, method='Nelder-Mead',
                              options={'xatol': 1e-3, 'fatol': 1e-4}).x
        r = ratios(u)
        _, rss = self._solve(y, x, sum(ri * p for ri, p in zip(r, self.parts)))
        return -neg(u), [rss / m * ri for ri in r]

    def draw(self, variances, rng):
        """Draw a record of group means (level 0) from the null with ``variances``."""
        cov = sum(v * p for v, p in zip(variances, self.parts))
        return np.r_[0.0, np.cumsum(np.linalg.cholesky(cov) @ rng.standard_normal(len(cov)))]


def _k_deg(variances):
    return math.sqrt(variances[2]) / DEG


def _flicker_rows(null, st, st0, n_boot, rng):
    """LR, bootstrap factors and p of the flicker nulls; print them."""
    y, x0 = st['y'], st['x0']
    x1 = np.column_stack([x0, st['x1']])
    q = st['x1'].shape[1]
    fit0, fit1 = null.fit(y, x0), null.fit(y, x1)
    lr = 2.0 * (fit1[0] - fit0[0])
    own = 2.0 * (fit1[0] - null.loglike(y, x0, fit1[1]))
    print(f'flicker + walk: K null {_k_deg(fit0[1]):.5f}, alternative {_k_deg(fit1[1]):.5f} '
          f'deg/s/sqrt(s)')
    for label, source in (('null MLE', fit0[1]), ("alternative's MLE", fit1[1])):
        boot, boot_own = [], []
        for _ in range(n_boot):
            ys = null.draw(source, rng)
            b0, b1 = null.fit(ys, x0), null.fit(ys, x1)
            boot.append(2.0 * (b1[0] - b0[0]))
            boot_own.append(2.0 * (b1[0] - null.loglike(ys, x0, b1[1])))
        rows = (('LR', lr, boot), ("LR, noise of the candidate's residual", own, boot_own))
        for name, value, sample in rows:
            c = float(np.mean(sample)) / q
            print(f'  {name:38s} {value:6.2f}  factor {c:4.2f} ({n_boot} draws, {label})  '
                  f'p {stats.chi2.sf(value / c, q):.3g}')
    known = null.fit(st0['y'], st0['x0'])[1]
    lr_known = 2.0 * (null.loglike(y, x1, known) - null.loglike(y, x0, known))
    print(f'  {"LR, noise known (stretch without effect)":38s} {lr_known:6.2f}  '
          f'p {stats.chi2.sf(lr_known, q):.3g}')


def main():
    """Run the study and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--boot', type=int, default=32, help='bootstrap draws per null')
    ap.add_argument('--seed', type=int, default=112, help='seed of the record (the test: 112)')
    ap.add_argument('--axis', default='y', choices=('x', 'y', 'z'))
    ap.add_argument('--profile', default='soaks', help='temperature profile (the test: soaks)')
    ap.add_argument('--scale', type=float, default=1 / 3,
                    help='tempco as a share of the datasheet figure (the test: 1/3)')
    args = ap.parse_args()
    if not os.path.exists(LOG):
        print(f'{LOG} is absent: nothing to study')
        return
    where = (args.seed, args.axis, args.profile)
    doc, st = _capture(_record({'bias_tempco': inj.DATASHEET['bias_tempco'] * args.scale},
                               *where))
    _, st0 = _capture(_record({}, *where))
    res = st['lr']
    print(f'diagnose: verdict {doc["verdict"]}; white + walk (K capped): LR {res.lr:.2f}, '
          f'K null {_k_deg([0, 0, res.null.rw_var_rad2_s3]):.5f}, alternative '
          f'{_k_deg([0, 0, res.alt.rw_var_rad2_s3]):.5f} deg/s/sqrt(s), factor '
          f'{res.bartlett:.2f}, p_LR {res.p_value:.3g}')
    _flicker_rows(FlickerNull(st['groups']), st, st0, args.boot, np.random.default_rng(0))


if __name__ == '__main__':
    main()
