#!/usr/bin/env python3
"""
Throughput of the fleet: devices per CPU-second, 1 -> 2 workers, Dask overhead.

The fleet is config/fleet_paper_etch2.yaml (the paper's device, +-2 % etch,
7-point grid from -40 to 85 C) with the first-order physics only (``exact``
off, no sensor runs, no attribution: those are extras with their own cost,
printed at the end). Every run writes its Parquet rows to a scratch
directory, as the command does. Printed side by side:

* per core: an in-process run, devices per CPU-second (CPU time of its
  blocks: draw, physics, specs, Parquet; and of the whole run, summary and
  plots included), beside a per-device Python loop over the same physics
  (:func:`gyro_emulator.physics.first_order.scale_factor_ratio` and the
  Brownian ARW per part) in the same run;
* scaling: the same fleet on a LocalCluster with 1 and with 2 worker
  processes, wall time (targets: >= 1.7x);
* Dask overhead: wall time (and CPU time, the workers' included) of the
  LocalCluster with 1 worker over the in-process run at the same size
  (target: under 10 % at 1e7 devices); each scheduler runs ``--repeats``
  times, interleaved, and keeps its best (the machine is shared);
* the same two figures on a cluster that is already running (passed by
  address, as a user's own cluster is): worker start-up is then not part
  of the run;
* memory: the peak resident size of this process after the small and the
  large in-process runs (bounded: it does not grow with the fleet).

Usage: .venv/bin/python bench/bench_fleet.py [--devices-core N] [--devices-dask N]
       [--loop-devices M] [--json OUT]
"""

import argparse
from dataclasses import replace
import json
import os
import resource
import shutil
import tempfile
import time

os.environ.setdefault('OMP_NUM_THREADS', '1')
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

from gyro_emulator.analysis.fleet import config as fleet_config  # noqa: E402
from gyro_emulator.analysis.fleet import run, sampling  # noqa: E402
from gyro_emulator.analysis.fleet.sensor_runs import part_device  # noqa: E402
from gyro_emulator.physics import first_order  # noqa: E402
from gyro_emulator.resources import config_file  # noqa: E402
from gyro_emulator.sensor import noise  # noqa: E402
import numpy as np  # noqa: E402


def first_order_fleet():
    """Return the study fleet with the first-order physics only."""
    cfg = fleet_config.load_fleet_config(config_file('fleet_paper_etch2.yaml'))
    specs = tuple(s for s in cfg.specs if s.metric not in fleet_config.EXACT_METRICS)
    return replace(cfg, exact=False, sensor_runs=None, attribution_devices=0, specs=specs)


def peak_rss_mb():
    """Peak resident set size of this process so far, MB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def children_cpu_s():
    """CPU time of this process's finished child processes (cluster workers), s."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(cfg, n, scratch, **kwargs):
    """Run a fleet; return (wall s, CPU s of this process and its workers, summary)."""
    out = os.path.join(scratch, 'fleet')
    w0, c0, k0 = time.perf_counter(), time.process_time(), children_cpu_s()
    summary = run.run_fleet(cfg, n, 2026, out, overwrite=True, **kwargs)
    wall = time.perf_counter() - w0
    cpu = time.process_time() - c0 + children_cpu_s() - k0
    shutil.rmtree(out)
    return wall, cpu, summary


def loop_rate(cfg, m):
    """Per-device Python loop over the same first-order physics: parts per CPU-second."""
    values, _, _ = sampling.checked(cfg, sampling.draw_block(cfg, 1, 0, m).values(), m)
    temps = np.array(cfg.temperatures_c)
    c0 = time.process_time()
    for i in range(m):
        device = part_device(cfg, values, i)
        first_order.scale_factor_ratio(device, temps, cfg.calibration_temp_c)
        noise.brownian_arw_rad_s_sqrt_hz(device, temps)
        first_order.lumped_parameters(device, cfg.calibration_temp_c)
    return m / (time.process_time() - c0)


def keep_best(fig, name, n, wall, cpu, summary):
    """Keep the shortest wall and CPU time of run ``name`` in ``fig``."""
    best = fig.setdefault(name, {'devices': n, 'wall_s': np.inf, 'cpu_s': None})
    best['wall_s'] = min(best['wall_s'], wall)
    if cpu is not None:             # None: not measurable here (a running cluster's workers)
        best['cpu_s'] = cpu if best['cpu_s'] is None else min(best['cpu_s'], cpu)
    best['tasks'] = summary['run']['tasks']
    best.setdefault('peak_rss_mb', peak_rss_mb())


def running_clusters(fig, cfg, n, scratch, repeats):
    """
    Run the same fleet on a LocalCluster already running (1, then 2 workers), by address.

    This is the ``tcp://HOST:PORT`` path of a user's own cluster: worker start-up
    (about 1.5 CPU-s a process, importing numpy, pyarrow and the package) is not
    in the run. Each cluster first runs one block so that its workers have
    imported the code. Wall time only: the workers' CPU is not this process's.
    """
    for workers in (1, 2):
        cluster = run.local_cluster(workers)
        try:
            address = cluster.scheduler_address
            timed(cfg, sampling.BLOCK_DEVICES, scratch, scheduler=address)   # warm up
            for _ in range(repeats):
                wall, _, summary = timed(cfg, n, scratch, scheduler=address)
                keep_best(fig, f'running_{workers}', n, wall, None, summary)
        finally:
            cluster.close()


def main():
    """Run the benchmark and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--devices-core', type=int, default=2_000_000)
    ap.add_argument('--devices-dask', type=int, default=10_000_000)
    ap.add_argument('--loop-devices', type=int, default=2000)
    ap.add_argument('--repeats', type=int, default=2,
                    help='runs of each scheduler at --devices-dask (best kept)')
    ap.add_argument('--json', metavar='OUT')
    args = ap.parse_args()
    cfg = first_order_fleet()
    fig = {}
    with tempfile.TemporaryDirectory(prefix='bench_fleet_') as scratch:
        timed(cfg, sampling.BLOCK_DEVICES, scratch, scheduler='in-process')     # warm up
        wall, cpu, summary = timed(cfg, args.devices_core, scratch, scheduler='in-process')
        fig['core'] = {'devices': args.devices_core, 'wall_s': wall, 'cpu_s': cpu,
                       'blocks_cpu_s': summary['run']['cpu_s'],
                       'devices_per_cpu_s': args.devices_core / summary['run']['cpu_s'],
                       'run_devices_per_cpu_s': args.devices_core / cpu,
                       'peak_rss_mb': peak_rss_mb()}
        fig['loop_devices_per_cpu_s'] = loop_rate(cfg, args.loop_devices)
        n = args.devices_dask
        runs = {'in_process': {'scheduler': 'in-process'},
                'local_1': {'scheduler': 'local', 'workers': 1},
                'local_2': {'scheduler': 'local', 'workers': 2}}
        for _ in range(args.repeats):   # interleaved; the best of each (shared machine)
            for name, kwargs in runs.items():
                wall, cpu, summary = timed(cfg, n, scratch, **kwargs)
                keep_best(fig, name, n, wall, cpu, summary)
        running_clusters(fig, cfg, n, scratch, args.repeats)
        extra = replace(first_order_fleet(), exact=True, attribution_devices=0)
        wall, cpu, _ = timed(extra, args.devices_core // 4, scratch, scheduler='in-process')
        fig['exact_devices_per_cpu_s'] = args.devices_core // 4 / cpu
    report(fig, args)


def report(fig, args):
    """Print the table (and the JSON)."""
    core, loop = fig['core'], fig['loop_devices_per_cpu_s']
    one, two, inp = fig['local_1'], fig['local_2'], fig['in_process']
    speedup = one['wall_s'] / two['wall_s']
    overhead = one['wall_s'] / inp['wall_s'] - 1.0
    cpu_overhead = one['cpu_s'] / inp['cpu_s'] - 1.0
    load = os.getloadavg()[0]
    print(f'fleet: paper device, +-2 % etch, 7 temperatures, first order, Parquet rows '
          f'(load average {load:.2f} on {os.cpu_count()} cores)')
    print(f'  per core  : {core["devices_per_cpu_s"]:12,.0f} devices per CPU-second '
          f'({core["devices"]:,} devices)   per-device Python loop {loop:9,.0f}/s   '
          f'ratio {core["devices_per_cpu_s"] / loop:,.0f}x   target 1,000,000: '
          f'{"met" if core["devices_per_cpu_s"] >= 1e6 else "NOT met"}')
    print(f'              the whole run, summary and plots included: '
          f'{core["run_devices_per_cpu_s"]:,.0f} devices per CPU-second')
    print(f'  {inp["devices"]:,} devices, wall: in-process {inp["wall_s"]:.1f} s, '
          f'LocalCluster 1 worker {one["wall_s"]:.1f} s, 2 workers {two["wall_s"]:.1f} s')
    print(f'  CPU, workers included: in-process {inp["cpu_s"]:.1f} s, 1 worker '
          f'{one["cpu_s"]:.1f} s, 2 workers {two["cpu_s"]:.1f} s')
    print(f'  1 -> 2 workers: {speedup:.2f}x (target 1.7x: '
          f'{"met" if speedup >= 1.7 else "NOT met"})   Dask overhead (1 worker vs '
          f'in-process): {100 * overhead:+.1f} % wall (target < 10 %: '
          f'{"met" if overhead < 0.10 else "NOT met"}), {100 * cpu_overhead:+.1f} % CPU '
          f'(best of {args.repeats} each)')
    r1, r2 = fig['running_1'], fig['running_2']
    run_speedup = r1['wall_s'] / r2['wall_s']
    run_overhead = r1['wall_s'] / inp['wall_s'] - 1.0
    print(f'  on a running cluster (by address, workers started and warm): 1 worker '
          f'{r1["wall_s"]:.1f} s, 2 workers {r2["wall_s"]:.1f} s: 1 -> 2 workers '
          f'{run_speedup:.2f}x ({"met" if run_speedup >= 1.7 else "NOT met"}), Dask overhead '
          f'{100 * run_overhead:+.1f} % wall ({"met" if run_overhead < 0.10 else "NOT met"})')
    print(f'  peak memory of this process: {core["peak_rss_mb"]:.0f} MB after '
          f'{core["devices"]:,} devices, {inp["peak_rss_mb"]:.0f} MB after '
          f'{inp["devices"]:,} (in-process)')
    print(f'  extra: with the exact 2-DOF ratio {fig["exact_devices_per_cpu_s"]:,.0f} devices '
          'per CPU-second')
    if args.json:
        fig.update(speedup_1_to_2=speedup, dask_overhead=overhead,
                   dask_overhead_cpu=cpu_overhead, running_speedup_1_to_2=run_speedup,
                   running_dask_overhead=run_overhead)
        with open(args.json, 'w', encoding='utf-8') as handle:
            json.dump(fig, handle, indent=2)


if __name__ == '__main__':
    main()
