"""
Simulate the gyro over a scripted profile and write the record as CSV.

Profiles: ``static`` (zero rate), ``steps`` (rate table about z at 0, 10, 20,
40 RPM and back to 0), ``temp-ramp`` (60 deg/s about z while the ambient goes
from 25 to 85 C, the paper's Fig 6 conditions) or a YAML profile file (see
``gyro_emulator.sensor.profiles``). The CSV columns are time_s, rate_{x,y,z}_rad_s
(true rate), temp_c (ambient) and gyro_{x,y,z}_rad_s (sensor output).
An ``--out`` path not ending in .csv/.csv.gz is a rosbag2 MCAP bag directory
with the node's topics (see ``gyro_emulator.analysis.replay``).
"""

import contextlib
import os
import shutil
import sys
import tempfile
import time

HELP = 'simulate the sensor over a scripted profile and write CSV or a rosbag2 bag'

#: Show progress when a run has at least this many samples.
PROGRESS_MIN_SAMPLES = 200_000


def add_arguments(parser):
    """Register the ``simulate`` options."""
    parser.add_argument('--config', default='paper', metavar='YAML|NAME',
                        help='sensor preset (paper, consumer, tactical) or YAML file '
                             '(default: %(default)s)')
    parser.add_argument('--profile', default='static', metavar='PROFILE',
                        help='static, steps, temp-ramp or a YAML profile '
                             '(default: %(default)s)')
    parser.add_argument('--duration-s', type=float, default=60.0, metavar='S',
                        help='duration, s (default: %(default)s)')
    parser.add_argument('--rate-hz', type=float, default=200.0, metavar='R',
                        help='output data rate, Hz (default: %(default)s)')
    parser.add_argument('--temp-c', type=float, default=25.0, metavar='C',
                        help='ambient of the static and steps profiles, deg C '
                             '(default: %(default)s)')
    parser.add_argument('--seed', type=int, default=0, metavar='N',
                        help='random seed (default: %(default)s)')
    parser.add_argument('--out', required=True, metavar='FILE.csv|DIR',
                        help='output CSV (.csv or .csv.gz), or else a rosbag2 MCAP bag '
                             'directory in the emulator topic layout')
    parser.add_argument('--overwrite', action='store_true',
                        help='replace an existing output (default: refuse)')


class Progress:
    """Progress lines on stderr at every 10 %, for runs worth reporting."""

    def __init__(self, stream=None):
        self.stream = stream or sys.stderr
        self.start = time.monotonic()
        self.next_pct = 10

    def __call__(self, done, total):
        """Report ``done`` of ``total`` samples."""
        if not total or total < PROGRESS_MIN_SAMPLES:
            return
        pct = 100.0 * done / total
        if pct + 1e-9 >= self.next_pct or done == total:
            elapsed = time.monotonic() - self.start
            print(f'simulate: {pct:5.1f} % ({done}/{total} samples, {elapsed:.1f} s)',
                  file=self.stream, flush=True)
            self.next_pct = 10 * (int(pct) // 10 + 1)


@contextlib.contextmanager
def staged_output(out, overwrite=False):
    """
    Yield a temporary path beside ``out``; move it to ``out`` only on success.

    A run that fails (or is interrupted) leaves nothing behind, and an
    existing ``out`` is replaced only with ``overwrite``. The temporary path
    has the same name inside a hidden sibling directory, so a bag keeps its
    file names.
    """
    out = os.path.abspath(out)
    if os.path.exists(out) and not overwrite:
        raise ValueError(f'--out {out} exists: pass --overwrite to replace it')
    parent = os.path.dirname(out)
    os.makedirs(parent, exist_ok=True)
    stage = tempfile.mkdtemp(prefix='.simulate-', dir=parent)
    try:
        partial = os.path.join(stage, os.path.basename(out))
        yield partial
        if os.path.isdir(out):
            shutil.rmtree(out)
        os.replace(partial, out)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _open_writer(path, args=None, config=None):
    """Return the record writer for ``path``: CSV for .csv/.csv.gz, else a bag directory."""
    from gyro_emulator.analysis import simulate

    if str(path).endswith(('.csv', '.csv.gz')):
        return simulate.write_simulation_csv
    import functools

    from gyro_emulator.analysis import replay
    custom = None if args is None else replay.simulation_custom_data(
        args.config, args.profile, args.duration_s, args.rate_hz, args.seed, args.temp_c)
    return functools.partial(replay.write_simulation_bag, config=config,
                             rate_hz=None if args is None else args.rate_hz,
                             custom_data=custom)


def run(args):
    """Run the simulation and write the record."""
    from gyro_emulator.analysis import simulate
    from gyro_emulator.sensor.config import load_sensor_config

    config = load_sensor_config(args.config)
    writer = _open_writer(args.out, args, config)
    total = simulate.sample_count(args.duration_s, args.rate_hz)
    chunks = simulate.iter_simulation(config, args.profile, args.duration_s, args.rate_hz,
                                      seed=args.seed, temp_c=args.temp_c)
    started = time.monotonic()
    with staged_output(args.out, args.overwrite) as partial:
        rows = writer(partial, chunks, progress=Progress(), total=total)
    print(f'wrote {args.out}: {rows} samples at {args.rate_hz:g} Hz '
          f'({args.duration_s:g} s, profile {args.profile}, config {args.config}) in '
          f'{time.monotonic() - started:.1f} s')
    return 0
