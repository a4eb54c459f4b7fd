"""
The node's pure driver alone: microseconds per sample, beside a reference.

    .venv/bin/python bench/bench_driver.py                 (5000 ticks, best of 3)
    .venv/bin/python bench/bench_driver.py --ticks 20000 --profile turn_x

A :class:`gyro_emulator.emulation.driver.Driver` with the shipped node
defaults at 1 kHz (the ``paper`` preset, accelerometer on) is ticked once
per period, one sample per tick, on a clock of its own (no ROS, no timer),
in these scenarios:

* ``rest``: no command, the part level and still;
* ``turn_z``: a held rate of 0.5 rad/s about z (the attitude turns, gravity
  stays on z, so the specific force holds);
* ``turn_x``: a held rate of 0.5 rad/s about x (gravity turns: the specific
  force changes every sample);
* ``stream_x``: a new rate about x every 10 samples (a simulator's 100 Hz
  commands on a 1 kHz part);
* ``jitter_x``: a new rate about x after 6 to 14 samples at random (a
  simulator's 100 Hz commands from a timer on a loaded machine; seeded);
* ``flood_z``: ten new rates about z per sample (a 10 kHz command flood),
  the driver taking them all (the node's inbox keeps the newest 100).

It prints the CPU time per sample (best of ``--repeats``), the driver's
model calls per sample, and in the same process a reference: the draw of
the 6-axis model's 19 standard normals for one sample,
``Generator.standard_normal(19)`` (one numpy call), so that figures of runs
on a loaded machine can be set against each other. ``--profile NAME`` runs
that scenario under cProfile and prints its top functions.
"""

import argparse
import cProfile
import math
import pstats
import time

import benchenv  # noqa: F401  (one BLAS thread; before numpy)
from gyro_emulator.emulation.driver import parameters
from gyro_emulator.emulation.driver.commands import CommandInbox
from gyro_emulator.emulation.driver.core import Driver
from gyro_emulator.resources import config_file, read_yaml
from gyro_emulator.sensor.config import load_sensor_config
import numpy as np

RATE_HZ = 1000.0
PERIOD_NS = 1_000_000
T0_NS = 10 ** 12
#: Scenario: (rate command, samples between commands, 0: one command at the start,
#: (low, high): at random in low..high; commands per tick).
SCENARIOS = {'rest': (None, 0, 1), 'turn_z': ((0.0, 0.0, 0.5), 0, 1),
             'turn_x': ((0.5, 0.0, 0.0), 0, 1), 'stream_x': ((0.5, 0.0, 0.0), 10, 1),
             'jitter_x': ((0.5, 0.0, 0.0), (6, 14), 1), 'flood_z': ((0.0, 0.0, 0.5), 1, 10)}


def node_values():
    """Return the shipped node parameters at 1 kHz, commands never stale."""
    doc = dict(read_yaml(config_file('gyro_emulator.yaml'))['/**']['ros__parameters'])
    for name, value in doc.pop('fault').items():
        doc['fault.' + name] = value
    doc.update(rate_hz=RATE_HZ, command_timeout_s=0.0)
    return {spec.name: parameters.check_value(spec, doc[spec.name])
            for spec in parameters.NODE_PARAMS}


def run(name, ticks, values, config):
    """Tick a fresh driver through scenario ``name``; return (CPU s, model calls) per sample."""
    rate, every, burst = SCENARIOS[name]
    inbox = CommandInbox()
    driver = Driver(values, config, 7, commands=inbox)
    driver.start(T0_NS)
    for k in range(200):                     # past the first samples and any block start
        driver.tick(T0_NS + k * PERIOD_NS)
    if rate is not None:
        inbox.push('rate', T0_NS + 200 * PERIOD_NS, rate)
    calls = driver.situation(0)['model_calls']
    changes = _change_ticks(every, 200, 200 + ticks)
    start = time.process_time()
    for k in range(200, 200 + ticks):
        if k in changes:
            sign = 1.0 if changes[k] % 2 else -1.0
            for i in range(burst):              # a new rate each, stamped within the period
                inbox.push('rate', T0_NS + k * PERIOD_NS - (burst - 1 - i) * PERIOD_NS // burst,
                           tuple(sign * (1.0 + 0.01 * i) * r for r in rate))
        driver.tick(T0_NS + k * PERIOD_NS)
    cpu = time.process_time() - start
    return cpu / ticks, (driver.situation(0)['model_calls'] - calls) / ticks


def _change_ticks(every, first, stop):
    """Return {tick: number of the change} of the ticks that bring a new rate."""
    if not every:
        return {}
    if isinstance(every, int):
        return {k: k // every for k in range(first, stop) if k % every == 0}
    rng = np.random.default_rng(5)
    ticks, k = {}, first
    while k < stop:
        ticks[k] = len(ticks)
        k += int(rng.integers(every[0], every[1] + 1))
    return ticks


def reference(ticks):
    """Return the CPU s of one ``standard_normal(19)`` draw (the reference)."""
    rng = np.random.default_rng(1)
    start = time.process_time()
    for _ in range(ticks):
        rng.standard_normal(19)
    return (time.process_time() - start) / ticks


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[1])
    parser.add_argument('--ticks', type=int, default=5000, help='samples per run')
    parser.add_argument('--repeats', type=int, default=3, help='runs per scenario (best kept)')
    parser.add_argument('--profile', choices=sorted(SCENARIOS), help='cProfile one scenario')
    args = parser.parse_args()
    values = node_values()
    config = load_sensor_config(values['sensor_config'])
    if args.profile:
        profile = cProfile.Profile()
        profile.runcall(run, args.profile, args.ticks, values, config)
        pstats.Stats(profile).sort_stats('tottime').print_stats(25)
        return
    run('rest', 500, values, config)                                   # warm the kernels
    ref = min(reference(args.ticks) for _ in range(args.repeats))
    print(f'reference: Generator.standard_normal(19) {ref * 1e6:.2f} us per call')
    print(f'{"scenario":9} {"us/sample":>9} {"x ref":>6} {"model calls/sample":>19}')
    for name in SCENARIOS:
        best = min((run(name, args.ticks, values, config) for _ in range(args.repeats)),
                   key=lambda figures: figures[0])
        print(f'{name:9} {best[0] * 1e6:9.2f} {best[0] / ref:6.1f} {best[1]:19.3f}')
    print(f'load average {" ".join(f"{x:.2f}" for x in _load())}')


def _load():
    try:
        import os
        return os.getloadavg()
    except OSError:
        return (math.nan,) * 3


if __name__ == '__main__':
    main()
