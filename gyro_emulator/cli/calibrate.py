"""
Calibrate from a measured log, export to the stacks users run, and check the emulated twin.

  calibrate noise LOG [--axis x|y|z|all] --format F -o OUT [--inflate F]
      IEEE Std 952 noise identification of a static log (Allan deviation, the
      band-limited short taus left out, five terms with confidence intervals,
      read-offs) written for: kalibr (imu.yaml), openvins (kalibr_imu_chain.yaml),
      vins (gyr_n/gyr_w block), orbslam3 (IMU.NoiseGyro/IMU.GyroWalk), gazebo
      (gz-sensors <imu> noise) or preset (this emulator's sensor YAML).
  calibrate thermal LOG [LOG ...] --format px4|ardupilot|preset -o OUT
      Bias against die temperature of a static log (temp_c and gyro columns;
      several one-axis files are x, y, z in order), written as PX4 TC_G0_*
      parameters, ArduPilot INS_TCAL1_* parameters or this emulator's bias terms.
      A log that spans too little temperature is refused: order k needs
      5 / 15 / 25 K (k = 1 / 2 / 3) and k + 3 distinct temperatures.
  calibrate check-noise LOG --config FITTED.yaml
      Simulate the fitted preset (as `simulate --config` does) at the log's rate
      and length for several seeds; compare the Allan deviation at every octave
      tau from 0.1 s to a tenth of the record (10 % tolerance).
  calibrate check-thermal LOG [LOG ...] --config FITTED.yaml [--px4 FILE]
      Simulate the fitted preset along the log's temperature and compare bias
      against temperature; with --px4, apply that correction to the log and
      report the spread before and after.

Every file states its source log, the tau range or temperature span used, the
continuous-to-discrete convention of its target and the inflation factor.
Accelerometer fields are written as FILL_IN: this is a gyro log.
"""

import os
import sys

from gyro_emulator.cli.jsonout import write_json

HELP = 'calibrate noise or thermal terms from a log; export to Kalibr, VINS, PX4, ...'

NOISE_FORMATS = ('kalibr', 'openvins', 'vins', 'orbslam3', 'gazebo', 'preset')
THERMAL_FORMATS = ('px4', 'ardupilot', 'preset')


def _common_log(parser, many=False):
    if many:
        parser.add_argument('log', nargs='+', metavar='LOG',
                            help='thermal log: one CSV/bag, or one-axis CSVs for x, y, z')
        parser.add_argument('--gyro-scale', type=float, default=1.0, metavar='F',
                            help='multiply the logged rates by F first (a known scale error; '
                                 'default: %(default)s)')
        parser.add_argument('--temperature-topic', default=None,
                            help='sensor_msgs/Temperature topic of a bag '
                                 '(default: imu/temperature)')
    else:
        parser.add_argument('log', metavar='LOG', help='static log: CSV (.gz ok) or bag')
        parser.add_argument('--axis', choices=('x', 'y', 'z', 'all'), default='all',
                            help='axis to calibrate (default: every axis of the log)')
    parser.add_argument('--topic', default=None, help='Imu topic of a bag')
    parser.add_argument('--json', metavar='OUT', help='write the results as JSON')
    parser.add_argument('--plot', metavar='PNG', help='write a plot')
    from gyro_emulator.cli.allan import add_outlier_arguments

    add_outlier_arguments(parser)


def add_arguments(parser):
    """Register ``calibrate noise|thermal|check-noise|check-thermal``."""
    sub = parser.add_subparsers(dest='what', metavar='WHAT')
    sub.required = True
    noise = sub.add_parser('noise', help='noise terms of a static log, exported')
    _common_log(noise)
    noise.add_argument('--format', required=True, choices=NOISE_FORMATS)
    noise.add_argument('-o', '--out', required=True, metavar='OUT', help='file to write')
    noise.add_argument('--inflate', type=float, default=1.0, metavar='F',
                       help='multiply N, B and K by F (stated in the file; default: none)')
    noise.add_argument('--rate-hz', type=float, default=None, metavar='R',
                       help="the estimator's IMU rate for discrete values (default: the log's)")
    noise.set_defaults(run_what=run_noise)
    therm = sub.add_parser('thermal', help='bias against temperature, exported')
    _common_log(therm, many=True)
    therm.add_argument('--format', required=True, choices=THERMAL_FORMATS)
    therm.add_argument('-o', '--out', required=True, metavar='OUT', help='file to write')
    therm.add_argument('--order', type=int, default=3, choices=(1, 2, 3),
                       help='highest polynomial order wanted (default: %(default)s)')
    therm.add_argument('--window-s', type=float, default=60.0, metavar='S',
                       help='group length of a log without gaps (default: %(default)s)')
    therm.set_defaults(run_what=run_thermal)
    check = sub.add_parser('check-noise', help='simulate the fitted preset; compare ADEV')
    _common_log(check)
    check.add_argument('--config', required=True, metavar='YAML', help='the fitted preset')
    check.add_argument('--seeds', type=int, default=8, metavar='N',
                       help='simulated records averaged (default: %(default)s)')
    check.set_defaults(run_what=run_check_noise)
    tcheck = sub.add_parser('check-thermal', help='simulate the fitted preset; compare bias(T)')
    _common_log(tcheck, many=True)
    tcheck.add_argument('--config', required=True, metavar='YAML', help='the fitted preset')
    tcheck.add_argument('--px4', metavar='PARAMS', help='a PX4 file to apply to the log')
    tcheck.add_argument('--window-s', type=float, default=60.0, metavar='S',
                        help='group length of a log without gaps (default: %(default)s)')
    tcheck.set_defaults(run_what=run_check_thermal)


def run(args):
    """Dispatch to the chosen calibration."""
    return args.run_what(args)


def _write(path, text):
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, 'w', encoding='utf-8') as handle:
        handle.write(text)
    print(f'wrote {path}')


def _threshold(args):
    from gyro_emulator.cli.allan import outlier_threshold

    return outlier_threshold(args)


def _calibrate(args):
    from gyro_emulator.analysis.calibrate import noise
    from gyro_emulator.recording.record import load_record

    axes = None if args.axis == 'all' else (args.axis,)
    cal = noise.calibrate_noise(load_record(args.log, {'gyro': args.topic}), axes,
                                outlier_threshold=_threshold(args))
    for note in cal.recovery + cal.skipped + cal.timing:
        print(f'gyro-emulator calibrate: warning: {note}', file=sys.stderr)
    return cal


def _print_noise(cal):
    from gyro_emulator.analysis.allan.analyse import summary
    from gyro_emulator.cli.allan import print_terms

    print(f'{cal.source}: {cal.rate_hz:.6g} Hz, {cal.duration_s:.1f} s')
    for item in cal.axes:
        print(f' axis {item.axis} ({item.column}): {item.fit.band.note}')
        print(f'   {item.set_aside["description"]}')
        print_terms({'fit': summary(item.fit)}, indent='   ')
        for warning in item.fit.warnings:
            print(f'gyro-emulator calibrate: warning: axis {item.axis}: {warning}',
                  file=sys.stderr)


def run_noise(args):
    """Identify the noise terms and write the chosen format."""
    from gyro_emulator import units
    from gyro_emulator.analysis.allan import plot_adev
    from gyro_emulator.analysis.allan.analyse import summary
    from gyro_emulator.analysis.calibrate import export_noise, noise

    cal = _calibrate(args)
    _print_noise(cal)
    text = export_noise.write_noise(cal, args.format, args.inflate, args.rate_hz)
    chosen = noise.export_noise(cal, args.inflate)
    print(f' exported: N {chosen.arw_rad_s_sqrt_hz:.4g} rad/s/sqrt(Hz) '
          f'({float(units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(chosen.arw_rad_s_sqrt_hz)):.4g} '
          f'deg/sqrt(h)), K {chosen.rrw_rad_s_sqrt_s:.4g} rad/s^2/sqrt(Hz)'
          + (f' ({chosen.note})' if chosen.note else ''))
    _write(args.out, text)
    if args.json:
        write_json(args.json, {'source': cal.source, 'rate_hz': cal.rate_hz,
                               'duration_s': cal.duration_s, 'lsb_rad_s': cal.lsb_rad_s,
                               'axes': {a.axis: summary(a.fit) for a in cal.axes},
                               'set_aside': {a.axis: a.set_aside for a in cal.axes},
                               'timing': list(cal.timing),
                               'exported': {'arw_rad_s_sqrt_hz': chosen.arw_rad_s_sqrt_hz,
                                            'rrw_rad_s_sqrt_s': chosen.rrw_rad_s_sqrt_s,
                                            'rrw_is_bound': chosen.rrw_is_bound,
                                            'inflate': chosen.inflate, 'note': chosen.note}})
    if args.plot:
        for item in cal.axes:
            path = args.plot if len(cal.axes) == 1 else _axis_path(args.plot, item.axis)
            plot_adev(item.result, item.fit, path,
                      title=f'{os.path.basename(cal.source)} [{item.column}]')
            print(f'wrote {path}')
    return 0


def _axis_path(path, axis):
    root, ext = os.path.splitext(path)
    return f'{root}_{axis}{ext or ".png"}'


def _thermal(args):
    from gyro_emulator.analysis.calibrate import thermal
    from gyro_emulator.recording.record import load_record

    roles = thermal.bag_topics(args.topic, args.temperature_topic)
    log = thermal.thermal_log([load_record(path, roles, thermal.REQUIRED_COLUMNS)
                               for path in args.log])
    fit = thermal.fit_thermal(log, getattr(args, 'order', 3), args.window_s, args.gyro_scale,
                              _threshold(args))
    return log, fit


def _print_thermal(fit):
    from gyro_emulator import units

    print(f'{", ".join(fit.sources)}: {fit.grouping}, {fit.temp_min_c:.2f} .. '
          f'{fit.temp_max_c:.2f} C (span {fit.span_k:.2f} K, {fit.distinct_temps} distinct)')
    print(f' order {fit.order}: {fit.order_reason}')
    for axis, coeffs in fit.coefficients.items():
        errs = fit.errors[axis]
        slope = (f'{float(units.rad_s_to_deg_s(coeffs[1])):+.4g} +- '
                 f'{float(units.rad_s_to_deg_s(errs[1])):.2g} deg/s/K') if len(coeffs) > 1 else ''
        print(f' axis {axis}: bias at {fit.temp_ref_c:.2f} C '
              f'{float(units.rad_s_to_deg_s(coeffs[0])):+.4g} deg/s, slope {slope}; '
              f'residual {float(units.rad_s_to_deg_s(fit.residual_rms[axis])) * 1e3:.3g} mdeg/s '
              f'rms (group noise {float(units.rad_s_to_deg_s(fit.group_noise[axis])) * 1e3:.3g})')
    for note in fit.notes:
        print(f'gyro-emulator calibrate: note: {note}', file=sys.stderr)


def _thermal_doc(fit):
    return {'sources': list(fit.sources), 'order': fit.order, 'order_reason': fit.order_reason,
            'temp_ref_c': fit.temp_ref_c, 'temp_min_c': fit.temp_min_c,
            'temp_max_c': fit.temp_max_c, 'span_k': fit.span_k,
            'distinct_temps': fit.distinct_temps, 'correlation_temp_time': fit.correlation,
            'grouping': fit.grouping, 'gyro_scale': fit.gyro_scale, 'notes': list(fit.notes),
            'coefficients_rad_s_per_k': {a: list(map(float, c))
                                         for a, c in fit.coefficients.items()},
            'errors_rad_s_per_k': {a: list(map(float, c)) for a, c in fit.errors.items()},
            'residual_rms_rad_s': fit.residual_rms, 'group_noise_rad_s': fit.group_noise,
            'set_aside': {a: dict(v.as_dict(), description=v.describe())
                          for a, v in fit.set_aside.items()}}


def run_thermal(args):
    """Fit bias against temperature and write the chosen format."""
    from gyro_emulator.analysis.calibrate import export_thermal, plots, thermal

    log, fit = _thermal(args)
    _print_thermal(fit)
    if args.format == 'preset':
        fit = thermal.with_white_noise(fit, log)
    _write(args.out, export_thermal.write_thermal(fit, args.format))
    if args.json:
        write_json(args.json, _thermal_doc(fit))
    if args.plot:
        plots.plot_thermal(fit, args.plot, title=', '.join(os.path.basename(s)
                                                           for s in fit.sources))
        print(f'wrote {args.plot}')
    return 0


def run_check_noise(args):
    """Simulate the fitted preset and compare its Allan deviation with the log's."""
    from gyro_emulator.analysis.calibrate import plots, twin
    from gyro_emulator.sensor.config import load_sensor_config
    from tqdm import tqdm

    config = load_sensor_config(args.config)
    cal = _calibrate(args)
    with tqdm(total=args.seeds, desc='simulated records', file=sys.stderr,
              disable=None) as bar:
        check = twin.check_noise(cal, config, args.seeds,
                                 progress=lambda done, total: bar.update(1))
    print(f'{cal.source}: twin {args.config} at {cal.rate_hz:g} Hz, {cal.duration_s:.0f} s, '
          f'mean of {args.seeds} records; octave taus {check.taus_s[0]:g} .. '
          f'{check.taus_s[-1]:g} s')
    for axis, ratio in check.ratio.items():
        verdict = 'PASS (10 %)' if check.passed[axis] else (
            "within 10 % or the log's own 95 % interval" if check.consistent[axis] else 'FAIL')
        print(f' axis {axis}: twin / log - 1 = '
              + ' '.join(f'{100 * r:+.0f}' for r in ratio) + f' %: {verdict}')
    if args.json:
        write_json(args.json, {'taus_s': check.taus_s.tolist(), 'seeds': list(check.seeds),
                               'ratio': {a: r.tolist() for a, r in check.ratio.items()},
                               'passed_10pct': check.passed,
                               'consistent_with_log_interval': check.consistent})
    if args.plot:
        plots.plot_noise_check(cal, check, args.plot,
                               title=f'{os.path.basename(cal.source)}: log and twin')
        print(f'wrote {args.plot}')
    return 0 if all(check.consistent.values()) else 1


def run_check_thermal(args):
    """Simulate the fitted preset along the log's temperature; apply a PX4 file if given."""
    from gyro_emulator import units
    from gyro_emulator.analysis.calibrate import export_thermal, plots, thermal, twin
    from gyro_emulator.sensor.config import load_sensor_config

    config = load_sensor_config(args.config)
    log, fit = _thermal(args)
    _print_thermal(fit)
    check = twin.check_thermal(fit, log, config)
    mdeg = lambda v: float(units.rad_s_to_deg_s(v)) * 1e3  # noqa: E731
    doc = {'thermal': _thermal_doc(fit), 'twin': {}, 'px4': {}}
    for axis in fit.groups:
        log_slope, sim_slope, err = check.slope[axis]
        rms_z = float((check.z[axis] ** 2).mean() ** 0.5)
        print(f' axis {axis}: twin slope {mdeg(sim_slope):+.3g} vs log {mdeg(log_slope):+.3g} '
              f'+- {mdeg(err):.2g} mdeg/s/K; group means within the noise: rms z {rms_z:.2f} '
              f'({"PASS" if check.passed[axis] else "FAIL"})')
        doc['twin'][axis] = {'slope_log': log_slope, 'slope_twin': sim_slope,
                             'slope_error': err, 'rms_z': rms_z, 'passed': check.passed[axis]}
    params = None
    if args.px4:
        with open(args.px4, encoding='utf-8') as handle:
            params = export_thermal.read_px4_params(handle.read())
        for axis in fit.groups:
            c = thermal.compensation_check(fit, params, axis)
            print(f' axis {axis}: PX4 correction: group-mean spread {mdeg(c.before_std):.3g} -> '
                  f'{mdeg(c.after_std):.3g} mdeg/s std ({mdeg(c.before_ptp):.3g} -> '
                  f'{mdeg(c.after_ptp):.3g} peak-to-peak; held out {mdeg(c.held_out_std):.3g}); '
                  f'residual slope {mdeg(c.slope_rad_s_k):+.2g} +- {mdeg(c.slope_error):.2g} '
                  'mdeg/s/K')
            doc['px4'][axis] = dict(c.__dict__)
    if args.json:
        write_json(args.json, doc)
    if args.plot:
        plots.plot_thermal(fit, args.plot, check=check, params=params,
                           title=', '.join(os.path.basename(s) for s in fit.sources))
        print(f'wrote {args.plot}')
    return 0 if all(check.passed.values()) else 1
