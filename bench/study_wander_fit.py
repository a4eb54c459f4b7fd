#!/usr/bin/env python3
"""
Study: whether a candidate predicts held-out data worse because its fit chases the wander.

Diagnose fits every model by weighted least squares on bin means
(:mod:`gyro_emulator.analysis.diagnose.models`), as if the residual were
white. Where it is not (bias instability, a random walk, an effect the
model does not hold yet), columns that are slow in time can take up the
wander of the training folds and carry it into the held-out one: the
spurious regression of Granger & Newbold (1974). This study refits the
same columns, at the same non-linear parameters, by generalised least
squares with a random walk in the noise (the local level of
:func:`.statespace.fit_level`, on the super-bin means of the training
folds), and predicts each held-out fold with those coefficients and a
level from the training samples. It prints, for a candidate and the model
it extends, the held-out RMSE ratio under both fits and the folds the
candidate predicts worse.

The default records are the scores over the bound of
``bench/study_held_out_ratio.py`` (docs/diagnose.md, "Re-run on
2026-11-30") and the g-sensitivity that its reversed fold test finds worse
at 1 %.

Usage: python bench/study_wander_fit.py [--record LABEL --models IDS IDS ...]
    LABEL as the held-out-ratio study prints it ('real adis y dtdt_bias
    x0.33 seed 7', 'truth g_sensitivity seed 3'); IDS the causes of a model,
    comma-separated ('' for the baseline): the first is the reference.
"""

import argparse
import functools
import os
import time

import benchenv  # one core: pins the BLAS thread pools before numpy loads

from gyro_emulator.analysis.diagnose import noise_model, statespace  # noqa: E402
import numpy as np  # noqa: E402
import study_held_out_ratio as study  # noqa: E402

#: (record, reference model, candidates): the scores of the study's re-run.
CASES = (
    ('real mpu z sf_tempco x1 seed 6', '', ('bias_temperature',)),
    ('truth g_sensitivity seed 3', '', ('bias_temperature',)),
    ('real mpu y dtdt_bias x0.33 seed 1', '', ('bias_time',)),
    ('truth scale_factor_step seed 4', '', ('scale_factor_temperature',)),
    ('real adis y dtdt_bias x0.33 seed 3', '', ('bias_time',)),
    ('real adis y dtdt_bias x0.33 seed 7', '', ('g_sensitivity',)),
    ('real adis y dtdt_bias x0.33 seed 7', 'temperature_rate_bias,bias_temperature',
     ('temperature_rate_bias,bias_temperature,g_sensitivity',)),
    ('truth g_sensitivity seed 5', '', ('bias_temperature', 'bias_hysteresis')),
    ('real mpu z bias_tempco x1 seed 7', '', ('bias_time',)),
    ('truth bias_step seed 6', '', ('bias_hysteresis',)),
    ('truth g_sensitivity seed 8', 'g_sensitivity',
     ('g_sensitivity,scale_factor_temperature',)),
)


def _ids(text):
    return tuple(e for e in text.split(',') if e)


def record_of(label):
    """Return the record the held-out-ratio study draws under ``label``."""
    words = label.split()
    try:
        seed = int(words[-1])
        source = (study.truth_records(1, [words[1]], seed) if words[0] == 'truth'
                  else study.real_records(1, None, seed))
        for name, record in source:
            if name == label:
                return record
    except (ValueError, IndexError) as exc:
        raise SystemExit(f'--record {label!r}: {exc}')
    raise SystemExit(f'--record: no record {label!r} (labels as the held-out-ratio study '
                     f'prints them)')


@functools.lru_cache(maxsize=1)
def evaluated(label):
    """Diagnose the record ``label``; return {cause ids: (cross-validation, evaluated model)}."""
    return study.evaluated_models(record_of(label))[1]


def walk_fit_sse(cv, ev):
    """
    Held-out SSE per fold of ``ev``'s columns fitted with a random walk in the noise.

    The columns but the constant at the model's fit on all rows; for each
    fold, the local-level GLS slopes on the super-bin means of the other
    folds (:func:`.statespace.fit_level`), the level the mean training
    residual.
    """
    prep, ctx = cv.prep, cv.ctx
    b, s = prep.binned, prep.samples
    sb = noise_model.SuperBins(b, cv.fold_of_bin, prep.dt_s)
    on_bins = ev.model.columns(ctx, b, ev.full.phis)[1:]
    groups_x = np.column_stack([sb.aggregate(c) for c in on_bins])
    x = np.column_stack([np.broadcast_to(c, (len(s),))
                         for c in ev.model.columns(ctx, s, ev.full.phis)[1:]])
    y_groups = sb.aggregate(b.gyro)
    sse = []
    for k in cv.used_folds:
        train = sb.fold != k
        groups = statespace.Groups(sb.weight[train], sb.weight[train] * prep.dt_s,
                                   sb.time_s[train])
        beta = statespace.fit_level(y_groups[train], groups_x[train], groups).beta
        level = np.mean((cv.y - x @ beta)[cv.fold_of_sample != k])
        held = cv.fold_of_sample == k
        sse.append(float(np.sum((cv.y[held] - level - x[held] @ beta) ** 2)))
    return np.asarray(sse)


def compare(label, reference, candidates):
    """Print the candidates' held-out ratios to ``reference`` under both fits."""
    evs = evaluated(label)
    missing = [m for m in (reference,) + candidates if _ids(m) not in evs]
    if missing:
        print(f'{label}: not scored by diagnose: {missing}')
        return
    cv, ref = evs[_ids(reference)]
    ref_walk = walk_fit_sse(cv, ref)
    for cand in candidates:
        ev = evs[_ids(cand)][1]
        walk = walk_fit_sse(cv, ev)
        print(f'{np.sqrt(ev.sse_fold.sum() / ref.sse_fold.sum()):7.4f} '
              f'{int(np.sum(ev.sse_fold > ref.sse_fold)):3d}/{len(ref.sse_fold):<3d}'
              f'{np.sqrt(walk.sum() / ref_walk.sum()):9.4f} '
              f'{int(np.sum(walk > ref_walk)):3d}/{len(ref_walk):<3d}'
              f'{np.sqrt(ref_walk.sum() / ref.sse_fold.sum()):12.4f}  '
              f'{label}: {cand or "baseline"} over {reference or "baseline"}', flush=True)


def main():
    """Run the study and print one line per candidate."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--record', default=None, help='a record label of the held-out-ratio study')
    ap.add_argument('--models', nargs='+', default=None,
                    help="the reference model's causes, then each candidate model's "
                         "(comma-separated; '' the baseline)")
    args = ap.parse_args()
    if (args.record is None) != (args.models is None) or len(args.models or ('', '')) < 2:
        ap.error('--record and --models (a reference and at least one candidate) go together')
    if not os.path.isdir(benchenv.REAL):
        print(f'{benchenv.REAL} is absent: the real-noise records are skipped')
    cases = CASES if args.record is None else (
        (args.record, args.models[0], tuple(args.models[1:])),)
    print(f'{"WLS":>7s} {"worse":>7s}{"walk GLS":>9s} {"worse":>7s} {"ref GLS/WLS":>11s} '
          f'record: candidate over the model it extends')
    start = time.perf_counter()
    for label, reference, candidates in cases:
        if label.startswith('real') and not os.path.isdir(benchenv.REAL):
            continue
        compare(label, reference, candidates)
    print(f'{time.perf_counter() - start:.0f} s')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
