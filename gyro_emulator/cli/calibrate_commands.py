"""
The work of ``gyro-emulator calibrate``: load, fit, print, export and check.

:mod:`gyro_emulator.cli.calibrate` holds the options and imports this module
only when a calibration runs: the calibration modules load scipy and
statsmodels (1-4 s), and ``gyro-emulator --help`` imports every command module.
"""

from dataclasses import replace
import os
import sys

from gyro_emulator import atomic, outputs, units
from gyro_emulator.analysis.allan import plot_adev
from gyro_emulator.analysis.allan.analyse import summary
from gyro_emulator.analysis.calibrate import (export_noise, export_thermal, noise, plots,
                                              thermal, twin)
from gyro_emulator.analysis.calibrate.accel_figures import accel_figures
from gyro_emulator.analysis.sense import ACCEL, GYRO
from gyro_emulator.cli.allan import outlier_threshold, print_terms
from gyro_emulator.cli.jsonout import write_json
from gyro_emulator.recording.record import load_record
from gyro_emulator.sensor.config import config_source, load_sensor_config
from gyro_emulator.validation import check_rate_hz
import numpy as np
from tqdm import tqdm


def _write(path, text):
    """Write an export file whole or not at all (:func:`gyro_emulator.atomic.write_text`)."""
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    atomic.write_text(path, text)
    print(f'wrote {path}')


def _check_outputs(args, plots=None):
    """Check every output of the action before it reads the log (:mod:`gyro_emulator.outputs`)."""
    logs = args.log if isinstance(args.log, list) else [args.log]
    plots = [args.plot] if plots is None else plots
    outputs.check([outputs.file('--out', getattr(args, 'out', None)),
                   outputs.file('--json', args.json)]
                  + [outputs.image('--plot', p) for p in plots if p],
                  inputs=logs + [config_source(getattr(args, 'config', None)),
                                 getattr(args, 'px4', None)],
                  overwrite=args.overwrite)


def _noise_plots(args):
    """Return the plots ``calibrate noise --plot`` may write: one, or one per axis of the log."""
    if not args.plot:
        return []
    if args.axis != 'all':
        return [args.plot]
    return [args.plot] + [_axis_path(args.plot, axis) for axis in units.AXES]


#: Kalibr's and OpenVINS's IMU topic for a CSV log (their examples' name).
CSV_TOPIC = '/imu0'


def _calibrate(args):
    """Return (the gyro's calibration, the accelerometer's or None, the record)."""
    record = load_record(args.log, {'gyro': args.topic, 'imu_accel': args.topic})
    axes = None if args.axis == 'all' else (args.axis,)
    threshold = outlier_threshold(args)
    notes = []
    if record.accel is not None and not np.any(record.accel.values):
        notes.append('accelerometer: it reads exactly 0 throughout (a gyro-only driver): '
                     'taken as absent')
        record = replace(record, accel=None)
    if record.accel is None and args.accel_scale != 1.0:
        raise ValueError(f'--accel-scale {args.accel_scale:g}: {record.path} has no '
                         "accelerometer (accel_{x,y,z}_m_s2 columns or an Imu's "
                         'linear_acceleration)')
    if record.accel is not None:        # a log in g is refused before any fit
        noise.gravity_at_rest(record.accel.values * args.accel_scale, record.path,
                              args.accel_scale)
    elif getattr(args, 'format', None) == 'vins':
        export_noise.require_accel('vins', _accel(args))    # before the fit: it takes seconds
    cal = noise.calibrate_noise(record, axes, outlier_threshold=threshold)
    accel = None
    if record.accel is not None:
        try:
            accel = noise.calibrate_noise(record, axes, outlier_threshold=threshold,
                                          sense=ACCEL, scale=args.accel_scale)
        except ValueError as exc:
            notes.append(f'accelerometer: not calibrated, the files are those of a gyro-only '
                         f'log: {exc}')
    if accel is not None:
        notes += [f'accelerometer: {note}' for note in accel.skipped + accel.notes]
    for note in cal.recovery + cal.skipped + cal.timing + tuple(notes):
        print(f'gyro-emulator calibrate: warning: {note}', file=sys.stderr)
    if accel is None and getattr(args, 'format', None) == 'vins':
        export_noise.require_accel('vins', _accel(args))
    return cal, accel, record


def _print_noise(cal):
    print(f'{cal.source}: {cal.rate_hz:.6g} Hz, {cal.duration_s:.1f} s'
          + ('' if cal.sense is GYRO else f' ({cal.sense.name}, {cal.sense.unit})'))
    for item in cal.axes:
        print(f' axis {item.axis} ({item.column}): {item.fit.band.note}')
        print(f'   {item.set_aside["description"]}')
        print_terms({'fit': summary(item.fit, cal.sense)}, indent='   ',
                    labels=cal.sense.labels)
        what = 'axis' if cal.sense is GYRO else f'{cal.sense.name} axis'
        for warning in item.fit.warnings:
            print(f'gyro-emulator calibrate: warning: {what} {item.axis}: {warning}',
                  file=sys.stderr)


def _accel(args):
    """Return the accelerometer figures of the command line: both or neither."""
    given = (args.accel_noise_density, args.accel_random_walk)
    if given == (None, None):
        return None
    if None in given:
        raise ValueError('give both --accel-noise-density and --accel-random-walk, or neither')
    return export_noise.AccelFigures(*given)


def _rostopic(args, record):
    """Kalibr's and OpenVINS's topic: --rostopic, else the bag's Imu topic, else /imu0."""
    if args.rostopic is not None:
        if not args.rostopic.strip() or any(c.isspace() for c in args.rostopic):
            raise ValueError(f'--rostopic {args.rostopic!r} is not a topic name: allowed a '
                             'non-empty name without spaces, e.g. /imu0')
        return args.rostopic
    return record.topics.get('gyro') or CSV_TOPIC


def _exported_line(cal, accel, inflate):
    """One line per channel: the single numbers an estimator gets."""
    chosen = noise.export_noise(cal, inflate)
    lines = [f' exported: N {chosen.arw_rad_s_sqrt_hz:.4g} rad/s/sqrt(Hz) '
             f'({float(units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(chosen.arw_rad_s_sqrt_hz)):.4g} '
             f'deg/sqrt(h)), K {chosen.rrw_rad_s_sqrt_s:.4g} rad/s^2/sqrt(Hz)'
             + (f' ({chosen.note})' if chosen.note else '')]
    if accel is not None:
        where = (accel.source('noise_density') if accel.given else
                 accel.log.note or 'the fitted values')
        lines.append(f' exported accelerometer: N_a {accel.noise_density_m_s2_sqrt_hz:.4g} '
                     f'm/s^2/sqrt(Hz) ({ACCEL.show("arw", accel.noise_density_m_s2_sqrt_hz):.4g}'
                     f' ug/sqrt(Hz)), K_a {accel.random_walk_m_s3_sqrt_hz:.4g} m/s^3/sqrt(Hz) '
                     f'({where})')
    return chosen, lines


def _noise_doc(cal, chosen):
    """Return the JSON of one channel's calibration."""
    return {'source': cal.source, 'rate_hz': cal.rate_hz, 'duration_s': cal.duration_s,
            'lsb_rad_s': cal.lsb_rad_s,
            'axes': {a.axis: summary(a.fit, cal.sense) for a in cal.axes},
            'set_aside': {a.axis: a.set_aside for a in cal.axes},
            'timing': list(cal.timing),
            'exported': {'arw_rad_s_sqrt_hz': chosen.arw_rad_s_sqrt_hz,
                         'rrw_rad_s_sqrt_s': chosen.rrw_rad_s_sqrt_s,
                         'rrw_is_bound': chosen.rrw_is_bound,
                         'inflate': chosen.inflate, 'note': chosen.note}}


def _accel_doc(cal, accel, inflate):
    """Return the JSON of the accelerometer: SI values (m/s^2), gravity, what was written."""
    doc = _noise_doc(cal, noise.export_noise(cal, inflate))
    doc.pop('lsb_rad_s')
    return dict(doc, lsb_m_s2=cal.lsb, gravity_m_s2=list(cal.gravity_m_s2),
                turn_on_bias_m_s2={a.axis: cal.turn_on_bias(a) for a in cal.axes},
                notes=list(cal.notes), scale=cal.scale,
                written={'noise_density_m_s2_sqrt_hz': accel.noise_density_m_s2_sqrt_hz,
                         'random_walk_m_s3_sqrt_hz': accel.random_walk_m_s3_sqrt_hz,
                         'given_by_the_user': accel.given})


def run_noise(args):
    """Identify the noise terms and write the chosen format."""
    given = _accel(args)
    noise.check_inflate(args.inflate)              # before the log is read, as the outputs
    check_rate_hz(args.rate_hz)
    _check_outputs(args, _noise_plots(args))
    cal, accel_cal, record = _calibrate(args)
    topic = _rostopic(args, record)
    _print_noise(cal)
    if accel_cal is not None:
        _print_noise(accel_cal)
    given = None if given is None else (given.noise_density_m_s2_sqrt_hz,
                                        given.random_walk_m_s3_sqrt_hz)
    accel = accel_figures(accel_cal, args.inflate, given)
    text = export_noise.write_noise(cal, args.format, args.inflate, args.rate_hz, accel, topic)
    chosen, lines = _exported_line(cal, accel, args.inflate)
    print('\n'.join(lines))
    _write(args.out, text)
    if args.json:
        doc = _noise_doc(cal, chosen)
        if accel_cal is not None:
            doc['accelerometer'] = _accel_doc(accel_cal, accel, args.inflate)
        write_json(args.json, doc)
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
    """Return the gyro's thermal log and fit, and the records read."""
    roles = thermal.bag_topics(args.topic, args.temperature_topic)
    records = [load_record(path, roles, thermal.REQUIRED_COLUMNS) for path in args.log]
    for rec in records:         # a log in g is refused before any fit
        if rec.accel is not None and np.any(rec.accel.values):
            noise.gravity_at_rest(rec.accel.values * args.accel_scale, rec.path,
                                  args.accel_scale)
    log = thermal.thermal_log(records)
    fit = thermal.fit_thermal(log, getattr(args, 'order', 3), args.window_s, args.gyro_scale,
                              outlier_threshold(args))
    return log, fit, records


def _accel_thermal(args, records, what):
    """
    Return (the accelerometer's thermal log, its fit, None) or (None, None, why not).

    ``why`` is None when no log has an accelerometer (the export says it is
    not measured); a log in g was refused by :func:`_thermal` (``--accel-scale``).
    """
    with_accel = [r for r in records if r.accel is not None and np.any(r.accel.values)]
    if not with_accel:
        if args.accel_scale != 1.0:
            raise ValueError(f'--accel-scale {args.accel_scale:g}: no log given has an '
                             'accelerometer')
        return None, None, None
    try:
        log = thermal.accel_thermal_log(records)
        fit = thermal.fit_thermal(log, getattr(args, 'order', 3), args.window_s,
                                  args.accel_scale, outlier_threshold(args))
        thermal.check_export(fit, f'{what} (accelerometer)')
    except ValueError as exc:
        return None, None, f'not written: {exc}'
    return log, fit, None


def _print_accel_thermal(fit, why):
    if fit is None:
        if why:
            print(f'gyro-emulator calibrate: note: accelerometer part {why}', file=sys.stderr)
        return
    print(f' accelerometer: order {fit.order}: {fit.order_reason}')
    for axis, coeffs in fit.coefficients.items():
        slope = (f', slope {float(units.m_s2_to_mg(coeffs[1])):+.4g} +- '
                 f'{float(units.m_s2_to_mg(fit.errors[axis][1])):.2g} mg/K'
                 if len(coeffs) > 1 else '')
        print(f' accelerometer axis {axis}: {coeffs[0]:+.6g} m/s^2 at {fit.temp_ref_c:.2f} C'
              f'{slope}; residual {float(units.m_s2_to_mg(fit.residual_rms[axis])):.3g} mg rms')
    for note in fit.notes:
        print('gyro-emulator calibrate: note: accelerometer: '
              + note.removeprefix('accelerometer '), file=sys.stderr)


def _print_thermal(fit):
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
    """Return the JSON of a thermal fit (the accelerometer's keys in m/s^2)."""
    doc = _thermal_values(fit)
    if fit.sense is GYRO:
        return doc
    return dict({key.replace('rad_s', 'm_s2').replace('gyro_scale', 'accel_scale'): value
                 for key, value in doc.items()}, median_m_s2=fit.median)


def _thermal_values(fit):
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
    _check_outputs(args)
    log, fit, records = _thermal(args)
    _print_thermal(fit)
    accel_log, accel, why = _accel_thermal(args, records, f'{args.out} ({args.format})')
    _print_accel_thermal(accel, why)
    if args.format == 'preset':
        fit = thermal.with_white_noise(fit, log)
        accel = None if accel is None else thermal.with_white_noise(accel, accel_log)
    thermal.check_export(fit, f'{args.out} ({args.format})')
    _write(args.out, export_thermal.write_thermal(fit, args.format, args.px4_gyro_id, accel,
                                                  args.px4_accel_id, why))
    if args.json:
        doc = _thermal_doc(fit)
        if accel is not None or why:
            doc['accelerometer'] = _thermal_doc(accel) if accel is not None else {
                'not_written': why}
        write_json(args.json, doc)
    if args.plot:
        plots.plot_thermal(fit, args.plot, title=', '.join(os.path.basename(s)
                                                           for s in fit.sources))
        print(f'wrote {args.plot}')
    if args.format == 'px4' and args.px4_gyro_id is None:
        print(f'gyro-emulator calibrate: warning: {export_thermal.PX4_NO_ID}', file=sys.stderr)
    if args.format == 'px4' and accel is not None and args.px4_accel_id is None:
        print(f'gyro-emulator calibrate: warning: {export_thermal.PX4_NO_ACCEL_ID}',
              file=sys.stderr)
    return 0


def _print_check(check, sense=GYRO):
    """Print one channel's round trip: per axis the ratios at the octave taus, the verdict."""
    what = 'axis' if sense is GYRO else f'{sense.name} axis'
    for axis, ratio in check.ratio.items():
        verdict = 'PASS (10 %)' if check.passed[axis] else (
            "within 10 % or the log's own 95 % interval" if check.consistent[axis] else 'FAIL')
        print(f' {what} {axis}: twin / log - 1 = '
              + ' '.join(f'{100 * r:+.0f}' for r in ratio) + f' %: {verdict}')


def _check_doc(check):
    return {'taus_s': check.taus_s.tolist(), 'seeds': list(check.seeds),
            'ratio': {a: r.tolist() for a, r in check.ratio.items()},
            'passed_10pct': check.passed, 'consistent_with_log_interval': check.consistent}


def run_check_noise(args):
    """Simulate the fitted preset and compare its Allan deviation with the log's."""
    _check_outputs(args)
    config = load_sensor_config(args.config)
    cal, accel, _ = _calibrate(args)
    with tqdm(total=args.seeds, desc='simulated records', file=sys.stderr,
              disable=None) as bar:
        check = twin.check_noise(cal, config, args.seeds,
                                 progress=lambda done, total: bar.update(1), accel=accel)
    print(f'{cal.source}: twin {args.config} at {cal.rate_hz:g} Hz, {cal.duration_s:.0f} s, '
          f'mean of {args.seeds} records; octave taus {check.taus_s[0]:g} .. '
          f'{check.taus_s[-1]:g} s')
    _print_check(check)
    if check.accel is not None:
        _print_check(check.accel, ACCEL)
    if args.json:
        doc = _check_doc(check)
        if check.accel is not None:
            doc['accelerometer'] = _check_doc(check.accel)
        write_json(args.json, doc)
    if args.plot:
        plots.plot_noise_check(cal, check, args.plot,
                               title=f'{os.path.basename(cal.source)}: log and twin')
        print(f'wrote {args.plot}')
    checks = [check] + ([] if check.accel is None else [check.accel])
    return 0 if all(all(c.consistent.values()) for c in checks) else 1


def run_check_thermal(args):
    """Simulate the fitted preset along the log's temperature; apply a PX4 file if given."""
    _check_outputs(args)
    config = load_sensor_config(args.config)
    log, fit, _ = _thermal(args)
    _print_thermal(fit)
    check = twin.check_thermal(fit, log, config)
    mdeg = lambda v: float(units.rad_s_to_deg_s(v)) * 1e3  # noqa: E731
    doc = {'thermal': _thermal_doc(fit), 'twin': {}, 'px4': {}}
    for axis in fit.groups:
        log_slope, sim_slope, err = check.slope[axis]
        rms_z = float((check.z[axis] ** 2).mean() ** 0.5)
        where = 'within' if rms_z <= twin.THERMAL_RMS_Z else 'beyond'
        print(f' axis {axis}: twin slope {mdeg(sim_slope):+.3g} vs log {mdeg(log_slope):+.3g} '
              f'+- {mdeg(err):.2g} mdeg/s/K; group means {where} the noise: rms z {rms_z:.2f} '
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


#: The function of each ``calibrate`` action.
RUNS = {'noise': run_noise, 'thermal': run_thermal, 'check-noise': run_check_noise,
        'check-thermal': run_check_thermal}
