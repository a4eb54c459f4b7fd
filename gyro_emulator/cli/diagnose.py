"""
Diagnose a measured record against the paper's physics.

  gyro-emulator diagnose FILE.csv --json OUT.json --report DIR
  gyro-emulator diagnose static_log.csv.gz --static --axis x
  gyro-emulator diagnose BAG_DIR --gyro-topic imu/data_raw --axis z ...

FILE is a CSV with columns time_s, rate_cmd_rad_s (or simulate's
rate_x/y/z_rad_s), temp_c (optional), gyro_rad_s (or gyro_x/y/z_rad_s with
--axis) and optionally accel_x_m_s2,
accel_y_m_s2, accel_z_m_s2; --static reads a log of a part at rest that has
no rate column. A rosbag2 MCAP bag (directory or .mcap file) has its topics
mapped with the --*-topic options. Outliers are set aside, then causes are
added one by one while each gives a significant held-out gain; the verdict
says whether the residual is at the record's own noise floor, what cannot
be told apart and which experiment would separate it.
"""

# (The docstring above is the command's --help text.) The options become one
# gyro_emulator.analysis.diagnose.command.Request; command.execute does the
# rest and speaks through Console.

import sys

from gyro_emulator.cli.jsonout import add_overwrite, write_json
from gyro_emulator.physics.presets import PHYSICS_PRESETS
from gyro_emulator.recording import topics
from gyro_emulator.units import AXES

HELP = 'find what the physics model gets wrong in measured data, name the cause'


def add_arguments(parser):
    """Register the ``diagnose`` options."""
    parser.add_argument('input', metavar='FILE',
                        help='measured CSV (.csv or .csv.gz), or a rosbag2 MCAP bag directory / '
                             '.mcap')
    parser.add_argument('--json', metavar='OUT', help='write the findings as JSON')
    parser.add_argument('--report', metavar='DIR',
                        help='write report.md and residual PNGs into DIR')
    parser.add_argument('--config', metavar='NAME|FILE', default=None,
                        help='baseline: the deterministic output (noise off) of this sensor '
                             "config (preset or YAML) on the record's inputs, with the user's "
                             'bias and scale-factor calibration (default: the paper physics '
                             'of --preset)')
    parser.add_argument('--write-config', metavar='OUT.yaml', default=None,
                        help='write the starting config (--config, else the paper preset) plus '
                             'every selected cause as a sensor YAML the emulator loads '
                             '(extended terms, fitted values, provenance comments)')
    parser.add_argument('--noise', action='store_true',
                        help="with --write-config: also write the record's noise terms (N, B, "
                             'K, turn-on bias, LSB of the diagnosed axis), from the IEEE 952 '
                             'fit of calibrate noise on the record minus the written model '
                             "(default: the starting config's noise stays)")
    add_overwrite(parser, text='replace existing outputs (--json, the --report files, '
                               '--write-config; default: refuse them, before any work)')
    parser.add_argument('--axis', default=None, choices=AXES,
                        help='sense axis: the gyro_<axis>_rad_s column of a 3-axis CSV, or the '
                             'axis of a bag (default: gyro_rad_s; z for a bag)')
    parser.add_argument('--static', action='store_true',
                        help='the part was at rest: a CSV without rate_cmd_rad_s has zero '
                             'applied rate')
    parser.add_argument('--preset', default='paper', choices=sorted(PHYSICS_PRESETS),
                        help='physics preset of the baseline device (default: %(default)s)')
    parser.add_argument('--ref-temp', type=float, default=None, metavar='C',
                        help="calibration temperature, deg C (default: the device's, 25 C)")
    parser.add_argument('--folds', type=int, default=8,
                        help='contiguous cross-validation blocks (default: %(default)s)')
    parser.add_argument('--alpha', type=float, default=0.01,
                        help='chance that a record with no effect gets a cause, per '
                             'selection step (default: %(default)s)')
    parser.add_argument('--outlier-sigma', type=float, default=6.0, metavar='K',
                        help="set aside samples beyond K robust sigma; 'inf' keeps every "
                             'sample (default: %(default)s)')
    parser.add_argument('--max-causes', type=int, default=4,
                        help='most causes to add (default: %(default)s)')
    parser.add_argument('--effects', default=None, metavar='LIST',
                        help='comma-separated candidate causes to test (default: all)')
    parser.add_argument('--reference', default=None, metavar='STATIC_LOG',
                        help='a second, static record of the same part (CSV or bag, the same '
                             '--axis): its noise (white, flicker, random walk) is measured '
                             'there and held fixed in the null, so that a slow effect cannot '
                             'hide in the wander it inflates')
    bag = parser.add_argument_group('bag input (topic mapping)')
    bag.add_argument('--rate-topic', default=topics.RATE_CMD.name,
                     help='applied rate topic (default: %(default)s)')
    bag.add_argument('--temp-topic', default=topics.TEMPERATURE_CMD.name,
                     help='temperature topic (default: %(default)s)')
    bag.add_argument('--gyro-topic', default=topics.IMU_OUT.name,
                     help='measured output topic (default: %(default)s)')
    bag.add_argument('--accel-topic', default=None,
                     help=f'acceleration topic (default: {topics.ACCEL_CMD.name} if '
                          "present; 'none' to ignore)")


class Console:
    """The terminal and the command line's JSON writer, as the diagnose run speaks to them."""

    @staticmethod
    def out(line):
        """Print a line on stdout."""
        print(line)

    @staticmethod
    def err(line):
        """Print a line on stderr."""
        print(line, file=sys.stderr)

    @staticmethod
    def write_json(path, doc):
        """Write ``doc`` as the command line writes JSON (:mod:`gyro_emulator.cli.jsonout`)."""
        write_json(path, doc)


def request(args):
    """Return the :class:`~gyro_emulator.analysis.diagnose.command.Request` of the options."""
    # The analysis is imported here, not at the top: `gyro-emulator --help`
    # imports every command module.
    from gyro_emulator.analysis.diagnose.command import Request

    effects = None if args.effects is None else tuple(
        e.strip() for e in args.effects.split(',') if e.strip())
    return Request(
        source=args.input, rate_topic=args.rate_topic, temp_topic=args.temp_topic,
        gyro_topic=args.gyro_topic, accel_topic=args.accel_topic, axis=args.axis,
        static=args.static, preset=args.preset, config=args.config, ref_temp_c=args.ref_temp,
        folds=args.folds, effects=effects, alpha=args.alpha, outlier_sigma=args.outlier_sigma,
        max_causes=args.max_causes, json=args.json, report=args.report,
        write_config=args.write_config, noise=args.noise, overwrite=args.overwrite,
        reference=args.reference)


def run(args):
    """Diagnose the record the options name: print the verdict, write JSON, report, config."""
    from gyro_emulator.analysis.diagnose import command

    asked = request(args)
    command.execute(asked, Console)
    return 0
