"""
Exact 2-DOF response against the paper's first-order method, and rate dynamics.

For a drive-sense split S (Hz) and a true rate R (deg/s) this prints the
first-order sense amplitude (Eq 20), the exact harmonic solution of Eq 3-4,
the steady state of the time-domain simulation, and the rate channel's
bandwidth. ``--json`` writes the numbers; ``--plot DIR`` draws the sense
amplitude against split (-500..500 Hz), the rate step response and the
rate-channel Bode plot (time-domain points over the envelope model).

Example::

    gyro-emulator dynamics --split-hz 100 --json out/dynamics/split100.json
    gyro-emulator dynamics --split-hz 100 --plot out/dynamics
"""

import os

from gyro_emulator import outputs
from gyro_emulator.cli.jsonout import add_overwrite, write_json
from gyro_emulator.physics.presets import physics_preset
from gyro_emulator.units import deg_s_to_rad_s

HELP = 'exact 2-DOF response, time-domain simulation and rate-channel dynamics'


def add_arguments(parser):
    """Register the ``dynamics`` options."""
    parser.add_argument('--split-hz', type=float, default=0.0, metavar='S',
                        help='drive-sense split f_y - f_x in Hz (default: 0)')
    parser.add_argument('--rate-dps', type=float, default=60.0, metavar='R',
                        help='true rate in deg/s (default: 60, Table 1)')
    parser.add_argument('--temp-c', type=float, default=25.0, metavar='T',
                        help='die temperature in deg C (default: 25)')
    parser.add_argument('--preset', default='paper', metavar='NAME',
                        help='physics preset (default: %(default)s)')
    parser.add_argument('--json', metavar='FILE',
                        help='write the results as JSON')
    parser.add_argument('--plot', metavar='DIR',
                        help='write sense_vs_split.png, step_response.png and '
                             'rate_channel_bode.png into DIR')
    add_overwrite(parser)


#: The plots ``--plot DIR`` writes.
PLOTS = ('sense_vs_split.png', 'step_response.png', 'rate_channel_bode.png')


def run(args):
    """Print the summary; write JSON and plots when asked."""
    # The 2-DOF dynamics (0.2 s) are imported here, not at the top:
    # `gyro-emulator --help` imports every command module.
    from gyro_emulator.analysis import dynamics_report as report

    outputs.check([outputs.file('--json', args.json), outputs.inside('--plot', args.plot, PLOTS)],
                  overwrite=args.overwrite)
    device = physics_preset(args.preset)
    doc = report.summary(device, args.split_hz, args.rate_dps, args.temp_c)
    doc['preset'] = args.preset
    print(report.format_summary(doc))
    if args.plot:
        os.makedirs(args.plot, exist_ok=True)
        # The plots are normalised; a zero rate would leave nothing to draw.
        rate = float(deg_s_to_rad_s(args.rate_dps or 60.0))
        for name, draw in zip(PLOTS, (
                lambda p: report.plot_sense_vs_split(p, device, rate, args.temp_c,
                                                     args.split_hz),
                lambda p: report.plot_step_response(p, device, rate, args.temp_c,
                                                    args.split_hz),
                lambda p: report.plot_bode(p, device, args.temp_c, args.split_hz))):
            path = os.path.join(args.plot, name)
            draw(path)
            print(f'wrote {path}')
    if args.json:
        write_json(args.json, doc)
    return 0
