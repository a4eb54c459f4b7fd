#!/usr/bin/env python3
"""
Study: diagnose's detection threshold against the likelihood test it must beat (issue 23).

Issue 23's anchor: the ADIS16405 noise (``../shared/data/real``, the whole
2.8 h log as 10 Hz block means) through two chamber cycles 15 <-> 55 C with
a bias tempco swept from 0 to 0.01 deg/s/K. The reference is statsmodels'
``UnobservedComponents(level='llevel', exog=T)`` on 20 s bin means against
the same model without ``exog``, its likelihood ratio referred to chi^2(1):
one pre-chosen test at alpha = 1 %. ``diagnose`` tests every cause the
record allows and holds its 1 % over all of them (and names the cause).

The noise varies over 12 versions of the log: three axes, each as recorded,
time-reversed, sign-flipped and both (a reversed or flipped stationary noise
is the same noise statistically, but the effect meets different wander).
Prints, per size, how many of the 12 each finds: ``diagnose`` when it names
``bias_temperature`` (or one it cannot be told from), the reference when
p < alpha, and the reference held to the same family-wise level as
``diagnose`` (p < alpha / m, m the causes ``diagnose`` could test on the
record: one test per cause, as a user who tried each would need).

Usage: python bench/study_anchor.py [--sizes 0,0.0005,...] [--alpha A]
"""

import argparse
import os
import warnings

import benchenv  # one core: pins the BLAS thread pools before numpy loads

from gyro_emulator.analysis.diagnose import diagnose, to_json  # noqa: E402
from gyro_emulator.emulation.truth import injection as inj  # noqa: E402
import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402
from statsmodels.tsa.statespace.structural import UnobservedComponents  # noqa: E402
from tqdm import tqdm  # noqa: E402

REAL = benchenv.REAL
ADIS = os.path.join(REAL, 'adis16405_static', 'adis16405_run1_100hz.csv.gz')
DEG = np.pi / 180.0
#: Names that count as finding a bias tempco.
FOUND = {'bias_temperature', 'bias_hysteresis', 'temperature_rate_bias'}
#: The reference's bin length, s (the issue's).
BIN_S = 20.0


def _bin_means(time_s, values):
    """Return the means of ``values`` over consecutive BIN_S bins."""
    k = ((time_s - time_s[0]) // BIN_S).astype(int)
    n = np.bincount(k)
    return np.bincount(k, values)[n > 0] / n[n > 0]


def reference_p(time_s, gyro_rad_s, temp_c):
    """Return the p of the local-level likelihood-ratio test for temperature as exog."""
    y = _bin_means(time_s, gyro_rad_s) / DEG
    x = _bin_means(time_s, temp_c)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')      # the optimiser's convergence chatter
        null = UnobservedComponents(y, level='llevel').fit(disp=False)
        alt = UnobservedComponents(y, level='llevel', exog=x).fit(disp=False)
    return float(stats.chi2.sf(max(2.0 * (alt.llf - null.llf), 0.0), 1))


def _versions():
    """Yield (label, time_s, noise rad/s) of the 12 versions of the log's noise."""
    for axis in 'xyz':
        t, y, _ = inj.load_real(ADIS, axis)
        t, y = inj.block_means(t, y, 10)
        for reverse in (False, True):
            for sign in (1.0, -1.0):
                yield (f'{axis}{"r" if reverse else ""}{"-" if sign < 0 else "+"}', t,
                       sign * (y[::-1] if reverse else y))


def main():
    """Run the sweep and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--sizes', default='0,0.0005,0.001,0.002,0.004',
                    help='bias tempcos, deg/s/K, comma-separated (default: %(default)s)')
    ap.add_argument('--alpha', type=float, default=0.01)
    args = ap.parse_args()
    sizes = [float(s) for s in args.sizes.split(',')]
    if not os.path.isfile(ADIS):
        print(f'{ADIS} is absent: the study needs ../shared/data/real')
        return 1
    versions = list(_versions())
    rows = []
    for size in sizes:
        found_d = found_r = found_fw = 0
        for label, t, noise in tqdm(versions, desc=f'{size:g} deg/s/K', unit='record'):
            inputs = inj.profile('cycles', t, np.random.default_rng(0))
            record = inj.inject(noise, inputs, {'bias_tempco': size * DEG} if size else {})
            doc = to_json(diagnose(record, alpha=args.alpha))
            named = set()
            for entry in doc['selected']:
                named |= {entry['effect']} | set(entry['indistinguishable_from'])
            found_d += bool(named & FOUND)
            effect = inj.effect_signal(inputs, 'bias_tempco', size * DEG) if size else 0.0
            p_ref = reference_p(t, noise + effect, inputs.temp_c)
            found_r += p_ref < args.alpha
            found_fw += p_ref < args.alpha / len(doc['residual']['causes_tested'])
        rows.append((size, found_d, found_r, found_fw))
    n = len(versions)
    print(f'\nADIS16405 noise, two chamber cycles 15 <-> 55 C, {n} versions of the log; '
          f'alpha {args.alpha:g}')
    print(f'{"tempco deg/s/K":>15s} {"diagnose":>9s} {"reference":>10s} '
          f'{"reference, alpha/m":>19s}')
    for size, found_d, found_r, found_fw in rows:
        print(f'{size:15g} {found_d:5d}/{n:<3d} {found_r:6d}/{n:<3d} {found_fw:15d}/{n:<3d}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
