"""
Allan deviation of a gyro record, with the N (ARW), B and K noise fit.

Reads a CSV with ``time_s`` and ``gyro_rad_s`` or ``gyro_{x,y,z}_rad_s``
(``.csv.gz`` too; our ``simulate`` output and measured logs alike), or a
rosbag2 MCAP bag (directory or ``.mcap``) with a sensor_msgs/Imu topic. The
samples are taken as uniformly spaced at the median time step (repeated
timestamps of a jittery logger are accepted); a step longer than
``--gap-factor`` times the median is a gap, and the Allan variance is then
pooled over the contiguous segments.

Units: N (angle random walk) in deg/sqrt(h), B (bias instability, Allan floor
0.664 B) in deg/h, K (rate random walk) in deg/h/sqrt(h) (IEEE Std 952).
"""

import os
import sys

from gyro_emulator.cli.jsonout import write_json

HELP = 'overlapping Allan deviation of a gyro record and its N, B, K fit'


def add_arguments(parser):
    """Register the ``allan`` options."""
    parser.add_argument('file', metavar='FILE',
                        help='CSV (time_s + gyro_rad_s or gyro_{x,y,z}_rad_s; .gz ok) '
                             'or an MCAP bag')
    parser.add_argument('--axis', choices=('x', 'y', 'z'), default=None,
                        help='axis of a 3-axis record (default: x)')
    parser.add_argument('--topic', default=None,
                        help='Imu topic of a bag (default: the only Imu topic)')
    parser.add_argument('--json', metavar='OUT', help='write the results as JSON')
    parser.add_argument('--plot', metavar='PNG', help='write the Allan deviation plot')
    parser.add_argument('--gap-factor', type=float, default=3.0, metavar='F',
                        help='a time step over F median steps is a gap '
                             '(default: %(default)s)')
    parser.add_argument('--max-tau-fraction', type=float, default=0.25, metavar='F',
                        help='longest tau as a fraction of the longest segment '
                             '(default: %(default)s)')


def run(args):
    """Analyse the record, print the summary, write JSON and plot if asked."""
    from gyro_emulator.analysis import allan

    info, result, fit = allan.analyse_record(args.file, args.axis, args.topic,
                                             args.max_tau_fraction, args.gap_factor)
    for note in info['recovery']:
        print(f'gyro-emulator allan: warning: {note}', file=sys.stderr)
    print(f'{info["file"]} [{info["column"]}]: {info["n_samples"]} samples at '
          f'{info["sample_rate_hz"]:.4g} Hz, {info["duration_s"]:.1f} s, '
          f'{info["segments"]} segment(s), {info["repeated_timestamps"]} repeated '
          'timestamp(s)')
    print(f'  fit  N (ARW)              {info["arw_deg_sqrt_h"]:10.4g} deg/sqrt(h)')
    print(f'  fit  B (bias instability) {info["bias_instability_deg_h"]:10.4g} deg/h')
    print(f'  fit  K (rate random walk) {info["rrw_deg_h_sqrt_h"]:10.4g} deg/h/sqrt(h)')
    print(f'  read ADEV(1 s) sqrt(1 s)  {info["arw_at_1s_deg_sqrt_h"]:10.4g} deg/sqrt(h)')
    print(f'  read min ADEV / 0.664     {info["bias_instability_min_deg_h"]:10.4g} deg/h '
          f'at tau = {info["tau_at_min_s"]:.4g} s')
    if args.json:
        write_json(args.json, info)
    if args.plot:
        os.makedirs(os.path.dirname(os.path.abspath(args.plot)), exist_ok=True)
        allan.plot_adev(result, fit, args.plot,
                        title=f'{os.path.basename(str(args.file))} [{info["column"]}]')
        print(f'wrote {args.plot}')
    return 0
