"""
Drive the emulator offline from a bag and compare it with what was measured.

Sources (``--source``, default auto):

  command   our own bags: cmd/angular_velocity (+ cmd/temperature,
            cmd/linear_acceleration) drive the model; imu/data_raw is the
            measured output (a node recording or ``simulate --out``)
  imu       a real robot's sensor_msgs/Imu: its angular_velocity is the true
            rate, one emulated sample per message; the IMU itself is the
            measured output; the ambient comes from --temperature-topic or
            --temp-c

Writes DIR/emulated (a rosbag2 MCAP bag: inputs, emulated imu/data_raw,
truth, /replay/measured and /replay/residual), DIR/report.md and
DIR/report.json (residual statistics per axis), and rates.png, residual.png,
allan.png (Allan deviation overlay). The same bag, config and seed give the
identical decoded output.
"""

import sys

from gyro_emulator import outputs
from gyro_emulator.cli.jsonout import add_overwrite

HELP = 'drive the emulator offline from a bag; write an output bag and a report'


def add_arguments(parser):
    """Register the ``replay`` options."""
    parser.add_argument('bag', metavar='BAG', help='bag directory or .mcap file')
    parser.add_argument('--out', required=True, metavar='DIR',
                        help='output directory (emulated bag, report, plots)')
    parser.add_argument('--config', default=None, metavar='YAML|NAME',
                        help='sensor preset or YAML (default: the bag custom_data '
                             'sensor_config, else paper)')
    parser.add_argument('--seed', type=int, default=None, metavar='N',
                        help='random seed (default: the bag custom_data seed, else 0)')
    parser.add_argument('--source', choices=('auto', 'command', 'imu'), default='auto',
                        help='what drives the model (default: %(default)s)')
    parser.add_argument('--rate-topic', metavar='TOPIC', default=None,
                        help='rate commands (Vector3Stamped) or the Imu taken as truth')
    parser.add_argument('--temperature-topic', metavar='TOPIC', default=None,
                        help='ambient temperature (sensor_msgs/Temperature)')
    parser.add_argument('--accel-topic', metavar='TOPIC', default=None,
                        help='specific force commands (Vector3Stamped)')
    parser.add_argument('--measured-topic', metavar='TOPIC', default=None,
                        help='measured gyro output (sensor_msgs/Imu) to compare with')
    parser.add_argument('--rate-hz', type=float, default=None, metavar='R',
                        help='model sample rate, Hz (default: from the bag)')
    parser.add_argument('--temp-c', type=float, default=None, metavar='C',
                        help='ambient when the bag has no temperature, deg C (default 25)')
    parser.add_argument('--use-log-time', action='store_true',
                        help='use receive times instead of header stamps')
    parser.add_argument('--no-plots', action='store_true', help='skip the PNG plots')
    add_overwrite(parser, text='replace existing outputs in DIR (default: refuse them, before '
                               'any work)')


def run(args):
    """Replay the bag through the model, write the bag and the report."""
    from gyro_emulator.analysis.replay.run import OUTPUTS, replay_bag
    from gyro_emulator.sensor.config import config_source

    outputs.check([outputs.inside('--out', args.out, OUTPUTS)],
                  inputs=[args.bag, config_source(args.config)],
                  overwrite=args.overwrite)
    run = replay_bag(
        args.bag, args.out, config=args.config, seed=args.seed, plots=not args.no_plots,
        overwrite=args.overwrite,
        warn=lambda note: print(f'replay: warning: {note}', file=sys.stderr),
        source=args.source, rate_topic=args.rate_topic,
        temperature_topic=args.temperature_topic, accel_topic=args.accel_topic,
        measured_topic=args.measured_topic, rate_hz=args.rate_hz, temp_c=args.temp_c,
        use_log_time=args.use_log_time)
    print(run.report, end='')
    print(f'wrote {run.bag_dir} ({run.samples} samples)')
    for path in run.paths:
        print(f'wrote {path}')
    return 0
