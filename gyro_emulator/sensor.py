"""
The gyro as a sensor: a 3-axis error model built on the physics.

For axis i at sample n (true body rate omega, ambient temperature T_amb,
specific force a; SI units)::

    T_die = lag(T_amb + self_heating)                 thermal time constant
    x     = (I + misalignment) omega                  cross-axis coupling
    g_i   = SF_i(T_die) (1 + scale_factor_error_i)    SF_i: physics (Eq 5-22)
    s_i   = H_sense[ g_i (x_i + nonlinearity_i x_i^2) ]   sense-mode envelope
    b_i   = turn_on_i + c1_i dT + c2_i dT^2 + (G a)_i + flicker_i + walk_i
    y_i   = Q( sat( H_filter[ s_i + b_i + w_i ] ) )

* SF_i(T) is :func:`gyro_emulator.physics.scale_factor_ratio` of the axis's
  device (Young's modulus, gas damping with the selected viscosity law,
  pressure), tabulated once every 0.01 C (relative error < 1e-10).
* H_sense is the exact ZOH discretisation of the sense-mode envelope
  (:func:`gyro_emulator.dynamics.rate_channel_discrete`, DC gain 1) at the
  calibration temperature and the configured mode split; H_filter is the
  ASIC's digital Butterworth low-pass.
* w_i is white rate noise of two-sided density N_i(T) = sqrt(N_mech(T)^2 +
  N_elec^2) with N_mech = sqrt(4 k_B T C_sense) / (2 M V_drive)
  (:func:`gyro_emulator.noise.brownian_arw_rad_s_sqrt_hz`); per-sample sigma
  N / sqrt(dt) (exact).
* flicker_i is the bias instability B (Gauss-Markov sum, phi = exp(-dt/T_k),
  exact) and walk_i the rate random walk K (increments K sqrt(dt), exact).
* The die temperature follows T[n] = phi T[n-1] + (1 - phi) T_target[n],
  phi = exp(-dt / tau): the exact response of a first-order lag to an input
  held over each sample period.
* Latency, timestamp jitter and clock drift do not change the samples; they
  are reported per sample in ``output_delay_s`` for the publisher to stamp.

Both APIs give IDENTICAL samples for the same seed and inputs: ``run`` and
``step`` share one block kernel whose every recursion carries its state
exactly, and every noise term draws from its own child generator (spawned
from the injected ``numpy.random.Generator``), so draws do not depend on how a
record is split into calls.
"""

from dataclasses import dataclass
import math

from gyro_emulator import dynamics, noise, physics, units
from gyro_emulator.params import MODEL_TEMP_RANGE_C
from gyro_emulator.sensor_config import SensorConfig
import numpy as np
from scipy import linalg, signal

#: Samples per block of the vectorised kernel (fits the L2 cache).
BLOCK_SAMPLES = 8192

_STREAMS = ('turn_on', 'white', 'flicker', 'rate_random_walk', 'jitter')


@dataclass(frozen=True)
class SensorSample:
    """
    One 3-axis output sample.

    Attributes
    ----------
    gyro_rad_s : numpy.ndarray
        Rate output (x, y, z), rad/s.
    true_rate_rad_s : numpy.ndarray
        True body rate, rad/s.
    die_temp_c : float
        Die temperature, deg C.
    bias_rad_s : numpy.ndarray
        Total bias of this sample (all bias terms, no white noise), rad/s.
    scale_factor : numpy.ndarray
        Total gain: physics temperature ratio times (1 + scale-factor error).
    saturated : numpy.ndarray
        True where the output hit the range limit.
    output_delay_s : float
        Latency + this sample's timestamp jitter + clock drift, s.

    """

    gyro_rad_s: np.ndarray
    true_rate_rad_s: np.ndarray
    die_temp_c: float
    bias_rad_s: np.ndarray
    scale_factor: np.ndarray
    saturated: np.ndarray
    output_delay_s: float


@dataclass(frozen=True)
class SensorBatch:
    """The fields of :class:`SensorSample` for N samples: (N, 3) or (N,) arrays."""

    gyro_rad_s: np.ndarray
    true_rate_rad_s: np.ndarray
    die_temp_c: np.ndarray
    bias_rad_s: np.ndarray
    scale_factor: np.ndarray
    saturated: np.ndarray
    output_delay_s: np.ndarray

    def __len__(self):
        """Return the number of samples."""
        return len(self.die_temp_c)

    def sample(self, index):
        """Return sample ``index`` as a :class:`SensorSample`."""
        return SensorSample(
            gyro_rad_s=self.gyro_rad_s[index], true_rate_rad_s=self.true_rate_rad_s[index],
            die_temp_c=float(self.die_temp_c[index]), bias_rad_s=self.bias_rad_s[index],
            scale_factor=self.scale_factor[index], saturated=self.saturated[index],
            output_delay_s=float(self.output_delay_s[index]))

    @staticmethod
    def concatenate(batches):
        """Join batches in time order."""
        names = SensorBatch.__dataclass_fields__
        return SensorBatch(**{n: np.concatenate([getattr(b, n) for b in batches])
                              for n in names})


class TemperatureTable:
    """
    ``function(temp_c)`` tabulated every 0.01 C over ``MODEL_TEMP_RANGE_C``.

    Linear interpolation between grid points: a fixed function of the
    temperature (so every sample gets the same value whichever block it is
    in), a few operations per sample, and a relative error below 1e-10 for
    the smooth physics curves it holds (checked in test/test_sensor.py).
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
        for k, axes in groups:
            if k == key:
                axes.append(axis)
                break
        else:
            groups.append((key, [axis]))
    return groups


def _cross(matrix, vec):
    """Return vec @ matrix.T for (n, 3) ``vec``, written out (no BLAS, fixed order)."""
    return (vec[:, 0:1] * matrix[:, 0] + vec[:, 1:2] * matrix[:, 1]
            + vec[:, 2:3] * matrix[:, 2])


def _noise_gain(b, a):
    """RMS gain sqrt(sum h[k]^2) of a digital filter to white noise (Lyapunov)."""
    ad, bd, cd, dd = signal.tf2ss(b, a)
    p = linalg.solve_discrete_lyapunov(ad, bd @ bd.T)
    return float(np.sqrt((cd @ p @ cd.T)[0, 0] + dd[0, 0] ** 2))


class _Plan:
    """Everything the kernel needs, precomputed from a config and a sample rate."""

    def __init__(self, config, sample_rate_hz):
        c, t = config, config.terms
        fs = float(sample_rate_hz)
        self.config = c
        self.fs = fs
        self.dt = 1.0 / fs
        self.cal_temp_c = np.array([d.calibration_temp_c for d in c.device])
        groups = _group_axes(c.device)
        # thermal lag
        self.thermal_phi = None
        self.self_heating_c = c.self_heating_c if t.thermal_lag else 0.0
        if t.thermal_lag and c.thermal_time_constant_s > 0.0:
            self.thermal_phi = math.exp(-self.dt / c.thermal_time_constant_s)
            self.thermal_gain = -math.expm1(-self.dt / c.thermal_time_constant_s)
        self.initial_die_temp_c = c.initial_die_temp_c
        # scale factor
        self.sf_curves = []
        if t.scale_factor_temperature:
            self.sf_curves = [
                (TemperatureTable(lambda temp, d=dev: physics.scale_factor_ratio(d, temp)),
                 axes) for dev, axes in groups]
        self.sf_error = np.array(c.scale_factor_error) if t.scale_factor_error else None
        self.misalignment = np.array(c.misalignment) if t.misalignment and np.any(
            c.misalignment) else None
        self.nonlinearity = np.array(c.nonlinearity_s_rad) if t.nonlinearity and np.any(
            c.nonlinearity_s_rad) else None
        # sense dynamics: one 2nd-order filter per distinct (device, split)
        self.dynamics = []
        if t.sense_dynamics:
            keys = [(d, s) for d, s in zip(c.device, c.mode_split_hz)]
            for (dev, split), axes in _group_axes(keys):
                ad, bd, cd, dd = dynamics.rate_channel_discrete(
                    dev, fs, dev.calibration_temp_c, split)
                num, den = signal.ss2tf(ad, bd, cd, dd)
                self.dynamics.append((num[0] / den[0], den / den[0], axes))
        # bias terms
        self.turn_on = t.turn_on_bias
        self.bias_temperature = (np.array(c.bias_temp_coeff_rad_s_k),
                                 np.array(c.bias_temp_coeff2_rad_s_k2)) \
            if t.bias_temperature else None
        self.g_sensitivity = np.array(c.g_sensitivity_rad_s_m_s2) if t.g_sensitivity \
            and np.any(c.g_sensitivity_rad_s_m_s2) else None
        self.flicker = None
        if t.bias_instability:
            self.flicker = noise.flicker_plan(c.bias_instability_band_s, self.dt,
                                              c.bias_instability_per_decade)
            self.flicker_b = np.array(c.bias_instability_rad_s)
        self.rrw_step = np.array(units.rrw_to_step_sigma(
            c.rate_random_walk_rad_s_sqrt_s, fs)) if t.rate_random_walk else None
        # white noise
        self.white = t.mechanical_noise or t.electronics_noise
        self.elec_sq = np.array(c.electronics_noise_rad_s_sqrt_hz) ** 2 \
            if t.electronics_noise else np.zeros(3)
        self.mech_curves = []
        if t.mechanical_noise:
            self.mech_curves = [
                (TemperatureTable(
                    lambda temp, d=dev: noise.brownian_arw_rad_s_sqrt_hz(d, temp) ** 2),
                 axes) for dev, axes in groups]
        self.sqrt_fs = math.sqrt(fs)
        self.white_sigma = np.sqrt(self.elec_sq) * self.sqrt_fs
        # output filter
        self.lpf = None
        self.lpf_noise_gain = 1.0
        if t.output_filter and c.output_filter_hz > 0.0:
            if c.output_filter_hz >= 0.5 * fs:
                raise ValueError(
                    f'SensorConfig.output_filter_hz = {c.output_filter_hz!r} is out of '
                    f'range at {fs:g} Hz sampling: allowed (0, {0.5 * fs:g}) Hz (below '
                    'Nyquist), or 0 for no filter')
            b, a = signal.butter(c.output_filter_order, c.output_filter_hz, fs=fs)
            self.lpf = (b, a)
            self.lpf_noise_gain = _noise_gain(b, a)
        # output stage
        lsb = np.array(c.lsb_rad_s)
        self.quant_axes = [i for i in range(3) if t.quantization and lsb[i] > 0.0]
        self.lsb = lsb
        rng_ = np.array(c.range_rad_s)
        self.sat_limit = None
        if t.saturation:
            limit = rng_.copy()
            for i in self.quant_axes:
                limit[i] = math.floor(rng_[i] / lsb[i] * (1.0 + 1e-12)) * lsb[i]
            self.sat_limit = limit
            self.range = rng_
        self.latency_s = c.latency_s if t.latency else 0.0
        self.jitter_s = c.timestamp_jitter_s if t.timestamp_jitter else 0.0
        self.drift = c.clock_drift_ppm * 1e-6 if t.clock_drift else 0.0

    def turn_on_rad_s(self, unit_normals):
        """Turn-on bias: fixed part + sigma x this run's standard normals, rad/s."""
        c = self.config
        return np.array(c.turn_on_bias_rad_s) + np.array(
            c.turn_on_bias_sigma_rad_s) * unit_normals

    def mech_sq(self, die):
        out = np.empty((len(die), 3))
        for curve, axes in self.mech_curves:
            out[:, axes] = curve(die)[:, np.newaxis]
        return out


class _State:
    """Mutable state carried between blocks."""

    def __init__(self):
        self.index = 0
        self.die_last = None
        self.dyn_zi = None
        self.lpf_zi = None
        self.flicker = None
        self.flicker_key = None
        self.rrw = np.zeros(3)


def _spawn(rng, count):
    """Child generators of ``rng``: one independent stream per noise term."""
    try:
        return rng.spawn(count)
    except (TypeError, ValueError, AttributeError):
        seeds = np.random.SeedSequence(rng.integers(0, 2 ** 63, size=4).tolist())
        kind = type(rng.bit_generator)
        return [np.random.Generator(kind(s)) for s in seeds.spawn(count)]


class GyroModel:
    """
    Stateful 3-axis gyro: batch (:meth:`run`) and streaming (:meth:`step`) APIs.

    Parameters
    ----------
    config : SensorConfig
        The error model.
    sample_rate_hz : float
        Output data rate, Hz.
    rng : numpy.random.Generator
        Source of every random number (one child stream per noise term).

    """

    def __init__(self, config, sample_rate_hz, rng):
        if not isinstance(config, SensorConfig):
            raise ValueError(f'GyroModel.config = {config!r} is not a SensorConfig')
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f'GyroModel.rng = {rng!r} is not a numpy.random.Generator')
        rate = float(sample_rate_hz) if np.isscalar(sample_rate_hz) else float('nan')
        if not (math.isfinite(rate) and 0.0 < rate <= 1e6):
            raise ValueError(f'GyroModel.sample_rate_hz = {sample_rate_hz!r} is out of '
                             'range: allowed (0, 1e6] Hz')
        self.sample_rate_hz = rate
        self.dt_s = 1.0 / rate
        self._streams = dict(zip(_STREAMS, _spawn(rng, len(_STREAMS))))
        self._turn_on_z = self._streams['turn_on'].standard_normal(3)
        self._state = _State()
        self._plan = None
        self.update_config(config)

    # --- configuration ---------------------------------------------------

    @property
    def config(self):
        """Return the active :class:`SensorConfig`."""
        return self._plan.config

    @property
    def temp_range_c(self):
        """Ambient/die temperatures the model accepts, deg C (MODEL_TEMP_RANGE_C)."""
        return MODEL_TEMP_RANGE_C

    def update_config(self, config):
        """
        Apply a new configuration at run time, keeping the model's states.

        Die temperature, bias random walk, flicker states and filter states
        carry over. A filter whose coefficients change restarts from steady
        state at its next input; a changed flicker band redraws its states
        from the stationary distribution.
        """
        if not isinstance(config, SensorConfig):
            raise ValueError(f'GyroModel.config = {config!r} is not a SensorConfig')
        old = self._plan
        plan = _Plan(config, self.sample_rate_hz)
        st = self._state
        if old is None or _dyn_key(old) != _dyn_key(plan):
            st.dyn_zi = None
        if old is None or _lpf_key(old) != _lpf_key(plan):
            st.lpf_zi = None
        if plan.flicker is not None:
            key = (tuple(plan.flicker.corr_times_s), plan.dt)
            if st.flicker_key != key:
                z = self._streams['flicker'].standard_normal((len(plan.flicker.phi), 3))
                st.flicker = noise.flicker_initial_state(plan.flicker, plan.flicker_b, z)
                st.flicker_key = key
        self._plan = plan

    @property
    def white_noise_sigma_rad_s(self):
        """
        Per-sample sigma of the white rate noise at the output, rad/s, (3,).

        N(T_die) sqrt(f_s) times the output filter's RMS noise gain, at the
        current die temperature (the calibration temperature before the first
        sample). Use diag(sigma^2) as sensor_msgs/Imu angular_velocity_covariance.
        """
        plan = self._plan
        if not plan.white:
            return np.zeros(3)
        die = self._state.die_last
        if die is not None:
            temps = np.full(3, float(die))
        elif self.config.initial_die_temp_c is not None:
            temps = np.full(3, self.config.initial_die_temp_c)
        else:
            temps = plan.cal_temp_c
        sq = plan.elec_sq.copy()
        for curve, axes in plan.mech_curves:
            sq[axes] += curve(temps[axes])
        return np.sqrt(sq) * plan.sqrt_fs * plan.lpf_noise_gain

    @property
    def die_temp_c(self):
        """Die temperature after the last sample (None before the first)."""
        return None if self._state.die_last is None else float(self._state.die_last)

    @property
    def sample_index(self):
        """Return the number of samples produced so far."""
        return self._state.index

    # --- the two APIs ----------------------------------------------------

    def step(self, rate_rad_s, ambient_temp_c, accel_m_s2=None):
        """
        Produce one sample.

        Parameters
        ----------
        rate_rad_s : array_like
            True body rate (x, y, z), rad/s.
        ambient_temp_c : float
            Ambient temperature, deg C.
        accel_m_s2 : array_like, optional
            Specific force (x, y, z), m/s^2, for the g-sensitivity; None = 0.

        Returns
        -------
        SensorSample

        """
        rate = _vector('rate_rad_s', rate_rad_s)[np.newaxis, :]
        temp = _finite('ambient_temp_c', np.array([ambient_temp_c], dtype=float))
        self._check_temp(temp)
        accel = None if accel_m_s2 is None else _vector(
            'accel_m_s2', accel_m_s2)[np.newaxis, :]
        out = _new_outputs(1)
        _block(self, rate, temp, accel, out)
        return SensorSample(
            gyro_rad_s=out['gyro_rad_s'][0], true_rate_rad_s=out['true_rate_rad_s'][0],
            die_temp_c=float(out['die_temp_c'][0]), bias_rad_s=out['bias_rad_s'][0],
            scale_factor=out['scale_factor'][0], saturated=out['saturated'][0],
            output_delay_s=float(out['output_delay_s'][0]))

    def run(self, rate_rad_s, ambient_temp_c, accel_m_s2=None):
        """
        Produce N samples at once (vectorised; identical to N :meth:`step` calls).

        Parameters
        ----------
        rate_rad_s : array_like
            True body rates, rad/s, shape (N, 3).
        ambient_temp_c : array_like or float
            Ambient temperatures, deg C, shape (N,) (a scalar is held).
        accel_m_s2 : array_like, optional
            Specific force, m/s^2, shape (N, 3) or (3,); None = 0.

        Returns
        -------
        SensorBatch

        """
        rate = np.asarray(rate_rad_s, dtype=float)
        if rate.ndim != 2 or rate.shape[1] != 3:
            raise ValueError(f'GyroModel.run: rate_rad_s has shape {rate.shape}: '
                             'expected (N, 3)')
        n = rate.shape[0]
        _finite('rate_rad_s', rate)
        temp = np.asarray(ambient_temp_c, dtype=float)
        if temp.ndim == 0:
            temp = np.full(n, float(temp))
        if temp.shape != (n,):
            raise ValueError(f'GyroModel.run: ambient_temp_c has shape {temp.shape}: '
                             f'expected ({n},)')
        _finite('ambient_temp_c', temp)
        self._check_temp(temp)
        accel = None
        if accel_m_s2 is not None:
            accel = np.asarray(accel_m_s2, dtype=float)
            if accel.shape == (3,):
                accel = np.broadcast_to(accel, (n, 3))
            if accel.shape != (n, 3):
                raise ValueError(f'GyroModel.run: accel_m_s2 has shape {accel.shape}: '
                                 f'expected ({n}, 3) or (3,)')
            _finite('accel_m_s2', accel)
        out = _new_outputs(n)
        for start in range(0, n, BLOCK_SAMPLES):
            sl = slice(start, start + BLOCK_SAMPLES)
            _block(self, rate[sl], temp[sl], None if accel is None else accel[sl],
                   {k: v[sl] for k, v in out.items()})
        return SensorBatch(**out)

    def _check_temp(self, temp):
        lo, hi = MODEL_TEMP_RANGE_C
        if temp.min() < lo or temp.max() > hi:
            bad = float(temp[(temp < lo) | (temp > hi)][0])
            raise ValueError(f'GyroModel: ambient_temp_c = {bad!r} is out of range: '
                             f'allowed [{lo}, {hi}] C')


def _dyn_key(plan):
    return [(tuple(b), tuple(a), tuple(ax)) for b, a, ax in plan.dynamics]


def _lpf_key(plan):
    return None if plan.lpf is None else (tuple(plan.lpf[0]), tuple(plan.lpf[1]))


def _vector(name, value):
    arr = np.asarray(value, dtype=float)
    if arr.shape != (3,):
        raise ValueError(f'GyroModel.step: {name} has shape {arr.shape}: expected (3,)')
    return _finite(name, arr)


def _finite(name, arr):
    if not np.all(np.isfinite(arr)):
        bad = np.flatnonzero(~np.isfinite(arr.ravel()))[0]
        raise ValueError(f'GyroModel: {name} = {float(arr.ravel()[bad])!r} (element {bad}) is '
                         'not finite: allowed finite numbers')
    return arr


#: Blocks up to this many samples run the recursions as explicit loops (the
#: same arithmetic as scipy.signal.lfilter's transposed direct form II, so the
#: results are bit-identical) to keep the streaming step cheap.
_SMALL = 4


def _iir1(u, phi, gain, last):
    """y[n] = phi y[n-1] + gain u[n] along axis 0; returns (y, y[-1])."""
    if len(u) > _SMALL:
        return noise.first_order_filter(u, phi, gain, last)
    y = np.empty_like(u)
    for n in range(len(u)):
        last = phi * last + gain * u[n]
        y[n] = last
    return y, np.array(last, copy=True)


def _iir(b, a, x, zi):
    """scipy.signal.lfilter(b, a, x, axis=0, zi=zi) with a loop for tiny blocks."""
    if len(x) > _SMALL:
        return signal.lfilter(b, a, x, axis=0, zi=zi)
    order = len(a) - 1
    z = [zi[k].copy() for k in range(order)]
    y = np.empty_like(x)
    for n in range(len(x)):
        xn = x[n]
        yn = z[0] + b[0] * xn
        for k in range(order - 1):
            z[k] = z[k + 1] + b[k + 1] * xn - a[k + 1] * yn
        z[order - 1] = b[order] * xn - a[order] * yn
        y[n] = yn
    return y, np.array(z)


def _flicker(z, plan, bias_instability, states, out):
    """Add the flicker bias of a block to ``out`` (see noise.flicker)."""
    u = z * bias_instability
    new = np.empty_like(states)
    for k in range(len(plan.phi)):
        xk, new[k] = _iir1(u, plan.phi[k], plan.gains[k], states[k])
        out += xk
    return new


def _new_outputs(n):
    return {'gyro_rad_s': np.empty((n, 3)), 'true_rate_rad_s': np.empty((n, 3)),
            'die_temp_c': np.empty(n), 'bias_rad_s': np.empty((n, 3)),
            'scale_factor': np.empty((n, 3)), 'saturated': np.empty((n, 3), dtype=bool),
            'output_delay_s': np.empty(n)}


def _block(model, rate, amb, accel, out):
    """
    Advance ``model`` over one block of samples (the kernel of run and step).

    ``out`` maps the SensorBatch field names to arrays of the block's length,
    filled in place.
    """
    plan, st, streams = model._plan, model._state, model._streams
    n = amb.shape[0]
    out['true_rate_rad_s'][...] = rate
    # die temperature (exact first-order lag)
    die = out['die_temp_c']
    target = amb + plan.self_heating_c if plan.self_heating_c else amb
    if plan.thermal_phi is not None:
        if st.die_last is None:
            st.die_last = np.array(plan.initial_die_temp_c
                                   if plan.initial_die_temp_c is not None else target[0])
        die[...], st.die_last = _iir1(target, plan.thermal_phi, plan.thermal_gain,
                                      st.die_last)
    else:
        die[...] = target
        st.die_last = np.array(die[-1])
    lo, hi = MODEL_TEMP_RANGE_C
    if die.min() < lo or die.max() > hi:
        raise ValueError(f'GyroModel: die temperature {float(die.max()):g} C (ambient + '
                         f'self_heating_c) is out of range: allowed [{lo}, {hi}] C')
    # total gain: physics ratio x (1 + scale-factor error)
    gain = out['scale_factor']
    if plan.sf_curves:
        for curve, axes in plan.sf_curves:
            gain[:, axes] = curve(die)[:, np.newaxis]
        if plan.sf_error is not None:
            gain *= 1.0 + plan.sf_error
    elif plan.sf_error is not None:
        gain[...] = 1.0 + plan.sf_error
    else:
        gain.fill(1.0)
    # sensed signal
    x = rate
    if plan.misalignment is not None:
        x = x + _cross(plan.misalignment, rate)
    if plan.nonlinearity is not None:
        x = x + plan.nonlinearity * x * x
    y = out['gyro_rad_s']
    if plan.sf_curves or plan.sf_error is not None:
        np.multiply(x, gain, out=y)
    else:
        y[...] = x
    if plan.dynamics:
        if st.dyn_zi is None:
            st.dyn_zi = [signal.lfilter_zi(b, a)[:, np.newaxis] * y[0, axes]
                         for b, a, axes in plan.dynamics]
        for k, (b, a, axes) in enumerate(plan.dynamics):
            if len(axes) == 3:
                y[...], st.dyn_zi[k] = _iir(b, a, y, st.dyn_zi[k])
            else:
                y[:, axes], st.dyn_zi[k] = _iir(b, a, y[:, axes], st.dyn_zi[k])
    # bias
    bias = out['bias_rad_s']
    bias.fill(0.0)
    if plan.turn_on:
        bias += plan.turn_on_rad_s(model._turn_on_z)
    if plan.bias_temperature is not None:
        c1, c2 = plan.bias_temperature
        d_temp = die[:, np.newaxis] - plan.cal_temp_c
        bias += (c1 + c2 * d_temp) * d_temp
    if plan.g_sensitivity is not None and accel is not None:
        bias += _cross(plan.g_sensitivity, accel)
    if plan.flicker is not None:
        z = streams['flicker'].standard_normal((n, 3))
        st.flicker = _flicker(z, plan.flicker, plan.flicker_b, st.flicker, bias)
    if plan.rrw_step is not None:
        z = streams['rate_random_walk'].standard_normal((n, 3))
        walk, st.rrw = noise.random_walk(z, plan.rrw_step, st.rrw)
        bias += walk
    y += bias
    # white rate noise of two-sided density N(T): sigma = N sqrt(fs) (exact)
    if plan.white:
        z = streams['white'].standard_normal((n, 3))
        if plan.mech_curves:
            sigma = plan.mech_sq(die)
            sigma += plan.elec_sq
            np.sqrt(sigma, out=sigma)
            sigma *= plan.sqrt_fs
            z *= sigma
        else:
            z *= plan.white_sigma
        y += z
    if plan.lpf is not None:
        b, a = plan.lpf
        if st.lpf_zi is None:
            st.lpf_zi = signal.lfilter_zi(b, a)[:, np.newaxis] * y[0]
        y[...], st.lpf_zi = _iir(b, a, y, st.lpf_zi)
    # output stage: range flag, LSB, clip
    saturated = out['saturated']
    if plan.sat_limit is not None:
        np.greater(np.abs(y), plan.range, out=saturated)
    else:
        saturated.fill(False)
    for i in plan.quant_axes:
        y[:, i] = np.rint(y[:, i] / plan.lsb[i]) * plan.lsb[i]
    if plan.sat_limit is not None:
        np.clip(y, -plan.sat_limit, plan.sat_limit, out=y)
    # timing
    delay = out['output_delay_s']
    delay.fill(plan.latency_s)
    if plan.jitter_s > 0.0:
        delay += plan.jitter_s * streams['jitter'].standard_normal(n)
        np.maximum(delay, 0.0, out=delay)
    if plan.drift:
        delay += (st.index + np.arange(n)) * model.dt_s * plan.drift
    st.index += n
