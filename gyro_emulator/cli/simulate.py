"""
Simulate the gyro over a scripted profile and write the record as CSV.

Profiles: ``static`` (zero rate), ``steps`` (rate table about z at 0, 10, 20,
40 RPM and back to 0), ``temp-ramp`` (60 deg/s about z while the ambient goes
from 25 to 85 C, the paper's Fig 6 conditions) or a YAML profile file (see
``gyro_emulator.emulation.profiles``), or a measured record (CSV, CSV.gz or
rosbag2 bag: its applied rate, temperature and acceleration on its own
times, the output at its sample times; ``--static`` for a record without a
rate; ``gyro_emulator.emulation.recorded_profile``). The CSV columns are time_s, rate_{x,y,z}_rad_s
(true rate), temp_c (ambient), gyro_{x,y,z}_rad_s (sensor output) and
accel_{x,y,z}_m_s2 (the accelerometer's output).
An ``--out`` path not ending in .csv/.csv.gz is a rosbag2 MCAP bag directory
with the node's topics (see ``gyro_emulator.analysis.replay``), stamped from
``--start-time`` (default: now).
"""

import sys
import time

from gyro_emulator import outputs, validation
from gyro_emulator.units import AXES

HELP = 'simulate the sensor over a scripted profile and write CSV or a rosbag2 bag'

#: Show progress when a run has at least this many samples.
PROGRESS_MIN_SAMPLES = 200_000
#: Duration (s) and output rate (Hz) of a scripted profile when not given.
DURATION_S, RATE_HZ = 60.0, 200.0


def add_arguments(parser):
    """Register the ``simulate`` options."""
    parser.add_argument('--config', default='paper', metavar='YAML|NAME',
                        help='sensor preset (paper, consumer, tactical) or YAML file '
                             '(default: %(default)s)')
    parser.add_argument('--profile', default='static', metavar='PROFILE',
                        help='static, steps, temp-ramp, a YAML profile, or a measured '
                             'record (.csv, .csv.gz, bag): its inputs on its own times, the '
                             'output at its sample times (--duration-s and --rate-hz are '
                             "the record's) (default: %(default)s)")
    parser.add_argument('--axis', default='z', choices=AXES,
                        help="a measured profile: the sense axis of a CSV's single "
                             'rate_cmd_rad_s column (default: %(default)s)')
    parser.add_argument('--topic', default=None, metavar='TOPIC',
                        help='a measured bag profile: the Imu topic whose stamps are the '
                             "sample times (default: the bag's only Imu topic with messages)")
    parser.add_argument('--static', action='store_true',
                        help='a measured profile without an applied rate: the part was at '
                             'rest (zero rate); without it such a record is refused')
    # None: not given (a measured profile refuses them; a scripted one takes the defaults)
    parser.add_argument('--duration-s', type=float, default=None, metavar='S',
                        help=f'duration, s (default: {DURATION_S})')
    parser.add_argument('--rate-hz', type=float, default=None, metavar='R',
                        help=f'output data rate, Hz (default: {RATE_HZ})')
    parser.add_argument('--temp-c', type=float, default=25.0, metavar='C',
                        help='ambient of the static and steps profiles, and of a measured '
                             'profile without a temperature, deg C (default: %(default)s)')
    parser.add_argument('--seed', type=int, default=0, metavar='N',
                        help='random seed (default: %(default)s)')
    parser.add_argument('--out', required=True, metavar='FILE.csv|DIR',
                        help='output CSV (.csv or .csv.gz), or else a rosbag2 MCAP bag '
                             'directory in the emulator topic layout')
    parser.add_argument('--overwrite', action='store_true',
                        help='replace an existing output (default: refuse)')
    parser.add_argument('--faults', metavar='FILE.yaml',
                        help='inject the faults: list of a YAML file (a scenario, a '
                             'profile, or only faults:), times from the start of the record '
                             '(see gyro_emulator.sensor.faults)')
    parser.add_argument('--start-time', default='now', metavar='WHEN',
                        help='bag time of the first sample: now, seconds since the epoch '
                             '(0 = 1970) or an ISO 8601 date-time, UTC unless it says '
                             'otherwise (default: %(default)s)')


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


def _refuse_own_timing(args):
    """Refuse --duration-s and --rate-hz with a measured profile: it runs on the record's."""
    for option, value in (('--duration-s', args.duration_s), ('--rate-hz', args.rate_hz)):
        if value is not None:
            raise ValueError(f'simulate: {option} {value:g} is for a scripted --profile: a '
                             'measured record runs at its own rate and length '
                             f'({args.profile}); drop {option}')


def run(args):
    """Run the simulation and write the record."""
    # The sensor model (numba: 1.4 s, 2.5 s cold) is imported here, not at the
    # top: `gyro-emulator --help` imports every command module.
    from gyro_emulator.emulation import recorded_profile, simulate
    from gyro_emulator.sensor import faults
    from gyro_emulator.sensor.config import config_source

    started = time.monotonic()
    validation.check_ambient_c(args.temp_c)
    outputs.check([simulate.output(args.out)],
                  inputs=[config_source(args.config), args.profile, args.faults],
                  overwrite=args.overwrite)
    profile, measured = args.profile, recorded_profile.is_record_path(args.profile)
    if measured:
        _refuse_own_timing(args)
        profile = recorded_profile.recorded_profile(
            args.profile, args.axis, args.static, args.temp_c,
            topics=recorded_profile.default_topics(args.topic))
        for note in profile.notes:
            print(f'simulate: note: {note}', file=sys.stderr)
    elif args.static:
        raise ValueError('simulate: --static is for a measured --profile without an applied '
                         "rate; the built-in profile 'static' is zero rate")
    elif args.topic:
        raise ValueError(f'simulate: --topic is for a measured bag --profile; {args.profile!r} '
                         'is not a record')
    if not measured:
        args.duration_s = DURATION_S if args.duration_s is None else args.duration_s
        args.rate_hz = RATE_HZ if args.rate_hz is None else args.rate_hz
    start_ns = simulate.parse_start_time(args.start_time)
    schedule = faults.load_schedule(args.faults) if args.faults else ()
    rows = simulate.write_record(args.out, args.config, profile, args.duration_s,
                                 args.rate_hz, seed=args.seed, temp_c=args.temp_c,
                                 overwrite=args.overwrite, progress=Progress(),
                                 start_time_ns=start_ns, faults=schedule)
    rate_hz, duration_s = ((profile.rate_hz, profile.duration_s) if measured
                           else (args.rate_hz, args.duration_s))
    print(f'wrote {args.out}: {rows} samples at {rate_hz:g} Hz '
          f'({duration_s:g} s, profile {args.profile}, config {args.config}) in '
          f'{time.monotonic() - started:.1f} s')
    return 0
