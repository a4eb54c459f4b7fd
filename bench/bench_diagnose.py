#!/usr/bin/env python3
"""
Benchmark: diagnose one hour of 100 Hz data (360k rows) on one core.

Writes a simulated lab record with a hidden effect (truth generator) as CSV
under out/bench/, then times, on one core (BLAS threads pinned to 1):
reading the CSV, ``diagnose`` with the full catalogue, and the report.
Beside it, in the same run, the reference: the hidden effect alone fitted at
full resolution (no binning, every sample a row) against the same effect on
bin means; the ratio of times and the two parameter estimates show what the
decimation buys and that it does not move the answer. The budget is 30 s.

Usage: python bench/bench_diagnose.py [--effect E] [--seed N] [--hours H]
"""

import argparse
import os
import time

# one core: pin the BLAS thread pools before numpy is imported
for _var in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ[_var] = '1'

from gyro_emulator.analysis.diagnose import (diagnose, EFFECT_IDS, load_csv,  # noqa: E402
                                             make_truth, write_measured_csv)
from gyro_emulator.analysis.diagnose.report import write_report  # noqa: E402

BUDGET_S = 30.0


def main():
    """Run the benchmark and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--effect', default='thermal_lag', choices=EFFECT_IDS + ('none',))
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--hours', type=float, default=1.0)
    ap.add_argument('--out', default='out/bench/diagnose')
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    record, truth = make_truth(args.effect, args.seed, sample_rate_hz=100.0,
                               max_duration_s=args.hours * 3600.0)
    path = os.path.join(args.out, 'measured.csv')
    write_measured_csv(path, record)

    t0 = time.perf_counter()
    data = load_csv(path)
    t1 = time.perf_counter()
    result = diagnose(data)
    t2 = time.perf_counter()
    write_report(result, os.path.join(args.out, 'report'))
    t3 = time.perf_counter()
    total = t3 - t0
    doc = result.doc
    print(f'record: {data.rows} rows, {doc["input"]["duration_s"]:.0f} s at '
          f'100 Hz, hidden effect {truth["effect"]} (seed {args.seed}); '
          f'fits on {doc["input"]["bins"]} bins of {doc["input"]["bin_s"]:.2f} s')
    print(f'read CSV      {t1 - t0:7.2f} s')
    print(f'diagnose      {t2 - t1:7.2f} s   (full catalogue, {doc["method"]["folds"]} '
          'folds, held-out RMSE on every sample)')
    print(f'report        {t3 - t2:7.2f} s')
    print(f'total         {total:7.2f} s   budget {BUDGET_S:.0f} s   '
          f'budget/total = {BUDGET_S / total:.1f}x')
    print(f'verdict: best = {doc["best"]["effect"]}, gain '
          f'{100 * doc["best"]["gain"]:.1f} %')

    if args.effect == 'none':
        return
    only = [args.effect]
    t4 = time.perf_counter()
    binned = diagnose(data, effects=only)
    t5 = time.perf_counter()
    full = diagnose(data, effects=only, max_bins=data.rows)
    t6 = time.perf_counter()
    print(f'reference ({args.effect} only): bin means {t5 - t4:.2f} s, '
          f'full resolution ({full.doc["input"]["bins"]} rows) {t6 - t5:.2f} s, '
          f'ratio {(t6 - t5) / (t5 - t4):.1f}x')
    pb = binned.doc['findings'][0]['parameters']
    pf = full.doc['findings'][0]['parameters']
    for name, true_value in truth['parameters'].items():
        print(f'  {name}: truth {true_value:.5g}, bin means '
              f'{pb[name]["value"]:.5g} +- {pb[name]["sigma"]:.2g}, full '
              f'resolution {pf[name]["value"]:.5g} +- {pf[name]["sigma"]:.2g}')
    print(f'  held-out RMSE: bin-mean fit {binned.doc["findings"][0]["rmse_rad_s"]:.5g}'
          f', full-resolution fit {full.doc["findings"][0]["rmse_rad_s"]:.5g} rad/s')


if __name__ == '__main__':
    main()
