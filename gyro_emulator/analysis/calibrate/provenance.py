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

#: The value written where the user must fill in a figure this log does not give.
MARKER = 'FILL_IN'
#: The comment beside it.
NOT_MEASURED = 'NOT MEASURED by this gyro log: replace FILL_IN with your own figure'


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


def axis_lines(item):
    """Provenance of one calibrated axis: taus used, N, B, K with intervals, warnings."""
    fit = item.fit
    lo, hi = fit.tau_range_s
    lines = [f'Axis {item.axis} ({item.column}): tau {lo:.3g} .. {hi:.4g} s used; '
             f'{fit.band.note if fit.band is not None else ""}',
             f'  N {_term(fit, "arw", units.rad_s_sqrt_hz_to_arw_deg_sqrt_h, "deg/sqrt(h)")}'
             f', B {_term(fit, "bias_instability", units.rad_s_to_deg_h, "deg/h")}'
             f', K {_term(fit, "rrw", units.rad_s_sqrt_s_to_rrw_deg_h_sqrt_h, "deg/h/sqrt(h)")}'
             f' ({100 * fit.ci:.0f} % intervals, IEEE Std 952)']
    if item.set_aside is not None:
        lines.append(f'  {item.set_aside["description"]}')
    lines += [f'  warning: {warning}' for warning in fit.warnings]
    return lines


def noise_lines(calibration, exported, tool, convention):
    """Provenance of a noise export: source, tau range, fitted terms, convention, inflation."""
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
    return lines


def thermal_lines(fit, tool, convention):
    """Provenance of a thermal export: source, span, rule, order, confounding, spread."""
    lines = [f'Written by `gyro-emulator calibrate thermal --format {tool}`.',
             f'Source log: {", ".join(fit.sources)}; {len(fit.groups_temp_c)} groups '
             f'({fit.grouping}), temperature {fit.temp_min_c:.2f} .. {fit.temp_max_c:.2f} C '
             f'(span {fit.span_k:.2f} K, {fit.distinct_temps} distinct).',
             f'Polynomial order {fit.order}: {fit.order_reason}',
             f'Convention: {convention}']
    for axis, coeffs in fit.coefficients.items():
        shown = ', '.join(f'{c:+.4g}' for c in coeffs)
        lines.append(f'Axis {axis}: rad/s vs (T - {fit.temp_ref_c:.3f} C)^0..{fit.order}: '
                     f'{shown}; residual rms {fit.residual_rms[axis]:.3g} rad/s vs '
                     f'within-group noise {fit.group_noise[axis]:.3g} rad/s')
    for note in fit.notes:
        lines.append(f'Note: {note}')
    return lines
