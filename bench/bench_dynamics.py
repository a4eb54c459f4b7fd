#!/usr/bin/env python3
"""
Benchmark: time-domain model of Eq 3-4 against fixed-step RK4, and the envelope.

Prints simulated seconds per wall second of ``simulate_time_domain`` (exact
one-step-per-drive-cycle discretisation) for an open-loop run with a
sinusoidal rate, an AGC run with a temperature ramp, and a run with 40
demodulator samples per cycle; beside them, in the same run, a plain
fixed-step RK4 loop at 40 points per drive cycle (the brute-force way), with
the ratio, both models' sense-displacement error against scipy's DOP853
(test/dynamics_reference.py) and the exact model's steady state against the
harmonic solution. Then the envelope (rate-channel) model's samples per second, per
sample as a node runs it and batched.

Usage: python bench/bench_dynamics.py [--sim-s S] [--rk4-s S] [--repeats N]
"""

import argparse
import math
import os
import sys
import time

from gyro_emulator.physics import dynamics, time_domain
from gyro_emulator.physics.presets import PAPER_DEVICE
from gyro_emulator.units import deg_s_to_rad_s
import numpy as np


def best_of(repeats, func):
    """Return (min wall time in s, last result) over ``repeats`` calls."""
    best, out = float('inf'), None
    for _ in range(repeats):
        start = time.perf_counter()
        out = func()
        best = min(best, time.perf_counter() - start)
    return best, out


def rk4_loop(device, duration_s, rate_rad_s, temp_c, split_hz, points_per_cycle):
    """
    Plain fixed-step RK4 of Eq 3-4 from rest: the brute-force way, timed here.

    Open-loop drive F_d sin(w_x t), constant rate and temperature; a scalar
    Python loop, the usual way such models are integrated. Its error is
    O((w h)^4) per unit time. Returns (x, x', y, y') at the start of each
    drive cycle, shape (n_cycles + 1, 4).
    """
    mech = time_domain._mechanics(device, temp_c, split_hz, None)
    w = 2.0 * np.pi * mech.drive_freq_hz
    cycles = max(1, int(math.ceil(duration_s * mech.drive_freq_hz - 1e-9)))
    h = 1.0 / (mech.drive_freq_hz * points_per_cycle)
    inv_m = 1.0 / mech.mass
    kx, ky, cd, cs = (mech.k_x * inv_m, mech.k_y * inv_m, mech.c_d * inv_m,
                      mech.c_s * inv_m)
    fm = mech.force * inv_m
    two_r = 2.0 * float(rate_rad_s)
    sin = math.sin

    def deriv(t, x, vx, y, vy):
        return (vx, fm * sin(w * t) - cd * vx - kx * x + two_r * vy,
                vy, -cs * vy - ky * y - two_r * vx)

    x = vx = y = vy = 0.0
    out = [(0.0, 0.0, 0.0, 0.0)]
    t = 0.0
    for c in range(cycles):
        for i in range(points_per_cycle):
            t = (c * points_per_cycle + i) * h
            k1 = deriv(t, x, vx, y, vy)
            k2 = deriv(t + 0.5 * h, x + 0.5 * h * k1[0], vx + 0.5 * h * k1[1],
                       y + 0.5 * h * k1[2], vy + 0.5 * h * k1[3])
            k3 = deriv(t + 0.5 * h, x + 0.5 * h * k2[0], vx + 0.5 * h * k2[1],
                       y + 0.5 * h * k2[2], vy + 0.5 * h * k2[3])
            k4 = deriv(t + h, x + h * k3[0], vx + h * k3[1], y + h * k3[2],
                       vy + h * k3[3])
            x += h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
            vx += h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
            y += h / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
            vy += h / 6.0 * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3])
        out.append((x, vx, y, vy))
    return np.array(out)


def dynamics_reference():
    """Import the DOP853 reference that the tests share (test/dynamics_reference.py)."""
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                    os.pardir, 'test'))
    import dynamics_reference as reference
    return reference


def main():
    """Run the benchmark and print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--sim-s', type=float, default=4.0,
                    help='simulated seconds per time-domain run')
    ap.add_argument('--rk4-s', type=float, default=0.03,
                    help='simulated seconds of the RK4 and reference runs')
    ap.add_argument('--repeats', type=int, default=3)
    args = ap.parse_args()
    dev = PAPER_DEVICE
    rate = float(deg_s_to_rad_s(60.0))
    split = 20.0

    def sine(t):
        return rate * np.sin(2 * np.pi * 10.0 * t)

    def ramp(t):
        return 25.0 + 60.0 * min(t / args.sim_s, 1.0)

    cases = [
        ('exact, open loop, sine rate', lambda: dynamics.simulate_time_domain(
            dev, args.sim_s, sine, 25.0, split)),
        ('exact, AGC, 25->85 C ramp', lambda: dynamics.simulate_time_domain(
            dev, args.sim_s, rate, ramp, split, drive='agc')),
        ('exact, open loop, 40 samples/cycle', lambda: dynamics.simulate_time_domain(
            dev, args.sim_s, sine, 25.0, split, samples_per_cycle=40)),
    ]
    f_x = float(dynamics.exact_steady_state(dev, rate).drive_freq_hz)
    print(f'time domain of Eq 3-4, paper device (f_x = {f_x:.0f} Hz), '
          f'split {split:g} Hz, best of {args.repeats}')
    rk4_wall, rk4_states = best_of(1, lambda: rk4_loop(
        dev, args.rk4_s, rate, 25.0, split, points_per_cycle=40))
    rk4_speed = args.rk4_s / rk4_wall
    speeds = []
    for name, run in cases:
        wall, res = best_of(args.repeats, run)
        speeds.append(wall and args.sim_s / wall)
        print(f'  {name:38s} {args.sim_s / wall:9.1f} sim s / wall s '
              f'({len(res.time_s) / wall / 1e6:.2f} M cycles/s)')
    print(f'  {"plain RK4, 40 points/cycle (loop)":38s} {rk4_speed:9.3f} sim s / wall s')
    print(f'  ratio exact / RK4 (open loop, sine rate): {speeds[0] / rk4_speed:.0f}x; '
          f'(AGC + temperature): {speeds[1] / rk4_speed:.0f}x')

    # Accuracy after the same simulated time, both from rest.
    exact = dynamics.exact_steady_state(dev, rate, 25.0, split)
    res = dynamics.simulate_time_domain(dev, args.rk4_s, rate, 25.0, split,
                                        initial='rest')
    ref = dynamics_reference().simulate_reference(dev, args.rk4_s, rate, 25.0, split)
    n = len(res.time_s)
    y_amp = float(np.max(np.abs(ref[-40:, 2])))
    err_exact = np.max(np.abs(res.state_m[-20:, 2] - ref[n - 20:n, 2])) / y_amp
    err_rk4 = np.max(np.abs(rk4_states[n - 20:n, 2] - ref[n - 20:n, 2])) / y_amp
    print(f'  sense displacement error at {args.rk4_s * 1e3:.0f} ms vs DOP853 '
          f'(rtol 1e-12): exact {err_exact:.1e}, RK4/40 {err_rk4:.1e} '
          f'(relative); exact steady state vs harmonic solution '
          f'{abs(res.sense_amplitude_m[-1] / exact.sense_amplitude_m - 1):.1e}')

    # Envelope model.
    disc = dynamics.rate_channel_discrete(dev, 1000.0, 25.0, split)
    n_loop = 20000
    u = np.random.default_rng(0).normal(size=1_000_000)

    def loop():
        x = np.zeros(2)
        step = dynamics.rate_channel_step
        for value in u[:n_loop]:
            x, _ = step(disc, x, value)

    wall_loop, _ = best_of(args.repeats, loop)
    ad, bd = disc[0], disc[1][:, 0]
    c0 = disc[2][0]

    def raw_loop():
        x = np.zeros(2)
        for value in u[:n_loop]:
            c0 @ x
            x = ad @ x + bd * value

    wall_raw, _ = best_of(args.repeats, raw_loop)
    wall_batch, _ = best_of(args.repeats, lambda: dynamics.rate_channel_filter(disc, u))
    wall_disc, _ = best_of(args.repeats, lambda: [dynamics.rate_channel_discrete(
        dev, 1000.0, t, split) for t in np.linspace(25.0, 85.0, 100)])
    print('envelope (rate-channel) model, 1 kHz')
    print(f'  per sample, rate_channel_step       {n_loop / wall_loop:12.0f} samples/s')
    print(f'  per sample, inline Ad @ x + Bd * u  {n_loop / wall_raw:12.0f} samples/s')
    print(f'  batch, rate_channel_filter          {u.size / wall_batch:12.0f} samples/s')
    print(f'  rate_channel_discrete (per temperature update) '
          f'{wall_disc / 100 * 1e6:.0f} us')


if __name__ == '__main__':
    main()
