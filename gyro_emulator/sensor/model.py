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

* SF_i(T) is :func:`gyro_emulator.physics.first_order.scale_factor_ratio` of the axis's
  device (Young's modulus, gas damping with the selected viscosity law,
  pressure), tabulated once every 0.01 C (relative error < 1e-10) and
  interpolated linearly per sample.
* H_sense is the exact ZOH discretisation of the sense-mode envelope
  (:func:`gyro_emulator.physics.dynamics.rate_channel_discrete`, DC gain 1) at the
  calibration temperature and the configured mode split; H_filter is the
  ASIC's digital Butterworth low-pass. Both run as transposed direct form II
  recursions (the arithmetic of ``scipy.signal.lfilter``), started in steady
  state at their first input.
* w_i is white rate noise of two-sided density N_i(T) = sqrt(N_mech(T)^2 +
  N_elec^2) with N_mech = sqrt(4 k_B T C_sense) / (2 M V_drive)
  (:func:`gyro_emulator.sensor.noise.brownian_arw_rad_s_sqrt_hz`); per-sample sigma
  N sqrt(f_s) = N / sqrt(dt) (exact, IEEE Std 952).
* flicker_i is the bias instability B: a sum of Gauss-Markov sections
  x_k[n] = phi_k x_k[n-1] + c_k B w[n], phi_k = exp(-dt/T_k) (exact; one
  normal per sample shared by the sections, :func:`gyro_emulator.sensor.noise.flicker_plan`),
  and walk_i the rate random walk K with increments K sqrt(dt) (exact).
* The die temperature follows T[n] = phi T[n-1] + (1 - phi) T_target[n],
  phi = exp(-dt / tau): the exact response of a first-order lag to an input
  held over each sample period.
* Latency, timestamp jitter and clock drift do not change the samples; they
  are reported per sample in ``output_delay_s`` for the publisher to stamp.

One implementation: a single compiled kernel (:func:`_kernel`, numba) runs
every term sample by sample in one pass. :meth:`GyroModel.run` calls it on the
whole record and :meth:`GyroModel.step` on one sample, so both give IDENTICAL
samples for the same seed and inputs, however a record is split into calls.

Random numbers: every noise term and axis has its own stream (white x3,
flicker x3, rate random walk x3, timestamp jitter, turn-on bias), a SFC64
generator seeded by a child ``SeedSequence`` spawned from the injected
``numpy.random.Generator``. The kernel runs SFC64 and numpy's 256-level
ziggurat itself, on generator states held in a small uint64 array: its normals
are bit for bit those of ``numpy.random.Generator(numpy.random.SFC64(child))``
(tested), and the state costs nothing to pass per call, unlike numba's boxed
``Generator`` objects (about 6 us each per call).
"""

import copy
from dataclasses import dataclass
import math

from gyro_emulator import units
from gyro_emulator.physics import dynamics, first_order
from gyro_emulator.sensor import noise
from gyro_emulator.sensor.config import SensorConfig
from gyro_emulator.validation import MODEL_TEMP_RANGE_C
import numba
from numba.np.random import _constants as ziggurat
import numpy as np
from scipy import linalg, signal

#: Random streams (rows of the generator-state array): turn-on, jitter, then
#: white, flicker and rate random walk for axes x, y, z.
_R_TURN_ON, _R_JITTER, _R_WHITE, _R_FLICKER, _R_RRW = 0, 1, 2, 5, 8
_STREAM_COUNT = 11


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
        for k, axes in groups:
            if k == key:
                axes.append(axis)
                break
        else:
            groups.append((key, [axis]))
    return groups


def _noise_gain(b, a):
    """RMS gain sqrt(sum h[k]^2) of a digital filter to white noise (Lyapunov)."""
    ad, bd, cd, dd = signal.tf2ss(b, a)
    p = linalg.solve_discrete_lyapunov(ad, bd @ bd.T)
    return float(np.sqrt((cd @ p @ cd.T)[0, 0] + dd[0, 0] ** 2))


# Indices into the kernel's coefficient arrays (compile-time constants in numba).
# flags (int64)
(_F_THERMAL, _F_SF, _F_MIS, _F_NONLIN, _F_DYN, _F_BIAS_T, _F_GSENS, _F_FLICKER,
 _F_RRW, _F_WHITE, _F_MECH, _F_LPF, _F_SAT, _F_QUANT, _F_JITTER, _F_DRIFT) = range(16)
# scalars (float64)
(_S_PHI, _S_GAIN, _S_HEAT, _S_INIT_DIE, _S_LOW_C, _S_STEPS, _S_SQRT_FS, _S_LATENCY,
 _S_JITTER, _S_DT, _S_DRIFT, _S_TEMP_LO, _S_TEMP_HI) = range(13)
# per-axis rows (float64, (rows, 3))
(_A_SF1, _A_NONLIN, _A_CAL, _A_C1, _A_C2, _A_TURN_ON, _A_FLICKER_B, _A_RRW_STEP,
 _A_ELEC_SQ, _A_WHITE_SIGMA, _A_RANGE, _A_SAT_LIMIT, _A_LSB) = range(13)
# state: integers and floats
_I_INDEX, _I_DIE_READY, _I_DYN_READY, _I_LPF_READY = range(4)


def _tables(curves):
    """Stack (TemperatureTable, axes) pairs into (tables, 2, grid) and an axis index."""
    if not curves:
        return np.zeros((1, 2, 2)), np.zeros(3, dtype=np.int64)
    stack = np.empty((len(curves), 2, len(curves[0][0].values)))
    index = np.zeros(3, dtype=np.int64)
    for k, (table, axes) in enumerate(curves):
        stack[k, 0] = table.values
        stack[k, 1] = table.slopes
        index[axes] = k
    return stack, index


class _Plan:
    """
    Everything the kernel needs, precomputed from a config and a sample rate.

    Immutable once built (``ros.stepper.clone_model`` shares it between copies
    of a model): the kernel only reads these arrays.
    """

    def __init__(self, config, sample_rate_hz, turn_on_z):
        c, t = config, config.terms
        fs = float(sample_rate_hz)
        self.config = c
        self.fs = fs
        self.dt = 1.0 / fs
        self.cal_temp_c = np.array([d.calibration_temp_c for d in c.device])
        groups = _group_axes(c.device)
        flags = np.zeros(16, dtype=np.int64)
        sc = np.zeros(13)
        ax = np.zeros((13, 3))
        lo, hi = MODEL_TEMP_RANGE_C
        sc[_S_TEMP_LO], sc[_S_TEMP_HI] = lo, hi
        sc[_S_LOW_C], sc[_S_STEPS] = lo, TemperatureTable.STEPS_PER_DEG
        sc[_S_DT] = self.dt
        # thermal lag: exact first-order response, phi = exp(-dt / tau)
        sc[_S_HEAT] = c.self_heating_c if t.thermal_lag else 0.0
        sc[_S_INIT_DIE] = math.nan if c.initial_die_temp_c is None else c.initial_die_temp_c
        if t.thermal_lag and c.thermal_time_constant_s > 0.0:
            flags[_F_THERMAL] = 1
            sc[_S_PHI] = float(noise.gauss_markov_phi(c.thermal_time_constant_s, self.dt))
            sc[_S_GAIN] = -math.expm1(-self.dt / c.thermal_time_constant_s)
        # total gain: physics ratio x (1 + scale-factor error)
        self.sf_curves = []
        if t.scale_factor_temperature:
            flags[_F_SF] = 1
            self.sf_curves = [
                (TemperatureTable(lambda temp, d=dev: first_order.scale_factor_ratio(d, temp)),
                 axes) for dev, axes in groups]
        ax[_A_SF1] = 1.0 + np.array(c.scale_factor_error) if t.scale_factor_error else 1.0
        self.misalignment = np.array(c.misalignment)
        flags[_F_MIS] = t.misalignment and np.any(self.misalignment)
        ax[_A_NONLIN] = c.nonlinearity_s_rad
        flags[_F_NONLIN] = t.nonlinearity and np.any(ax[_A_NONLIN])
        # sense dynamics: the 2nd-order envelope filter of each axis
        self.dyn_b = np.zeros((3, 3))
        self.dyn_a = np.zeros((3, 3))
        self.dyn_zi = np.zeros((3, 2))
        if t.sense_dynamics:
            flags[_F_DYN] = 1
            keys = [(d, s) for d, s in zip(c.device, c.mode_split_hz)]
            for (dev, split), axes in _group_axes(keys):
                ad, bd, cd, dd = dynamics.rate_channel_discrete(
                    dev, fs, dev.calibration_temp_c, split)
                num, den = signal.ss2tf(ad, bd, cd, dd)
                b, a = num[0] / den[0], den / den[0]
                self.dyn_b[axes], self.dyn_a[axes] = b, a
                self.dyn_zi[axes] = signal.lfilter_zi(b, a)
        # bias terms
        if t.turn_on_bias:
            ax[_A_TURN_ON] = np.array(c.turn_on_bias_rad_s) + np.array(
                c.turn_on_bias_sigma_rad_s) * turn_on_z
        ax[_A_CAL] = self.cal_temp_c
        if t.bias_temperature:
            flags[_F_BIAS_T] = 1
            ax[_A_C1], ax[_A_C2] = c.bias_temp_coeff_rad_s_k, c.bias_temp_coeff2_rad_s_k2
        self.g_sensitivity = np.array(c.g_sensitivity_rad_s_m_s2)
        flags[_F_GSENS] = t.g_sensitivity and np.any(self.g_sensitivity)
        self.flicker = None
        self.flicker_phi = np.zeros(1)
        self.flicker_gains = np.zeros(1)
        if t.bias_instability:
            flags[_F_FLICKER] = 1
            self.flicker = noise.flicker_plan(c.bias_instability_band_s, self.dt,
                                              c.bias_instability_per_decade)
            self.flicker_b = np.array(c.bias_instability_rad_s)
            self.flicker_phi = self.flicker.phi.copy()
            self.flicker_gains = self.flicker.gains.copy()
            ax[_A_FLICKER_B] = self.flicker_b
        if t.rate_random_walk:
            flags[_F_RRW] = 1
            ax[_A_RRW_STEP] = units.rrw_to_step_sigma(c.rate_random_walk_rad_s_sqrt_s, fs)
        # white noise: sigma = N sqrt(fs) (exact), N^2 = N_mech(T)^2 + N_elec^2
        self.white = t.mechanical_noise or t.electronics_noise
        flags[_F_WHITE] = self.white
        self.elec_sq = np.array(c.electronics_noise_rad_s_sqrt_hz) ** 2 \
            if t.electronics_noise else np.zeros(3)
        self.mech_curves = []
        if t.mechanical_noise:
            flags[_F_MECH] = 1
            self.mech_curves = [
                (TemperatureTable(
                    lambda temp, d=dev: noise.brownian_arw_rad_s_sqrt_hz(d, temp) ** 2),
                 axes) for dev, axes in groups]
        self.sqrt_fs = math.sqrt(fs)
        sc[_S_SQRT_FS] = self.sqrt_fs
        ax[_A_ELEC_SQ] = self.elec_sq
        ax[_A_WHITE_SIGMA] = np.sqrt(self.elec_sq) * self.sqrt_fs
        self.sf_tab, self.sf_index = _tables(self.sf_curves)
        self.mech_tab, self.mech_index = _tables(self.mech_curves)
        # output filter
        self.lpf_b = np.zeros(2)
        self.lpf_a = np.zeros(2)
        self.lpf_zi = np.zeros(1)
        self.lpf_noise_gain = 1.0
        if t.output_filter and c.output_filter_hz > 0.0:
            if c.output_filter_hz >= 0.5 * fs:
                raise ValueError(
                    f'SensorConfig.output_filter_hz = {c.output_filter_hz!r} is out of '
                    f'range at {fs:g} Hz sampling: allowed (0, {0.5 * fs:g}) Hz (below '
                    'Nyquist), or 0 for no filter')
            flags[_F_LPF] = 1
            self.lpf_b, self.lpf_a = signal.butter(c.output_filter_order, c.output_filter_hz,
                                                   fs=fs)
            self.lpf_zi = signal.lfilter_zi(self.lpf_b, self.lpf_a)
            self.lpf_noise_gain = _noise_gain(self.lpf_b, self.lpf_a)
        # output stage: range flag, LSB rounding, clip to whole LSBs inside the range
        lsb = np.array(c.lsb_rad_s) if t.quantization else np.zeros(3)
        flags[_F_QUANT] = np.any(lsb > 0.0)
        ax[_A_LSB] = lsb
        if t.saturation:
            flags[_F_SAT] = 1
            ax[_A_RANGE] = c.range_rad_s
            ax[_A_SAT_LIMIT] = c.range_rad_s
            for i in np.flatnonzero(lsb > 0.0):
                ax[_A_SAT_LIMIT, i] = math.floor(
                    c.range_rad_s[i] / lsb[i] * (1.0 + 1e-12)) * lsb[i]
        sc[_S_LATENCY] = c.latency_s if t.latency else 0.0
        sc[_S_JITTER] = c.timestamp_jitter_s if t.timestamp_jitter else 0.0
        flags[_F_JITTER] = sc[_S_JITTER] > 0.0
        sc[_S_DRIFT] = c.clock_drift_ppm * 1e-6 if t.clock_drift else 0.0
        flags[_F_DRIFT] = sc[_S_DRIFT] != 0.0
        self.flags, self.scalars, self.axis = flags, sc, ax
        for arr in (flags, sc, ax, self.misalignment, self.g_sensitivity, self.sf_tab,
                    self.sf_index, self.mech_tab, self.mech_index, self.dyn_b, self.dyn_a,
                    self.dyn_zi, self.lpf_b, self.lpf_a, self.lpf_zi, self.flicker_phi,
                    self.flicker_gains):
            arr.flags.writeable = False


class _State:
    """Mutable state carried between calls (copied by ``copy.deepcopy``)."""

    def __init__(self, rng_state):
        self.rng = rng_state                       # (11, 4) uint64 SFC64 states
        self.ints = np.zeros(4, dtype=np.int64)    # sample index, ready flags
        self.die_c = np.zeros(1)                   # die temperature of the last sample
        self.dyn_z = np.zeros((3, 2))
        self.lpf_z = np.zeros((3, 1))
        self.flicker = np.zeros((3, 1))            # (axes, sections)
        self.flicker_key = None
        self.rrw = np.zeros(3)


def _stream_states(rng, count):
    """
    SFC64 states of ``count`` child streams of the injected generator.

    The children are spawned from ``rng``'s SeedSequence (as ``rng.spawn``
    does); a generator without one seeds a SeedSequence from its own draws.
    """
    try:
        children = rng.bit_generator.seed_seq.spawn(count)
    except (AttributeError, TypeError, ValueError, NotImplementedError):
        children = np.random.SeedSequence(
            rng.integers(0, 2 ** 63, size=4).tolist()).spawn(count)
    return np.array([np.random.SFC64(s).state['state']['state'] for s in children],
                    dtype=np.uint64)


class GyroModel:
    """
    Stateful 3-axis gyro: batch (:meth:`run`) and streaming (:meth:`step`) APIs.

    Both call the same compiled kernel, so for the same seed and inputs they
    give identical samples, however a record is split into calls.

    Parameters
    ----------
    config : SensorConfig
        The error model.
    sample_rate_hz : float
        Output data rate, Hz.
    rng : numpy.random.Generator
        Source of every random number: one SFC64 child stream per noise term
        and axis is spawned from its SeedSequence.

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
        self._state = _State(_stream_states(rng, _STREAM_COUNT))
        self._turn_on_z = np.empty(3)
        _fill_normals(self._state.rng, _R_TURN_ON, self._turn_on_z)
        self._plan = None
        self.update_config(config)

    def copy(self):
        """
        Return an independent copy: same configuration, states and streams.

        The copy and the original then produce identical samples for the same
        inputs. The precomputed plan is immutable, so the copy shares it.
        """
        return copy.deepcopy(self, {id(self._plan): self._plan})

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
        plan = _Plan(config, self.sample_rate_hz, self._turn_on_z)
        st = self._state
        if old is None or not (np.array_equal(old.dyn_b, plan.dyn_b)
                               and np.array_equal(old.dyn_a, plan.dyn_a)):
            st.ints[_I_DYN_READY] = 0
            st.dyn_z = np.zeros((3, len(plan.dyn_a) - 1))
        if old is None or not (np.array_equal(old.lpf_b, plan.lpf_b)
                               and np.array_equal(old.lpf_a, plan.lpf_a)):
            st.ints[_I_LPF_READY] = 0
            st.lpf_z = np.zeros((3, len(plan.lpf_a) - 1))
        if plan.flicker is not None:
            key = (tuple(plan.flicker.corr_times_s), plan.dt)
            if st.flicker_key != key:
                count = len(plan.flicker.phi)
                z = np.empty((3, count))
                for i in range(3):
                    _fill_normals(st.rng, _R_FLICKER + i, z[i])
                st.flicker = np.ascontiguousarray(
                    noise.flicker_initial_state(plan.flicker, plan.flicker_b, z.T).T)
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
        die = self.die_temp_c
        if die is not None:
            temps = np.full(3, die)
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
        st = self._state
        return float(st.die_c[0]) if st.ints[_I_DIE_READY] else None

    @property
    def sample_index(self):
        """Return the number of samples produced so far."""
        return int(self._state.ints[_I_INDEX])

    # --- the two APIs ----------------------------------------------------

    def step(self, rate_rad_s, ambient_temp_c, accel_m_s2=None):
        """
        Produce one sample (the kernel of :meth:`run` on a record of one).

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
        rate = _vector('rate_rad_s', rate_rad_s)
        try:
            temp = float(ambient_temp_c)
        except (TypeError, ValueError):
            raise ValueError(f'GyroModel.step: ambient_temp_c = {ambient_temp_c!r} is not '
                             'a number') from None
        if not math.isfinite(temp):
            raise ValueError(f'GyroModel: ambient_temp_c = {temp!r} is not finite: allowed '
                             'finite numbers')
        lo, hi = MODEL_TEMP_RANGE_C
        if not lo <= temp <= hi:
            self._check_temp(np.array([temp]))
        accel = None if accel_m_s2 is None else _vector('accel_m_s2', accel_m_s2)
        out = self._advance(rate, np.array([temp]), accel)
        return SensorSample(
            gyro_rad_s=out[0][0], true_rate_rad_s=out[1][0], die_temp_c=float(out[2][0]),
            bias_rad_s=out[3][0], scale_factor=out[4][0], saturated=out[5][0],
            output_delay_s=float(out[6][0]))

    def run(self, rate_rad_s, ambient_temp_c, accel_m_s2=None):
        """
        Produce N samples at once (compiled kernel; identical to N :meth:`step` calls).

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
        if n:
            self._check_temp(temp)
        accel = None
        if accel_m_s2 is not None:
            accel = np.asarray(accel_m_s2, dtype=float)
            if accel.shape == (3,):
                accel = accel.reshape(1, 3)
            elif accel.shape != (n, 3):
                raise ValueError(f'GyroModel.run: accel_m_s2 has shape {accel.shape}: '
                                 f'expected ({n}, 3) or (3,)')
            _finite('accel_m_s2', accel)
        return SensorBatch(*self._advance(rate, temp, accel))

    def _advance(self, rate, temp, accel):
        """Run the kernel over validated inputs; return the SensorBatch fields in order."""
        n = rate.shape[0]
        out = (np.empty((n, 3)), np.empty((n, 3)), np.empty(n), np.empty((n, 3)),
               np.empty((n, 3)), np.empty((n, 3), dtype=np.bool_), np.empty(n))
        if n == 0:
            return out
        p, st = self._plan, self._state
        if accel is None:
            accel, use_accel = _NO_ACCEL, False
        else:
            accel, use_accel = _kernel_input(accel), True
        bad = _kernel(
            _kernel_input(rate), _kernel_input(temp), accel, use_accel,
            p.flags, p.scalars, p.axis, p.misalignment, p.g_sensitivity,
            p.sf_tab, p.sf_index, p.mech_tab, p.mech_index, p.dyn_b, p.dyn_a, p.dyn_zi,
            p.lpf_b, p.lpf_a, p.lpf_zi, p.flicker_phi, p.flicker_gains,
            st.rng, st.ints, st.die_c, st.dyn_z, st.lpf_z, st.flicker, st.rrw, *out)
        if bad:
            lo, hi = MODEL_TEMP_RANGE_C
            raise ValueError(f'GyroModel: die temperature {float(out[2][bad - 1]):g} C '
                             '(ambient + self_heating_c) is out of range: allowed '
                             f'[{lo}, {hi}] C')
        return out

    def _check_temp(self, temp):
        lo, hi = MODEL_TEMP_RANGE_C
        if temp.min() < lo or temp.max() > hi:
            bad = float(temp[(temp < lo) | (temp > hi)][0])
            raise ValueError(f'GyroModel: ambient_temp_c = {bad!r} is out of range: '
                             f'allowed [{lo}, {hi}] C')


#: Stand-in for "no specific force" (the kernel then skips the g-sensitivity).
_NO_ACCEL = np.zeros((1, 3))
_NO_ACCEL.flags.writeable = False


def _kernel_input(arr):
    """C-contiguous, read-only float64 view or copy (one compiled kernel signature)."""
    arr = np.ascontiguousarray(arr, dtype=float)
    if arr.flags.writeable:
        arr = arr.view()
        arr.flags.writeable = False
    return arr


def _vector(name, value):
    """Return ``value`` as a read-only (1, 3) float array of finite numbers."""
    try:
        values = [float(v) for v in value]
    except (TypeError, ValueError):
        raise ValueError(f'GyroModel.step: {name} = {value!r} is not 3 numbers') from None
    if len(values) != 3:
        raise ValueError(f'GyroModel.step: {name} has shape ({len(values)},): expected (3,)')
    for i, v in enumerate(values):
        if not math.isfinite(v):
            raise ValueError(f'GyroModel: {name} = {v!r} (element {i}) is not finite: '
                             'allowed finite numbers')
    arr = np.array([values])
    arr.flags.writeable = False
    return arr


def _finite(name, arr):
    if not np.all(np.isfinite(arr)):
        bad = np.flatnonzero(~np.isfinite(arr.ravel()))[0]
        raise ValueError(f'GyroModel: {name} = {float(arr.ravel()[bad])!r} (element {bad}) is '
                         'not finite: allowed finite numbers')
    return arr


# --- the compiled kernel -------------------------------------------------------
#
# SFC64 (Chris Doty-Humphrey's Small Fast Chaotic generator, as numpy.random.SFC64)
# and numpy's 256-level ziggurat for standard normals (Marsaglia & Tsang 2000,
# with numpy's tables and tail), on states s[k] = (a, b, c, counter).

_U1, _U3, _U8, _U11, _U24, _U40 = (np.uint64(v) for v in (1, 3, 8, 11, 24, 40))
_U255 = np.uint64(0xff)
_MANTISSA = np.uint64(0x000fffffffffffff)
_KI = np.asarray(ziggurat.ki_double, dtype=np.uint64)
_WI = np.asarray(ziggurat.wi_double, dtype=np.float64)
_FI = np.asarray(ziggurat.fi_double, dtype=np.float64)
_ZIG_R = float(ziggurat.ziggurat_nor_r)
_ZIG_INV_R = float(ziggurat.ziggurat_nor_inv_r)
_TO_UNIT = 1.0 / 9007199254740992.0          # 2^-53


@numba.njit(cache=True)
def _next_uint64(s, k):
    a, b, c, w = s[k, 0], s[k, 1], s[k, 2], s[k, 3]
    tmp = a + b + w
    s[k, 0] = b ^ (b >> _U11)
    s[k, 1] = c + (c << _U3)
    s[k, 2] = ((c << _U24) | (c >> _U40)) + tmp
    s[k, 3] = w + _U1
    return tmp


@numba.njit(cache=True)
def _next_double(s, k):
    return (_next_uint64(s, k) >> _U11) * _TO_UNIT


@numba.njit(cache=True)
def _normal(s, k):
    """One standard normal from stream k (numpy's Generator.standard_normal, bit for bit)."""
    while True:
        r = _next_uint64(s, k)
        idx = np.intp(r & _U255)
        r = r >> _U8
        rabs = (r >> _U1) & _MANTISSA
        x = rabs * _WI[idx]
        if r & _U1:
            x = -x
        if rabs < _KI[idx]:
            return x
        if idx == 0:
            while True:
                xx = -_ZIG_INV_R * np.log1p(-_next_double(s, k))
                yy = -np.log1p(-_next_double(s, k))
                if yy + yy > xx * xx:
                    if (rabs >> _U8) & _U1:
                        return -(_ZIG_R + xx)
                    return _ZIG_R + xx
        elif (_FI[idx - 1] - _FI[idx]) * _next_double(s, k) + _FI[idx] < np.exp(-0.5 * x * x):
            return x


@numba.njit(cache=True)
def _fill_normals(s, k, out):
    """Fill ``out`` with standard normals from stream ``k`` of the states ``s``."""
    for j in range(out.shape[0]):
        out[j] = _normal(s, k)


@numba.njit(cache=True)
def _tdf2(b, a, z, i, x):
    """One sample of transposed direct form II (scipy.signal.lfilter) on state row z[i]."""
    m = b.shape[0]
    y = z[i, 0] + b[0] * x
    for k in range(m - 2):
        z[i, k] = z[i, k + 1] + b[k + 1] * x - a[k + 1] * y
    z[i, m - 2] = b[m - 1] * x - a[m - 1] * y
    return y


@numba.njit(cache=True, error_model='numpy')
def _kernel(rate, amb, accel, use_accel, flags, sc, ax, mis, gsens, sf_tab, sf_idx,
            mech_tab, mech_idx, dyn_b, dyn_a, dyn_zi0, lpf_b, lpf_a, lpf_zi0, fl_phi,
            fl_gain, rng, ints, die_c, dyn_z, lpf_z, fl_x, rrw,
            gyro, true, die, bias, gain, sat, delay):
    """
    Advance the model over n samples, every term in one pass per sample.

    Inputs (n, 3) / (n,) and coefficients are read-only; the state arrays
    (``rng`` .. ``rrw``) are updated in place and the outputs filled. Returns
    0, or 1 + the index of the first die temperature outside the model range,
    in which case nothing but ``die`` has been written (the state is intact).
    Exact discretisation throughout: first-order lags and Gauss-Markov
    sections phi = exp(-dt/T); white sigma N sqrt(fs); walk steps K sqrt(dt).
    """
    n = amb.shape[0]
    # 1. die temperature (exact first-order lag), checked before any state changes
    heat, phi_t, gain_t = sc[_S_HEAT], sc[_S_PHI], sc[_S_GAIN]
    thermal = flags[_F_THERMAL] != 0
    if ints[_I_DIE_READY]:
        last = die_c[0]
    elif thermal and not math.isnan(sc[_S_INIT_DIE]):
        last = sc[_S_INIT_DIE]
    else:
        last = amb[0] + heat
    lo, hi = sc[_S_TEMP_LO], sc[_S_TEMP_HI]
    for j in range(n):
        target = amb[j] + heat
        last = phi_t * last + gain_t * target if thermal else target
        if not lo <= last <= hi:
            die[j] = last
            return j + 1
        die[j] = last
    die_c[0] = last
    ints[_I_DIE_READY] = 1
    # 2. hoisted switches and coefficients
    use_sf, use_mis, use_nl = flags[_F_SF] != 0, flags[_F_MIS] != 0, flags[_F_NONLIN] != 0
    use_dyn, use_bt, use_fl = flags[_F_DYN] != 0, flags[_F_BIAS_T] != 0, flags[_F_FLICKER] != 0
    use_g = use_accel and flags[_F_GSENS] != 0
    use_rrw, use_white, use_mech = flags[_F_RRW] != 0, flags[_F_WHITE] != 0, flags[_F_MECH] != 0
    use_lpf, use_sat, use_q = flags[_F_LPF] != 0, flags[_F_SAT] != 0, flags[_F_QUANT] != 0
    use_jit, use_drift = flags[_F_JITTER] != 0, flags[_F_DRIFT] != 0
    low_c, steps, sqrt_fs = sc[_S_LOW_C], sc[_S_STEPS], sc[_S_SQRT_FS]
    last_cell = sf_tab.shape[2] - 2 if use_sf else mech_tab.shape[2] - 2
    latency, jitter, dt, drift = sc[_S_LATENCY], sc[_S_JITTER], sc[_S_DT], sc[_S_DRIFT]
    index0 = ints[_I_INDEX]
    n_fl = fl_phi.shape[0]
    accel_step = 1 if accel.shape[0] == n else 0
    x = np.empty(3)
    sigma = np.empty(3)
    u, cell = 0.0, 0
    for i in range(3):
        sigma[i] = ax[_A_WHITE_SIGMA, i]
    for j in range(n):
        d = die[j]
        # temperature tables: one grid cell for every curve of this sample
        if use_sf or use_mech:
            u = (d - low_c) * steps
            cell = min(max(int(u), 0), last_cell)
            u -= cell
        # sensed signal: misalignment, nonlinearity, total gain
        r0, r1, r2 = rate[j, 0], rate[j, 1], rate[j, 2]
        true[j, 0], true[j, 1], true[j, 2] = r0, r1, r2
        for i in range(3):
            xi = rate[j, i]
            if use_mis:
                xi = xi + (r0 * mis[i, 0] + r1 * mis[i, 1] + r2 * mis[i, 2])
            if use_nl:
                xi = xi + ax[_A_NONLIN, i] * xi * xi
            gi = ax[_A_SF1, i]
            if use_sf:
                t = sf_idx[i]
                gi = (sf_tab[t, 0, cell] + u * sf_tab[t, 1, cell]) * gi
            gain[j, i] = gi
            x[i] = xi * gi
        # sense-mode envelope (2nd-order IIR), started in steady state
        if use_dyn:
            if ints[_I_DYN_READY] == 0:
                for i in range(3):
                    for k in range(dyn_z.shape[1]):
                        dyn_z[i, k] = dyn_zi0[i, k] * x[i]
                ints[_I_DYN_READY] = 1
            for i in range(3):
                x[i] = _tdf2(dyn_b[i], dyn_a[i], dyn_z, i, x[i])
        # white-noise sigma at this die temperature: N(T) sqrt(fs)
        if use_mech:
            for i in range(3):
                t = mech_idx[i]
                sigma[i] = math.sqrt(mech_tab[t, 0, cell] + u * mech_tab[t, 1, cell]
                                     + ax[_A_ELEC_SQ, i]) * sqrt_fs
        for i in range(3):
            # bias: turn-on, temperature, g-sensitivity, flicker, random walk
            b = ax[_A_TURN_ON, i]
            if use_bt:
                dtemp = d - ax[_A_CAL, i]
                b += (ax[_A_C1, i] + ax[_A_C2, i] * dtemp) * dtemp
            if use_g:
                ja = j * accel_step
                b += (accel[ja, 0] * gsens[i, 0] + accel[ja, 1] * gsens[i, 1]
                      + accel[ja, 2] * gsens[i, 2])
            if use_fl:
                w = _normal(rng, _R_FLICKER + i) * ax[_A_FLICKER_B, i]
                for k in range(n_fl):
                    xk = fl_phi[k] * fl_x[i, k] + fl_gain[k] * w
                    fl_x[i, k] = xk
                    b += xk
            if use_rrw:
                rrw[i] += _normal(rng, _R_RRW + i) * ax[_A_RRW_STEP, i]
                b += rrw[i]
            bias[j, i] = b
            y = x[i] + b
            if use_white:
                y += _normal(rng, _R_WHITE + i) * sigma[i]
            x[i] = y
        # ASIC low-pass (Butterworth), started in steady state
        if use_lpf:
            if ints[_I_LPF_READY] == 0:
                for i in range(3):
                    for k in range(lpf_z.shape[1]):
                        lpf_z[i, k] = lpf_zi0[k] * x[i]
                ints[_I_LPF_READY] = 1
            for i in range(3):
                x[i] = _tdf2(lpf_b, lpf_a, lpf_z, i, x[i])
        # output stage: range flag, LSB rounding, clip
        for i in range(3):
            y = x[i]
            sat[j, i] = use_sat and abs(y) > ax[_A_RANGE, i]
            lsb = ax[_A_LSB, i]
            if use_q and lsb > 0.0:
                y = np.rint(y / lsb) * lsb
            if use_sat:
                limit = ax[_A_SAT_LIMIT, i]
                y = max(min(y, limit), -limit)
            gyro[j, i] = y
        # timing: latency + jitter (clipped at 0) + clock drift
        dl = latency
        if use_jit:
            dl = max(dl + jitter * _normal(rng, _R_JITTER), 0.0)
        if use_drift:
            dl += (index0 + j) * dt * drift
        delay[j] = dl
    ints[_I_INDEX] = index0 + n
    return 0
