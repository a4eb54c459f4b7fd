#!/usr/bin/env python3
"""
Study: effects at datasheet size and at a third of it, hidden in real noise under new profiles.

The records are the real logs of ``../shared/data/real`` (ADIS16405 x/y/z as
10 Hz block means, MPU-6050 x/y/z at 100 Hz, the LSM6DSM chamber cooling)
driven through profiles this study draws itself, not the package's
injection profiles (:mod:`gyro_emulator.emulation.truth.injection` only adds
the effects): a random temperature staircase (levels in random order, ramps
of 0.5-3 K/min, holds of random length, the die lagging), a sinusoidal
chamber, tilts to random directions, a rate table of random steps with
chirps, and pairs of them. Each record is a random stretch, reversed and
sign-flipped at random. Effects (:data:`injection.DATASHEET`, the ADIS16405's
typical figures, at 1x or 1/3, random sign): bias tempco, SF tempco,
g-sensitivity (along a random direction), a delay, SF nonlinearity, an SF
step at a random time, and a bias that follows the die's dT/dt while the
logged temperature lags the die; raw records get none.

Prints, per effect and size: found (named, or a cause it cannot be told
from), supported in-sample only, and missed; for each miss, whether the
95 % bound the diagnosis states for that cause is above the truth (what it
rules out must not exclude what is there). Raw records: false causes with
one-sided 95 % bounds. The SF tempco against the paper's physics is always
named (the part's factory compensation): its line reads the part's own
tempco back and its 95 % interval. Per-record results go to ``--out``.

Usage: python bench/study_real_injections.py [--records N] [--raw N] [--seed S] [--out FILE]
"""

import argparse
import json
import os
import time

import benchenv  # one core: pins the BLAS thread pools before numpy loads

from gyro_emulator.analysis.diagnose import diagnose, to_json  # noqa: E402
from gyro_emulator.emulation.profiles import rate_about_z, SampledProfile  # noqa: E402
from gyro_emulator.emulation.truth import injection as inj  # noqa: E402
from gyro_emulator.recording.record import Record  # noqa: E402
from gyro_emulator.units import (deg_s_to_rad_s, rad_s_per_m_s2_to_deg_s_per_g,  # noqa: E402
                                 rad_s_to_deg_s, STANDARD_GRAVITY_M_S2)
import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402

REAL = benchenv.REAL
LOGS = {
    'adis': (os.path.join(REAL, 'adis16405_static', 'adis16405_run1_100hz.csv.gz'), 10,
             (1800.0, 10000.0)),
    'mpu': (os.path.join(REAL, 'mpu6050_static', 'mpu6050_static_100hz.csv'), 1,
            (240.0, 450.0)),
}
DS = inj.DATASHEET
#: Causes that name each effect.
NAMES = {
    'bias_tempco': {'bias_temperature', 'bias_hysteresis', 'temperature_rate_bias'},
    'g_sensitivity': {'g_sensitivity'},
    'delay': {'time_delay'},
    'sf_nonlinearity': {'scale_factor_nonlinearity'},
    'sf_step': {'scale_factor_step', 'scale_factor_time', 'pressure_drift'},
    'dtdt_bias': {'temperature_rate_bias', 'bias_temperature', 'bias_hysteresis'},
}
#: The bound (cause, quantity) that must hold the truth of a missed effect, and its unit factor.
BOUND_OF = {'bias_tempco': ('bias_temperature', 'bias tempco'),
            'g_sensitivity': ('g_sensitivity', 'g-sensitivity'),
            'delay': ('time_delay', 'delay'),
            'sf_nonlinearity': ('scale_factor_nonlinearity',
                                'SF nonlinearity at the largest rate'),
            'sf_step': ('scale_factor_step', 'SF step'),
            'dtdt_bias': ('temperature_rate_bias', 'bias per dT/dt')}
#: A gradient bias of the datasheet's order: 0.5 deg/s per K/min, rad/s per K/s.
DTDT_BIAS = float(deg_s_to_rad_s(0.5)) * 60.0
#: What each effect needs of the profile.
NEEDS = {'bias_tempco': 'temp', 'sf_tempco': 'temp+rate', 'g_sensitivity': 'tilt',
         'delay': 'rate', 'sf_nonlinearity': 'rate', 'sf_step': 'rate', 'dtdt_bias': 'temp'}
_LOGS = {}


def _noise(log, axis, rng):
    """Return (time_s, noise) of a random stretch of a log (reversed, flipped at random)."""
    key = (log, axis)
    if key not in _LOGS:
        path, factor, _ = LOGS[log]
        t, y, _ = inj.load_real(path, axis)
        _LOGS[key] = inj.block_means(t, y, factor)
    t, y = _LOGS[key]
    lo, hi = LOGS[log][2]
    return inj.stretch(t, y, float(rng.uniform(lo, min(hi, t[-1]))), rng)


def _lag(t, target, tau_s):
    return inj.first_order_lag(t, target, tau_s)


def staircase(t, rng):
    """
    Return a chamber staircase: 4-7 levels in -10..60 C in random order, the die lagging.

    Holds of random shares; ramps of 0.5-3 K/min against them, the whole
    program then stretched to the record.
    """
    span = float(t[-1] - t[0])
    levels = rng.permutation(np.linspace(rng.uniform(-10, 15), rng.uniform(40, 60),
                                         int(rng.integers(4, 8))))
    rate = rng.uniform(0.5, 3.0) / 60.0
    holds = rng.dirichlet(np.ones(len(levels))) * span
    kt, kc, now = [0.0], [levels[0]], 0.0
    for i, level in enumerate(levels):
        if i:
            now += abs(level - levels[i - 1]) / rate
            kt.append(now)
            kc.append(level)
        now += holds[i]
        kt.append(now)
        kc.append(level)
    kt = np.asarray(kt) * span / kt[-1]
    return _lag(t, np.interp(t - t[0], kt, kc), span / 50.0)


def sine_chamber(t, rng):
    """Return a sinusoidal chamber: 1-3 periods, 10-25 K about 20-35 C, the die lagging."""
    span = float(t[-1] - t[0])
    periods = rng.uniform(1.0, 3.0)
    temp = rng.uniform(20, 35) + rng.uniform(10, 25) * np.sin(
        2 * np.pi * periods * (t - t[0]) / span + rng.uniform(0, 2 * np.pi))
    return _lag(t, temp, span / 80.0)


def random_tilts(t, rng):
    """Gravity along 8-20 random directions held for random times, m/s^2 (n, 3)."""
    k = int(rng.integers(8, 21))
    u = rng.standard_normal((k, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    edges = np.sort(rng.uniform(t[0], t[-1], k - 1))
    return STANDARD_GRAVITY_M_S2 * u[np.searchsorted(edges, t)]


def rate_table(t, rng):
    """Knots of random rate steps (+-300 deg/s, 2-10 s dwells, 2000 deg/s^2) with chirps."""
    kt, kr, now = [float(t[0])], [0.0], float(t[0])
    rate = 0.0
    while now < t[-1]:
        new = 0.0 if rng.random() < 0.3 else float(rng.uniform(-300, 300))
        now += abs(new - rate) / 2000.0
        kt.append(now)
        kr.append(new)
        if rng.random() < 0.15:                  # a chirp about the level
            dwell = rng.uniform(4, 10)
            tc = np.arange(0.0, dwell, 0.02)
            kt += list(now + tc[1:])
            kr += list(new + 40.0 * np.sin(2 * np.pi * (0.3 * tc + 0.15 * tc * tc))[1:])
            now += dwell
        else:
            now += rng.uniform(2, 10)
            kt.append(now)
            kr.append(new)
        rate = kr[-1]
    return np.asarray(kt), deg_s_to_rad_s(np.asarray(kr))


def profile(parts, t, rng):
    """Return the study's own SampledProfile of ``parts`` (temp, tilt, rate) on ``t``."""
    n = len(t)
    temp = np.full(n, inj.REF_TEMP_C)
    if 'temp' in parts:
        temp = (staircase if rng.random() < 0.6 else sine_chamber)(t, rng)
    accel = random_tilts(t, rng) if 'tilt' in parts else np.tile(
        [0.0, 0.0, STANDARD_GRAVITY_M_S2], (n, 1))
    if 'rate' not in parts:
        return SampledProfile('+'.join(parts), t, np.zeros((n, 3)), temp, accel)
    kt, kr = rate_table(t, rng)
    return SampledProfile('+'.join(parts), t, rate_about_z(np.interp(t, kt, kr, 0.0, 0.0)), temp,
                          accel, rate_knots=(kt, rate_about_z(kr)))


def record(log, axis, effect, scale, rng):
    """Return (Record, truth) of one injected record."""
    t, y = _noise(log, axis, rng)
    parts = set(NEEDS.get(effect, 'static').split('+'))
    if effect is None:        # not temperature and rate together: that names the part's trim
        parts = [{'temp', 'tilt'}, {'rate', 'tilt'}, {'temp'}, {'rate'}, {'tilt'}][
            int(rng.integers(5))]
    elif rng.random() < 0.3:       # a second excitation beside (not the trim's pair)
        more = ['temp', 'tilt', 'rate'][int(rng.integers(3))]
        if not {'temp', 'rate'} <= parts | {more}:
            parts.add(more)
    if effect == 'sf_tempco':
        parts = {'temp', 'rate'}
    prof = profile(parts, t, rng)
    sign = 1.0 if rng.random() < 0.5 else -1.0
    truth = {'effect': effect, 'scale': scale, 'parts': sorted(parts), 'log': log, 'axis': axis}
    effects, extra = {}, np.zeros(len(t))
    if effect in ('bias_tempco', 'sf_tempco', 'sf_nonlinearity'):
        effects[effect] = sign * scale * DS[effect]
    elif effect == 'delay':
        effects['delay'] = scale * DS['delay']
    elif effect == 'g_sensitivity':
        u = rng.standard_normal(3)
        g = scale * DS['g_sensitivity'] * u / np.linalg.norm(u)
        extra = prof.accel_m_s2 @ g
        truth['size'] = float(rad_s_per_m_s2_to_deg_s_per_g(np.linalg.norm(g)))
    elif effect == 'sf_step':
        when = rng.uniform(t[0] + 0.2 * (t[-1] - t[0]), t[-1] - 0.2 * (t[-1] - t[0]))
        extra = sign * scale * DS['sf_step'] * inj.sensed_rate(prof) * (t >= when)
        truth['size'] = 1e6 * scale * DS['sf_step']
    elif effect == 'dtdt_bias':
        die = prof.temp_c
        extra = sign * scale * DTDT_BIAS * np.gradient(die, t)
        prof = SampledProfile(prof.name, t, prof.rate_rad_s, _lag(t, die, 400.0),
                              prof.accel_m_s2, rate_knots=prof.rate_knots)
        truth['size'] = scale * DTDT_BIAS * float(rad_s_to_deg_s(1.0)) / 60.0
    if effect in effects:
        top = float(np.max(np.abs(prof.rate_rad_s[:, 2])))
        truth['size'] = {'bias_tempco': float(rad_s_to_deg_s(scale * DS['bias_tempco'])),
                         'sf_tempco': 1e6 * sign * scale * DS['sf_tempco'],
                         # the cubic at the record's largest rate, in % of it
                         'sf_nonlinearity': 100 * scale * DS['sf_nonlinearity'] * (
                             top / inj.FULL_SCALE_RAD_S) ** 2,
                         'delay': 1e3 * scale * DS['delay']}[effect]
    rec = inj.inject(y, prof, effects, sf_error=float(rng.uniform(-5e-3, 5e-3)))
    return Record.from_arrays(t, rec.gyro['x'] + extra, rec.rate.values, prof.temp_c,
                              prof.accel_m_s2, path=f'{log} {axis} {effect}'), truth


def judge(doc, truth):
    """Return the row: found, in-sample only, the bound against the truth, the own SF tempco."""
    named = set()
    for entry in doc['selected']:
        named |= {entry['effect']} | set(entry['indistinguishable_from'])
    row = dict(truth, verdict=doc['verdict'], selected=[e['effect'] for e in doc['selected']],
               in_sample_only=[e['effect'] for e in doc['supported_in_sample']])
    effect = truth['effect']
    if effect is None:
        row['false_cause'] = bool(doc['selected'])
        return row
    if effect == 'sf_tempco':
        entry = next((e for e in doc['selected'] if e['effect'] == 'scale_factor_temperature'),
                     None)
        own = None if entry is None else entry.get('part_sf_temp_coeff_per_k')
        row['own_ppm_k'] = None if own is None else [1e6 * v for v in own['interval']]
        row['found'] = own is not None and own['interval'][0] <= 1e-6 * truth['size'] \
            <= own['interval'][1]
        return row
    row['found'] = bool(named & NAMES[effect])
    row['in_sample'] = bool(NAMES[effect] & set(row['in_sample_only']))
    cause, quantity = BOUND_OF[effect]
    bound = next((b['upper'] for b in doc['ruled_out']
                  if b['effect'] == cause and b['quantity'] == quantity), None)
    row['bound'] = bound
    row['bound_holds'] = None if bound is None else bound >= abs(truth['size'])
    return row


def summary(rows):
    """Print detections per effect and size, the bounds' coverage, the raw false causes."""
    print(f'{"effect":16s} {"size":>6s} {"found":>9s} {"in-sample only":>15s} '
          f'{"missed, bound above the truth":>30s}')
    for effect in NEEDS:
        for scale in (1.0, 1 / 3):
            at = [r for r in rows if r['effect'] == effect and abs(r['scale'] - scale) < 1e-9]
            if not at:
                continue
            found = sum(r['found'] for r in at)
            insample = sum(r.get('in_sample', False) for r in at)
            missed = [r for r in at if not r['found']]
            held = sum(bool(r.get('bound_holds')) for r in missed)
            print(f'{effect:16s} {"1" if scale == 1.0 else "1/3":>6s} {found:4d}/{len(at):<4d} '
                  f'{insample:15d} {held:25d}/{len(missed):<4d}')
    raw = [r for r in rows if r['effect'] is None]
    if raw:
        k = sum(r['false_cause'] for r in raw)
        up = stats.beta.ppf(0.95, k + 1, len(raw) - k) if k < len(raw) else 1.0
        verdicts = {}
        for r in raw:
            verdicts[r['verdict']] = verdicts.get(r['verdict'], 0) + 1
        print(f'raw records: {k} false causes in {len(raw)} (one-sided 95 % bound '
              f'{100 * up:.2f} %); verdicts {verdicts}; '
              f'{[r["selected"] for r in raw if r["false_cause"]]}')


def main():
    """Run the study and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--records', type=int, default=8, help='records per effect and size')
    ap.add_argument('--raw', type=int, default=60, help='raw records (no effect)')
    ap.add_argument('--seed', type=int, default=2033)
    ap.add_argument('--out', default='out/study_real_injections.jsonl')
    args = ap.parse_args()
    if not all(os.path.exists(p) for p, _, _ in LOGS.values()):
        print(f'the real logs are absent ({REAL})')
        return 1
    rng = np.random.default_rng(args.seed)
    jobs = [(e, s) for e in NEEDS for s in (1.0, 1 / 3) for _ in range(args.records)]
    jobs += [(None, 0.0)] * args.raw
    run_jobs(jobs, rng, record, judge, summary, args.out)
    return 0


def run_jobs(jobs, rng, make, score, report, out):
    """
    Diagnose one record per job, a log and an axis drawn at random, and print the figures.

    ``jobs``: (effect, scale) pairs; ``make(log, axis, effect, scale, rng)``
    gives (record, truth), ``score(document, truth)`` a row, written to
    ``out`` (JSON lines) as it comes; ``report(rows)`` prints the summary.
    """
    rows, start = [], time.perf_counter()
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    with open(out, 'w', encoding='utf-8') as handle:
        for effect, scale in jobs:
            log = 'adis' if rng.random() < 0.5 else 'mpu'
            axis = 'xyz'[int(rng.integers(3))]
            rec, truth = make(log, axis, effect, scale, rng)
            row = score(to_json(diagnose(rec)), truth)
            rows.append(row)
            handle.write(json.dumps(row, default=float) + '\n')
            handle.flush()
    report(rows)
    print(f'{len(rows)} records in {time.perf_counter() - start:.0f} s')


if __name__ == '__main__':
    raise SystemExit(main())
