"""
Reproduction of Patel & McCluskey's Table 1 and Figures 5 and 6.

Table 1 is evaluated at 25 C, 1 atm and a true rate of 60 deg/s; Fig 5 is the
capacitance change against rate over -50..50 RPM; Fig 6 is the apparent rate
of a part calibrated at 25 C, at a true 60 deg/s, from 25 to 85 C.
"""

from dataclasses import replace
import os

from gyro_emulator import plotting
from gyro_emulator.physics import first_order
from gyro_emulator.physics.presets import PAPER_DEVICE
from gyro_emulator.units import deg_s_to_rad_s, rad_s_to_deg_s, rpm_to_rad_s
import numpy as np

#: Table 1's operating point.
TABLE1_TEMP_C = 25.0
TABLE1_RATE_DEG_S = 60.0

#: (JSON key, description, unit, value printed in the paper's Table 1).
TABLE1_PAPER = (
    ('M', 'mass of suspended structure', 'kg', 4.0e-9),
    ('kx', 'drive beam stiffness', 'N/m', 30.95),
    ('ky', 'sense beam stiffness', 'N/m', 30.95),
    ('fx', 'drive mode frequency', 'Hz', 14000.0),
    ('fy', 'sense mode frequency', 'Hz', 14000.0),
    ('Kn', 'Knudsen number', '-', 0.0334),
    ('C_proof', 'proof mass damping', 'N s/m', 7.61e-6),
    ('C_comb', 'comb structure damping (drive)', 'N s/m', 1.37e-7),
    ('C_drive', 'drive damping', 'N s/m', 7.75e-6),
    ('C_sense', 'sense damping', 'N s/m', 7.94e-6),
    ('Fd', 'electrostatic drive force', 'N', 4.36e-6),
    ('Xdrive', 'drive displacement', 'm', 6.39e-6),
    ('Ysense', 'sense displacement', 'm', 6.75e-9),
    ('dC', 'capacitance change', 'F', 7.45e-18),
)

#: Fig 5 abscissa, RPM.
FIG5_RPM = np.arange(-50.0, 50.0 + 1e-9, 1.0)
#: Fig 6 abscissa, deg C.
FIG6_TEMPS_C = np.arange(25.0, 85.0 + 1e-9, 5.0)
FIG6_RATE_DEG_S = 60.0
#: The paper's Fig 6 ends between these apparent rates at 85 C, deg/s.
FIG6_85C_BAND_DEG_S = (61.8, 62.0)


def table1_values(device=PAPER_DEVICE):
    """Return our Table 1 quantities, SI, keyed as in :data:`TABLE1_PAPER`."""
    r = first_order.first_order_response(
        device, deg_s_to_rad_s(TABLE1_RATE_DEG_S), TABLE1_TEMP_C)
    p = r.params
    values = {
        'M': p.mass_kg, 'kx': p.stiffness_x_n_m, 'ky': p.stiffness_y_n_m,
        'fx': p.freq_x_hz, 'fy': p.freq_y_hz, 'Kn': p.knudsen,
        'C_proof': p.damping_proof_n_s_m,
        'C_comb': p.damping_comb_drive_n_s_m,
        'C_drive': p.damping_drive_n_s_m, 'C_sense': p.damping_sense_n_s_m,
        'Fd': p.drive_force_n, 'Xdrive': r.drive_amplitude_m,
        'Ysense': r.sense_amplitude_m, 'dC': r.capacitance_change_f,
    }
    return {k: float(v) for k, v in values.items()}


def table1_rows(device=PAPER_DEVICE):
    """Return Table 1 rows ``(key, description, unit, ours, paper, error_pct)``."""
    ours = table1_values(device)
    return [(key, desc, unit, ours[key], paper,
             100.0 * (ours[key] - paper) / paper)
            for key, desc, unit, paper in TABLE1_PAPER]


def format_table1(rows):
    """Format Table 1 rows as aligned text."""
    # Five significant digits: the errors are 0.01-0.2 %, so four would print
    # f_x = 13997 Hz and the paper's 14000 Hz both as 1.4e+04.
    lines = ['%-8s %-32s %-6s %12s %12s %8s' % (
        'quantity', 'description', 'unit', 'ours', 'paper', 'err %')]
    for key, desc, unit, ours, paper, err in rows:
        lines.append('%-8s %-32s %-6s %12.5g %12.5g %+8.3f' % (
            key, desc, unit, ours, paper, err))
    return '\n'.join(lines)


def summary_text(device=PAPER_DEVICE):
    """
    Return the report ``gyro-emulator paper`` prints.

    Table 1 ours against the paper's, the row with the largest relative
    error, and Fig 6's apparent rate at 85 C with constant and with
    Sutherland viscosity.
    """
    rows = table1_rows(device)
    worst = max(rows, key=lambda row: abs(row[5]))
    rate = fig6_data(device, viscosity_law='constant')[1]
    rate_s = fig6_data(device, viscosity_law='sutherland')[1]
    low, high = FIG6_85C_BAND_DEG_S
    return '\n'.join((
        'Table 1 (25 C, 1 atm, 60 deg/s): ours vs paper',
        format_table1(rows),
        f'largest |error|: {worst[0]} {worst[5]:+.3f} %',
        f'Fig 6 at 85 C (true 60 deg/s): {rate[-1]:.3f} deg/s with constant '
        f'viscosity (paper: {low:.1f}..{high:.1f}); {rate_s[-1]:.3f} deg/s with '
        f"Sutherland's law"))


def fig5_data(device=PAPER_DEVICE, rpm=FIG5_RPM, temp_c=TABLE1_TEMP_C):
    """Capacitance change (F) against rate (RPM) (Fig 5); returns (rpm, dC)."""
    rpm = np.asarray(rpm, dtype=float)
    r = first_order.first_order_response(device, rpm_to_rad_s(rpm), temp_c)
    return rpm, r.capacitance_change_f


def fig6_data(device=PAPER_DEVICE, temps_c=FIG6_TEMPS_C,
              rate_deg_s=FIG6_RATE_DEG_S, viscosity_law=None):
    """
    Apparent rate (deg/s) against temperature at a true rate (Fig 6).

    ``viscosity_law`` overrides the device's law ('constant' or 'sutherland').
    Returns ``(temps_c, apparent_rate_deg_s)``.
    """
    if viscosity_law is not None:
        device = replace(device, gas=replace(device.gas,
                                             viscosity_law=viscosity_law))
    temps = np.asarray(temps_c, dtype=float)
    apparent = first_order.apparent_rate_rad_s(
        device, deg_s_to_rad_s(rate_deg_s), temps)
    return temps, rad_s_to_deg_s(apparent)


def fig6_variants(device=PAPER_DEVICE, temps_c=FIG6_TEMPS_C):
    """
    Fig 6 for every gas variant worth overlaying.

    Returns a dict label -> (temps_c, apparent_rate_deg_s): the paper's
    constant viscosity, Sutherland viscosity in a vented cavity, and
    Sutherland viscosity in a cavity sealed at 1 atm.
    """
    sealed = replace(device, gas=replace(device.gas, cavity='sealed'))
    return {
        'constant viscosity (paper)': fig6_data(device, temps_c,
                                                viscosity_law='constant'),
        'Sutherland viscosity, vented': fig6_data(device, temps_c,
                                                  viscosity_law='sutherland'),
        'Sutherland viscosity, sealed at 1 atm': fig6_data(
            sealed, temps_c, viscosity_law='sutherland'),
    }


def paper_json(device=PAPER_DEVICE):
    """Return the JSON document of ``gyro-emulator paper --json``."""
    doc = table1_values(device)
    rpm, dc = fig5_data(device)
    doc['fig5'] = [[float(a), float(b)] for a, b in zip(rpm, dc)]
    for key, law in (('fig6', 'constant'), ('fig6_sutherland', 'sutherland')):
        temps, rate = fig6_data(device, viscosity_law=law)
        doc[key] = [[float(a), float(b)] for a, b in zip(temps, rate)]
    return doc


def plot_fig5(path, device=PAPER_DEVICE):
    """Write Fig 5 (capacitance change against rate) as a PNG at ``path``."""
    plt = plotting.pyplot()

    rpm, dc = fig5_data(device)
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.plot(rpm, dc, lw=2, label='gyro_emulator (first order, 25 C)')
    ax.plot([-50, 50], [-3.7e-17, 3.7e-17], 'k--', lw=1,
            label='paper Fig 5 end points (about +-3.7e-17 F)')
    plotting.label(ax, 'angular velocity (RPM)', 'capacitance change (F)',
                   'Fig 5: capacitance change vs angular velocity', 'upper left')
    plotting.save(fig, path)


def plot_fig6(path, device=PAPER_DEVICE):
    """Write Fig 6 with viscosity variants overlaid as a PNG at ``path``."""
    plt = plotting.pyplot()

    variants = fig6_variants(device)
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for label, (temps, rate) in variants.items():
        ax2.plot(temps, rate, marker='o', ms=3, label=label)
    temps, rate = variants['constant viscosity (paper)']
    ax.plot(temps, rate, marker='o', ms=4, label='gyro_emulator, constant mu')
    ax.axhspan(*FIG6_85C_BAND_DEG_S, xmin=0.9, color='tab:green', alpha=0.3,
               label='paper at 85 C (61.8..62.0)')
    ax.set_ylim(60, 62.2)
    ax.set_title('Fig 6 as in the paper (constant viscosity)')
    ax2.set_title('what the constant-viscosity assumption hides')
    for a in (ax, ax2):
        plotting.label(a, 'temperature (C)', 'apparent rate at a true 60 deg/s (deg/s)')
    plotting.save(fig, path)


#: The files :func:`write_figures` writes.
FIGURES = ('fig5.png', 'fig6.png')


def write_figures(directory, device=PAPER_DEVICE):
    """Write fig5.png and fig6.png into ``directory`` (made if absent); return the paths."""
    os.makedirs(directory, exist_ok=True)
    paths = []
    for name, plot in zip(FIGURES, (plot_fig5, plot_fig6)):
        paths.append(os.path.join(directory, name))
        plot(paths[-1], device)
    return paths
