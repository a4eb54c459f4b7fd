"""
What the kernel needs, precomputed once from a configuration and a sample rate.

:class:`Plan` turns a :class:`~gyro_emulator.sensor.config.SensorConfig` into
the read-only :class:`~gyro_emulator.sensor.kernel.Coefficients` of the
compiled kernel: temperature tables of the physics curves
(:class:`TemperatureTable`), the exact discretisations of the thermal lag
(phi = exp(-dt/tau)), the sense-mode envelope
(:func:`gyro_emulator.physics.dynamics.rate_channel_discrete`) and the ASIC's
Butterworth low-pass, the flicker sections
(:func:`gyro_emulator.sensor.noise.flicker_plan`), the white-noise sigma
N sqrt(fs) and the rate-random-walk step K sqrt(dt) (IEEE Std 952), and the
output stage.
"""

import math

from gyro_emulator import units
from gyro_emulator.physics import dynamics, first_order
from gyro_emulator.sensor import kernel, noise
from gyro_emulator.validation import MODEL_TEMP_RANGE_C
import numpy as np
from scipy import linalg, signal


class TemperatureTable:
    """
    ``function(temp_c)`` tabulated every 0.01 C over ``MODEL_TEMP_RANGE_C``.

    Linear interpolation between grid points: a fixed function of the
    temperature (so every sample gets the same value whichever call it is
    in), a few operations per sample, and a relative error below 1e-10 for
    the smooth physics curves it holds (checked in test/test_sensor.py). The
    kernel interpolates ``values`` and ``slopes`` with the same arithmetic.
    """

    STEPS_PER_DEG = 100

    def __init__(self, function):
        lo, hi = MODEL_TEMP_RANGE_C
        count = int(round((hi - lo) * self.STEPS_PER_DEG)) + 1
        self.low_c = float(lo)
        self.grid_c = lo + np.arange(count) / self.STEPS_PER_DEG
        self.values = np.asarray(function(self.grid_c), dtype=float)
        self.slopes = np.append(np.diff(self.values), 0.0)
        self._last = count - 2

    def __call__(self, temp_c):
        """Evaluate at ``temp_c`` (array, deg C, inside the model range)."""
        u = (np.asarray(temp_c, dtype=float) - self.low_c) * self.STEPS_PER_DEG
        i = u.astype(np.intp)
        np.clip(i, 0, self._last, out=i)
        u -= i
        return self.values[i] + u * self.slopes[i]


def _group_axes(keys):
    """Group axis indices by equal keys: [(key, [axes])]."""
    groups = []
    for axis, key in enumerate(keys):
        for known, axes in groups:
            if known == key:
                axes.append(axis)
                break
        else:
            groups.append((key, [axis]))
    return groups


#: Lowest output-filter cut-off as a fraction of the sample rate, by order: in
#: transfer-function form the Butterworth's DC gain stays within 1e-6 of 1 and its
#: poles inside the unit circle down to it (order 4 at 1e-5 f_s is unstable).
MIN_FILTER_FRACTION = {1: 1e-6, 2: 1e-5, 3: 1e-4, 4: 1e-3}


def _noise_gain(b, a):
    """RMS gain sqrt(sum h[k]^2) of a digital filter to white noise (Lyapunov)."""
    ad, bd, cd, dd = signal.tf2ss(b, a)
    p = linalg.solve_discrete_lyapunov(ad, bd @ bd.T)
    return float(np.sqrt((cd @ p @ cd.T)[0, 0] + dd[0, 0] ** 2))


def _tables(curves):
    """Stack (TemperatureTable, axes) pairs into (tables, 2, grid) and an axis index."""
    if not curves:
        return np.zeros((1, 2, 2)), np.zeros(3, dtype=np.int64)
    stack = np.empty((len(curves), 2, len(curves[0][0].values)))
    index = np.zeros(3, dtype=np.int64)
    for row, (table, axes) in enumerate(curves):
        stack[row, 0] = table.values
        stack[row, 1] = table.slopes
        index[axes] = row
    return stack, index


class Plan:
    """
    Everything the kernel needs, precomputed from a config and a sample rate.

    Immutable once built (:meth:`GyroModel.copy` shares it between copies of
    a model): the kernel only reads :attr:`coefficients`.

    ``config`` and ``sample_rate_hz`` are those of the :class:`GyroModel`
    that owns the plan; ``turn_on_z`` holds the model's three standard normals
    of the random turn-on bias (numpy array of shape (3,)).

    """

    def __init__(self, config, sample_rate_hz, turn_on_z):
        self.config = config
        self.fs = float(sample_rate_hz)
        self.dt = 1.0 / self.fs
        self.sqrt_fs = math.sqrt(self.fs)
        self.cal_temp_c = np.array([d.calibration_temp_c for d in config.device])
        self.flags = np.zeros(kernel.FLAG_COUNT, dtype=np.int64)
        self.scalars = np.zeros(kernel.SCALAR_COUNT)
        self.axis = np.zeros((kernel.AXIS_ROWS, 3))
        lo, hi = MODEL_TEMP_RANGE_C
        self.scalars[[kernel.S_TEMP_LO, kernel.S_TEMP_HI, kernel.S_LOW_C]] = lo, hi, lo
        self.scalars[[kernel.S_STEPS, kernel.S_DT, kernel.S_SQRT_FS]] = (
            TemperatureTable.STEPS_PER_DEG, self.dt, self.sqrt_fs)
        self._thermal()
        self._gain()
        self._sense_dynamics()
        self._bias(turn_on_z)
        self._white_noise()
        self._output_filter()
        self._output_stage()
        self._timing()
        self.streams = kernel.consumed_streams(self.flags)
        self.coefficients = kernel.Coefficients(
            self.flags, self.scalars, self.axis, self.misalignment, self.g_sensitivity,
            *_tables(self.sf_curves), *_tables(self.mech_curves), self.dyn_b, self.dyn_a,
            self.dyn_zi, self.lpf_b, self.lpf_a, self.lpf_zi, self.flicker_phi,
            self.flicker_gains, self.streams)
        for arr in self.coefficients:
            arr.flags.writeable = False

    def _thermal(self):
        """Die temperature lag: exact first-order response, phi = exp(-dt / tau)."""
        c, on = self.config, self.config.terms.thermal_lag
        self.scalars[kernel.S_HEAT] = c.self_heating_c if on else 0.0
        init = c.initial_die_temp_c
        self.scalars[kernel.S_INIT_DIE] = math.nan if init is None else init
        if on and c.thermal_time_constant_s > 0.0:
            self.flags[kernel.F_THERMAL] = 1
            self.scalars[kernel.S_PHI] = float(
                noise.gauss_markov_phi(c.thermal_time_constant_s, self.dt))
            self.scalars[kernel.S_GAIN] = -math.expm1(-self.dt / c.thermal_time_constant_s)

    def _gain(self):
        """Set the gain (physics ratio x (1 + scale-factor error)), misalignment, nonlinearity."""
        c, t = self.config, self.config.terms
        self.sf_curves = []
        if t.scale_factor_temperature:
            self.flags[kernel.F_SF] = 1
            self.sf_curves = [
                (TemperatureTable(lambda temp, d=dev: first_order.scale_factor_ratio(d, temp)),
                 axes) for dev, axes in _group_axes(c.device)]
        self.axis[kernel.A_SF1] = 1.0 + np.array(c.scale_factor_error) \
            if t.scale_factor_error else 1.0
        self.misalignment = np.array(c.misalignment)
        self.flags[kernel.F_MIS] = t.misalignment and np.any(self.misalignment)
        self.axis[kernel.A_NONLIN] = c.nonlinearity_s_rad
        self.flags[kernel.F_NONLIN] = t.nonlinearity and np.any(self.axis[kernel.A_NONLIN])

    def _sense_dynamics(self):
        """Set the 2nd-order sense-mode envelope filter of each axis (exact ZOH, DC gain 1)."""
        c = self.config
        self.dyn_b = np.zeros((3, 3))
        self.dyn_a = np.zeros((3, 3))
        self.dyn_zi = np.zeros((3, 2))
        if not c.terms.sense_dynamics:
            return
        self.flags[kernel.F_DYN] = 1
        keys = list(zip(c.device, c.mode_split_hz))
        for (dev, split), axes in _group_axes(keys):
            ad, bd, cd, dd = dynamics.rate_channel_discrete(
                dev, self.fs, dev.calibration_temp_c, split)
            num, den = signal.ss2tf(ad, bd, cd, dd)
            b, a = num[0] / den[0], den / den[0]
            self.dyn_b[axes], self.dyn_a[axes] = b, a
            self.dyn_zi[axes] = signal.lfilter_zi(b, a)

    def _bias(self, turn_on_z):
        """Turn-on, temperature, g-sensitivity, flicker and rate-random-walk bias terms."""
        c, t, ax = self.config, self.config.terms, self.axis
        if t.turn_on_bias:
            ax[kernel.A_TURN_ON] = np.array(c.turn_on_bias_rad_s) + np.array(
                c.turn_on_bias_sigma_rad_s) * turn_on_z
        ax[kernel.A_CAL] = self.cal_temp_c
        if t.bias_temperature:
            self.flags[kernel.F_BIAS_T] = 1
            ax[kernel.A_C1] = c.bias_temp_coeff_rad_s_k
            ax[kernel.A_C2] = c.bias_temp_coeff2_rad_s_k2
        self.g_sensitivity = np.array(c.g_sensitivity_rad_s_m_s2)
        self.flags[kernel.F_GSENS] = t.g_sensitivity and np.any(self.g_sensitivity)
        self.flicker = None
        self.flicker_phi = np.zeros(1)
        self.flicker_gains = np.zeros(1)
        if t.bias_instability:
            self.flags[kernel.F_FLICKER] = 1
            self.flicker = noise.flicker_plan(c.bias_instability_band_s, self.dt,
                                              c.bias_instability_per_decade)
            self.flicker_b = np.array(c.bias_instability_rad_s)
            self.flicker_phi = self.flicker.phi.copy()
            self.flicker_gains = self.flicker.gains.copy()
            ax[kernel.A_FLICKER_B] = self.flicker_b
        if t.rate_random_walk:
            self.flags[kernel.F_RRW] = 1
            ax[kernel.A_RRW_STEP] = units.rrw_to_step_sigma(c.rate_random_walk_rad_s_sqrt_s,
                                                            self.fs)

    def _white_noise(self):
        """White rate noise: sigma = N sqrt(fs) (exact), N^2 = N_mech(T)^2 + N_elec^2."""
        c, t = self.config, self.config.terms
        self.white = t.mechanical_noise or t.electronics_noise
        self.flags[kernel.F_WHITE] = self.white
        self.elec_sq = np.array(c.electronics_noise_rad_s_sqrt_hz) ** 2 \
            if t.electronics_noise else np.zeros(3)
        self.mech_curves = []
        if t.mechanical_noise:
            self.flags[kernel.F_MECH] = 1
            self.mech_curves = [
                (TemperatureTable(
                    lambda temp, d=dev: noise.brownian_arw_rad_s_sqrt_hz(d, temp) ** 2),
                 axes) for dev, axes in _group_axes(c.device)]
        self.axis[kernel.A_ELEC_SQ] = self.elec_sq
        self.axis[kernel.A_WHITE_SIGMA] = np.sqrt(self.elec_sq) * self.sqrt_fs

    def _output_filter(self):
        """Set the ASIC's digital Butterworth low-pass (same coefficients on every axis)."""
        c, fs = self.config, self.fs
        self.lpf_b = np.zeros((3, 2))
        self.lpf_a = np.zeros((3, 2))
        self.lpf_zi = np.zeros((3, 1))
        self.lpf_noise_gain = 1.0
        if not (c.terms.output_filter and c.output_filter_hz > 0.0):
            return
        if c.output_filter_hz >= 0.5 * fs:
            raise ValueError(
                f'SensorConfig.output_filter_hz = {c.output_filter_hz!r} is out of '
                f'range at {fs:g} Hz sampling: allowed (0, {0.5 * fs:g}) Hz (below '
                'Nyquist), or 0 for no filter')
        low = MIN_FILTER_FRACTION[c.output_filter_order] * fs
        if c.output_filter_hz < low:
            raise ValueError(
                f'SensorConfig.output_filter_hz = {c.output_filter_hz!r} is out of range at '
                f'{fs:g} Hz sampling and order {c.output_filter_order}: allowed [{low:g}, '
                f'{0.5 * fs:g}) Hz (below, the coefficients lose the DC gain), or 0 '
                'for no filter')
        self.flags[kernel.F_LPF] = 1
        b, a = signal.butter(c.output_filter_order, c.output_filter_hz, fs=fs)
        self.lpf_b, self.lpf_a = np.tile(b, (3, 1)), np.tile(a, (3, 1))
        self.lpf_zi = np.tile(signal.lfilter_zi(b, a), (3, 1))
        self.lpf_noise_gain = _noise_gain(b, a)

    def _output_stage(self):
        """Range flag, LSB rounding and the clip to whole LSBs inside the range."""
        c, t, ax = self.config, self.config.terms, self.axis
        lsb = np.array(c.lsb_rad_s) if t.quantization else np.zeros(3)
        self.flags[kernel.F_QUANT] = np.any(lsb > 0.0)
        ax[kernel.A_LSB] = lsb
        if t.saturation:
            self.flags[kernel.F_SAT] = 1
            ax[kernel.A_RANGE] = c.range_rad_s
            ax[kernel.A_SAT_LIMIT] = c.range_rad_s
            for i in np.flatnonzero(lsb > 0.0):
                ax[kernel.A_SAT_LIMIT, i] = math.floor(
                    c.range_rad_s[i] / lsb[i] * (1.0 + 1e-12)) * lsb[i]

    def _timing(self):
        """Latency, timestamp jitter and clock drift (reported, samples unchanged)."""
        c, t, sc = self.config, self.config.terms, self.scalars
        sc[kernel.S_LATENCY] = c.latency_s if t.latency else 0.0
        sc[kernel.S_JITTER] = c.timestamp_jitter_s if t.timestamp_jitter else 0.0
        self.flags[kernel.F_JITTER] = sc[kernel.S_JITTER] > 0.0
        sc[kernel.S_DRIFT] = c.clock_drift_ppm * 1e-6 if t.clock_drift else 0.0
        self.flags[kernel.F_DRIFT] = sc[kernel.S_DRIFT] != 0.0
