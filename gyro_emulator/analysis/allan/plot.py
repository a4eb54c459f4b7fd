"""
Allan deviation plots: the measured curve, its band, the fitted terms and the slopes.

The upper panel shows the overlapping Allan deviation (deg/h) with its
chi-squared band, the five-term fit, each term alone, the band-limited
region left out of the fit and the read-off points; the lower panel the
local log-log slope against the IEEE Std 952 slopes of the terms (-1 Q,
-1/2 N, 0 B, +1/2 K, +1 R).
"""

from gyro_emulator import plotting, units
from gyro_emulator.analysis.allan.adev import local_slopes
from gyro_emulator.analysis.allan.fit import SLOPES, TERMS
import numpy as np

_SYMBOL = {'quantization': 'Q', 'arw': 'N', 'bias_instability': 'B', 'rrw': 'K',
           'rate_ramp': 'R'}


def _term_label(fit, term):
    value = fit.value(term)
    interval = fit.intervals.get(term)
    conv = {'quantization': (lambda v: v * 1e6, 'urad'),
            'arw': (units.rad_s_sqrt_hz_to_arw_deg_sqrt_h, 'deg/sqrt(h)'),
            'bias_instability': (units.rad_s_to_deg_h, 'deg/h'),
            'rrw': (units.rad_s_sqrt_s_to_rrw_deg_h_sqrt_h, 'deg/h/sqrt(h)'),
            'rate_ramp': (lambda v: units.rad_s_to_deg_h(v) * 3600.0, 'deg/h/h')}[term]
    text = f'{_SYMBOL[term]} = {float(conv[0](value)):.3g}'
    if interval is not None:
        text += f' [{float(conv[0](interval.low)):.3g}, {float(conv[0](interval.high)):.3g}]'
    return f'{text} {conv[1]}'


def draw_adev(ax, result, fit=None, label='overlapping ADEV', color='C0'):
    """Draw a measured Allan deviation (deg/h) with its band, and the fit if given."""
    to = units.rad_s_to_deg_h
    taus = result.taus_s
    ax.fill_between(taus, to(result.adev_lo), to(result.adev_hi), color=color, alpha=0.25,
                    label=f'{100 * result.ci:.0f} % confidence')
    ax.loglog(taus, to(result.adev), 'o-', color=color, ms=3, label=label)
    if fit is None:
        return
    dense = np.logspace(np.log10(taus[0]), np.log10(taus[-1]), 200)
    ax.loglog(dense, to(fit.adev(dense)), 'k--', lw=1.2, label='fit (sum of the terms)')
    for term, style in zip(TERMS, (':', ':', ':', ':', ':')):
        if fit.value(term) > 0.0:
            ax.loglog(dense, to(fit.term_adev(term, dense)), style, lw=1.0,
                      label=_term_label(fit, term))
    if fit.band is not None and fit.band.tau_min_s > taus[0]:
        ax.axvspan(taus[0], fit.band.tau_min_s, color='0.85', zorder=0,
                   label='band-limited: left out')
    for term, reading in fit.readings.items():
        if reading.identified:
            i = int(np.argmin(np.abs(taus - reading.tau_s)))
            ax.plot(taus[i], to(result.adev[i]), 's', mfc='none', mec='C3', ms=7)


def plot_adev(result, fit, path, title=''):
    """Write the two-panel Allan deviation plot (module docstring) to ``path`` (PNG)."""
    plt = plotting.pyplot()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7.0, 6.4), sharex=True,
                                      gridspec_kw={'height_ratios': (3, 1.2)})
    draw_adev(top, result, fit)
    positive = result.adev_lo[result.adev_lo > 0]
    if len(positive):
        top.set_ylim(units.rad_s_to_deg_h(np.min(positive)) / 2.0, None)
    plotting.label(top, '', 'Allan deviation (deg/h)', title or 'Overlapping Allan deviation')
    top.legend(fontsize=7, loc='best')
    slopes = local_slopes(result.taus_s, result.adev)
    bottom.semilogx(result.taus_s, slopes, '.-', color='C0', ms=3, label='local slope')
    for term, slope in SLOPES.items():
        bottom.axhline(slope, color='0.6', lw=0.6)
        bottom.text(result.taus_s[-1], slope, f' {_SYMBOL[term]}', va='center', fontsize=7)
    bottom.set_ylim(-1.3, 1.3)
    plotting.label(bottom, 'averaging time tau (s)', 'slope')
    plotting.save(fig, path)
