"""
The diagnose report: a Markdown page with PNG residual plots.

Residuals (measured minus model, bin means, rad/s) are plotted against
temperature, applied rate and time, before (the user-calibrated baseline)
and after (the best cause's model, fitted on the whole record), with the
fitted parameters and their jackknife uncertainty in the page.
"""

import os

import numpy as np

PLOTS = (('temperature', 'temp_c', 'temperature reading (C)'),
         ('rate', 'rate', 'applied rate (rad/s)'),
         ('time', 'time_s', 'time (s)'))


def _binned_curve(x, r, groups=25):
    """Mean residual in equal-count groups of x, for a trend line."""
    if np.ptp(x) <= 0.0:
        return np.array([x[0]]), np.array([np.mean(r)])
    order = np.argsort(x, kind='stable')
    parts = np.array_split(order, min(groups, len(order)))
    return (np.array([np.mean(x[p]) for p in parts]),
            np.array([np.mean(r[p]) for p in parts]))


def plot_residuals(diagnosis, out_dir):
    """
    Write residuals_<temperature|rate|time>.png; return their file names.

    Parameters
    ----------
    diagnosis : gyro_emulator.analysis.diagnose.selection.Diagnosis
        The result of :func:`gyro_emulator.analysis.diagnose.diagnose`.
    out_dir : str
        Directory for the PNG files (created if needed).

    Returns
    -------
    list of str

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    os.makedirs(out_dir, exist_ok=True)
    b = diagnosis.prepared.binned
    names = []
    before, after = diagnosis.residual_before, diagnosis.residual_after
    for key, attr, label in PLOTS:
        x = getattr(b, attr)
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        for ax, res, title in ((axes[0], before, 'before: paper model, '
                                'user calibration'),
                               (axes[1], after, 'after: '
                                + diagnosis.after_label)):
            ax.plot(x, res, '.', ms=1.5, alpha=0.35, color='tab:blue',
                    rasterized=True)
            cx, cy = _binned_curve(x, res)
            ax.plot(cx, cy, '-', color='tab:red', lw=1.5, label='group mean')
            ax.axhline(0.0, color='k', lw=0.6)
            ax.set_title(title, fontsize=10)
            ax.set_xlabel(label)
            ax.grid(True, alpha=0.3)
            rms = float(np.sqrt(np.mean(res ** 2)))
            ax.text(0.02, 0.95, f'rms of bin means {rms:.3g} rad/s',
                    transform=ax.transAxes, fontsize=8, va='top')
            lim = 1.15 * float(np.percentile(np.abs(res), 99.8))
            ax.set_ylim(-lim or -1e-9, lim or 1e-9)
            ax.set_ylabel('residual, measured - model (rad/s)')
        axes[1].legend(loc='lower right', fontsize=8)
        fig.tight_layout()
        name = f'residuals_{key}.png'
        fig.savefig(os.path.join(out_dir, name), dpi=110)
        plt.close(fig)
        names.append(name)
    return names


def _fmt(v):
    return 'n/a' if v is None or not np.isfinite(v) else f'{v:.4g}'


def markdown(doc, plots=()):
    """
    Return the report page for a diagnose JSON document.

    Parameters
    ----------
    doc : dict
        The JSON document of ``gyro-emulator diagnose``.
    plots : sequence of str
        PNG file names to embed (relative to the page).

    Returns
    -------
    str

    """
    sections = (('Verdict', _verdict_lines(doc)),
                ('Baseline', [_baseline_text(doc), '']),
                ('Findings (ranked by held-out RMSE)', _findings_lines(doc)),
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
    inp = doc['input']
    return [f"# Diagnosis of `{os.path.basename(inp['source']) or 'record'}`",
            '',
            f"{inp['rows']} samples over {inp['duration_s']:.0f} s "
            f"(sample interval {inp['sample_interval_s']:.4g} s), "
            f"temperature {inp['temp_range_c'][0]:.1f}..."
            f"{inp['temp_range_c'][1]:.1f} C, rms applied rate "
            f"{inp['rate_rms_rad_s']:.3g} rad/s, acceleration "
            f"{'recorded' if inp['has_accel'] else 'not recorded'}. Fits run "
            f"on {inp['bins']} bin means of {inp['bin_s']:.3g} s.", '']


def _verdict_lines(doc):
    """Return the verdict: the cause, its gain, the residual message, its parameters."""
    best = doc['best']
    if best['effect'] == 'none':
        lines = ['**No cause found** (`none`): no candidate improves the '
                 'held-out fit significantly.']
    else:
        lines = [f"**{best['effect']}**: {best['cause']}", '',
                 f"Held-out RMSE {doc['baseline']['rmse_rad_s']:.4g} -> "
                 f"{best['rmse_rad_s']:.4g} rad/s: gain "
                 f"{100 * best['gain']:.1f} % (gain = 1 - RMSE_cause / "
                 'RMSE_baseline).']
    lines += ['', doc['residual']['message'], '']
    if best['parameters']:
        lines += ['| parameter | value | 1 sigma | unit | meaning |',
                  '|---|---|---|---|---|']
        lines += [f"| {name} | {_fmt(p['value'])} | {_fmt(p['sigma'])} "
                  f"| {p['unit']} | {p['meaning']} |"
                  for name, p in best['parameters'].items()] + ['']
    return lines


def _baseline_text(doc):
    """Return the paragraph on the baseline model, its calibration and held-out RMSE."""
    cal = doc['calibration']
    return (f"{doc['baseline']['model']}. Calibration: bias "
            f"{cal['bias_rad_s']:.4g} rad/s, scale factor "
            f"{cal['scale_factor']:.5g}"
            + ('' if cal['scale_factor_calibrated'] else
               ' (nominal: no rate excitation near the reference temperature)')
            + f", from {cal['samples']} samples within "
            f"{cal['window_c']:.2f} C of {cal['ref_temp_c']:.1f} C. Held-out "
            f"RMSE {doc['baseline']['rmse_rad_s']:.4g} rad/s (recalibrated "
            'on all training data: '
            f"{doc['recalibrated_baseline']['rmse_rad_s']:.4g} rad/s).")


def _findings_lines(doc):
    """Return the table of findings, then the entries not tested."""
    rows = [f"| {f['effect']} | {f['rmse_rad_s']:.4g} | {100 * f['gain']:.2f} % "
            f"| {100 * f['gain_over_recalibrated']:.2f} % | {f['p_value']:.2g} "
            f"| {f['delta_bic']:.0f} | {'yes' if f['significant'] else 'no'} |"
            for f in doc['findings']]
    rows += [f"| {nt['effect']} | not tested: {nt['reason']} | | | | | |"
             for nt in doc['not_tested']]
    return ['| effect | held-out RMSE (rad/s) | gain | gain over recalibrated '
            '| p | delta BIC | significant |',
            '|---|---|---|---|---|---|---|'] + rows + ['']


def _method_text(doc):
    """Return the selection rules in one paragraph."""
    m = doc['method']
    return (f"{m['folds']} contiguous cross-validation blocks; every model "
            'is fitted on the other blocks and predicts the held-out one '
            'sample by sample. A cause is significant when its held-out '
            'RMSE gain over the recalibrated baseline is >= '
            f"{100 * m['min_gain']:.1f} %, a paired test over "
            f"{m['sub_blocks']} sub-blocks gives p < {m['alpha']:g} and its "
            f"BIC is lower by more than {-m['delta_bic_max']:g}. "
            f"Uncertainties: {m['uncertainty']}.")


def write_report(diagnosis, out_dir):
    """
    Write ``report.md`` and the residual PNGs into ``out_dir``.

    Parameters
    ----------
    diagnosis : gyro_emulator.analysis.diagnose.selection.Diagnosis
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
    with open(path, 'w', encoding='utf-8') as handle:
        handle.write(markdown(diagnosis.doc, plots))
    return path
