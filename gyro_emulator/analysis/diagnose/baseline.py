"""
The baseline: the paper's first-order physics, calibrated as a user would.

Model (paper Eq 13-21 and Fig 6)::

    gyro = b0 + s0 R(T) Omega,   R(T) = Y_sense(T) / Y_sense(T_ref)

where ``R`` is :func:`gyro_emulator.physics.first_order.scale_factor_ratio` of the chosen
device preset (default ``paper``: constant viscosity) and T is the
temperature reading. The user's calibration fixes the two constants, the bias
``b0`` and the scale factor ``s0`` at the reference temperature ``T_ref``
(default: the device's calibration temperature, 25 C):

1. the calibration samples are those with ``|T - T_ref| <= W``, where W is
   2 C, widened to the smallest value that holds 5 % of the samples when
   fewer lie within 2 C (so a record that never visits T_ref is calibrated
   on its samples nearest T_ref);
2. ``b0`` and ``s0`` are the weighted least-squares fit of
   ``gyro = b0 + s0 R(T) Omega`` on those samples;
3. when the calibration samples have no rate excitation (rms applied rate
   below 1e-3 rad/s, e.g. a static record), ``s0`` stays at its nominal 1
   and ``b0`` is the mean output there.
"""

from dataclasses import dataclass

from gyro_emulator.physics import first_order
import numpy as np

#: Half width of the calibration temperature window, deg C.
CAL_WINDOW_C = 2.0
#: Smallest share of samples the calibration window must hold.
CAL_MIN_FRACTION = 0.05
#: Rms applied rate below which a scale factor cannot be calibrated, rad/s.
MIN_RATE_RMS_RAD_S = 1e-3


@dataclass(frozen=True)
class Calibration:
    """A user's calibration: bias and scale factor at the reference temperature."""

    ref_temp_c: float
    window_c: float
    bias_rad_s: float
    scale_factor: float
    scale_factor_calibrated: bool
    samples: int
    mean_time_s: float

    def as_dict(self):
        """JSON-ready form."""
        return {'ref_temp_c': self.ref_temp_c, 'window_c': self.window_c,
                'bias_rad_s': self.bias_rad_s, 'scale_factor': self.scale_factor,
                'scale_factor_calibrated': self.scale_factor_calibrated,
                'samples': self.samples, 'mean_time_s': self.mean_time_s}


class DevicePhysics:
    """
    The physics core evaluated for one device and one record.

    Temperature functions are computed once on a fine grid spanning the
    record (plus margin) and interpolated; they are smooth, so a 0.05 K grid
    is exact to far below the noise.

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The baseline device (a preset).
    ref_temp_c : float
        Reference (calibration) temperature, deg C.
    temp_lo_c, temp_hi_c : float
        Span of the record's temperatures, deg C.

    """

    def __init__(self, device, ref_temp_c, temp_lo_c, temp_hi_c):
        self.device = device
        self.ref_temp_c = float(ref_temp_c)
        lo = max(-60.0, min(temp_lo_c, ref_temp_c) - 2.0)
        hi = min(200.0, max(temp_hi_c, ref_temp_c) + 2.0)
        n = int(min(4001, max(81, (hi - lo) / 0.05)))
        self.grid_c = np.linspace(lo, hi, n)
        self.ratio_grid = first_order.scale_factor_ratio(device, self.grid_c,
                                                         ref_temp_c)
        p = first_order.lumped_parameters(device, self.grid_c)
        self.q_sense_grid = p.q_sense
        self.freq_grid_hz = p.freq_y_hz
        self.sf_grid = first_order.sense_scale_factor_m_per_rad_s(device,
                                                                  self.grid_c)
        self._sutherland = {}
        self._pressure = None

    def _interp(self, temp_c, grid_values):
        return np.interp(temp_c, self.grid_c, grid_values)

    def ratio(self, temp_c):
        """Baseline scale-factor ratio R(T) (Eq 13-20 relative to T_ref)."""
        return self._interp(temp_c, self.ratio_grid)

    def sutherland_ratio(self, temp_c, sutherland_k):
        """
        R(T) with the gas viscosity following Sutherland's law.

        mu(T) = mu_ref (T/T_ref)^1.5 (T_ref + S)/(T + S), S = ``sutherland_k``,
        evaluated inside the physics core (both dampings, Eq 9-11).
        """
        key = float(sutherland_k)
        grid = self._sutherland.get(key)
        if grid is None:
            dev = self.device.with_gas(viscosity_law='sutherland',
                                       sutherland_constant_k=key)
            grid = first_order.scale_factor_ratio(dev, self.grid_c, self.ref_temp_c)
            if len(self._sutherland) > 512:
                self._sutherland.clear()
            self._sutherland[key] = grid
        return self._interp(temp_c, grid)

    def pressure_factor(self, temp_c, pressure_ratio):
        """
        Scale factor at a cavity pressure relative to the preset's pressure.

        Y_sense(T, P) / Y_sense(T, P_ref) through Eq 8-11 (Knudsen number ->
        slide-film and comb damping), tabulated once on 0.05 K x 0.5 %
        steps of ln P (0.05 to 5 P_ref) and interpolated bilinearly (to
        2e-6 of the physics);
        ``temp_c`` may be the :meth:`temp_index` of the temperatures.
        """
        if self._pressure is None:
            self._pressure = self._pressure_table()
        log_p, table = self._pressure
        x = np.clip(np.log(np.asarray(pressure_ratio, dtype=float)), log_p[0], log_p[-1])
        i = np.clip(np.searchsorted(log_p, x) - 1, 0, len(log_p) - 2)
        f = (x - log_p[i]) / (log_p[i + 1] - log_p[i])
        j, g = temp_c if isinstance(temp_c, tuple) else self.temp_index(temp_c)
        lo = table[i, j] * (1.0 - g) + table[i, j + 1] * g
        hi = table[i + 1, j] * (1.0 - g) + table[i + 1, j + 1] * g
        return lo * (1.0 - f) + hi * f

    def temp_index(self, temp_c):
        """Return the grid cell and weight of each temperature (:meth:`pressure_factor` input)."""
        temp = np.asarray(temp_c, dtype=float)
        grid = self.grid_c
        j = np.clip(np.searchsorted(grid, temp) - 1, 0, len(grid) - 2)
        return j, np.clip((temp - grid[j]) / (grid[j + 1] - grid[j]), 0.0, 1.0)

    def q_and_freq(self, temp_c):
        """Sense quality factor Q_s(T) and sense frequency f(T), Hz (Eq 9-12)."""
        return (self._interp(temp_c, self.q_sense_grid),
                self._interp(temp_c, self.freq_grid_hz))

    def _pressure_table(self):
        """Y_sense(T, P) / Y_sense(T, P_ref) on the temperature grid and a ln P grid."""
        log_p = np.linspace(np.log(0.05), np.log(5.0), 461)
        p_ref = self.device.gas.pressure_pa
        rows = [first_order.sense_scale_factor_m_per_rad_s(
            self.device.with_gas(pressure_pa=p_ref * float(np.exp(v))), self.grid_c)
            for v in log_p]
        return log_p, np.asarray(rows) / self.sf_grid[None, :]

    def mode_split_factor(self, temp_c, split_hz):
        """
        Sense amplitude of a mode split relative to matched modes.

        1 / sqrt(1 + (2 Q_s df / f)^2) with Q_s and f from the physics core
        (the exact 2-DOF steady state near resonance; docs/physics.md);
        ``temp_c`` may be the :meth:`q_and_freq` of the temperatures.
        """
        q, f = temp_c if isinstance(temp_c, tuple) else self.q_and_freq(temp_c)
        return 1.0 / np.sqrt(1.0 + (2.0 * q * np.asarray(split_hz) / f) ** 2)


def calibration_rows(temp_c, weight, ref_temp_c, window_c=CAL_WINDOW_C,
                     min_fraction=CAL_MIN_FRACTION):
    """
    Select the calibration rows: the 2 C window, widened to 5 % of samples.

    Parameters
    ----------
    temp_c : numpy.ndarray
        Row temperatures, deg C.
    weight : numpy.ndarray
        Samples per row.
    ref_temp_c : float
        Reference temperature, deg C.
    window_c : float
        Minimum half width, deg C.
    min_fraction : float
        Share of the samples the window must hold.

    Returns
    -------
    (numpy.ndarray of bool, float)
        The selection and the half width used, deg C.

    """
    dist = np.abs(temp_c - ref_temp_c)
    order = np.argsort(dist, kind='stable')
    cum = np.cumsum(weight[order])
    k = int(np.searchsorted(cum, min_fraction * cum[-1]))
    width = max(window_c, float(dist[order[min(k, len(order) - 1)]]))
    return dist <= width + 1e-12, width


def rows_or_all(frame, rows=None):
    """Return the row selection ``rows`` (a training set), or every row of ``frame`` when None."""
    return np.ones(len(frame), bool) if rows is None else rows


def calibrate(frame, dev_physics, rows=None):
    """
    Calibrate bias and scale factor at the reference temperature.

    Parameters
    ----------
    frame : gyro_emulator.analysis.diagnose.data.Frame
        The rows to calibrate from (bin means).
    dev_physics : DevicePhysics
        The baseline physics.
    rows : numpy.ndarray of bool, optional
        Rows available (a training set); all when None.

    Returns
    -------
    Calibration

    """
    avail = rows_or_all(frame, rows)
    t = frame.temp_c[avail]
    w = frame.weight[avail]
    sel, width = calibration_rows(t, w, dev_physics.ref_temp_c)
    w = w[sel]
    y = frame.gyro[avail][sel]
    x = (dev_physics.ratio(t[sel]) * frame.rate[avail][sel])
    rate_rms = float(np.sqrt(np.sum(w * frame.rate2[avail][sel]) / np.sum(w)))
    if rate_rms >= MIN_RATE_RMS_RAD_S:
        sw = np.sqrt(w)
        design = np.column_stack([sw, sw * x])
        (b0, s0), *_ = np.linalg.lstsq(design, sw * y, rcond=None)
        calibrated = True
    else:
        s0 = 1.0
        b0 = float(np.sum(w * (y - x)) / np.sum(w))
        calibrated = False
    mean_t = float(np.sum(w * frame.time_s[avail][sel]) / np.sum(w))
    return Calibration(ref_temp_c=dev_physics.ref_temp_c, window_c=width,
                       bias_rad_s=float(b0), scale_factor=float(s0),
                       scale_factor_calibrated=calibrated,
                       samples=int(np.sum(w)), mean_time_s=mean_t)


def baseline_prediction(frame, dev_physics, cal):
    """Baseline output b0 + s0 R(T) Omega at every row of ``frame``, rad/s."""
    return cal.bias_rad_s + cal.scale_factor * frame.slow(
        dev_physics.ratio(frame.bins.binned.temp_c)) * frame.rate
