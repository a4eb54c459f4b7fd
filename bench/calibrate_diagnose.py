#!/usr/bin/env python3
"""
Study: how often diagnose names a cause in records that have none.

Runs ``diagnose`` on seeded simulated records with no hidden effect (truth
generator), four noise colours in turn (white; bias instability 10-40
deg/h; rate random walk 10-40 deg/h/sqrt(h); drawn), on three profiles: a
one-way thermal ramp at 0.2 Hz (where slow wander best passes for a
temperature drift), a static run at 2 Hz and a lab run at 1 Hz. Prints, per
profile and in all, the false causes, a one-sided 99 % Clopper-Pearson
upper bound on their rate against the nominal alpha, how often the
Bonferroni-adjusted smallest p-value of the first step falls below 0.05,
0.1 and 0.2, and the verdicts.

With ``--real N``, also N records per real log (``../shared/data/real``:
MPU-6050 3 axes, 120 s stretches at 100 Hz; ADIS16405 3 axes, 1800 s
stretches of 10 Hz block means), each a resampled stretch (random start,
random time reversal and sign flip) of the raw log through a profile drawn
from static, rate steps, tilt steps, temperature cycles and a ramp, with no
effect injected (:mod:`gyro_emulator.emulation.truth.injection`). Stretches
overlap: the count of independent ones (log length / record length, per
axis) is printed beside the rate.

With ``--disjoint SECONDS``, every real log (raw, 100 Hz) is cut into
consecutive stretches of SECONDS that share no sample, per axis, and each
stretch is diagnosed once through the next profile of the list (random
draws seeded per stretch). These records are independent in their noise (up
to what the three axes of one part share), so their count is the honest n
of the printed bound: with no false cause, a 95 % bound below 1 % needs
n >= 299. With ``--reference`` as well, each stretch is diagnosed a second
time with the noise of a reference held fixed (``diagnose --reference``):
the half of the same axis's log that does not hold the stretch, for logs at
least 20 times the stretch (the ADIS16405's).

Usage: python bench/calibrate_diagnose.py [--ramps N] [--static N] [--lab N] [--real N]
                                          [--disjoint SECONDS [--reference]]
"""

import argparse
import os
import time

import benchenv  # one core: pins the BLAS thread pools before numpy loads

from gyro_emulator.analysis.diagnose import diagnose, to_json  # noqa: E402
from gyro_emulator.analysis.diagnose.data import MeasuredData  # noqa: E402
from gyro_emulator.emulation.truth import injection as inj  # noqa: E402
from gyro_emulator.emulation.truth.generator import make_truth  # noqa: E402
import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402
from tqdm import tqdm  # noqa: E402

REAL = benchenv.REAL
#: Real logs of the --real study: (path, block-mean factor, record length s).
REAL_LOGS = {
    'mpu6050': (os.path.join(REAL, 'mpu6050_static', 'mpu6050_static_100hz.csv'), 1, 120.0),
    'adis16405': (os.path.join(REAL, 'adis16405_static', 'adis16405_run1_100hz.csv.gz'), 10,
                  1800.0),
}
REAL_PROFILES = ('static', 'rate_steps', 'tilt', 'cycles', 'ramp')
PROFILES = {'thermal_ramp': (0.2, {}), 'static': (2.0, {}), 'lab': (1.0, {'levels': 3})}


def _noise(seed):
    """Noise colour of a seed: white, flicker, random walk, or drawn."""
    rng = np.random.default_rng(1000 + seed)
    return [{'bias_instability_deg_h': 1.0, 'rrw_deg_h_sqrt_h': 0.5},
            {'bias_instability_deg_h': float(rng.uniform(10, 40)), 'rrw_deg_h_sqrt_h': 1.0},
            {'bias_instability_deg_h': 2.0, 'rrw_deg_h_sqrt_h': float(rng.uniform(10, 40))},
            {}][seed % 4]


def _run(profile, count, alpha):
    """Diagnose ``count`` records of a profile; return false causes, adjusted p, verdicts."""
    rate, extra = PROFILES[profile]
    false, pmins, verdicts = [], [], {}
    for seed in tqdm(range(count), desc=profile, unit='record'):
        record, _ = make_truth('none', seed, profile=profile, sample_rate_hz=rate,
                               noise=_noise(seed), **extra)
        doc = to_json(diagnose(record, alpha=alpha))
        if doc['best']['effect'] != 'none':
            false.append((seed, doc['best']['effect']))
        step1 = doc['steps'][0]['candidates']
        pmins.append(min(1.0, min(c['p_value'] for c in step1) * len(step1)))
        verdicts[doc['verdict']] = verdicts.get(doc['verdict'], 0) + 1
    return false, np.asarray(pmins), verdicts


def _line(name, false, n, pmins, alpha):
    k = len(false)
    up95, up99 = ((stats.beta.ppf(q, k + 1, n - k) if k < n else 1.0) for q in (0.95, 0.99))
    fractions = ', '.join(f'{np.mean(pmins < a):.3f} below {a:g}' for a in (0.05, 0.1, 0.2))
    print(f'{name:13s} {k:3d} false causes in {n:4d} records '
          f'({100 * k / n:.2f} %; one-sided upper bound 95 % {100 * up95:.2f} %, 99 % '
          f'{100 * up99:.2f} %, nominal {100 * alpha:g} %); adjusted p: {fractions}')


def _run_real(count, alpha):
    """Diagnose ``count`` raw stretches per real log; print false causes and independent count."""
    false, n, independent = [], 0, 0
    for name, (path, factor, seconds) in REAL_LOGS.items():
        logs = {}
        for axis in 'xyz':
            t, y, _ = inj.load_real(path, axis)
            logs[axis] = inj.block_means(t, y, factor)
            independent += int(logs[axis][0][-1] // seconds)
        rng = np.random.default_rng(len(name))
        for k in tqdm(range(count), desc=name, unit='record'):
            axis, prof = 'xyz'[k % 3], REAL_PROFILES[k % len(REAL_PROFILES)]
            tt, noise = inj.stretch(*logs[axis], seconds, rng)
            record = inj.inject(noise, inj.profile(prof, tt, rng), {},
                                sf_error=float(rng.uniform(-5e-3, 5e-3)))
            doc = to_json(diagnose(record, alpha=alpha))
            n += 1
            if doc['best']['effect'] != 'none':
                false.append((name, axis, prof, doc['best']['effect']))
    k = len(false)
    up95, up99 = ((stats.beta.ppf(q, k + 1, n - k) if k < n else 1.0) for q in (0.95, 0.99))
    print(f'real logs     {k:3d} false causes in {n:4d} records '
          f'({100 * k / max(n, 1):.2f} %; one-sided upper bound 95 % {100 * up95:.2f} %, 99 % '
          f'{100 * up99:.2f} %, nominal {100 * alpha:g} %); the records overlap: the logs '
          f'hold {independent} independent stretches of the record lengths; false causes '
          f'{false}')


def _disjoint_stretches(time_s, values, seconds):
    """Yield (time_s from 0, values) of the consecutive stretches of ``seconds`` of a log."""
    whole = int((time_s[-1] - time_s[0]) // seconds)
    edges = np.searchsorted(time_s, time_s[0] + seconds * np.arange(whole + 1))
    for start, stop in zip(edges[:-1], edges[1:]):
        yield time_s[start:stop] - time_s[start], np.asarray(values[start:stop], dtype=float)


def _reference_of(t, y, start_s, seconds):
    """Return the half of a log that does not hold the stretch at ``start_s`` (static)."""
    half = len(t) // 2
    first = start_s >= t[half]
    sl = slice(0, half) if first else slice(half, len(t))
    return MeasuredData(time_s=t[sl] - t[sl][0], rate_cmd_rad_s=np.zeros(len(t[sl])),
                        temp_c=None, gyro_rad_s=np.asarray(y[sl], dtype=float),
                        source='first half' if first else 'second half')


def _run_disjoint(seconds, alpha, with_reference=False):
    """Diagnose every disjoint stretch of ``seconds`` of the raw real logs once."""
    false, n, verdicts = [], 0, {}
    ref_false, ref_n, ref_verdicts = [], 0, {}
    for name, (path, _, _) in REAL_LOGS.items():
        for axis in 'xyz':
            t, y, _ = inj.load_real(path, axis)
            parts = list(_disjoint_stretches(t, y, seconds))
            long_log = t[-1] - t[0] >= 20.0 * seconds
            for k, (tt, noise) in enumerate(tqdm(parts, desc=f'{name} {axis}', unit='record')):
                rng = np.random.default_rng([len(name), ord(axis), k])
                prof = REAL_PROFILES[(n + k) % len(REAL_PROFILES)]
                record = inj.inject(noise, inj.profile(prof, tt, rng), {},
                                    sf_error=float(rng.uniform(-5e-3, 5e-3)))
                doc = to_json(diagnose(record, alpha=alpha))
                verdicts[doc['verdict']] = verdicts.get(doc['verdict'], 0) + 1
                if doc['best']['effect'] != 'none':
                    false.append((name, axis, k, prof, doc['best']['effect']))
                if with_reference and long_log:
                    ref = _reference_of(t, y, t[0] + k * seconds, seconds)
                    doc = to_json(diagnose(record, alpha=alpha, reference=ref))
                    ref_verdicts[doc['verdict']] = ref_verdicts.get(doc['verdict'], 0) + 1
                    ref_n += 1
                    if doc['best']['effect'] != 'none':
                        ref_false.append((name, axis, k, prof, doc['best']['effect']))
            n += len(parts)
    _disjoint_line('disjoint', false, n, seconds, alpha, verdicts)
    if with_reference:
        _disjoint_line('  --reference', ref_false, ref_n, seconds, alpha, ref_verdicts)


def _disjoint_line(label, false, n, seconds, alpha, verdicts):
    upper95, upper99 = (stats.beta.ppf(q, len(false) + 1, n - len(false)) for q in (0.95, 0.99))
    print(f'{label:13s} {len(false):3d} false causes in {n:4d} independent {seconds:g} s '
          f'stretches ({100 * len(false) / max(n, 1):.2f} %; one-sided upper bound 95 % '
          f'{100 * upper95:.2f} %, 99 % {100 * upper99:.2f} %, nominal {100 * alpha:g} %); '
          f'verdicts {verdicts}; false causes {false}')


def main():
    """Run the study and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--ramps', type=int, default=100)
    ap.add_argument('--static', type=int, default=60)
    ap.add_argument('--lab', type=int, default=60)
    ap.add_argument('--real', type=int, default=0, metavar='N',
                    help='records per real log (../shared/data/real), 0 to skip')
    ap.add_argument('--disjoint', type=float, default=0.0, metavar='SECONDS',
                    help='diagnose every disjoint stretch of SECONDS of the raw real logs, '
                    '0 to skip')
    ap.add_argument('--reference', action='store_true',
                    help='with --disjoint: diagnose each stretch again with the other half '
                    'of its log as the reference (diagnose --reference)')
    ap.add_argument('--alpha', type=float, default=0.01)
    args = ap.parse_args()
    start = time.perf_counter()
    if args.disjoint > 0:
        if not os.path.isdir(REAL):
            print(f'--disjoint: {REAL} is absent, skipped')
        else:
            _run_disjoint(args.disjoint, args.alpha, args.reference)
    if args.real > 0:
        if not os.path.isdir(REAL):
            print(f'--real: {REAL} is absent, skipped')
        else:
            _run_real(args.real, args.alpha)
    total_false, total_p = [], []
    for profile, count in (('thermal_ramp', args.ramps), ('static', args.static),
                           ('lab', args.lab)):
        if count <= 0:
            continue
        false, pmins, verdicts = _run(profile, count, args.alpha)
        _line(profile, false, count, pmins, args.alpha)
        print(f'{"":13s} verdicts {verdicts}; false causes {false}')
        total_false += false
        total_p += list(pmins)
    if total_p:
        _line('all', total_false, len(total_p), np.asarray(total_p), args.alpha)
    print(f'{time.perf_counter() - start:.0f} s')


if __name__ == '__main__':
    main()
