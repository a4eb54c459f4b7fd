#!/usr/bin/env python3
"""
Study: how often diagnose's 95 % coefficient intervals and upper bounds hold the truth.

Records: a random stretch of a real log (ADIS16405 x/y/z as 10 Hz block
means, MPU-6050 x/y/z at 100 Hz, as in ``study_real_injections.py``) or,
with ``--synthetic``, white Gaussian noise of the same log's per-sample
spread, driven through this study's profiles (a temperature staircase, a
sinusoidal chamber or a one-way ramp; random rate steps with chirps;
tilts to random directions) with one effect planted at datasheet size or a
third of it, random sign (:data:`injection.DATASHEET`; a bias step of
0.05 deg/s at a random time in the middle 60 %). Effects:

- ``bias_tempco``: the interval of ``bias_temp_coeff_rad_s_k`` when
  ``bias_temperature`` is chosen, else its ``bias tempco`` bound;
- ``bias_step``: ``bias_step_rad_s`` of ``bias_step``, else the
  ``bias step`` bound;
- ``sf_tempco``: the part's own SF tempco interval
  (``part_sf_temp_coeff_per_k``, beside the paper's physics) when
  ``scale_factor_temperature`` is chosen (no bound otherwise: the bound
  is beyond the baseline's);
- ``g_sensitivity``: the interval of the largest component when
  ``g_sensitivity`` is chosen, else the ``g-sensitivity`` bound (a norm).

A record where another cause took the effect (named instead) counts in
neither. Prints, per effect and size, how often the interval holds the
truth and how often the bound lies above it, each with a Clopper-Pearson
95 % interval, and the median interval half width over the truth.

Usage: python bench/study_interval_coverage.py [--records N] [--effects E,...]
                                                [--synthetic] [--seed S] [--out FILE]
"""

import argparse
import os

import benchenv  # noqa: F401  one core: pins the BLAS thread pools before numpy loads

from gyro_emulator.emulation.profiles import SampledProfile  # noqa: E402
from gyro_emulator.emulation.truth import injection as inj  # noqa: E402
from gyro_emulator.recording.record import Record  # noqa: E402
from gyro_emulator.units import (deg_s_to_rad_s, rad_s_per_m_s2_to_deg_s_per_g,  # noqa: E402
                                 rad_s_to_deg_s)
import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402
import study_real_injections as sri  # noqa: E402

DS = inj.DATASHEET
#: A bias step the size of a datasheet's turn-on repeatability, rad/s.
BIAS_STEP_RAD_S = float(deg_s_to_rad_s(0.05))
#: What each effect needs of the profile.
NEEDS = {'bias_tempco': {'temp'}, 'bias_step': set(), 'sf_tempco': {'temp', 'rate'},
         'g_sensitivity': {'tilt'}}
#: The cause that measures each effect, its parameter and its bound (quantity).
CAUSE = {'bias_tempco': ('bias_temperature', 'bias_temp_coeff_rad_s_k', 'bias tempco'),
         'bias_step': ('bias_step', 'bias_step_rad_s', 'bias step'),
         'sf_tempco': ('scale_factor_temperature', None, None),
         'g_sensitivity': ('g_sensitivity', None, 'g-sensitivity')}
_DEG = float(rad_s_to_deg_s(1.0))


def ramp(t, rng):
    """Return a one-way chamber ramp between two random levels, the die lagging."""
    lo, hi = rng.uniform(-10, 15), rng.uniform(40, 60)
    if rng.random() < 0.5:
        lo, hi = hi, lo
    return inj.first_order_lag(t, lo + (hi - lo) * (t - t[0]) / (t[-1] - t[0]),
                               float(t[-1] - t[0]) / 50.0)


def make_profile(parts, t, rng):
    """Return a SampledProfile of ``parts``; the temperature a staircase, a sine or a ramp."""
    prof = sri.profile(parts, t, rng)
    if 'temp' in parts and rng.random() < 0.3:
        prof = SampledProfile(prof.name, t, prof.rate_rad_s, ramp(t, rng), prof.accel_m_s2,
                              rate_knots=prof.rate_knots)
    return prof


def noise(log, axis, rng, synthetic):
    """Return (time_s, noise): a stretch of the log, or white noise of its spread."""
    t, y = sri._noise(log, axis, rng)
    if synthetic:
        y = float(np.std(y)) * rng.standard_normal(len(t))
    return t, y


def record(log, axis, effect, scale, rng, synthetic):
    """Return (Record, truth) of one planted record; truth in the cause's own unit."""
    t, y = noise(log, axis, rng, synthetic)
    parts = set(NEEDS[effect])
    if rng.random() < 0.3:               # a second excitation beside (not the trim's pair)
        more = ['temp', 'tilt', 'rate'][int(rng.integers(3))]
        if not {'temp', 'rate'} <= parts | {more}:
            parts.add(more)
    prof = make_profile(parts, t, rng)
    sign = 1.0 if rng.random() < 0.5 else -1.0
    truth = {'effect': effect, 'scale': scale, 'parts': sorted(parts), 'log': log,
             'axis': axis, 'span_s': float(t[-1] - t[0])}
    effects, extra = {}, np.zeros(len(t))
    if effect == 'bias_tempco':
        effects['bias_tempco'] = sign * scale * DS['bias_tempco']
        truth['value'] = effects['bias_tempco']
        truth['true_bound'] = abs(truth['value']) * _DEG
    elif effect == 'sf_tempco':
        effects['sf_tempco'] = sign * scale * DS['sf_tempco']
        truth['value'] = effects['sf_tempco']
    elif effect == 'bias_step':
        when = rng.uniform(t[0] + 0.2 * (t[-1] - t[0]), t[-1] - 0.2 * (t[-1] - t[0]))
        truth['value'] = sign * scale * BIAS_STEP_RAD_S
        truth['when_s'] = float(when)
        truth['true_bound'] = abs(truth['value']) * _DEG
        extra = truth['value'] * (t >= when)
    elif effect == 'g_sensitivity':
        u = rng.standard_normal(3)
        g = scale * DS['g_sensitivity'] * u / np.linalg.norm(u)
        extra = prof.accel_m_s2 @ g
        truth['vector'] = [float(v) for v in g]
        truth['true_bound'] = float(rad_s_per_m_s2_to_deg_s_per_g(np.linalg.norm(g)))
    rec = inj.inject(y, prof, effects, sf_error=float(rng.uniform(-5e-3, 5e-3)))
    return Record.from_arrays(t, rec.gyro['x'] + extra, rec.rate.values, prof.temp_c,
                              prof.accel_m_s2, path=f'{log} {axis} {effect}'), truth


def _interval_of(entry, truth):
    """Return (interval, true value) of the effect's parameter in a chosen cause."""
    effect = truth['effect']
    if effect == 'sf_tempco':
        own = entry.get('part_sf_temp_coeff_per_k')
        return (None if own is None else own['interval']), truth['value']
    params = entry['parameters']
    if effect == 'g_sensitivity':
        i = int(np.argmax(np.abs(truth['vector'])))
        p = params.get(f'g_sensitivity_{"xyz"[i]}_rad_s_per_m_s2')
        return (None if p is None else p['interval']), truth['vector'][i]
    return params[CAUSE[effect][1]]['interval'], truth['value']


def judge(doc, truth):
    """Return the row: chosen, the interval against the truth, or the bound against it."""
    cause, _, quantity = CAUSE[truth['effect']]
    chosen = {e['effect']: e for e in doc['selected']}
    row = dict(truth, verdict=doc['verdict'], selected=list(chosen))
    if cause in chosen:
        interval, value = _interval_of(chosen[cause], truth)
        row['interval'] = interval
        row['covered'] = None if interval is None else bool(interval[0] <= value <= interval[1])
        if interval is not None and value != 0.0:
            row['half_over_truth'] = 0.5 * (interval[1] - interval[0]) / abs(value)
        row['estimates'] = {k: {f: p.get(f) for f in ('value', 'sigma', 'interval', 'method')}
                            for k, p in chosen[cause]['parameters'].items()}
        return row
    if quantity is None:
        return row
    bound = next((b['upper'] for b in doc['ruled_out']
                  if b['effect'] == cause and b['quantity'] == quantity), None)
    row['bound'] = bound
    row['bound_holds'] = None if bound is None else bool(bound >= truth['true_bound'])
    row['other_cause'] = bool(chosen)
    return row


def _rate(k, n):
    """Return "k/n = p % [lo, hi]" with the Clopper-Pearson 95 % interval."""
    if n == 0:
        return '-'
    ci = stats.binomtest(k, n).proportion_ci(0.95, method='exact')
    return f'{k}/{n} = {100 * k / n:.0f} % [{100 * ci.low:.0f}, {100 * ci.high:.0f}]'


def summary(rows):
    """Print interval and bound coverage per effect and size, and for all together."""
    print(f'{"effect":14s} {"size":>4s} {"interval holds the truth":>28s} '
          f'{"median half/truth":>18s} {"bound above the truth":>26s}')
    keys = sorted({(r['effect'], r['scale']) for r in rows}, key=lambda k: (k[0], -k[1]))
    for key in keys + [('all', None)]:
        at = [r for r in rows if key[0] == 'all' or (r['effect'], r['scale']) == key]
        cov = [r['covered'] for r in at if r.get('covered') is not None]
        bnd = [r['bound_holds'] for r in at if r.get('bound_holds') is not None
               and not r.get('other_cause')]
        half = [r['half_over_truth'] for r in at if 'half_over_truth' in r]
        size = '' if key[1] is None else ('1' if key[1] == 1.0 else '1/3')
        print(f'{key[0]:14s} {size:>4s} {_rate(sum(cov), len(cov)):>28s} '
              f'{np.median(half) if half else float("nan"):18.2f} '
              f'{_rate(sum(bnd), len(bnd)):>26s}')


def main():
    """Run the study and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--records', type=int, default=20, help='records per effect and size')
    ap.add_argument('--effects', default='bias_tempco,bias_step,sf_tempco,g_sensitivity')
    ap.add_argument('--synthetic', action='store_true', help='white noise instead of the logs')
    ap.add_argument('--seed', type=int, default=3301)
    ap.add_argument('--out', default='out/study_interval_coverage.jsonl')
    args = ap.parse_args()
    if not all(os.path.exists(p) for p, _, _ in sri.LOGS.values()):
        print(f'the real logs are absent ({sri.REAL})')
        return 1
    effects = [e for e in args.effects.split(',') if e]
    unknown = sorted(set(effects) - set(NEEDS))
    if unknown:
        print(f'--effects: {", ".join(unknown)} unknown; choose from {", ".join(NEEDS)}')
        return 2
    rng = np.random.default_rng(args.seed)
    jobs = [(e, s) for e in effects for s in (1.0, 1 / 3) for _ in range(args.records)]
    sri.run_jobs(jobs, rng,
                 lambda log, axis, effect, scale, r: record(log, axis, effect, scale, r,
                                                            args.synthetic),
                 judge, summary, args.out)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
