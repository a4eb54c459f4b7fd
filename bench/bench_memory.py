#!/usr/bin/env python3
"""
Benchmark: peak memory and time of ``diagnose`` on a day of 100 Hz data.

Writes a measured log as CSV under --out (default out/bench/memory): a part
in a chamber cycling +-10 K over 6 h, a rate table stepping 0 / 0.5 rad/s
every 10 min, a bias tempco and a scale-factor error, white noise: 24 h at
100 Hz is 8.64 M rows (about 330 MB). Then runs ``gyro-emulator diagnose``
on it in a child process (BLAS pinned to one thread) and prints the child's
peak resident memory (``getrusage`` ``ru_maxrss``) and its wall time against
the targets: <= 2 GB and <= 3 min. A 2 h log of the same kind (720 k rows,
under :data:`gyro_emulator.analysis.diagnose.data.MAX_ROWS`) is read whole,
and the benchmark says so.

Usage: python bench/bench_memory.py [--hours 24] [--rate-hz 100] [--out DIR] [--keep]
"""

import argparse
import os
import resource
import subprocess
import sys
import time

import benchenv  # noqa: F401 - one core: pins the BLAS thread pools before numpy loads

from gyro_emulator.analysis.diagnose.data import MAX_ROWS  # noqa: E402
import numpy as np  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET_BYTES = 2 << 30
TARGET_S = 180.0


def write_log(path, hours, rate_hz, seed=5):
    """Write the log block by block (a million rows at a time); return its rows."""
    n = int(round(hours * 3600.0 * rate_hz))
    rng = np.random.default_rng(seed)
    with open(path, 'w') as handle:
        handle.write('time_s,rate_cmd_rad_s,temp_c,gyro_rad_s\n')
        for start in range(0, n, 1_000_000):
            t = np.arange(start, min(n, start + 1_000_000)) / rate_hz
            temp = 25.0 + 10.0 * np.sin(2.0 * np.pi * t / (6 * 3600.0))
            rate = np.where((t // 600.0) % 2 == 1, 0.5, 0.0)
            gyro = rate * 1.001 + 1e-3 * (temp - 25.0) + 2e-3 * rng.standard_normal(len(t))
            np.savetxt(handle, np.column_stack([t, rate, temp, gyro]),
                       fmt=['%.2f', '%.4f', '%.4f', '%.7e'], delimiter=',')
    return n


def run_diagnose(path, json_path):
    """Run ``diagnose`` in a child; return (wall s, peak RSS bytes of the child, stderr)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    started = time.perf_counter()
    proc = subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', 'diagnose', path,
                           '--json', json_path, '--overwrite'], capture_output=True, text=True,
                          env=dict(os.environ, PYTHONPATH=ROOT))
    wall = time.perf_counter() - started
    if proc.returncode != 0:
        raise SystemExit(f'diagnose failed: {proc.stderr}')
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    if peak <= before:
        print('note: the peak is that of an earlier, larger child (ru_maxrss is a maximum)')
    return wall, peak * 1024, proc.stderr


def main(argv=None):
    """Write the logs, diagnose them, print peak memory and time against the targets."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--hours', type=float, default=24.0)
    parser.add_argument('--rate-hz', type=float, default=100.0)
    parser.add_argument('--out', default=os.path.join(ROOT, 'out', 'bench', 'memory'))
    parser.add_argument('--keep', action='store_true', help='keep the CSV logs')
    args = parser.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    for hours in (2.0, args.hours):     # the small one first: ru_maxrss only grows
        path = os.path.join(args.out, f'log_{hours:g}h.csv')
        started = time.perf_counter()
        rows = write_log(path, hours, args.rate_hz)
        size = os.path.getsize(path)
        print(f'{hours:g} h at {args.rate_hz:g} Hz: {rows} rows, {size / 1e6:.0f} MB CSV '
              f'(written in {time.perf_counter() - started:.0f} s)')
        wall, peak, err = run_diagnose(path, os.path.join(args.out, f'diag_{hours:g}h.json'))
        binned = [line for line in err.splitlines() if 'rows are more than' in line]
        print(f'  diagnose: {wall:6.1f} s wall, peak RSS {peak / 2**30:.2f} GB '
              f'({peak / rows:.0f} bytes per row)')
        print('  ' + (binned[0].split('warning: ', 1)[1] if binned else
                      f'read whole ({rows} rows <= MAX_ROWS {MAX_ROWS})'))
        if hours == args.hours:
            print(f'  target: <= {TARGET_BYTES / 2**30:.0f} GB and <= {TARGET_S:.0f} s: '
                  f'{"met" if peak <= TARGET_BYTES and wall <= TARGET_S else "NOT met"}')
        if not args.keep:
            os.remove(path)


if __name__ == '__main__':
    main()
