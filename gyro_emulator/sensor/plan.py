"""
What the kernel needs, precomputed once from a configuration and a sample rate.

:class:`Plan` turns one sense channel of a
:class:`~gyro_emulator.sensor.config.SensorConfig` (the gyro, or its
accelerometer) into the read-only
:class:`~gyro_emulator.sensor.kernel.Coefficients` of the compiled kernel.
What each channel gives the kernel is a :class:`Channel`
(:func:`gyro_channel`, :func:`accel_channel`): the same terms in neutral
names, so that both run on the same kernel and the same plan: temperature
tables of the physics curves (:class:`TemperatureTable`), the exact
discretisations of the thermal lag (phi = exp(-dt/tau)), the sense-mode
envelope (:func:`gyro_emulator.physics.dynamics.rate_channel_discrete`) and
the ASIC's Butterworth low-pass, the flicker sections
(:func:`gyro_emulator.sensor.noise.flicker_plan`), the white-noise sigma
N sqrt(fs) and the random-walk step K sqrt(dt) (IEEE Std 952), and the
output stage.
"""

from dataclasses import dataclass
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


#: Lowest output-filter cut-off as a fraction of the sample rate, by order: down to
#: it the Butterworth in transfer-function form keeps its DC gain within 1e-6 of 1
#: and its poles inside the unit circle (order 4 at 1e-5 f_s is unstable), and its
#: white-noise gain (a discrete Lyapunov equation) stays well conditioned.
MIN_FILTER_FRACTION = {1: 1e-6, 2: 1e-5, 3: 1e-3, 4: 1e-2}


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


@dataclass(frozen=True)
class Channel:
    """
    One sense channel as the kernel sees it: the terms of a configuration in neutral names.

    Units are those of the channel (rad/s for the gyro, m/s^2 for the
    accelerometer); per-axis values are (3,) sequences, matrices 3x3. A
    switch that is off, or a value left at its default, leaves its term out.
    ``owner`` names the configuration in a one-line error (a filter cut-off
    at or above Nyquist). ``gain_curves`` and ``noise_curves`` are
    ``(function(temp_c), axes)`` pairs: the gain ratio and the squared
    physics white-noise density against the die temperature, tabulated by
    :class:`TemperatureTable`. ``dynamics_keys`` holds (device, mode split)
    per axis for the sense-mode envelope, or None for none.
    """

    owner: str
    cal_temp_c: tuple
    thermal_on: bool = False
    self_heating_c: float = 0.0
    initial_die_temp_c: float = None
    thermal_time_constant_s: float = 0.0
    gain_curves: tuple = ()
    gain_error: tuple = None
    misalignment: tuple = ((0.0,) * 3,) * 3
    misalignment_on: bool = False
    nonlinearity: tuple = (0.0, 0.0, 0.0)
    nonlinearity_on: bool = False
    dynamics_keys: tuple = None
    turn_on: tuple = None
    turn_on_sigma: tuple = (0.0, 0.0, 0.0)
    bias_temp_on: bool = False
    bias_temp_coeff: tuple = (0.0, 0.0, 0.0)
    bias_temp_coeff2: tuple = (0.0, 0.0, 0.0)
    g_sensitivity: tuple = ((0.0,) * 3,) * 3
    g_sensitivity_on: bool = False
    flicker_on: bool = False
    flicker_band_s: tuple = (0.1, 1000.0)
    flicker_per_decade: float = 1.0
    flicker_b: tuple = (0.0, 0.0, 0.0)
    walk_on: bool = False
    walk_k: tuple = (0.0, 0.0, 0.0)
    electronics_on: bool = False
    electronics_density: tuple = (0.0, 0.0, 0.0)
    noise_curves: tuple = ()
    lpf_on: bool = False
    lpf_hz: float = 0.0
    lpf_order: int = 2
    lsb: tuple = None
    range_limit: tuple = None
    latency_s: float = 0.0
    jitter_s: float = 0.0
    drift: float = 0.0


def gyro_channel(config):
    """
    Return the gyro's :class:`Channel` of a SensorConfig (the equations of :mod:`.model`).

    Gain: the physics scale-factor ratio (Eq 5-22) of each axis's device;
    white noise: the sense mode's Brownian ARW squared
    (:func:`gyro_emulator.sensor.noise.brownian_arw_rad_s_sqrt_hz`).
    """
    c, t = config, config.terms
    devices = _group_axes(c.device)
    return Channel(
        owner='SensorConfig', cal_temp_c=tuple(d.calibration_temp_c for d in c.device),
        thermal_on=t.thermal_lag, self_heating_c=c.self_heating_c,
        initial_die_temp_c=c.initial_die_temp_c,
        thermal_time_constant_s=c.thermal_time_constant_s,
        gain_curves=tuple(
            ((lambda temp, d=dev: first_order.scale_factor_ratio(d, temp)), axes)
            for dev, axes in devices) if t.scale_factor_temperature else (),
        gain_error=c.scale_factor_error if t.scale_factor_error else None,
        misalignment=c.misalignment, misalignment_on=t.misalignment,
        nonlinearity=c.nonlinearity_s_rad, nonlinearity_on=t.nonlinearity,
        dynamics_keys=tuple(zip(c.device, c.mode_split_hz)) if t.sense_dynamics else None,
        turn_on=(c.turn_on_bias_rad_s if t.turn_on_bias else None),
        turn_on_sigma=c.turn_on_bias_sigma_rad_s, bias_temp_on=t.bias_temperature,
        bias_temp_coeff=c.bias_temp_coeff_rad_s_k, bias_temp_coeff2=c.bias_temp_coeff2_rad_s_k2,
        g_sensitivity=c.g_sensitivity_rad_s_m_s2, g_sensitivity_on=t.g_sensitivity,
        flicker_on=t.bias_instability, flicker_band_s=c.bias_instability_band_s,
        flicker_per_decade=c.bias_instability_per_decade, flicker_b=c.bias_instability_rad_s,
        walk_on=t.rate_random_walk, walk_k=c.rate_random_walk_rad_s_sqrt_s,
        electronics_on=t.electronics_noise,
        electronics_density=c.electronics_noise_rad_s_sqrt_hz,
        noise_curves=tuple(
            ((lambda temp, d=dev: noise.brownian_arw_rad_s_sqrt_hz(d, temp) ** 2), axes)
            for dev, axes in devices) if t.mechanical_noise else (),
        lpf_on=t.output_filter, lpf_hz=c.output_filter_hz, lpf_order=c.output_filter_order,
        lsb=c.lsb_rad_s if t.quantization else None,
        range_limit=c.range_rad_s if t.saturation else None,
        latency_s=c.latency_s if t.latency else 0.0,
        jitter_s=c.timestamp_jitter_s if t.timestamp_jitter else 0.0,
        drift=c.clock_drift_ppm * 1e-6 if t.clock_drift else 0.0)


def accel_channel(config):
    """
    Return the accelerometer's :class:`Channel` of a SensorConfig (:mod:`.accel`).

    Its input is the specific force; its temperature the die temperature
    (given to the kernel as its ambient: no lag of its own); gain
    1 + scale_factor_temp_coeff (T - T_cal) and white noise the proof mass's
    Brownian VRW squared
    (:func:`gyro_emulator.sensor.noise.brownian_vrw_m_s2_sqrt_hz`); no
    sense-mode dynamics, no g-sensitivity, no timing terms.
    """
    a, t = config.accelerometer, config.accelerometer.terms
    cal = tuple(d.calibration_temp_c for d in config.device)
    tempco = a.scale_factor_temp_coeff_per_k
    gain = ()
    if t.scale_factor_temperature and any(tempco):
        gain = tuple(((lambda temp, k=k, c0=c0: 1.0 + k * (temp - c0)), axes)
                     for (k, c0), axes in _group_axes(list(zip(tempco, cal))))
    return Channel(
        owner='SensorConfig.accelerometer', cal_temp_c=cal, gain_curves=gain,
        gain_error=a.scale_factor_error if t.scale_factor_error else None,
        misalignment=a.misalignment, misalignment_on=t.misalignment,
        turn_on=a.turn_on_bias_m_s2 if t.turn_on_bias else None,
        turn_on_sigma=a.turn_on_bias_sigma_m_s2, bias_temp_on=t.bias_temperature,
        bias_temp_coeff=a.bias_temp_coeff_m_s2_k,
        flicker_on=t.bias_instability, flicker_band_s=a.bias_instability_band_s,
        flicker_per_decade=a.bias_instability_per_decade, flicker_b=a.bias_instability_m_s2,
        walk_on=t.random_walk, walk_k=a.random_walk_m_s3_sqrt_hz,
        electronics_on=t.electronics_noise, electronics_density=a.electronics_noise_m_s2_sqrt_hz,
        noise_curves=tuple(
            ((lambda temp, d=dev: noise.brownian_vrw_m_s2_sqrt_hz(d, temp) ** 2), axes)
            for dev, axes in _group_axes(config.device)) if t.mechanical_noise else (),
        lpf_on=t.output_filter, lpf_hz=a.output_filter_hz, lpf_order=a.output_filter_order,
        lsb=a.lsb_m_s2 if t.quantization else None,
        range_limit=a.range_m_s2 if t.saturation else None)


class Plan:
    """
    Everything the kernel needs, precomputed from a config and a sample rate.

    Immutable once built (:meth:`GyroModel.copy` shares it between copies of
    a model): the kernel only reads :attr:`coefficients`.

    ``config`` and ``sample_rate_hz`` are those of the model that owns the
    plan; ``turn_on_z`` holds the channel's three standard normals of the
    random turn-on bias (numpy array of shape (3,)); ``channel`` is the
    channel of ``config`` it plans (default the gyro's, :func:`gyro_channel`).

    """

    def __init__(self, config, sample_rate_hz, turn_on_z, channel=None):
        self.config = config
        ch = gyro_channel(config) if channel is None else channel
        self.channel = ch
        self.fs = float(sample_rate_hz)
        self.dt = 1.0 / self.fs
        self.sqrt_fs = math.sqrt(self.fs)
        self.cal_temp_c = np.array(ch.cal_temp_c)
        self.flags = np.zeros(kernel.FLAG_COUNT, dtype=np.int64)
        self.scalars = np.zeros(kernel.SCALAR_COUNT)
        self.axis = np.zeros((kernel.AXIS_ROWS, 3))
        lo, hi = MODEL_TEMP_RANGE_C
        self.scalars[[kernel.S_TEMP_LO, kernel.S_TEMP_HI, kernel.S_LOW_C]] = lo, hi, lo
        self.scalars[[kernel.S_STEPS, kernel.S_DT, kernel.S_SQRT_FS]] = (
            TemperatureTable.STEPS_PER_DEG, self.dt, self.sqrt_fs)
        self._thermal(ch)
        self._gain(ch)
        self._sense_dynamics(ch)
        self._bias(ch, turn_on_z)
        self._white_noise(ch)
        self._output_filter(ch)
        self._output_stage(ch)
        self._timing(ch)
        self.streams = kernel.consumed_streams(self.flags)
        self.coefficients = kernel.Coefficients(
            self.flags, self.scalars, self.axis, self.misalignment, self.g_sensitivity,
            *_tables(self.sf_curves), *_tables(self.mech_curves), self.dyn_b, self.dyn_a,
            self.dyn_zi, self.lpf_b, self.lpf_a, self.lpf_zi, self.flicker_phi,
            self.flicker_gains, self.streams)
        for arr in self.coefficients:
            arr.flags.writeable = False

    def _thermal(self, ch):
        """Die temperature lag: exact first-order response, phi = exp(-dt / tau)."""
        self.scalars[kernel.S_HEAT] = ch.self_heating_c if ch.thermal_on else 0.0
        init = ch.initial_die_temp_c
        self.scalars[kernel.S_INIT_DIE] = math.nan if init is None else init
        if ch.thermal_on and ch.thermal_time_constant_s > 0.0:
            self.flags[kernel.F_THERMAL] = 1
            self.scalars[kernel.S_PHI] = float(
                noise.gauss_markov_phi(ch.thermal_time_constant_s, self.dt))
            self.scalars[kernel.S_GAIN] = -math.expm1(-self.dt / ch.thermal_time_constant_s)

    def _gain(self, ch):
        """Set the gain (temperature ratio x (1 + scale-factor error)), misalignment, x^2 term."""
        self.sf_curves = [(TemperatureTable(function), axes)
                          for function, axes in ch.gain_curves]
        self.flags[kernel.F_SF] = bool(self.sf_curves)
        self.axis[kernel.A_SF1] = 1.0 + np.array(ch.gain_error) \
            if ch.gain_error is not None else 1.0
        self.misalignment = np.array(ch.misalignment)
        self.flags[kernel.F_MIS] = ch.misalignment_on and np.any(self.misalignment)
        self.axis[kernel.A_NONLIN] = ch.nonlinearity
        self.flags[kernel.F_NONLIN] = ch.nonlinearity_on and np.any(self.axis[kernel.A_NONLIN])

    def _sense_dynamics(self, ch):
        """
        Set the 2nd-order sense-mode envelope filter of each axis (exact, DC gain 1).

        H(z) = Cd (zI - Ad)^-1 Bd + Dd with (Ad, Bd, C Ad, C Bd) of
        :func:`~gyro_emulator.physics.dynamics.rate_channel_discrete`: the
        output at a sample's instant, so b[0] = C Bd != 0 and the samples
        are not delayed.
        """
        self.dyn_b = np.zeros((3, 3))
        self.dyn_a = np.zeros((3, 3))
        self.dyn_zi = np.zeros((3, 2))
        if ch.dynamics_keys is None:
            return
        self.flags[kernel.F_DYN] = 1
        for (dev, split), axes in _group_axes(list(ch.dynamics_keys)):
            ad, bd, cd, dd = dynamics.rate_channel_discrete(
                dev, self.fs, dev.calibration_temp_c, split)
            num, den = signal.ss2tf(ad, bd, cd, dd)
            b, a = num[0] / den[0], den / den[0]
            self.dyn_b[axes], self.dyn_a[axes] = b, a
            self.dyn_zi[axes] = signal.lfilter_zi(b, a)

    def _bias(self, ch, turn_on_z):
        """Turn-on, temperature, g-sensitivity, flicker and random-walk bias terms."""
        ax = self.axis
        if ch.turn_on is not None:
            ax[kernel.A_TURN_ON] = np.array(ch.turn_on) + np.array(ch.turn_on_sigma) * turn_on_z
        ax[kernel.A_CAL] = self.cal_temp_c
        if ch.bias_temp_on:
            self.flags[kernel.F_BIAS_T] = 1
            ax[kernel.A_C1] = ch.bias_temp_coeff
            ax[kernel.A_C2] = ch.bias_temp_coeff2
        self.g_sensitivity = np.array(ch.g_sensitivity)
        self.flags[kernel.F_GSENS] = ch.g_sensitivity_on and np.any(self.g_sensitivity)
        self.flicker = None
        self.flicker_phi = np.zeros(1)
        self.flicker_gains = np.zeros(1)
        if ch.flicker_on:
            self.flags[kernel.F_FLICKER] = 1
            self.flicker = noise.flicker_plan(ch.flicker_band_s, self.dt, ch.flicker_per_decade)
            self.flicker_b = np.array(ch.flicker_b)
            self.flicker_phi = self.flicker.phi.copy()
            self.flicker_gains = self.flicker.gains.copy()
            ax[kernel.A_FLICKER_B] = self.flicker_b
        if ch.walk_on:
            self.flags[kernel.F_RRW] = 1
            ax[kernel.A_RRW_STEP] = units.rrw_to_step_sigma(ch.walk_k, self.fs)

    def _white_noise(self, ch):
        """White noise: sigma = N sqrt(fs) (exact), N^2 = N_physics(T)^2 + N_elec^2."""
        self.mech_curves = [(TemperatureTable(function), axes)
                            for function, axes in ch.noise_curves]
        self.white = ch.electronics_on or bool(self.mech_curves)
        self.flags[kernel.F_WHITE] = self.white
        self.elec_sq = np.array(ch.electronics_density) ** 2 \
            if ch.electronics_on else np.zeros(3)
        self.flags[kernel.F_MECH] = bool(self.mech_curves)
        self.axis[kernel.A_ELEC_SQ] = self.elec_sq
        self.axis[kernel.A_WHITE_SIGMA] = np.sqrt(self.elec_sq) * self.sqrt_fs

    def _output_filter(self, ch):
        """Set the ASIC's digital Butterworth low-pass (same coefficients on every axis)."""
        fs = self.fs
        self.lpf_b = np.zeros((3, 2))
        self.lpf_a = np.zeros((3, 2))
        self.lpf_zi = np.zeros((3, 1))
        self.lpf_noise_gain = 1.0
        if not (ch.lpf_on and ch.lpf_hz > 0.0):
            return
        if ch.lpf_hz >= 0.5 * fs:
            raise ValueError(
                f'{ch.owner}.output_filter_hz = {ch.lpf_hz!r} is out of '
                f'range at {fs:g} Hz sampling: allowed (0, {0.5 * fs:g}) Hz (below '
                'Nyquist), or 0 for no filter')
        low = MIN_FILTER_FRACTION[int(ch.lpf_order)] * fs
        if ch.lpf_hz < low:
            raise ValueError(
                f'{ch.owner}.output_filter_hz = {ch.lpf_hz!r} is out of range at {fs:g} Hz '
                f'sampling and order {int(ch.lpf_order)}: allowed [{low:g}, {0.5 * fs:g}) Hz '
                '(below, the coefficients lose the DC gain), or 0 for no filter')
        self.flags[kernel.F_LPF] = 1
        b, a = signal.butter(ch.lpf_order, ch.lpf_hz, fs=fs)
        self.lpf_b, self.lpf_a = np.tile(b, (3, 1)), np.tile(a, (3, 1))
        self.lpf_zi = np.tile(signal.lfilter_zi(b, a), (3, 1))
        self.lpf_noise_gain = _noise_gain(b, a)

    def _output_stage(self, ch):
        """Range flag, LSB rounding and the clip to whole LSBs inside the range."""
        ax = self.axis
        lsb = np.array(ch.lsb) if ch.lsb is not None else np.zeros(3)
        self.flags[kernel.F_QUANT] = np.any(lsb > 0.0)
        ax[kernel.A_LSB] = lsb
        if ch.range_limit is not None:
            self.flags[kernel.F_SAT] = 1
            ax[kernel.A_RANGE] = ch.range_limit
            ax[kernel.A_SAT_LIMIT] = ch.range_limit
            for i in np.flatnonzero(lsb > 0.0):
                ax[kernel.A_SAT_LIMIT, i] = math.floor(
                    ch.range_limit[i] / lsb[i] * (1.0 + 1e-12)) * lsb[i]

    def _timing(self, ch):
        """Latency, timestamp jitter and clock drift (reported, samples unchanged)."""
        sc = self.scalars
        sc[kernel.S_LATENCY] = ch.latency_s
        sc[kernel.S_JITTER] = ch.jitter_s
        self.flags[kernel.F_JITTER] = sc[kernel.S_JITTER] > 0.0
        sc[kernel.S_DRIFT] = ch.drift
        self.flags[kernel.F_DRIFT] = sc[kernel.S_DRIFT] != 0.0
