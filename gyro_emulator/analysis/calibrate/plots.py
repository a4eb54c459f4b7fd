"""
Plots of the round trip: the twin's Allan deviation on the log's, and bias against temperature.

:func:`plot_noise_check`: per axis, the log's overlapping Allan deviation
with its confidence band, the twin's (the mean over the simulated records,
with the spread of single records), and the ratio twin / log - 1 against the
+-10 % band. :func:`plot_thermal`: per axis, the log's group means against
temperature with their standard errors, the fitted polynomial over the
logged range, the twin's group means, and the group means after the
exported PX4 correction.
"""

from gyro_emulator import plotting, units
from gyro_emulator.analysis.allan.plot import draw_adev
from gyro_emulator.analysis.calibrate import thermal
from gyro_emulator.analysis.calibrate.twin import ADEV_TOLERANCE
import numpy as np


def plot_noise_check(calibration, check, path, title=''):
    """Write the noise round-trip plot (module docstring) to ``path`` (PNG)."""
    plt = plotting.pyplot()
    axes = list(check.measured)
    fig, grid = plt.subplots(2, len(axes), figsize=(4.2 * len(axes), 5.6), squeeze=False,
                             sharex='col', gridspec_kw={'height_ratios': (3, 1.3)})
    to = units.rad_s_to_deg_h
    for col, axis in enumerate(axes):
        top, bottom = grid[0, col], grid[1, col]
        draw_adev(top, check.measured[axis], label=f'log, axis {axis}')
        runs = np.array([r.adev for r in check.simulated[axis]])
        top.fill_between(check.taus_s, to(runs.min(axis=0)), to(runs.max(axis=0)),
                         color='C1', alpha=0.2, label=f'{len(runs)} simulated records')
        top.loglog(check.taus_s, to(check.twin[axis]), 's-', color='C1', ms=3,
                   label='twin (mean)')
        fit = calibration.axis(axis).fit
        top.loglog(check.taus_s, to(fit.adev(check.taus_s)), 'k--', lw=1.0,
                   label='IEEE Std 952 fit')
        plotting.label(top, '', 'Allan deviation (deg/h)' if col == 0 else '',
                       f'axis {axis}', legend_loc='lower left')
        bottom.semilogx(check.taus_s, 100 * check.ratio[axis], 'o-', color='C1', ms=3,
                        label='twin / log - 1')
        half = 100 * (check.measured[axis].adev_hi / check.measured[axis].adev - 1)
        bottom.fill_between(check.taus_s, -half, half, color='C0', alpha=0.2,
                            label='log interval')
        for sign in (-1, 1):
            bottom.axhline(sign * 100 * ADEV_TOLERANCE, color='C3', lw=0.8)
        bottom.set_ylim(-40, 40)
        plotting.label(bottom, 'tau (s)', '%' if col == 0 else '', legend_loc='lower left')
    if title:
        fig.suptitle(title, fontsize=10)
    plotting.save(fig, path, dpi=90)


def plot_thermal(fit, path, check=None, params=None, title=''):
    """Write the bias-against-temperature plot (module docstring) to ``path`` (PNG)."""
    plt = plotting.pyplot()
    axes = list(fit.groups)
    rows = 2 if params is not None else 1
    fig, grid = plt.subplots(rows, len(axes), figsize=(4.2 * len(axes), 3.2 * rows + 0.4),
                             squeeze=False, sharex='col')
    to = units.rad_s_to_deg_s
    dense = np.linspace(fit.temp_min_c, fit.temp_max_c, 100)
    for col, axis in enumerate(axes):
        g = fit.groups[axis]
        ax = grid[0, col]
        ax.errorbar(g.temp_c, to(g.rate_rad_s), yerr=to(g.sem_rad_s), fmt='o', ms=3,
                    color='C0', label='log: group means')
        ax.plot(dense, to(fit.bias(axis, dense)), 'k-', lw=1.2,
                label=f'fit, order {fit.order}')
        if check is not None:
            ax.plot(g.temp_c, to(check.twin[axis]), 'x', color='C1', ms=5,
                    label='twin (simulate)')
        plotting.label(ax, '' if rows > 1 else 'die temperature (C)',
                       'bias (deg/s)' if col == 0 else '', f'axis {axis}')
        if params is not None:
            low = grid[1, col]
            after = g.rate_rad_s - thermal.px4_offset(params, axis, g.temp_c)
            low.plot(g.temp_c, 1e3 * to(g.rate_rad_s - np.mean(g.rate_rad_s)), 'o', ms=3,
                     color='0.6', label='before (mean removed)')
            low.plot(g.temp_c, 1e3 * to(after), 'o', ms=3, color='C2',
                     label='after the PX4 correction')
            low.axhline(0.0, color='k', lw=0.6)
            plotting.label(low, 'die temperature (C)', 'mdeg/s' if col == 0 else '')
    if title:
        fig.suptitle(title, fontsize=10)
    plotting.save(fig, path, dpi=90)
