"""
Reproduce the paper: Table 1 side by side, Fig 5 and Fig 6 as PNGs.

Table 1 compares our first-order physics (Eq 5-21) for the paper's device at
25 C, 1 atm and 60 deg/s with the values the paper prints. Fig 6 overlays the
viscosity variants so the effect of the constant-viscosity assumption shows.
"""

from gyro_emulator import outputs
from gyro_emulator.cli.jsonout import add_overwrite, write_json

HELP = "reproduce Patel & McCluskey's Table 1, Fig 5 and Fig 6"


def add_arguments(parser):
    """Register the ``paper`` options."""
    parser.add_argument('--json', metavar='FILE',
                        help='write Table 1 and the figure data as JSON')
    parser.add_argument('--out-dir', default='out/paper', metavar='DIR',
                        help='where to write fig5.png and fig6.png '
                             '(default: %(default)s)')
    parser.add_argument('--no-plots', action='store_true',
                        help='skip the PNG figures')
    add_overwrite(parser)


def run(args):
    """Print Table 1, write the figures and optionally the JSON."""
    # Imported here, as every command's work is: `gyro-emulator --help` imports
    # every command module (this one would cost it 2 ms).
    from gyro_emulator.physics import paper

    outputs.check([outputs.file('--json', args.json),
                   None if args.no_plots else outputs.inside('--out-dir', args.out_dir,
                                                             paper.FIGURES)],
                  overwrite=args.overwrite)
    print(paper.summary_text())
    if not args.no_plots:
        for path in paper.write_figures(args.out_dir):
            print(f'wrote {path}')
    if args.json:
        write_json(args.json, paper.paper_json())
    return 0
