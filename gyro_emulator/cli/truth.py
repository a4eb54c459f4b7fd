"""
Write a simulated measured CSV with one hidden effect (for diagnose demos).

  gyro-emulator truth OUT.csv --effect random --seed 7 --answer OUT.answer.json

The record is the paper's first-order physics with a random calibration
error, ONE effect of the diagnose catalogue (or none) with a random
magnitude, a seeded random lab profile (soaks, ramps, rate-table steps,
swept sines, tilt positions) and noise. The CSV holds only the diagnose
contract columns; the hidden effect goes to --answer (or stays hidden).
``--profile paper`` simulates the paper's validation experiment (0, 10, 20,
40 RPM at 25..85 C).
"""

import os

from gyro_emulator.cli.jsonout import write_json

HELP = 'write a simulated measured CSV with one hidden effect'


def add_arguments(parser):
    """Register the ``truth`` options."""
    from gyro_emulator.analysis.diagnose.truth import PROFILES, TRUTH_EFFECTS

    parser.add_argument('output', metavar='OUT.csv', help='CSV to write')
    parser.add_argument('--effect', default='random',
                        choices=('random',) + TRUTH_EFFECTS,
                        help='hidden effect (default: %(default)s, drawn from the seed)')
    parser.add_argument('--seed', type=int, default=0, help='random seed (default: 0)')
    parser.add_argument('--profile', default='lab', choices=PROFILES,
                        help='test profile (default: %(default)s)')
    parser.add_argument('--rate', type=float, default=25.0, metavar='HZ',
                        help='sample rate, Hz (default: %(default)s)')
    parser.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                        help='fix an effect parameter, e.g. sutherland_constant_k=110.4')
    parser.add_argument('--answer', metavar='FILE',
                        help='write the hidden truth (effect, parameters) as JSON here')


def run(args):
    """Simulate and write the CSV (and the answer if asked)."""
    from gyro_emulator.analysis.diagnose import make_truth, write_measured_csv
    from gyro_emulator.validation import check_range

    check_range('truth', 'rate', args.rate, 1.0, 2000.0, 'Hz')
    params = {}
    for item in args.set:
        name, sep, value = item.partition('=')
        if not sep:
            raise ValueError(f'truth --set {item!r}: expected NAME=VALUE')
        params[name.strip()] = check_range('truth', name.strip(), value, None, None)
    data, truth = make_truth(args.effect, args.seed, profile=args.profile,
                             sample_rate_hz=args.rate, params=params)
    directory = os.path.dirname(os.path.abspath(args.output))
    os.makedirs(directory, exist_ok=True)
    write_measured_csv(args.output, data)
    print(f'wrote {args.output}: {data.rows} samples, {truth["duration_s"]:.0f} s '
          f'({truth["profile"]} profile, seed {args.seed}); the effect is hidden')
    if args.answer:
        write_json(args.answer, truth)
    return 0
