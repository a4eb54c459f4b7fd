"""
The diagnose report: a Markdown page with PNG residual plots.

Residuals (measured minus model, bin means, rad/s) are plotted against
temperature, applied rate and time (each when the record varies it),
before (the user-calibrated baseline) and after (the chosen causes, fitted
on the whole record), with the stretches set aside as outliers marked on
the time axis. The page gives the verdict, the chosen causes with their
parameters, their 95 % intervals and held-out gains, what could not be
told apart, the residual against its noise floor, and every candidate of
each selection step.
"""

import os
import re

from gyro_emulator import atomic, plotting
from gyro_emulator.analysis.diagnose import intervals, ruled_out
import numpy as np

PLOTS = (('temperature', 'temp_c', 'temperature reading (C)'),
         ('rate', 'rate', 'applied rate (rad/s)'),
         ('time', 'time_s', 'time (s)'))


def gain_text(gain):
    """
    Return a held-out gain for a table: percent, or how many times worse.

    A candidate whose fit blows up on the held-out folds (a law extrapolated
    beyond the temperatures it was fitted on) can be hundreds of times worse
    than the baseline; -36162 % says that badly.
    """
    if gain < -1.0:
        return f'worse: {1.0 - gain:.3g}x the RMSE'
    return f'{100 * gain:.2f} %'


def terminal_lines(diagnosis):
    """Return what ``diagnose`` prints: the record, the verdict, the causes, the candidates."""
    d, sa = diagnosis, diagnosis.set_aside
    lines = [f'{d.record.rows} samples, {d.record.duration_s:.0f} s; baseline held-out RMSE '
             f'{d.baseline.rmse_rad_s:.4g} rad/s; set aside {sa.count} samples '
             f'({100 * sa.fraction:.3f} %)']
    if d.reference is not None:
        lines.append(f'noise held fixed from the reference {reference_text(d.reference)}')
    lines.append(f'verdict: {d.verdict}')
    for i, e in enumerate(d.selected, 1):
        alike = (f"; cannot be told from {', '.join(e.indistinguishable_from)}"
                 if e.indistinguishable_from else '')
        lines.append(f'cause {i}: {e.effect} ({e.kind})  gain {100 * e.gain:.1f} %  '
                     f'p {e.p_value:.1e}{alike}')
        lines += [f'  {name} = {parameter_text(p)}' for name, p in e.parameters.items()]
        own = e.part_sf_temp_coeff_per_k
        if own is not None:
            lines.append(f"  the part's own SF tempco = {own.value:.5g} 1/K, 95 % "
                         f'{_interval_text(own.interval)} (the physics: '
                         f'{own.physics_per_k:.5g} 1/K; a compensated part: '
                         f'{own.datasheet_per_k:.3g} 1/K): '
                         + ('compensated' if own.compensated else 'not read as compensated'))
    if d.temperature_polynomial.note:
        lines.append(f'note: {d.temperature_polynomial.note}')
    if not d.selected:
        lines.append('best: none')
    lines.append(d.residual.message)
    lines += [f'confounded: {c.a} and {c.b} (r = {c.correlation:+.4f})' for c in d.confounded]
    lines += [f'experiment: {text}' for text in d.experiments]
    lines += [f'supported in-sample, not confirmed on held-out data: {e.effect} '
              f'(p {e.p_value:.1e}; {e.reason})' for e in d.supported_in_sample]
    if d.ruled_out:
        lines.append('ruled out (95 %): ' + ruled_out_text(d.ruled_out))
    lines += [f'  {f.effect:<26} gain {gain_text(f.gain):>9}  p {f.p_value:.1e}  '
              f'dBIC {f.delta_bic:9.0f}  {_finding_flag(f)}'
              for f in d.findings]
    return lines + [f'  {nt.effect:<26} not tested: {nt.reason}' for nt in d.not_tested]


def reference_text(ref):
    """Return the reference record's noise in one phrase."""
    return (f'{ref.source} ({ref.duration_s:.0f} s): N {ref.arw_rad_s_sqrt_hz:.3g} '
            f'rad/s/sqrt(Hz), B {ref.bias_instability_rad_s:.3g} rad/s, K '
            f'{ref.rrw_rad_s_sqrt_s:.3g} rad/s/sqrt(s) (Allan deviation up to '
            f'{ref.allan_tau_max_s:.3g} s)')


def _finding_flag(f):
    return 'significant' if f.significant else ('in-sample only' if f.in_sample_only else '')


def ruled_out_text(bounds):
    """Return the bounds as "bias tempco above 0.0006 deg/s/K; ..." (:func:`.ruled_out.text`)."""
    return ruled_out.text(bounds)


def _interval_text(interval):
    return 'n/a' if interval is None else f'[{interval[0]:.5g}, {interval[1]:.5g}]'


def parameter_text(p):
    """Return a parameter as "value [low, high] unit (95 %, how)" or "value: not measured"."""
    if p.interval is None:
        return f'{p.value:.5g} {p.unit}: not measured' + (
            f' ({p.method[len("not measured: "):]})' if p.method and
            p.method.startswith('not measured: ') else '')
    how = next((word for word in ('profile', 'sandwich') if p.method and
                p.method.startswith(word)), 'jackknife')
    edge = re.search(r'its (\w+(?: and \w+)?) ends? at the edge of the searched range',
                     p.method or '')
    if edge:     # the interval may reach beyond the search: the terminal says so too
        how += f'; its {edge.group(1)} end at the edge of the searched range'
    if p.method and p.method.endswith(intervals.SHAPES_NOTE):
        how += "; over the rate's shapes between samples"
    return f'{p.value:.5g} {_interval_text(p.interval)} {p.unit} (95 %, {how})'


def _binned_curve(x, r, groups=25):
    """Mean residual in equal-count groups of x, for a trend line."""
    if np.ptp(x) <= 0.0:
        return np.array([x[0]]), np.array([np.mean(r)])
    order = np.argsort(x, kind='stable')
    parts = np.array_split(order, min(groups, len(order)))
    return (np.array([np.mean(x[p]) for p in parts]),
            np.array([np.mean(r[p]) for p in parts]))


def _panel(ax, x, res, title, label):
    """One residual panel: bin means (at most 3000 drawn), their group-mean curve, the RMS."""
    every = max(1, len(x) // 3000)
    ax.plot(x[::every], res[::every], '.', ms=1.5, alpha=0.35, color='tab:blue',
            rasterized=True, label='bin means' + (f' (1 in {every})' if every > 1 else ''))
    cx, cy = _binned_curve(x, res)
    ax.plot(cx, cy, '-', color='tab:red', lw=1.5, label='group mean')
    ax.axhline(0.0, color='k', lw=0.6)
    rms = float(np.sqrt(np.mean(res ** 2)))
    ax.text(0.02, 0.95, f'rms of bin means {rms:.3g} rad/s', transform=ax.transAxes,
            fontsize=8, va='top')
    lim = 1.15 * float(np.percentile(np.abs(res), 99.8))
    ax.set_ylim(-lim or -1e-9, lim or 1e-9)
    plotting.label(ax, label, 'measured - model (rad/s)', title)
    ax.title.set_fontsize(10)


def plot_residuals(diagnosis, out_dir):
    """
    Write residuals_<temperature|rate|time>.png; return their file names.

    Parameters
    ----------
    diagnosis : gyro_emulator.analysis.diagnose.diagnosis.Diagnosis
        The result of :func:`gyro_emulator.analysis.diagnose.diagnose`.
    out_dir : str
        Directory for the PNG files (created if needed).

    Returns
    -------
    list of str

    """
    plt = plotting.pyplot()
    os.makedirs(out_dir, exist_ok=True)
    plots = diagnosis.plots
    b = plots.prepared.binned
    names = []
    for key, attr, label in PLOTS:
        x = getattr(b, attr)
        if (key == 'temperature' and not diagnosis.record.has_temp) or np.ptp(x) <= 0.0:
            continue
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        _panel(axes[0], x, plots.before, 'before: paper model, user calibration', label)
        _panel(axes[1], x, plots.after, 'after: ' + plots.after_label, label)
        if key == 'time':
            for start, end, _ in diagnosis.set_aside.segments:
                for ax in axes:
                    ax.axvspan(start, max(end, start + 0.5 * b.bins.dt_s), color='tab:orange',
                               alpha=0.3, lw=0)
        name = f'residuals_{key}.png'
        plotting.save(fig, os.path.join(out_dir, name), dpi=85)
        names.append(name)
    return names


def _fmt(v):
    return 'n/a' if v is None or not np.isfinite(v) else f'{v:.4g}'


def markdown(doc, plots=()):
    """
    Return the report page of a diagnosis.

    Parameters
    ----------
    doc : gyro_emulator.analysis.diagnose.diagnosis.Diagnosis
        What ``diagnose`` found.
    plots : sequence of str
        PNG file names to embed (relative to the page).

    Returns
    -------
    str

    """
    sections = (('Verdict', _verdict_lines(doc)),
                ('What the data rule out', _ruled_out_lines(doc)),
                ('Supported in-sample, not confirmed on held-out data', [
                    f'- `{e.effect}`: p = {e.p_value:.2g}; {e.reason}.'
                    for e in doc.supported_in_sample] + ([''] if doc.supported_in_sample else [])),
                ('What cannot be told apart', _confound_lines(doc)),
                ('Outliers set aside', _set_aside_lines(doc)),
                ('Baseline', [_baseline_text(doc), '']),
                ('Selection, step by step', _steps_lines(doc)),
                ('Residuals before and after',
                 [line for name in plots for line in (f'![{name}]({name})', '')]),
                ('Method', [_method_text(doc), '']))
    lines = _summary_lines(doc)
    for title, body in sections:
        if body:
            lines += [f'## {title}', ''] + body
    return '\n'.join(lines)


def _summary_lines(doc):
    """Return the title and one paragraph on the record."""
    inp = doc.record
    temp = ('no temperature reading' if not inp.has_temp else
            f'temperature {inp.temp_range_c[0]:.1f}...{inp.temp_range_c[1]:.1f} C')
    return [f"# Diagnosis of `{os.path.basename(inp.source) or 'record'}`",
            '',
            f'{inp.rows} samples over {inp.duration_s:.0f} s '
            f'(sample interval {inp.sample_interval_s:.4g} s), {temp}, rms applied rate '
            f'{inp.rate_rms_rad_s:.3g} rad/s, acceleration '
            f"{'recorded' if inp.has_accel else 'not recorded'}. Fits run "
            f'on {inp.bins} bin means of {inp.bin_s:.3g} s.', '']


def _evidence_text(entry):
    """Return which test and which gain the cause rests on."""
    ev = entry.evidence
    p_ss = ev.p_state_space
    if ev.route == 'reference_noise':
        return (f'The decision rests on the likelihood ratio of the cause with the noise of '
                f'the reference record held fixed (LR {ev.likelihood_ratio:.1f}, p = '
                f'{p_ss:.2g}; the fold test gave p = {ev.p_fold_test:.2g}) and on its gain in '
                f'predicting the averaged residual ({100 * ev.gain_predictive:.1f} %).')
    if ev.route == 'state_space':
        return (f'The decision rests on the likelihood ratio of the noise and the cause '
                f'estimated jointly (LR {ev.likelihood_ratio:.1f}, p = {p_ss:.2g}; the '
                f'fold test gave p = {ev.p_fold_test:.2g}) and on its gain in '
                f'predicting the averaged residual ({100 * ev.gain_predictive:.1f} %), '
                'where a slow effect lives: per sample, white noise dominates.')
    return ('The decision rests on the fold test of the held-out gain per sample (p = '
            f'{ev.p_fold_test:.2g}'
            + ('' if p_ss is None else f'; the joint likelihood test gave p = {p_ss:.2g}')
            + ').')


def _cause_lines(entry):
    """One chosen cause: its sentence, gains, test and parameter table."""
    lines = [f'### {entry.effect} ({entry.kind})', '', entry.cause, '',
             f'Held-out gain {100 * entry.gain:.1f} % against the user-calibrated baseline '
             f'({100 * entry.gain_step:.1f} % over the step before, per sample; '
             f'{100 * entry.gain_binned:.1f} % in the averaged residual the verdict '
             f'uses); p = {entry.p_value:.2g}; BIC on {entry.effective_bins:.0f} '
             f'effective bins {entry.delta_bic:.0f}.', '', _evidence_text(entry)]
    if entry.indistinguishable_from:
        lines += ['', 'Not separable on held-out data from: '
                  + ', '.join(f'`{e}`' for e in entry.indistinguishable_from) + '.']
    if entry.kind == 'generic' and entry.mechanisms:
        lines += ['', 'Mechanisms that could produce it: '
                  + '; '.join(entry.mechanisms) + '.']
    lines += ['', '| parameter | value | 1 sigma | 95 % interval | unit | how | meaning |',
              '|---|---|---|---|---|---|---|']
    lines += [f'| {name} | {_fmt(p.value)} | {_fmt(p.sigma)} | {_interval_text(p.interval)} '
              f'| {p.unit} | {p.method} | {p.meaning} |' for name, p in entry.parameters.items()]
    return lines + ['']


def _verdict_lines(doc):
    """Return the verdict, the residual message and every chosen cause."""
    res = doc.residual
    lines = [f'**{doc.verdict}**', '', res.message, '']
    if not doc.selected:
        lines += ['No cause was chosen (`none`).', '']
    for entry in doc.selected:
        lines += _cause_lines(entry)
    noise = res.noise
    if doc.reference is not None:
        lines += [f'The noise of the nulls is held fixed from the reference record '
                  f'{reference_text(doc.reference)}; the per-sample spread is the '
                  "record's own.", '']
    lines += [f'Noise of the final residual: {noise.white_sigma_rad_s:.3g} rad/s per sample; '
              f'N = {noise.arw_rad_s_sqrt_hz:.3g} rad/s/sqrt(Hz), B = '
              f'{noise.bias_instability_rad_s:.3g} rad/s, K = '
              f'{noise.rrw_rad_s_sqrt_s:.3g} rad/s/sqrt(s) ({allan_text(noise)}).', '']
    note = doc.temperature_polynomial.note
    if note:
        lines += [note[0].upper() + note[1:] + '.', '']
    return lines


def allan_text(noise):
    """Return what the fitted N, B, K rest on: the Allan deviation's reach, or that it has none."""
    if noise.tau_max_s > 0.0:
        return f'robust Allan deviation up to {noise.tau_max_s:.3g} s'
    return ('no Allan deviation: no stretch of the record holds enough bins for three '
            'averaging times, so B and K are not measured (0) and N is the short-term '
            'spread: the floor holds the fast noise only')


def _ruled_out_lines(doc):
    """Return the 95 % upper bounds of the causes tested and not found, as a table."""
    if not doc.ruled_out:
        return []
    return (['Every cause the record could test and that was not chosen, with the largest '
             'size its 95 % interval allows (beside the final model):', '',
             '| cause | quantity | 95 % upper bound | unit |', '|---|---|---|---|']
            + [f'| {b.effect} | {b.quantity} | {b.upper:.3g} | {b.unit} |'
               for b in doc.ruled_out] + [''])


def _confound_lines(doc):
    lines = [f'- `{c.a}` and `{c.b}` move together: correlation {c.correlation:+.4f}.'
             for c in doc.confounded]
    lines += [f'- {text}' for text in doc.experiments]
    return lines + [''] if lines else []


def _set_aside_lines(doc):
    sa = doc.set_aside
    if not sa.count:
        return [f'None (threshold {sa.threshold_sigma:g} robust sigma).', '']
    lines = [f'{sa.count} samples ({100 * sa.fraction:.3f} %) in '
             f'{sa.segments_total} stretches, beyond {sa.threshold_sigma:g} robust sigma '
             f'({sa.sigma_rad_s:.3g} rad/s) of the local high-passed residual. Baseline RMSE '
             f'with them: {sa.baseline_rmse_all_samples_rad_s:.4g} rad/s'
             + ('' if sa.best_gain_all_samples is None else
                f"; the first cause's gain counted on every sample: "
                f'{100 * sa.best_gain_all_samples:.1f} %') + '.', '',
             '| from (s) | to (s) | samples |', '|---|---|---|']
    lines += [f'| {a:.3f} | {b:.3f} | {n} |' for a, b, n in sa.segments[:20]]
    return lines + ['']


def _baseline_text(doc):
    """Return the paragraph on the baseline model, its calibration and held-out RMSE."""
    cal = doc.calibration
    return (f'{doc.baseline.model}. Calibration: bias '
            f'{cal.bias_rad_s:.4g} rad/s, scale factor '
            f'{cal.scale_factor:.5g}'
            + ('' if cal.scale_factor_calibrated else
               ' (nominal: no rate excitation near the reference temperature)')
            + f', from {calibration_samples_text(doc)}. Held-out '
            f'RMSE {doc.baseline.rmse_rad_s:.4g} rad/s (recalibrated '
            'on all training data: '
            f'{doc.baseline.recalibrated_rmse_rad_s:.4g} rad/s).')


def calibration_samples_text(doc):
    """Return which samples the calibration used: the temperature window, or all of them."""
    cal = doc.calibration
    if not doc.record.has_temp:
        return (f'all {cal.samples} samples (the record has no temperature reading, so '
                f'no window about {cal.ref_temp_c:.1f} C could be chosen)')
    return f'{cal.samples} samples within {cal.window_c:.2f} C of {cal.ref_temp_c:.1f} C'


_TEST_TEXT = {'fold_test': 'fold', 'state_space': 'likelihood',
              'reference_noise': 'likelihood, reference noise'}


def _steps_lines(doc):
    """One table per selection step, then the causes not tested."""
    lines = []
    for i, st in enumerate(doc.steps, 1):
        lines += [f"Step {i}: added `{st.added or 'nothing'}`.", '',
                  '| candidate | held-out RMSE (rad/s) | gain over the step before | '
                  'gain in averaged residual | p | test | '
                  'delta BIC | significant |', '|---|---|---|---|---|---|---|---|']
        lines += [f'| {c.effect} | {c.rmse_rad_s:.4g} | {gain_text(c.gain_step)} '
                  f'| {gain_text(c.gain_binned)} | {c.p_value:.2g} | '
                  f'{_TEST_TEXT[c.route]} | {c.delta_bic:.0f} | '
                  f"{'yes' if c.significant else 'no'} |" for c in st.candidates]
        lines.append('')
    lines += [f'- `{nt.effect}` not tested: {nt.reason}' for nt in doc.not_tested]
    return lines + ['']


def _method_text(doc):
    """Return the selection rules in one paragraph."""
    m = doc.method
    return (f'{m.folds} contiguous cross-validation blocks; every model '
            'is fitted on the other blocks and predicts the held-out one '
            'sample by sample (a step keeps the time found on the whole record). '
            'A cause joins the model when its held-out RMSE gain over the current '
            f'model is >= {100 * m.min_gain:.1f} % (a cause on the applied rate: '
            f'>= {100 * m.min_gain_rate:.1f} %), p < {m.alpha:g} / candidates '
            f'({m.test}) and its {m.information_criterion} drops by more than '
            f'{-m.delta_bic_max:g}. A physical cause must beat its generic '
            f'competitors (p < {m.alpha_tie:g}). Uncertainties: {m.uncertainty}.')


def write_report(diagnosis, out_dir):
    """
    Write ``report.md`` and the residual PNGs into ``out_dir``.

    Parameters
    ----------
    diagnosis : gyro_emulator.analysis.diagnose.diagnosis.Diagnosis
        The result of :func:`gyro_emulator.analysis.diagnose.diagnose`.
    out_dir : str
        Directory for the report (created if needed).

    Returns
    -------
    str
        Path of ``report.md``.

    """
    plots = plot_residuals(diagnosis, out_dir)
    path = os.path.join(out_dir, 'report.md')
    atomic.write_text(path, markdown(diagnosis, plots))
    return path
