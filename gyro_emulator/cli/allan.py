"""
Allan deviation of a gyro record and its IEEE Std 952 noise identification.

Reads a CSV with ``time_s`` and ``gyro_rad_s`` or ``gyro_{x,y,z}_rad_s``
(``.csv.gz`` too; our ``simulate`` output and measured logs alike), or a
rosbag2 MCAP bag (directory or ``.mcap``) with a sensor_msgs/Imu topic. The
samples are taken as uniformly spaced at the median time step (repeated
timestamps of a jittery logger are accepted); a step longer than
``--gap-factor`` times the median is a gap, and the Allan variance is then
pooled over the contiguous segments.

The short-tau region shaped by an output filter or band-limiting is found
from the PSD (or the slope) and left out; the five IEEE Std 952 terms are
fitted above it, each with its confidence interval, and printed beside the
read-offs (tangent lines), with a warning where the fitted curve and the
measured one disagree.

Units: N (angle random walk) in deg/sqrt(h), B (bias instability, Allan floor
0.664 B) in deg/h, K (rate random walk) in deg/h/sqrt(h), Q (quantisation)
in urad, R (rate ramp) in deg/h/h.
"""

import math
import os
import sys

from gyro_emulator import outputs
from gyro_emulator.cli.jsonout import add_overwrite, write_json
from gyro_emulator.units import AXES

HELP = 'overlapping Allan deviation of a gyro record and its IEEE Std 952 noise terms'

_ROWS = (('quantization', 'Q (quantisation)     '), ('arw', 'N (ARW)              '),
         ('bias_instability', 'B (bias instability) '), ('rrw', 'K (rate random walk) '),
         ('rate_ramp', 'R (rate ramp)        '))
_READ = {'quantization': 'tau^-1 line at sqrt(3) s', 'arw': '-1/2 line at 1 s',
         'bias_instability': 'minimum / 0.664', 'rrw': '+1/2 line at 3 s',
         'rate_ramp': '+1 line at sqrt(2) s'}


def add_arguments(parser):
    """Register the ``allan`` options."""
    parser.add_argument('file', metavar='FILE',
                        help='CSV (time_s + gyro_rad_s or gyro_{x,y,z}_rad_s; .gz ok) '
                             'or an MCAP bag')
    parser.add_argument('--axis', choices=AXES, default=None,
                        help='axis of a 3-axis record (default: x)')
    parser.add_argument('--topic', default=None,
                        help='Imu topic of a bag (default: the only Imu topic)')
    parser.add_argument('--json', metavar='OUT', help='write the results as JSON')
    parser.add_argument('--plot', metavar='PNG', help='write the Allan deviation plot')
    add_overwrite(parser)
    parser.add_argument('--gap-factor', type=float, default=3.0, metavar='F',
                        help='a time step over F median steps is a gap; F > 1 '
                             '(default: %(default)s)')
    parser.add_argument('--max-tau-fraction', type=float, default=0.25, metavar='F',
                        help='longest tau as a fraction of the longest segment, '
                             'in (0, 0.5] (default: %(default)s)')
    add_outlier_arguments(parser)


def add_outlier_arguments(parser):
    """Register ``--keep-outliers`` (``allan`` and every ``calibrate`` command)."""
    parser.add_argument('--keep-outliers', action='store_true',
                        help='keep every sample (default: spikes and motion beyond 6 robust '
                             'sigma of their neighbours are set aside, and the output says '
                             'how many and when)')


def outlier_threshold(args):
    """Return the screening threshold the options ask for (``math.inf``: --keep-outliers)."""
    from gyro_emulator.analysis import outliers  # lazy: see run

    return math.inf if args.keep_outliers else outliers.THRESHOLD


def print_terms(info, out=None, indent='  ', labels=None):
    """
    Print the fitted terms, their intervals and read-offs of an ``analyse_record`` dict.

    ``labels`` names each term (``gyro_emulator.analysis.sense.Sense.labels``;
    default the gyro's).
    """
    out = sys.stdout if out is None else out
    fit = info['fit']
    lo, hi = fit['tau_range_s']
    print(f'{indent}fit over tau {lo:.3g} .. {hi:.4g} s, {100 * fit["ci"]:.0f} % intervals '
          f'(model discrepancy {100 * fit["misfit"]:.1f} %)', file=out)
    rows = _ROWS if labels is None else tuple((term, f'{labels[term]:<21}')
                                              for term, _ in _ROWS)
    for term, name in rows:
        row = fit['terms'][term]
        if term in ('quantization', 'rate_ramp') and not row['resolved']:
            continue
        low, high = row['interval']
        flag = '' if row['resolved'] else '  (not resolved: upper bound)'
        read = f'read-off {row["read_off"]:.4g} ({_READ[term]}, tau {row["read_off_tau_s"]:.3g} s)'
        if not row['read_off_identified']:
            read += ' upper bound'
        elif row['share_at_read_off'] is not None and row['share_at_read_off'] < 0.8:
            read += (f' upper bound: the term carries {100 * row["share_at_read_off"]:.0f} % '
                     'of the fitted variance there')
        print(f'{indent}fit  {name}{row["value"]:10.4g} [{low:.4g}, {high:.4g}] {row["unit"]}'
              f'{flag}; {read}', file=out)


def run(args):
    """Analyse the record, print the summary, write JSON and plot if asked."""
    # The analysis (scipy, numba: 0.9 s) is imported here, not at the top:
    # `gyro-emulator --help` imports every command module.
    from gyro_emulator.analysis import allan
    from gyro_emulator.recording.record import load_record

    outputs.check([outputs.file('--json', args.json), outputs.image('--plot', args.plot)],
                  inputs=[args.file], overwrite=args.overwrite)
    info, result, fit = allan.analyse_record(load_record(args.file, {'gyro': args.topic}),
                                             args.axis, args.max_tau_fraction, args.gap_factor,
                                             outlier_threshold=outlier_threshold(args))
    for note in info['recovery'] + info['timing']:
        print(f'gyro-emulator allan: warning: {note}', file=sys.stderr)
    print(f'{info["file"]} [{info["column"]}]: {info["n_samples"]} samples at '
          f'{info["sample_rate_hz"]:.4g} Hz, {info["duration_s"]:.1f} s, '
          f'{info["segments"]} segment(s), {info["repeated_timestamps"]} repeated '
          'timestamp(s)')
    print(f'  {info["set_aside"]["description"]}')
    print(f'  band limit: {fit.band.note}')
    print_terms(info)
    for warning in fit.warnings:
        print(f'gyro-emulator allan: warning: {warning}', file=sys.stderr)
    if args.json:
        write_json(args.json, info)
    if args.plot:
        os.makedirs(os.path.dirname(os.path.abspath(args.plot)), exist_ok=True)
        allan.plot_adev(result, fit, args.plot,
                        title=f'{os.path.basename(str(args.file))} [{info["column"]}]')
        print(f'wrote {args.plot}')
    return 0
