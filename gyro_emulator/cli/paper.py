"""
Reproduce the paper: Table 1 side by side, Fig 5 and Fig 6 as PNGs.

Table 1 compares our first-order physics (Eq 5-21) for the paper's device at
25 C, 1 atm and 60 deg/s with the values the paper prints. Fig 6 overlays the
viscosity variants so the effect of the constant-viscosity assumption shows.
"""

import os

from gyro_emulator.cli.jsonout import write_json

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


def run(args):
    """Print Table 1, write the figures and optionally the JSON."""
    from gyro_emulator.physics import paper

    rows = paper.table1_rows()
    print('Table 1 (25 C, 1 atm, 60 deg/s): ours vs paper')
    print(paper.format_table1(rows))
    worst = max(rows, key=lambda r: abs(r[5]))
    print(f'largest |error|: {worst[0]} {worst[5]:+.3f} %')
    temps, rate = paper.fig6_data(viscosity_law='constant')
    temps_s, rate_s = paper.fig6_data(viscosity_law='sutherland')
    print(f'Fig 6 at 85 C (true 60 deg/s): {rate[-1]:.3f} deg/s with constant '
          f'viscosity (paper: 61.8..62.0); {rate_s[-1]:.3f} deg/s with '
          f"Sutherland's law")
    if not args.no_plots:
        os.makedirs(args.out_dir, exist_ok=True)
        for name, plot in (('fig5.png', paper.plot_fig5),
                           ('fig6.png', paper.plot_fig6)):
            path = os.path.join(args.out_dir, name)
            plot(path)
            print(f'wrote {path}')
    if args.json:
        write_json(args.json, paper.paper_json())
    return 0
