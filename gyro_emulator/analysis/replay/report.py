"""Comparison of emulated and measured output: residuals, Allan deviations, report, plots."""

from dataclasses import dataclass
import os

from gyro_emulator import atomic, plotting, units
from gyro_emulator.analysis import allan
from gyro_emulator.units import AXES, NS_PER_S
import numpy as np


@dataclass(frozen=True)
class Comparison:
    """
    Emulated vs measured gyro output at matched samples.

    Attributes
    ----------
    stamp_ns : numpy.ndarray of int64
        Emulated output stamps of the matched samples, ns.
    emulated_rad_s, measured_rad_s, truth_rad_s : numpy.ndarray, shape (K, 3)
        Outputs and the true (input) rate at the matched samples.
    matched : int
        Samples matched (measured within half a period of an emulated one).
    emulated_count, measured_count : int
        Samples of each stream.
    stats : dict
        Residual statistics (see :func:`compare`).
    adev : dict
        Allan deviation curves, per signal and axis.

    """

    stamp_ns: np.ndarray
    emulated_rad_s: np.ndarray
    measured_rad_s: np.ndarray
    truth_rad_s: np.ndarray
    matched: int
    emulated_count: int
    measured_count: int
    stats: dict
    adev: dict


def _axis_stats(x):
    return {'mean': float(np.mean(x)), 'std': float(np.std(x)),
            'rms': float(np.sqrt(np.mean(x * x))), 'max_abs': float(np.max(np.abs(x))),
            'p95_abs': float(np.percentile(np.abs(x), 95))}


def _adev_curves(signal, rate_hz):
    if signal.shape[0] < 16:
        return None
    curves = []
    for axis in range(3):
        result = allan.overlapping_adev(signal[:, axis], rate_hz)
        curves.append({'taus_s': result.taus_s.tolist(), 'adev_rad_s': result.adev.tolist()})
    return curves


def compare(inputs, batch):
    """
    Match emulated and measured samples and compute the residual statistics.

    Each emulated output (stamped sample time + output delay) is paired with
    the measured sample nearest in stamp, if within half a sample period.
    ``residual = emulated - measured``. With the command source the error
    signals ``output - true rate`` of both are also summarised and their
    Allan deviations overlaid; with the imu source (truth = measured) the
    Allan deviations of the two outputs are.

    Returns
    -------
    Comparison

    """
    delay_ns = np.round(np.asarray(batch.output_delay_s, dtype=float) * NS_PER_S)
    emulated_stamp = inputs.stamp_ns + delay_ns.astype(np.int64)
    if inputs.source == 'imu':
        emulated_stamp = inputs.stamp_ns
    n = len(emulated_stamp)
    stats = {'source': inputs.source, 'rate_hz': inputs.rate_hz, 'samples': n}
    if inputs.measured_rad_s is None or inputs.measured_stamp_ns.size == 0:
        empty = np.zeros((0, 3))
        stats['matched'] = 0
        return Comparison(emulated_stamp[:0], empty, empty, empty, 0, n, 0, stats,
                          {'emulated_error' if inputs.source == 'command' else 'emulated':
                           _adev_curves(batch.gyro_rad_s - inputs.rate_rad_s, inputs.rate_hz)})
    m_stamp = inputs.measured_stamp_ns
    half = NS_PER_S / inputs.rate_hz / 2.0
    right = np.clip(np.searchsorted(m_stamp, emulated_stamp), 0, len(m_stamp) - 1)
    left = np.clip(right - 1, 0, len(m_stamp) - 1)
    pick = np.where(np.abs(m_stamp[left] - emulated_stamp) <=
                    np.abs(m_stamp[right] - emulated_stamp), left, right)
    ok = np.abs(m_stamp[pick] - emulated_stamp) <= half
    # one measured sample pairs with at most one emulated sample
    ok &= np.concatenate(([True], pick[1:] != pick[:-1]))
    emulated = batch.gyro_rad_s[ok]
    measured = inputs.measured_rad_s[pick[ok]]
    truth = inputs.rate_rad_s[ok]
    matched = int(ok.sum())
    stats['matched'] = matched
    stats['measured_samples'] = int(len(m_stamp))
    adev = {}
    if matched:
        residual = emulated - measured
        axes = AXES
        stats['residual_rad_s'] = {axes[i]: _axis_stats(residual[:, i]) for i in range(3)}
        stats['identical'] = bool(np.array_equal(emulated, measured))
        if inputs.source == 'command':
            for name, out in (('measured_error_rad_s', measured),
                              ('emulated_error_rad_s', emulated)):
                err = out - truth
                stats[name] = {axes[i]: _axis_stats(err[:, i]) for i in range(3)}
            adev['measured_error'] = _adev_curves(measured - truth, inputs.rate_hz)
            adev['emulated_error'] = _adev_curves(emulated - truth, inputs.rate_hz)
        else:
            adev['measured'] = _adev_curves(measured, inputs.rate_hz)
            adev['emulated'] = _adev_curves(emulated, inputs.rate_hz)
    return Comparison(emulated_stamp[ok], emulated, measured, truth, matched, n,
                      int(len(m_stamp)), stats, adev)


def report_text(comparison, inputs, header=()):
    """Return the comparison as Markdown (residual table in deg/s and deg/h)."""
    lines = ['# Replay report', '']
    lines += [f'- {h}' for h in header]
    used = ', '.join(f'{k}={v}' for k, v in inputs.topics.items() if v)
    lines += [f'- source: {inputs.source} ({used})',
              f'- sample rate: {inputs.rate_hz:g} Hz, {comparison.emulated_count} emulated '
              f'samples, {comparison.measured_count} measured, {comparison.matched} matched']
    lines += [f'- {note}' for note in inputs.notes]
    stats = comparison.stats
    if not comparison.matched:
        lines += ['', 'No measured gyro output to compare with.']
        return '\n'.join(lines) + '\n'
    lines += ['', '## Residual (emulated - measured)', '',
              '| axis | mean (deg/h) | std (deg/s) | RMS (deg/s) | max abs (deg/s) |',
              '|---|---|---|---|---|']
    for axis, s in stats['residual_rad_s'].items():
        lines.append(f'| {axis} | {units.rad_s_to_deg_h(s["mean"]):.4g} | '
                     f'{np.rad2deg(s["std"]):.4g} | {np.rad2deg(s["rms"]):.4g} | '
                     f'{np.rad2deg(s["max_abs"]):.4g} |')
    if 'measured_error_rad_s' in stats:
        lines += ['', '## Errors against the commanded rate (output - truth)', '',
                  '| axis | measured bias (deg/h) | emulated bias (deg/h) | measured std '
                  '(deg/s) | emulated std (deg/s) |', '|---|---|---|---|---|']
        for axis in AXES:
            m, e = stats['measured_error_rad_s'][axis], stats['emulated_error_rad_s'][axis]
            lines.append(f'| {axis} | {units.rad_s_to_deg_h(m["mean"]):.4g} | '
                         f'{units.rad_s_to_deg_h(e["mean"]):.4g} | '
                         f'{np.rad2deg(m["std"]):.4g} | {np.rad2deg(e["std"]):.4g} |')
    if stats.get('identical'):
        lines += ['', 'The emulated output is identical to the measured one.']
    return '\n'.join(lines) + '\n'


def plot_report(comparison, inputs, out_dir):
    """Write rates.png, residual.png and allan.png (each whole or absent); return their paths."""
    plt = plotting.pyplot()

    paths = []
    if not comparison.matched:
        return paths
    t = (comparison.stamp_ns - comparison.stamp_ns[0]) / NS_PER_S
    step = max(1, len(t) // 20000)
    deg = np.rad2deg
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for i, ax in enumerate(axes):
        ax.plot(t[::step], deg(comparison.measured_rad_s[::step, i]), lw=0.6,
                label='measured')
        ax.plot(t[::step], deg(comparison.emulated_rad_s[::step, i]), lw=0.6, alpha=0.8,
                label='emulated')
        if inputs.source == 'command':
            ax.plot(t[::step], deg(comparison.truth_rad_s[::step, i]), 'k--', lw=0.6,
                    label='commanded')
        ax.set_ylabel(f'{AXES[i]} (deg/s)')
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8, loc='upper right')
    axes[-1].set_xlabel('time (s)')
    fig.suptitle('Gyro output: measured vs emulated')
    paths.append(os.path.join(out_dir, 'rates.png'))
    plotting.save(fig, paths[-1], dpi=110)

    residual = deg(comparison.emulated_rad_s - comparison.measured_rad_s)
    fig, axes = plt.subplots(3, 2, figsize=(10, 7), gridspec_kw={'width_ratios': [3, 1]})
    for i in range(3):
        axes[i, 0].plot(t[::step], residual[::step, i], lw=0.5)
        axes[i, 0].set_ylabel(f'{AXES[i]} (deg/s)')
        axes[i, 0].grid(True, alpha=0.3)
        axes[i, 1].hist(residual[:, i], bins=60)
    axes[-1, 0].set_xlabel('time (s)')
    fig.suptitle('Residual: emulated - measured')
    paths.append(os.path.join(out_dir, 'residual.png'))
    plotting.save(fig, paths[-1], dpi=110)

    curves = {k: v for k, v in comparison.adev.items() if v}
    if curves:
        fig, axes = plt.subplots(1, 3, figsize=(12, 4), sharey=True)
        for i, ax in enumerate(axes):
            for name, per_axis in sorted(curves.items()):
                ax.loglog(per_axis[i]['taus_s'],
                          units.rad_s_to_deg_h(np.asarray(per_axis[i]['adev_rad_s'])),
                          'o-' if name.startswith('measured') else 's--', ms=3,
                          label=name.replace('_', ' '))
            ax.set_title(f'{AXES[i]} axis')
            ax.set_xlabel('tau (s)')
            ax.grid(True, which='both', alpha=0.3)
        axes[0].set_ylabel('Allan deviation (deg/h)')
        axes[0].legend(fontsize=8)
        fig.suptitle('Overlapping Allan deviation: measured vs emulated')
        paths.append(os.path.join(out_dir, 'allan.png'))
        plotting.save(fig, paths[-1], dpi=110)
    return paths


def write_report(out_dir, comparison, inputs, header=(), plots=True):
    """
    Write report.json, report.md and the PNG plots into ``out_dir``; return the paths.

    Each file is written whole or not at all (:mod:`gyro_emulator.atomic`).
    """
    os.makedirs(out_dir, exist_ok=True)
    paths = []
    data = {'stats': comparison.stats, 'topics': inputs.topics, 'notes': inputs.notes,
            'header': list(header), 'adev': comparison.adev}
    path = os.path.join(out_dir, 'report.json')
    atomic.write_json(path, data, indent=1)
    paths.append(path)
    path = os.path.join(out_dir, 'report.md')
    atomic.write_text(path, report_text(comparison, inputs, header))
    paths.append(path)
    if plots:
        paths += plot_report(comparison, inputs, out_dir)
    return paths
