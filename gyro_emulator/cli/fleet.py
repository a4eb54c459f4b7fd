"""
Fleet: Monte Carlo over fabrication tolerances and a temperature grid.

Draws N parts from the tolerances of FLEET.yaml (see docs/fleet.md and
config/fleet_paper_etch2.yaml), evaluates each part's first-order physics
over the temperature grid (frequencies, split, Q, SF(T), Brownian ARW;
optionally the exact 2-DOF sense amplitude at the part's own split and short
sensor-level runs of a few parts), checks the specs and writes DIR/devices/
(Parquet, one row per part), DIR/summary.json (yield per spec, overall
yield, quantiles, which tolerance drives the yield, devices/s) and
DIR/plots/. Part i is the same for the same seed whatever the scheduler,
the number of workers or the partitioning.
"""

import argparse
import sys

from gyro_emulator import outputs

HELP = 'Monte Carlo of a fleet over fabrication tolerances and temperature: yield per spec'


def add_arguments(parser):
    """Register the ``fleet`` options."""
    parser.add_argument('fleet', metavar='FLEET.yaml',
                        help='the fleet: nominal device, tolerances, temperatures, specs')
    parser.add_argument('--devices', type=_count, required=True, metavar='N',
                        help='number of parts (1 to 1e10; 1e6 and 1000000 alike)')
    parser.add_argument('--seed', type=int, default=0, metavar='S',
                        help='random seed (default: %(default)s)')
    parser.add_argument('--out', required=True, metavar='DIR', help='output directory')
    parser.add_argument('--scheduler', default=None, metavar='in-process|local|tcp://HOST:PORT',
                        help='where the blocks run: this process (no Dask), a Dask '
                             'LocalCluster, or an existing Dask cluster (default: '
                             'in-process below 1e6 parts, local from 1e6 on)')
    parser.add_argument('--workers', type=int, default=None, metavar='K',
                        help='workers of a local cluster (default: one per core)')
    parser.add_argument('--blocks-per-task', type=int, default=None, metavar='B',
                        help='blocks of 65536 parts per task (changes no result)')
    parser.add_argument('--no-parquet', action='store_true',
                        help='write summary.json and plots only')
    parser.add_argument('--overwrite', action='store_true',
                        help='replace an earlier fleet in DIR (default: refuse)')
    parser.add_argument('--resume', action='store_true',
                        help='finish the unfinished fleet in DIR (same FLEET.yaml, '
                             '--devices, --seed): its finished tasks are kept')


def _count(text):
    """Parse a whole number of parts: ``1000000``, ``1_000_000`` or ``1e6``."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number of parts') from None
    if not value.is_integer():
        raise argparse.ArgumentTypeError(f'{text!r} is not a whole number of parts')
    return int(value)


def run(args):
    """Run the fleet and print its yields."""
    # The fleet (scipy, pyarrow: 1 s) is imported here, not at the top:
    # `gyro-emulator --help` imports every command module.
    from gyro_emulator.analysis.fleet.config import load_fleet_config
    from gyro_emulator.analysis.fleet.run import FleetIncomplete, OUTPUTS, run_fleet

    # not an input, a folder that can be written; an earlier fleet there is the run's own
    # check (--overwrite or --resume)
    outputs.check([outputs.inside('--out', args.out, OUTPUTS)], inputs=[args.fleet],
                  overwrite=True)
    config = load_fleet_config(args.fleet)
    try:
        summary = run_fleet(config, args.devices, args.seed, args.out,
                            scheduler=args.scheduler, workers=args.workers,
                            blocks_per_task=args.blocks_per_task,
                            progress=True if sys.stderr.isatty() else 'log',
                            overwrite=args.overwrite,
                            write=not args.no_parquet, resume=args.resume)
    except FleetIncomplete as exc:
        print(f'gyro-emulator fleet: error: {exc}', file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:
        how = getattr(exc, 'name', None)
        print(f'gyro-emulator fleet: {"stopped by " + how if how else "interrupted"}; the '
              f'finished tasks are kept in {args.out}: run again with --resume to finish',
              file=sys.stderr)
        raise           # the command line's stop: its status, and no interpreter exit
    run_info = summary['run']
    print(f'{summary["devices"]} parts ({summary["invalid"]} invalid, {summary["clipped"]} '
          f'clipped) over {len(summary["temperatures_c"])} temperatures in '
          f'{run_info["wall_s"]:.1f} s ({run_info["devices_per_s"]:.3g} parts/s, '
          f'{run_info["scheduler"]}, {run_info["workers"]} worker(s))'
          + (f'; {run_info["tasks_resumed"]} task(s) kept from the unfinished run'
             if 'tasks_resumed' in run_info else ''))
    for metric, spec in summary['specs'].items():
        print(f'  {metric:22s} yield {_yield(spec)}')
    print(f'  {"all specs":22s} yield {_yield(summary)}'
          + (f'; fails most: {summary["fails_most"]}' if summary['fails_most'] else ''))
    if summary['attribution']:
        print('  ' + _driver_line(summary['attribution']))
    for line in _model_check_lines(summary.get('model_checks')):
        print(line)
    for line in _sensor_run_lines(config.sensor_runs, summary['sensor_runs']):
        print(line)
    print(f'wrote {args.out}/summary.json, {args.out}/plots/'
          + ('' if args.no_parquet else f', {args.out}/devices/'))
    return 0


def _model_check_lines(checks):
    """Return the lines of the model-validity checks: apart from the specs, not in the yield."""
    if not checks:
        return []
    lines = ['model validity (checks of the first-order model, not part specs; not in '
             'the yield):']
    for metric, entry in checks.items():
        low, high = entry['share_ci95']
        lines.append(f'  {metric:22s} holds for {100 * entry["share"]:6.2f} % of the parts '
                     f'[{100 * low:.2f}, {100 * high:.2f}]')
    return lines


def _bounded(run, name, unit, label):
    """Format a fitted Allan term: its value if resolved, else its upper bound; the model's."""
    value = run[f'{name}_{unit}']
    model = run[f'{name}_model_{unit}']
    if value is not None:
        return f'{value:.3g} {label} (model {model:.3g})'
    return f'< {run[f"{name}_upper_{unit}"]:.3g} {label} (not resolved; model {model:.3g})'


def _sensor_run_lines(runs_config, runs):
    """One line per sensor run: split, ARW fitted and predicted, B and K or their bounds."""
    if not runs:
        return []
    lines = [f'sensor runs ({runs_config.duration_s:g} s at {runs_config.rate_hz:g} Hz, '
             'static, x axis; IEEE Std 952 fit, 95 % upper bound where a term is not '
             'resolved):']
    for run in runs:
        lines.append(
            f'  part {run["device_id"]}: split {run["split_hz"]:+.2f} Hz, ARW '
            f'{run["arw_deg_sqrt_h"]:.4f} deg/sqrt(h) (predicted '
            f'{run["arw_predicted_deg_sqrt_h"]:.4f}), B '
            f'{_bounded(run, "bias_instability", "deg_h", "deg/h")}, K '
            f'{_bounded(run, "rrw", "deg_h_sqrt_h", "deg/h/sqrt(h)")}')
    return lines


def _yield(entry):
    """Format a yield and its 95 % interval, in %."""
    low, high = entry['yield_ci95']
    return f'{100 * entry["yield"]:6.2f} % [{100 * low:.2f}, {100 * high:.2f}]'


def _gain(source):
    """Format a source's gain in yield points, +- the half-width of its 95 % interval."""
    low, high = source['gain_ci95']
    return f'{100 * source["gain"]:+.1f} +- {100 * (high - low) / 2:.1f} points'


def _driver_line(attribution):
    """Say which source drives the yield and its rivals, or that none is shown to."""
    sources, n = attribution['sources'], attribution['devices']
    top = attribution['drives_the_yield']
    if top is None:
        best = attribution['ranking'][0] if attribution['ranking'] else None
        return ('no source is shown to drive the yield on ' + f'{n} parts'
                + (f' (largest: {best}, {_gain(sources[best])})' if best else ''))
    line = f'drives the yield: {top} (without it: {_gain(sources[top])}, on {n} parts)'
    rivals = attribution['indistinguishable_from']
    if rivals:
        line += '; cannot be told apart from ' + ', '.join(
            f'{s} ({_gain(sources[s])})' for s in rivals)
    return line
