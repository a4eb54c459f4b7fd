"""
The ``dynamics`` report: exact 2-DOF response against the first-order method.

For a drive-sense split S and a true rate R: the first-order sense amplitude
(Eq 20), the exact harmonic solution of Eq 3-4, the steady state of the
time-domain simulation and the rate channel's bandwidth (:func:`summary`,
:func:`format_summary`), and three plots: the sense amplitude against split,
the rate step response and the rate-channel Bode plot.
"""

from gyro_emulator import plotting
from gyro_emulator.physics import dynamics
from gyro_emulator.units import deg_s_to_rad_s
import numpy as np

#: Splits of the README table, Hz.
TABLE_SPLITS_HZ = (10.0, 50.0, 100.0, 500.0)


def summary(device, split_hz, rate_dps, temp_c):
    """Return the JSON document (SI values) for one operating point."""
    rate = float(deg_s_to_rad_s(rate_dps))
    exact = dynamics.exact_steady_state(device, rate, temp_c, split_hz)
    settle = dynamics.settle_time_s(device, temp_c)
    sim = dynamics.simulate_time_domain(device, settle, rate, temp_c, split_hz,
                                        initial='rest')
    poles = dynamics.rate_channel_poles(device, temp_c, split_hz)
    table = dynamics.exact_steady_state(device, rate, temp_c,
                                        np.array(TABLE_SPLITS_HZ))
    exact_m = float(exact.sense_amplitude_m)
    td_m = float(sim.sense_amplitude_m[-1])
    return {
        'rate_dps': float(rate_dps), 'rate_rad_s': rate, 'temp_c': float(temp_c),
        'split_hz': float(split_hz),
        'drive_freq_hz': float(exact.drive_freq_hz),
        'sense_freq_hz': float(exact.sense_freq_hz),
        'q_drive': float(exact.params.q_drive),
        'q_sense': float(exact.params.q_sense),
        'first_order_m': float(exact.first_order_m),
        'exact_m': exact_m,
        'time_domain_m': td_m,
        'ratio_exact_to_first_order': float(exact.ratio_to_first_order),
        'ratio_time_domain_to_exact': td_m / exact_m if exact_m else None,
        'sense_phase_deg': float(np.degrees(exact.sense_phase_rad)),
        'in_phase_m': float(exact.sense_in_phase_m),
        'quadrature_m': float(exact.sense_quadrature_m),
        'time_domain_s': float(sim.time_s[-1] + 0.5 * sim.period_s[-1]),
        'rate_channel': {
            'bandwidth_hz': dynamics.rate_channel_bandwidth_hz(device, temp_c,
                                                               split_hz),
            'sigma_1_s': poles.sigma_1_s,
            'delta_rad_s': poles.delta_rad_s,
            'tau_s': 1.0 / poles.sigma_1_s,
        },
        'first_order_error_vs_split': [
            {'split_hz': s, 'ratio_exact_to_first_order': float(r),
             'first_order_error_pct': 100.0 * (1.0 - float(r)),
             'first_order_overestimate_pct': 100.0 * (1.0 / float(r) - 1.0)}
            for s, r in zip(TABLE_SPLITS_HZ, table.ratio_to_first_order)],
    }


def format_summary(doc):
    """Return the human summary of :func:`summary`'s document."""
    lines = [
        f"device at {doc['temp_c']:g} C, rate {doc['rate_dps']:g} deg/s, "
        f"split {doc['split_hz']:g} Hz (f_x {doc['drive_freq_hz']:.1f} Hz, "
        f"f_y {doc['sense_freq_hz']:.1f} Hz, Q_s {doc['q_sense']:.1f})",
        f"  first order (Eq 20)   {doc['first_order_m'] * 1e9:10.4f} nm",
        f"  exact (Eq 3-4)        {doc['exact_m'] * 1e9:10.4f} nm   "
        f"ratio to first order {doc['ratio_exact_to_first_order']:.5f}",
        f"  time domain           {doc['time_domain_m'] * 1e9:10.4f} nm   "
        f"after {doc['time_domain_s'] * 1e3:.1f} ms from rest",
        f"  sense phase vs drive velocity {doc['sense_phase_deg']:.2f} deg; "
        f"in-phase {doc['in_phase_m'] * 1e9:.4f} nm, "
        f"quadrature {doc['quadrature_m'] * 1e9:.4f} nm",
        f"  rate channel: bandwidth {doc['rate_channel']['bandwidth_hz']:.1f} Hz, "
        f"tau {doc['rate_channel']['tau_s'] * 1e3:.3f} ms, "
        f"oscillation {doc['rate_channel']['delta_rad_s'] / 6.283185307179586:.1f} Hz",
        '  exact falls short of first order by: ' + ', '.join(
            f"{row['split_hz']:g} Hz {row['first_order_error_pct']:.1f} %"
            for row in doc['first_order_error_vs_split']),
    ]
    return '\n'.join(lines)


def plot_sense_vs_split(path, device, rate_rad_s, temp_c, split_hz):
    """Sense amplitude against split: exact, first order, time domain."""
    plt = plotting.pyplot()

    splits = np.linspace(-500.0, 500.0, 401)
    exact = dynamics.exact_steady_state(device, rate_rad_s, temp_c, splits)
    first = float(np.ravel(exact.first_order_m)[0])
    q_s = float(exact.params.q_sense)
    f_x = float(exact.params.freq_x_hz)
    approx = first / np.sqrt(1.0 + (2.0 * q_s * splits / f_x) ** 2)
    marks = np.unique(np.append([-500, -250, -100, -50, 0, 50, 100, 250, 500],
                                split_hz))
    settle = dynamics.settle_time_s(device, temp_c)
    td = [dynamics.simulate_time_domain(device, settle, rate_rad_s, temp_c, s,
                                        initial='rest').sense_amplitude_m[-1]
          for s in marks]
    fig, ax = plt.subplots(figsize=(7, 4.4))
    ax.plot(splits, exact.sense_amplitude_m * 1e9, lw=2,
            label='exact harmonic solution of Eq 3-4')
    ax.plot(splits, approx * 1e9, 'k:', lw=1,
            label='1 / sqrt(1 + (2 Q df / f)^2) x first order')
    ax.axhline(first * 1e9, color='tab:red', ls='--', lw=1,
               label='first order (paper, Eq 20)')
    ax.plot(marks, np.array(td) * 1e9, 'o', ms=5, mfc='none',
            label='time domain (steady state)')
    plotting.label(ax, 'drive-sense split f_y - f_x (Hz)', 'sense amplitude (nm)',
                   f'sense amplitude at {np.degrees(rate_rad_s):g} deg/s, '
                   f'{temp_c:g} C (Q_s = {q_s:.1f})', 'upper right')
    plotting.save(fig, path)


def _splits(split_hz):
    return sorted({0.0, 50.0, 100.0, 500.0, float(split_hz)})


def plot_step_response(path, device, rate_rad_s, temp_c, split_hz):
    """Normalised rate step response: time domain against the envelope model."""
    plt = plotting.pyplot()

    fig, ax = plt.subplots(figsize=(7, 4.4))
    for i, s in enumerate(_splits(split_hz)):
        res = dynamics.simulate_time_domain(
            device, 0.006, lambda t: rate_rad_s * (t > 0.0), temp_c, s)
        gain = float(dynamics.exact_steady_state(device, rate_rad_s, temp_c,
                                                 s).sense_in_phase_m)
        t_ms = res.time_s * 1e3
        color = f'C{i}'
        ax.plot(t_ms, res.in_phase_m / gain, '.', ms=2, color=color,
                label=f'time domain, split {s:g} Hz')
        ax.plot(t_ms, dynamics.rate_channel_step_response(
            device, res.time_s, temp_c, s), '-', lw=1, color=color)
    ax.plot([], [], 'k-', lw=1, label='envelope model (lines)')
    plotting.label(ax, 'time after the rate step (ms)', 'in-phase output / final value',
                   'rate step response of the demodulated sense channel', 'lower right')
    plotting.save(fig, path)


def plot_bode(path, device, temp_c, split_hz):
    """Rate-channel Bode plot: envelope model, time-domain points for S."""
    plt = plotting.pyplot()

    freqs = np.logspace(0, np.log10(3000.0), 300)
    fig, (ax_m, ax_p) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for i, s in enumerate(_splits(split_hz)):
        h = dynamics.rate_channel_frequency_response(device, freqs, temp_c, s)
        bw = dynamics.rate_channel_bandwidth_hz(device, temp_c, s)
        label = f'split {s:g} Hz (-3 dB at {bw:.0f} Hz)'
        ax_m.semilogx(freqs, 20.0 * np.log10(np.abs(h)), color=f'C{i}', label=label)
        ax_p.semilogx(freqs, np.degrees(np.angle(h)), color=f'C{i}')
    points = np.array([10.0, 30.0, 100.0, 160.0, 300.0, 600.0])
    h_td = np.array([dynamics.time_domain_frequency_response(
        device, f, temp_c, split_hz) for f in points])
    ax_m.semilogx(points, 20.0 * np.log10(np.abs(h_td)), 'ko', mfc='none',
                  label=f'time domain, split {split_hz:g} Hz')
    ax_p.semilogx(points, np.degrees(np.angle(h_td)), 'ko', mfc='none')
    ax_m.axhline(-3.0, color='gray', lw=0.8, ls=':')
    ax_m.set_ylabel('|H| (dB, DC = 0)')
    ax_p.set_ylabel('phase (deg)')
    ax_p.set_xlabel('rate frequency (Hz)')
    ax_m.set_title('rate channel: envelope model (lines) and time domain (circles)')
    for ax in (ax_m, ax_p):
        ax.grid(True, which='both', alpha=0.3)
    ax_m.legend(loc='lower left', fontsize=8)
    plotting.save(fig, path)
