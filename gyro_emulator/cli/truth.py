r"""
Write a simulated measured CSV with hidden effects (for diagnose demos and tests).

  gyro-emulator truth OUT.csv --effect random --seed 7 --answer OUT.answer.json
  gyro-emulator truth OUT.csv --effect bias_temperature --profile thermal_ramp \\
      --rate 1 --duration 266400 --outliers spikes

The record is the output of GyroModel configured as the paper's device with
a random calibration error, the hidden effects (none, one of the diagnose
catalogue or beyond it, or several joined by +) with random magnitudes, a
seeded profile (lab: soaks, ramps, rate-table steps, swept sines, tilts;
paper: the paper's validation experiment; thermal_ramp / thermal_cycle: a
static part in a chamber; static: an Allan run), white noise, bias
instability and rate random walk, and optionally outliers (logger spikes,
handling motion). The CSV holds only the diagnose contract columns; the
hidden truth goes to --answer (or stays hidden).
"""

import os

from gyro_emulator import outputs
from gyro_emulator.cli.jsonout import add_overwrite, write_json
from gyro_emulator.emulation.truth import SAMPLED_PROFILES
from gyro_emulator.emulation.truth.effects import TRUTH_EFFECTS
from gyro_emulator.validation import check_range

HELP = 'write a simulated measured CSV with hidden effects'


def add_arguments(parser):
    """Register the ``truth`` options."""
    parser.add_argument('output', metavar='OUT.csv', help='CSV to write')
    parser.add_argument('--effect', default='random', metavar='E[+E...]',
                        help='hidden effect(s): random (drawn from the seed), '
                             f'{", ".join(TRUTH_EFFECTS)}, or several joined by + '
                             '(default: %(default)s)')
    parser.add_argument('--seed', type=int, default=0, help='random seed (default: 0)')
    parser.add_argument('--profile', default='lab', choices=SAMPLED_PROFILES,
                        help='test profile (default: %(default)s)')
    parser.add_argument('--rate', type=float, default=25.0, metavar='HZ',
                        help='sample rate, Hz (default: %(default)s)')
    parser.add_argument('--duration', type=float, default=None, metavar='S',
                        help='length of the thermal and static profiles, or a cut of the lab '
                             'profile, s (default: drawn)')
    parser.add_argument('--outliers', default=None, metavar='KINDS',
                        help='spikes, motion or spikes+motion (default: none)')
    parser.add_argument('--no-temperature', action='store_true',
                        help='leave the temperature column out (a log without it)')
    parser.add_argument('--set', action='append', default=[], metavar='NAME=VALUE',
                        help='fix an effect parameter, e.g. sutherland_constant_k=110.4')
    parser.add_argument('--answer', metavar='FILE',
                        help='write the hidden truth (effects, parameters) as JSON here')
    add_overwrite(parser)


def run(args):
    """Simulate and write the CSV (and the answer if asked)."""
    # The generator and the writer (scipy, numba: 1.5 s) are imported here,
    # not at the top: `gyro-emulator --help` imports every command module.
    from gyro_emulator.analysis.diagnose import write_measured_csv
    from gyro_emulator.emulation.truth.generator import make_truth

    check_range('truth', 'rate', args.rate, 1e-3, 2000.0, 'Hz')
    outputs.check([outputs.file('OUT.csv', args.output), outputs.file('--answer', args.answer)],
                  overwrite=args.overwrite)
    params = {}
    for item in args.set:
        name, sep, value = item.partition('=')
        if not sep:
            raise ValueError(f'truth --set {item!r}: expected NAME=VALUE')
        params[name.strip()] = check_range('truth', name.strip(), value, None, None)
    data, truth = make_truth(args.effect, args.seed, profile=args.profile,
                             sample_rate_hz=args.rate, params=params, duration_s=args.duration,
                             outliers=args.outliers,
                             record_temperature=not args.no_temperature)
    directory = os.path.dirname(os.path.abspath(args.output))
    os.makedirs(directory, exist_ok=True)
    write_measured_csv(args.output, data)
    print(f'wrote {args.output}: {len(data.time_s)} samples, {truth["duration_s"]:.0f} s '
          f'({truth["profile"]} profile, seed {args.seed}); the effect is hidden')
    if args.answer:
        write_json(args.answer, truth)
    return 0
