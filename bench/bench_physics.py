#!/usr/bin/env python3
"""Benchmark: first-order model over a population of devices.

Evaluates Eq 5-21 for 1e6 devices whose geometry lengths are each drawn
uniformly within +-5 % of the paper's preset, vectorised, and the same
computation as a per-device Python loop (on a subset, extrapolated), in the
same run. Prints devices per CPU-second (the vectorised call best of 3, its
wall-clock rate beside it) and the ratio.

Usage: python bench/bench_physics.py [--devices N] [--loop-devices M] [--seed S]
"""

import argparse
from dataclasses import fields, replace
import time

from gyro_emulator.physics import first_order
from gyro_emulator.physics.presets import PAPER_DEVICE
from gyro_emulator.units import deg_s_to_rad_s
import numpy as np


def random_population(n, rng, spread=0.05):
    """Paper device with every geometry length scaled by U(1-spread, 1+spread)."""
    geo = PAPER_DEVICE.geometry
    changes = {}
    for f in fields(geo):
        if f.name.endswith('_m') and not f.name.startswith('_'):
            changes[f.name] = getattr(geo, f.name) * rng.uniform(
                1 - spread, 1 + spread, n)
    return replace(PAPER_DEVICE, geometry=replace(geo, **changes))


def device_at(population, i):
    """Return device i of a population as a scalar Device."""
    geo = population.geometry
    one = {f.name: float(np.asarray(getattr(geo, f.name))[i])
           for f in fields(geo) if np.ndim(getattr(geo, f.name))}
    return replace(population, geometry=replace(geo, **one))


def main():
    """Run the benchmark and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--devices', type=int, default=1_000_000)
    ap.add_argument('--loop-devices', type=int, default=2000)
    ap.add_argument('--seed', type=int, default=1)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    rate = deg_s_to_rad_s(60.0)

    t0 = time.perf_counter()
    pop = random_population(args.devices, rng)
    t_build = time.perf_counter() - t0
    t_vec = cpu_vec = float('inf')
    for _ in range(3):                  # best of 3; CPU time is the one-core figure
        t0, c0 = time.perf_counter(), time.process_time()
        resp = first_order.first_order_response(pop, rate, 25.0)
        t_vec = min(t_vec, time.perf_counter() - t0)
        cpu_vec = min(cpu_vec, time.process_time() - c0)
    y = resp.sense_amplitude_m

    m = min(args.loop_devices, args.devices)
    t0 = time.process_time()
    loop = np.empty(m)
    for i in range(m):
        loop[i] = float(first_order.first_order_response(device_at(pop, i), rate,
                                                         25.0).sense_amplitude_m)
    t_loop = time.process_time() - t0
    np.testing.assert_allclose(loop, y[:m], rtol=1e-12)

    vec_rate = args.devices / cpu_vec
    loop_rate = m / t_loop
    print(f'first-order model, {args.devices} devices with geometry +-5 % (per CPU-second)')
    print(f'  build + validate population : {t_build:8.3f} s')
    print(f'  vectorised (best of 3)      : {cpu_vec:8.3f} s  '
          f'{vec_rate:12.4g} devices/s  ({args.devices / t_vec:.4g}/s wall)')
    print(f'  per-device Python loop      : {t_loop:8.3f} s for {m}  '
          f'{loop_rate:12.4g} devices/s')
    print(f'  ratio vectorised / loop     : {vec_rate / loop_rate:8.1f}x')
    print(f'  sense amplitude at 60 deg/s : mean {y.mean():.4g} m, '
          f'std/mean {y.std() / y.mean():.3%}, '
          f'5-95 % [{np.percentile(y, 5):.4g}, {np.percentile(y, 95):.4g}] m')


if __name__ == '__main__':
    main()
