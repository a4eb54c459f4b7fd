"""
Diagnose a measured record against the paper's physics.

  gyro-emulator diagnose FILE.csv --json OUT.json --report DIR
  gyro-emulator diagnose static_log.csv.gz --static --axis x
  gyro-emulator diagnose BAG_DIR --gyro-topic imu/data_raw --axis z ...

FILE is a CSV with columns time_s, rate_cmd_rad_s, temp_c (optional),
gyro_rad_s (or gyro_x/y/z_rad_s with --axis) and optionally accel_x_m_s2,
accel_y_m_s2, accel_z_m_s2; --static reads a log of a part at rest that has
no rate column. A rosbag2 MCAP bag (directory or .mcap file) has its topics
mapped with the --*-topic options. Outliers are set aside, then causes are
added one by one while each gives a significant held-out gain; the verdict
says whether the residual is at the record's own noise floor, what cannot
be told apart and which experiment would separate it.
"""

import contextlib
import math
import sys
import warnings

from gyro_emulator.cli.jsonout import write_json
from gyro_emulator.physics.presets import PHYSICS_PRESETS
from gyro_emulator.recording import topics
from gyro_emulator.units import AXES
from gyro_emulator.validation import check_range

HELP = 'find what the physics model gets wrong in measured data, name the cause'


def add_arguments(parser):
    """Register the ``diagnose`` options."""
    parser.add_argument('input', metavar='FILE',
                        help='measured CSV (.csv or .csv.gz), or a rosbag2 MCAP bag directory / '
                             '.mcap')
    parser.add_argument('--json', metavar='OUT', help='write the findings as JSON')
    parser.add_argument('--report', metavar='DIR',
                        help='write report.md and residual PNGs into DIR')
    parser.add_argument('--config', metavar='NAME|FILE', default=None,
                        help='baseline: the deterministic output (noise off) of this sensor '
                             "config (preset or YAML) on the record's inputs, with the user's "
                             'bias and scale-factor calibration (default: the paper physics '
                             'of --preset)')
    parser.add_argument('--write-config', metavar='OUT.yaml', default=None,
                        help='write the starting config (--config, else the paper preset) plus '
                             'every selected cause as a sensor YAML the emulator loads '
                             '(extended terms, fitted values, provenance comments)')
    parser.add_argument('--noise', action='store_true',
                        help="with --write-config: also write the record's noise terms (N, B, "
                             'K, turn-on bias, LSB of the diagnosed axis), from the IEEE 952 '
                             'fit of calibrate noise on the record minus the written model '
                             "(default: the starting config's noise stays)")
    parser.add_argument('--overwrite', action='store_true',
                        help='let --write-config replace an existing file')
    parser.add_argument('--axis', default=None, choices=AXES,
                        help='sense axis: the gyro_<axis>_rad_s column of a 3-axis CSV, or the '
                             'axis of a bag (default: gyro_rad_s; z for a bag)')
    parser.add_argument('--static', action='store_true',
                        help='the part was at rest: a CSV without rate_cmd_rad_s has zero '
                             'applied rate')
    parser.add_argument('--preset', default='paper', choices=sorted(PHYSICS_PRESETS),
                        help='physics preset of the baseline device (default: %(default)s)')
    parser.add_argument('--ref-temp', type=float, default=None, metavar='C',
                        help="calibration temperature, deg C (default: the device's, 25 C)")
    parser.add_argument('--folds', type=int, default=8,
                        help='contiguous cross-validation blocks (default: %(default)s)')
    parser.add_argument('--alpha', type=float, default=0.01,
                        help='chance that a record with no effect gets a cause, per '
                             'selection step (default: %(default)s)')
    parser.add_argument('--outlier-sigma', type=float, default=6.0, metavar='K',
                        help="set aside samples beyond K robust sigma; 'inf' keeps every "
                             'sample (default: %(default)s)')
    parser.add_argument('--max-causes', type=int, default=4,
                        help='most causes to add (default: %(default)s)')
    parser.add_argument('--effects', default=None, metavar='LIST',
                        help='comma-separated candidate causes to test (default: all)')
    bag = parser.add_argument_group('bag input (topic mapping)')
    bag.add_argument('--rate-topic', default=topics.RATE_CMD.name,
                     help='applied rate topic (default: %(default)s)')
    bag.add_argument('--temp-topic', default=topics.TEMPERATURE_CMD.name,
                     help='temperature topic (default: %(default)s)')
    bag.add_argument('--gyro-topic', default=topics.IMU_OUT.name,
                     help='measured output topic (default: %(default)s)')
    bag.add_argument('--accel-topic', default=None,
                     help=f'acceleration topic (default: {topics.ACCEL_CMD.name} if '
                          "present; 'none' to ignore)")


def _check(args):
    """One-line errors for out-of-range options."""
    check_range('diagnose', 'alpha', args.alpha, 0.0, 1.0, '', high_open=True)
    if not math.isinf(args.outlier_sigma):
        check_range('diagnose', 'outlier_sigma', args.outlier_sigma, 3.0, 1e6, 'sigma',
                    low_open=False)
    check_range('diagnose', 'max_causes', args.max_causes, 1, 20, '', low_open=False)
    if args.noise and not args.write_config:
        raise ValueError('diagnose: --noise writes noise terms into the --write-config file: '
                         'give --write-config OUT.yaml too')
    if args.write_config:
        from gyro_emulator.analysis.diagnose import export

        export.check_target(args.write_config, args.overwrite)


def _print(doc):
    """Print the verdict on stdout."""
    from gyro_emulator.analysis.diagnose import report  # lazy: see run

    best = doc['best']
    sa = doc['set_aside']
    print(f"{doc['input']['rows']} samples, {doc['input']['duration_s']:.0f} s; baseline "
          f"held-out RMSE {doc['baseline']['rmse_rad_s']:.4g} rad/s; set aside "
          f"{sa['count']} samples ({100 * sa['fraction']:.3f} %)")
    print(f"verdict: {doc['verdict']}")
    for i, e in enumerate(doc['selected'], 1):
        alike = (f"; cannot be told from {', '.join(e['indistinguishable_from'])}"
                 if e['indistinguishable_from'] else '')
        print(f"cause {i}: {e['effect']} ({e['kind']})  gain {100 * e['gain']:.1f} %  "
              f"p {e['p_value']:.1e}{alike}")
        for name, p in e['parameters'].items():
            print(f"  {name} = {p['value']:.5g} +- {p['sigma']:.2g} {p['unit']}")
        own = e.get('part_sf_temp_coeff_per_k')
        if own is not None:
            print(f"  the part's own SF tempco = {own['value']:.5g} +- {own['sigma']:.2g} 1/K "
                  f"(the physics: {own['physics_per_k']:.5g} 1/K)")
    note = (doc.get('temperature_polynomial') or {}).get('note')
    if note:
        print(f'note: {note}')
    if not doc['selected']:
        print(f"best: {best['effect']}")
    print(doc['residual']['message'])
    for c in doc['confounded']:
        print(f"confounded: {c['a']} and {c['b']} (r = {c['correlation']:+.4f})")
    for text in doc['experiments']:
        print(f'experiment: {text}')
    for f in doc['findings']:
        print(f"  {f['effect']:<26} gain {report.gain_text(f['gain']):>9}  "
              f"p {f['p_value']:.1e}  dBIC {f['delta_bic']:9.0f}  "
              f"{'significant' if f['significant'] else ''}")
    for nt in doc['not_tested']:
        print(f"  {nt['effect']:<26} not tested: {nt['reason']}")


def run(args):
    """Load the record, diagnose it, print the verdict, write JSON/report."""
    # The analysis (scipy, numba: 0.9 s, 2.4 s cold) is imported here, not at
    # the top: `gyro-emulator --help` imports every command module.
    from gyro_emulator.analysis.diagnose import data, diagnose, report

    _check(args)
    record = data.load_measured(args.input, rate_topic=args.rate_topic,
                                temp_topic=args.temp_topic, gyro_topic=args.gyro_topic,
                                accel_topic=args.accel_topic, axis=args.axis,
                                static=args.static)
    for note in record.recovery:
        print(f'gyro-emulator diagnose: warning: {note}', file=sys.stderr)
    effects = None if args.effects is None else [
        e.strip() for e in args.effects.split(',') if e.strip()]
    with quiet_numerics():
        result = diagnose(record, preset=args.preset, ref_temp_c=args.ref_temp,
                          folds=args.folds, effects=effects, alpha=args.alpha,
                          outlier_threshold=args.outlier_sigma, max_causes=args.max_causes,
                          config=args.config, axis=args.axis or 'z')
        _print(result.doc)
        if args.json:
            write_json(args.json, result.doc)
        if args.report:
            print(f'wrote {report.write_report(result, args.report)}')
    if args.write_config:
        _write_config(args, result.doc, record)
    return 0


def _write_config(args, doc, record):
    """Write the extended model (:mod:`gyro_emulator.analysis.diagnose.export`)."""
    from gyro_emulator.analysis.diagnose import export

    # the per-axis amplitudes go to the diagnosed axis: --axis, else z (a bag's default)
    if args.config is None:
        start = {'config': 'paper', 'device': args.preset,
                 'config_name': f"sensor preset 'paper', device {args.preset!r}"}
    else:
        start = {'config': args.config, 'config_name': args.config}
    axis = args.axis or 'z'
    text, commented = export.extended_model(doc, axis=axis, **start)
    if args.noise:
        from gyro_emulator.analysis.diagnose import record_noise

        with quiet_numerics():
            noise = record_noise.identify(text, record, axis, args.outlier_sigma)
        text, commented = export.extended_model(doc, axis=axis, noise=noise, **start)
    export.write_text(args.write_config, text, args.overwrite)
    for cause, why in commented:
        print(f'gyro-emulator diagnose: warning: {cause} written commented out: {why}',
              file=sys.stderr)
    print(f'wrote {args.write_config}')


@contextlib.contextmanager
def quiet_numerics():
    """
    Keep numpy's and scipy's numerical warnings off the user's terminal.

    An empty slice or a degenerate fit on an odd record is handled where it
    happens (a NaN the verdict reads as "not measurable"); the warning that
    came with it says nothing the report does not. A failure that is not a
    ValueError or OSError (which :func:`gyro_emulator.cli.main` prints as one
    line) is turned into one, naming what failed.
    """
    import numpy as np

    with warnings.catch_warnings(), np.errstate(all='ignore'):
        warnings.simplefilter('ignore', RuntimeWarning)
        warnings.simplefilter('ignore', UserWarning)
        try:
            yield
        except (ValueError, OSError, KeyboardInterrupt):
            raise
        except Exception as exc:
            raise ValueError(f'the diagnosis failed ({type(exc).__name__}: {exc}); please '
                             'report it with the input') from exc
