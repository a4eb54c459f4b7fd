#!/usr/bin/env python3
"""
Study: diagnose's detection threshold against the likelihood test it must match, on every log.

A bias tempco is swept through two chamber cycles 15 <-> 55 C (the die
lagging by 1/60 of the record) on the noise of each real log
(``../shared/data/real``):

- ``adis-x``, ``adis-y``, ``adis-z``: one ADIS16405 axis, the whole 2.8 h log
  as 10 Hz block means; 12 versions: as recorded, time-reversed,
  sign-flipped and both, each with the cycles starting at 0, 1/3 and 2/3 of
  a cycle;
- ``mpu``: the MPU-6050 log (7.5 min at 100 Hz), its three axes, each in
  the four orientations (12 versions);
- ``adis-1hz``: the ADIS16405 log resampled to 1 Hz (100-sample block
  means, 10 000 samples), its three axes in the four orientations.

The reference (the anchor) is statsmodels' ``UnobservedComponents`` local
level with temperature as ``exog`` against the same model without it, on
bin means (20 s on the ADIS logs, 500 bins on the MPU-6050's 7.5 min), its
likelihood ratio referred to chi^2(1): one pre-chosen test of one cause.
``diagnose`` tests every cause the record allows and holds its level over
all of them, so the anchor is also held to the same family-wise level,
alpha / m with m the causes ``diagnose`` tested on the record (a user who
tried each cause with the anchor would need it). Prints, per log and size,
how many versions each finds (``diagnose`` when it names
``bias_temperature`` or a cause it cannot be told from), the 50 % detection
points (linear between the sizes) and diagnose's over the family-wise
anchor's. The per-record results go to ``--out`` as JSON lines.

Usage: python bench/study_anchor.py [--logs adis-y,mpu,...] [--sizes ...] [--alpha A]
                                    [--versions N] [--out FILE]
"""

import argparse
import json
import os
import time
import warnings

import benchenv  # one core: pins the BLAS thread pools before numpy loads

from gyro_emulator.analysis.diagnose import diagnose, to_json  # noqa: E402
from gyro_emulator.emulation.profiles import SampledProfile  # noqa: E402
from gyro_emulator.emulation.truth import injection as inj  # noqa: E402
import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402
from statsmodels.tsa.statespace.structural import UnobservedComponents  # noqa: E402

REAL = benchenv.REAL
ADIS = os.path.join(REAL, 'adis16405_static', 'adis16405_run1_100hz.csv.gz')
MPU = os.path.join(REAL, 'mpu6050_static', 'mpu6050_static_100hz.csv')
DEG = np.pi / 180.0
#: Names that count as finding a bias tempco.
FOUND = {'bias_temperature', 'bias_hysteresis', 'temperature_rate_bias'}
#: Per log: (path, axes, block-mean factor, anchor bin s (None: 500 bins), cycle phases).
LOGS = {
    'adis-x': (ADIS, 'x', 10, 20.0, (0.0, 1 / 3, 2 / 3)),
    'adis-y': (ADIS, 'y', 10, 20.0, (0.0, 1 / 3, 2 / 3)),
    'adis-z': (ADIS, 'z', 10, 20.0, (0.0, 1 / 3, 2 / 3)),
    'mpu': (MPU, 'xyz', 1, None, (0.0,)),
    'adis-1hz': (ADIS, 'xyz', 100, 20.0, (0.0,)),
}
#: Default tempcos per log, deg/s/K: the sizes of the table in docs/diagnose.md.
_ADIS_SIZES = '0.0005,0.001,0.0015,0.002,0.003'
SIZES = {'adis-x': _ADIS_SIZES, 'adis-y': _ADIS_SIZES, 'adis-z': _ADIS_SIZES,
         'mpu': '0.00005,0.0001,0.00015,0.0002,0.0003', 'adis-1hz': _ADIS_SIZES}


def _bin_means(time_s, values, bin_s):
    """Return the means of ``values`` over consecutive bins of ``bin_s``."""
    k = ((time_s - time_s[0]) // bin_s).astype(int)
    n = np.bincount(k)
    return np.bincount(k, values)[n > 0] / n[n > 0]


def reference_p(time_s, gyro_rad_s, temp_c, bin_s):
    """Return the p of the local-level likelihood-ratio test for temperature as exog."""
    y = _bin_means(time_s, gyro_rad_s, bin_s) / DEG
    x = _bin_means(time_s, temp_c, bin_s)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')      # the optimiser's convergence chatter
        null = UnobservedComponents(y, level='llevel').fit(disp=False)
        alt = UnobservedComponents(y, level='llevel', exog=x).fit(disp=False)
    return float(stats.chi2.sf(max(2.0 * (alt.llf - null.llf), 0.0), 1))


def versions(log):
    """Yield (label, time_s, noise rad/s, cycle phase) of the versions of a log's noise."""
    path, axes, factor, _, phases = LOGS[log]
    for axis in axes:
        t, y, _ = inj.load_real(path, axis)
        t, y = inj.block_means(t, y, factor)
        for phase in phases:
            for reverse in (False, True):
                for sign in (1.0, -1.0):
                    yield (f'{axis}{"r" if reverse else ""}{"-" if sign < 0 else "+"}'
                           f'@{phase:.2f}', t, sign * (y[::-1] if reverse else y), phase)


def spread(items, count):
    """Return ``count`` of ``items`` evenly spread through the list (all: None)."""
    if count is None or count >= len(items):
        return items
    return [items[int(i * len(items) / count)] for i in range(count)]


def cycles_profile(time_s, phase):
    """Two chamber cycles 15 <-> 55 C starting ``phase`` into a cycle, the part at rest."""
    n = len(time_s)
    return SampledProfile('cycles', time_s, np.zeros((n, 3)),
                          inj.temperature_cycles(time_s, phase=phase),
                          np.tile([0.0, 0.0, 9.80665], (n, 1)))


def run_one(log, label, t, noise, phase, size, alpha):
    """Diagnose one record and run the anchor on it; return the row."""
    prof = cycles_profile(t, phase)
    record = inj.inject(noise, prof, {'bias_tempco': size * DEG} if size else {})
    doc = to_json(diagnose(record, alpha=alpha))
    named = set()
    for entry in doc['selected']:
        named |= {entry['effect']} | set(entry['indistinguishable_from'])
    bin_s = LOGS[log][3] or (t[-1] - t[0]) / 500.0
    effect = inj.effect_signal(prof, 'bias_tempco', size * DEG) if size else 0.0
    p_ref = reference_p(t, noise + effect, prof.temp_c, bin_s)
    m = len(doc['residual']['causes_tested'])
    return {'log': log, 'version': label, 'size_deg_s_k': size, 'diagnose': bool(named & FOUND),
            'selected': [e['effect'] for e in doc['selected']], 'verdict': doc['verdict'],
            'in_sample_only': [e['effect'] for e in doc['supported_in_sample']],
            'p_anchor': p_ref, 'm': m, 'anchor': p_ref < alpha,
            'anchor_fw': p_ref < alpha / m}


def fifty(sizes, found):
    """Return the size where the found share crosses 0.5 (linear between sizes), or None."""
    for i in range(1, len(sizes)):
        if found[i] >= 0.5 > found[i - 1]:
            return sizes[i - 1] + (0.5 - found[i - 1]) / (found[i] - found[i - 1]) * (
                sizes[i] - sizes[i - 1])
    return sizes[0] if found and found[0] >= 0.5 else None


def _shares(rows, sizes, key):
    """Return the found share of ``key`` at each size."""
    out = []
    for size in sizes:
        at = [r[key] for r in rows if r['size_deg_s_k'] == size]
        out.append(sum(at) / len(at) if at else 0.0)
    return out


def ratio_interval(rows, sizes, draws=2000, seed=0):
    """
    Return the 95 % bootstrap interval of diagnose's 50 % point over the anchor's.

    The versions are resampled with replacement (a version keeps all its
    sizes); a draw where either 50 % point is not reached is counted as
    unbounded above (diagnose's) or dropped (the anchor's).
    """
    rng = np.random.default_rng(seed)
    labels = sorted({r['version'] for r in rows})
    by = {v: [r for r in rows if r['version'] == v] for v in labels}
    ratios = []
    for _ in range(draws):
        pick = rng.choice(len(labels), len(labels))
        sample = [r for i in pick for r in by[labels[i]]]
        d50 = fifty(sizes, _shares(sample, sizes, 'diagnose'))
        a50 = fifty(sizes, _shares(sample, sizes, 'anchor_fw'))
        if a50:
            ratios.append(np.inf if d50 is None else d50 / a50)
    if not ratios:
        return None
    return tuple(float(q) for q in np.percentile(ratios, [2.5, 97.5]))


def table(log, rows):
    """Print the table of one log; return (diagnose's, the family-wise anchor's) 50 % points."""
    sizes = sorted({r['size_deg_s_k'] for r in rows})
    share = {k: [] for k in ('diagnose', 'anchor', 'anchor_fw')}
    print(f'\n{log}: {len({r["version"] for r in rows})} versions; tempco deg/s/K, found')
    print(f'{"tempco":>9s} {"diagnose":>9s} {"anchor":>8s} {"anchor alpha/m":>15s}')
    for size in sizes:
        at = [r for r in rows if r['size_deg_s_k'] == size]
        counts = {k: sum(r[k] for r in at) for k in share}
        for k in share:
            share[k].append(counts[k] / len(at))
        print(f'{size:9g} {counts["diagnose"]:5d}/{len(at):<3d} '
              f'{counts["anchor"]:4d}/{len(at):<3d}'
              f' {counts["anchor_fw"]:11d}/{len(at):<3d}')
    d50, a50 = fifty(sizes, share['diagnose']), fifty(sizes, share['anchor_fw'])
    ratio = 'n/a' if d50 is None or not a50 else f'{d50 / a50:.2f}'
    ci = ratio_interval(rows, sizes)
    ci_text = 'n/a' if ci is None else f'[{ci[0]:.2f}, {ci[1]:.2f}]'
    print(f'50 % points: diagnose {d50}, anchor alpha/m {a50}, anchor alpha '
          f'{fifty(sizes, share["anchor"])}; diagnose / anchor alpha/m = {ratio} '
          f'(95 % bootstrap over the versions {ci_text})')
    return d50, a50


def main():
    """Run the sweep and print the tables."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--logs', default=','.join(LOGS), help='logs (default: %(default)s)')
    ap.add_argument('--sizes', default=None,
                    help='bias tempcos, deg/s/K, comma-separated (default: per log)')
    ap.add_argument('--alpha', type=float, default=0.01)
    ap.add_argument('--versions', type=int, default=None,
                    help='at most N versions per log, spread through the list (fewer draws: '
                         'the bootstrap interval of the ratio says what that costs)')
    ap.add_argument('--out', default='out/study_anchor.jsonl')
    args = ap.parse_args()
    if not os.path.isfile(ADIS) or not os.path.isfile(MPU):
        print(f'the real logs are absent ({REAL}): the study needs ../shared/data/real')
        return 1
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    start = time.perf_counter()
    points = {}
    with open(args.out, 'w', encoding='utf-8') as handle:
        for log in args.logs.split(','):
            sizes = [float(s) for s in (args.sizes or SIZES[log]).split(',')]
            chosen = spread(list(versions(log)), args.versions)
            rows = []
            for label, t, noise, phase in chosen:
                for size in sizes:
                    row = run_one(log, label, t, noise, phase, size, args.alpha)
                    handle.write(json.dumps(row) + '\n')
                    handle.flush()
                    rows.append(row)
            points[log] = table(log, rows)
    print(f'\n{time.perf_counter() - start:.0f} s in all')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
