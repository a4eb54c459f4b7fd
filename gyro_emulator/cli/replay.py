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

import os
import sys

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
    parser.add_argument('--overwrite', action='store_true',
                        help='replace an existing output in DIR')


def run(args):
    """Replay the bag through the model, write the bag and the report."""
    from gyro_emulator.analysis import replay
    from gyro_emulator.recording import bag
    from gyro_emulator.sensor.config import load_sensor_config

    reader = bag.BagReader(args.bag, tolerant=True)
    for note in reader.problems:
        print(f'replay: warning: incomplete bag, {note}', file=sys.stderr)
    bag_dir = os.path.join(args.out, 'emulated')
    if os.path.isdir(bag_dir) and os.listdir(bag_dir) and not args.overwrite:
        raise FileExistsError(f'{bag_dir} exists and is not empty (pass --overwrite)')
    config_name = args.config or reader.custom_data.get('sensor_config', 'paper')
    seed = args.seed if args.seed is not None else int(reader.custom_data.get('seed', 0))
    config = load_sensor_config(config_name)
    shown = list(reader.problems)
    inputs = replay.load_inputs(
        reader, args.source, args.rate_topic, args.temperature_topic, args.accel_topic,
        args.measured_topic, args.rate_hz, args.temp_c, args.use_log_time)
    for note in reader.problems[len(shown):]:
        print(f'replay: warning: {note}', file=sys.stderr)
    _, batch = replay.emulate(inputs, config, seed)
    comparison = replay.compare(inputs, batch)
    header = [f'bag: {os.path.abspath(args.bag)}', f'sensor config: {config_name}',
              f'seed: {seed}'] + [f'recovered: {note}' for note in reader.problems]
    sigma = replay.white_noise_sigma(config, inputs.rate_hz)
    replay.write_output_bag(bag_dir, inputs, batch, comparison, sigma, custom_data={
        'generator': 'gyro-emulator replay', 'source_bag': os.path.abspath(args.bag),
        'sensor_config': str(config_name), 'seed': str(seed),
        'rate_hz': repr(inputs.rate_hz), 'source': inputs.source})
    paths = replay.write_report(args.out, comparison, inputs, header,
                                plots=not args.no_plots)
    print(replay.report_text(comparison, inputs, header), end='')
    print(f'wrote {bag_dir} ({len(inputs.stamp_ns)} samples)')
    for path in paths:
        print(f'wrote {path}')
    return 0
