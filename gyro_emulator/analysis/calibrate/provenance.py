"""
What every exported file says about where its numbers came from.

Comment lines, one format-neutral list (:func:`noise_lines`,
:func:`thermal_lines`) turned into ``#`` or XML comments by
:func:`as_comments`. Fields the log cannot give (the accelerometer of a
gyro log, a device id) are never a made-up number: each writer leaves them
out or writes :data:`MARKER` where that makes its consumer stop and name
the field, and says which in a comment.
"""

from gyro_emulator import units
from gyro_emulator.analysis.sense import GYRO
from gyro_emulator.yaml_text import float_text

#: The value written where the user must fill in a figure this log does not give.
MARKER = 'FILL_IN'
#: The comment beside it.
NOT_MEASURED = 'NOT MEASURED by this gyro log: replace FILL_IN with your own figure'
#: The continuous-to-discrete convention every noise export states first.
CONTINUOUS = ('N and K are continuous-time densities (IEEE Std 952): the sampled white noise '
              'has sigma_d = N sqrt(f), the bias walk steps K / sqrt(f) per sample at rate f.')


def as_comments(lines, style='#'):
    """Return ``lines`` as comment text: ``# line`` or one XML comment block."""
    if style == 'xml':
        body = '\n'.join(f'  {line}'.replace('--', '- -') for line in lines)
        return f'<!--\n{body}\n-->\n'
    return ''.join(f'# {line}'.rstrip() + '\n' for line in lines)


def _term(fit, name, to, unit):
    value = fit.value(name)
    interval = fit.intervals.get(name)
    text = f'{float(to(value)):.4g} {unit}'
    if interval is not None:
        text += (f' [{float(to(interval.low)):.4g}, {float(to(interval.high)):.4g}]'
                 + ('' if interval.resolved else ' not resolved'))
    return text


def axis_lines(item, sense=GYRO):
    """Provenance of one calibrated axis: taus used, N, B, K with intervals, warnings."""
    fit = item.fit
    lo, hi = fit.tau_range_s
    terms = ', '.join(f'{label} {_term(fit, term, *sense.shown[term])}' for label, term in
                      (('N', 'arw'), ('B', 'bias_instability'), ('K', 'rrw')))
    lines = [f'Axis {item.axis} ({item.column}): tau {lo:.3g} .. {hi:.4g} s used; '
             f'{fit.band.note if fit.band is not None else ""}',
             f'  {terms} ({100 * fit.ci:.0f} % intervals, IEEE Std 952)']
    if item.set_aside is not None:
        lines.append(f'  {item.set_aside["description"]}')
    lines += [f'  warning: {warning}' for warning in fit.warnings]
    return lines


def accel_lines(accel):
    """
    Provenance of the accelerometer figures of a noise export (none when the user gave them alone).

    ``accel`` is an :class:`~gyro_emulator.analysis.calibrate.accel_figures.AccelFigures`
    or None. With the log's accelerometer: its axes as :func:`axis_lines`,
    its notes, its grid, and how the two figures were chosen, or that the
    user's replace them.
    """
    if accel is None or accel.calibration is None:
        return []
    cal, log = accel.calibration, accel.log
    lines = [f'Accelerometer of the same log (the same IEEE Std 952 identification, '
             f'{cal.sense.unit}):']
    for item in cal.axes:
        lines += axis_lines(item, cal.sense)
    lines += [f'Accelerometer axis left out: {note}' for note in cal.skipped]
    lines += [f'Accelerometer note: {note}' for note in cal.notes]
    if cal.lsb > 0.0:
        lines.append(f'Accelerometer samples lie on a grid of {cal.lsb:.6g} m/s^2 = '
                     f'{float(units.m_s2_to_mg(cal.lsb)):.6g} mg.')
    logged = (f'N_a {float_text(log.arw_rad_s_sqrt_hz)} m/s^2/sqrt(Hz), K_a '
              f'{float_text(log.rrw_rad_s_sqrt_s)} m/s^3/sqrt(Hz)')
    if accel.given:
        lines.append('Accelerometer written: the figures given by the user (not inflated) in '
                     f"place of the log's {logged}.")
    else:
        lines.append(f'Accelerometer written: {logged} ({log.note or "the fitted values"}'
                     + (f'; inflation factor {log.inflate:g}' if log.inflate != 1.0 else '')
                     + ').')
    return lines


def noise_lines(calibration, exported, tool, convention, accel=None):
    """
    Provenance of a noise export: source, tau range, fitted terms, convention, inflation.

    The accelerometer's (:func:`accel_lines`) follow when ``accel`` came from the log.
    """
    lines = [f'Written by `gyro-emulator calibrate noise --format {tool}`.',
             f'Source log: {calibration.source} ({calibration.rate_hz:.6g} Hz, '
             f'{calibration.duration_s:.1f} s).']
    for item in calibration.axes:
        lines += axis_lines(item)
    for note in calibration.skipped:
        lines.append(f'Axis left out: {note}')
    for note in calibration.timing:
        lines.append(f'Timing: {note}')
    lines.append(f'Convention: {convention}')
    if exported is not None:
        lines.append(f'Chosen: {exported.note or "the fitted values"}.')
        lines.append(f'Inflation factor: {exported.inflate:g}'
                     + (' (none)' if exported.inflate == 1.0 else ' (applied to N, B and K)'))
    if calibration.lsb_rad_s > 0.0:
        lines.append(f'Samples lie on a grid of {calibration.lsb_rad_s:.6g} rad/s = '
                     f'{float(units.rad_s_to_deg_s(calibration.lsb_rad_s)):.6g} deg/s (the '
                     'LSB, or the precision the log was written with).')
    return lines + accel_lines(accel)


def thermal_lines(fit, tool, convention):
    """Provenance of a thermal export: source, span, rule, order, confounding, spread."""
    lines = [f'Written by `gyro-emulator calibrate thermal --format {tool}`.',
             f'Source log: {", ".join(fit.sources)}; {len(fit.groups_temp_c)} groups '
             f'({fit.grouping}), temperature {fit.temp_min_c:.2f} .. {fit.temp_max_c:.2f} C '
             f'(span {fit.span_k:.2f} K, {fit.distinct_temps} distinct).',
             f'Polynomial order {fit.order}: {fit.order_reason}',
             f'Convention: {convention}']
    return lines + _thermal_axes(fit)


def _thermal_axes(fit):
    """Each axis's polynomial and residual, in the fit's unit; then the notes."""
    lines = []
    unit = fit.sense.unit
    for axis, coeffs in fit.coefficients.items():
        shown = ', '.join(f'{c:+.4g}' for c in coeffs)
        lines.append(f'Axis {axis}: {unit} vs (T - {fit.temp_ref_c:.3f} C)^0..{fit.order}: '
                     f'{shown}; residual rms {fit.residual_rms[axis]:.3g} {unit} vs '
                     f'within-group noise {fit.group_noise[axis]:.3g} {unit}')
    for note in fit.notes:
        lines.append(f'Note: {note}')
    return lines


def accel_thermal_lines(fit, what):
    """
    Provenance of the accelerometer part of a thermal export: its fit and what is written.

    ``fit`` is the accelerometer's ThermalFit; ``what`` says what the file
    holds of it.
    """
    lines = [f'Accelerometer ({what}): the same fit on its axes, {len(fit.groups_temp_c)} '
             f'groups, temperature {fit.temp_min_c:.2f} .. {fit.temp_max_c:.2f} C; polynomial '
             f'order {fit.order}: {fit.order_reason}',
             'At rest each axis reads its share of gravity plus its offset: gravity is in the '
             'constant term, and at this one attitude a sensitivity that changes with '
             'temperature reads as an offset change (the fit holds for the attitude of the '
             'log).']
    return lines + [f'Accelerometer {line[0].lower()}{line[1:]}'.replace(
        'note: accelerometer axis', 'note: axis') for line in _thermal_axes(fit)]
