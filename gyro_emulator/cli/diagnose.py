"""
Diagnose a measured record against the paper's physics.

  gyro-emulator diagnose FILE.csv --json OUT.json --report DIR
  gyro-emulator diagnose BAG_DIR --gyro-topic imu/data_raw --axis z ...

FILE is a CSV with columns time_s, rate_cmd_rad_s, temp_c, gyro_rad_s and
optionally accel_x_m_s2, accel_y_m_s2, accel_z_m_s2; or a rosbag2 MCAP bag
(directory or .mcap file), whose topics are mapped with the --*-topic
options. The baseline is the paper's first-order model calibrated with one
bias and one scale factor at the reference temperature; every candidate
cause is fitted and judged on held-out blocks; the best significant one is
named, with its parameters and the held-out gain.
"""

import sys

from gyro_emulator.cli.jsonout import write_json
from gyro_emulator.recording import topics

HELP = 'find what the physics model gets wrong in measured data, name the cause'


def add_arguments(parser):
    """Register the ``diagnose`` options."""
    from gyro_emulator.physics.presets import PHYSICS_PRESETS

    parser.add_argument('input', metavar='FILE',
                        help='measured CSV, or a rosbag2 MCAP bag directory / .mcap')
    parser.add_argument('--json', metavar='OUT', help='write the findings as JSON')
    parser.add_argument('--report', metavar='DIR',
                        help='write report.md and residual PNGs into DIR')
    parser.add_argument('--preset', default='paper', choices=sorted(PHYSICS_PRESETS),
                        help='physics preset of the baseline device (default: %(default)s)')
    parser.add_argument('--ref-temp', type=float, default=None, metavar='C',
                        help="calibration temperature, deg C (default: the device's, 25 C)")
    parser.add_argument('--folds', type=int, default=6,
                        help='contiguous cross-validation blocks (default: %(default)s)')
    parser.add_argument('--effects', default=None, metavar='LIST',
                        help='comma-separated catalogue entries to test (default: all)')
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
    bag.add_argument('--axis', default='z', choices=('x', 'y', 'z'),
                     help='sense axis (default: %(default)s)')


def run(args):
    """Load the record, diagnose it, print the verdict, write JSON/report."""
    from gyro_emulator.analysis.diagnose import data, diagnose, report

    record = data.load_measured(args.input, rate_topic=args.rate_topic,
                                temp_topic=args.temp_topic, gyro_topic=args.gyro_topic,
                                accel_topic=args.accel_topic, axis=args.axis)
    for note in record.recovery:
        print(f'gyro-emulator diagnose: warning: {note}', file=sys.stderr)
    effects = None if args.effects is None else [
        e.strip() for e in args.effects.split(',') if e.strip()]
    result = diagnose(record, preset=args.preset, ref_temp_c=args.ref_temp,
                      folds=args.folds, effects=effects)
    doc = result.doc
    best = doc['best']
    print(f"{record.rows} samples, {doc['input']['duration_s']:.0f} s; baseline "
          f"held-out RMSE {doc['baseline']['rmse_rad_s']:.4g} rad/s")
    print(f"best: {best['effect']}  RMSE {best['rmse_rad_s']:.4g} rad/s  "
          f"gain {100 * best['gain']:.1f} %")
    if best['cause']:
        print(f"cause: {best['cause']}")
    for name, p in best['parameters'].items():
        print(f"  {name} = {p['value']:.5g} +- {p['sigma']:.2g} {p['unit']}")
    print(doc['residual']['message'])
    for f in doc['findings']:
        print(f"  {f['effect']:<26} gain {100 * f['gain']:7.2f} %  "
              f"p {f['p_value']:.1e}  dBIC {f['delta_bic']:9.0f}  "
              f"{'significant' if f['significant'] else ''}")
    for nt in doc['not_tested']:
        print(f"  {nt['effect']:<26} not tested: {nt['reason']}")
    if args.json:
        write_json(args.json, doc)
    if args.report:
        print(f'wrote {report.write_report(result, args.report)}')
    return 0
