"""
Extended error terms: every cause :mod:`gyro_emulator.analysis.diagnose` can name.

Each term is a frozen, validated dataclass named after the diagnose cause it
models, with that cause's parameters in its units (``effect.params`` of
:mod:`gyro_emulator.analysis.diagnose.generic` and ``.effects``). A term is
off unless it is given (``None`` by default) and on while its ``enabled``
switch is true. With no term on, the model skips this stage entirely.

The terms form an additive bias b_x and a scale-factor multiplier s_x of
axis i at sample n (``T`` the temperature input of the model: the record's
temperature reading, as diagnose uses it; ``t`` the record time of the
sample, ``t = start_time_s + elapsed``; ``th = (t - time_origin_s) / 3600``)::

    b_x = A_h (p - T)/w                                  bias_hysteresis
        + A_w exp(-(t - start_time_s)/tau_w) + d th      bias_time
        + B H(t - t_b)                                   bias_step
        + kappa (T - T_g)/tau_g                          temperature_rate_bias
    s_x = Y(T, P(t))/Y(T, P_ref)                         pressure_drift
          (1 + c1 dT + c2 dT^2                           scale_factor_temperature
             + k1 th + k2 th^2                           scale_factor_time
             + k H(t - t_s))                             scale_factor_step

* p is the play (backlash) operator of half width w,
  p[n] = min(T[n] + w, max(T[n] - w, p[n-1])), p[0] = T[0]
  (Krasnosel'skii & Pokrovskii; :func:`gyro_emulator.analysis.diagnose.generic.play`).
* T_g is T through a first-order lag tau_g, exact for a temperature linear
  between samples: T_g[n] = a T_g[n-1] + (1 - c) T[n] + (c - a) T[n-1],
  a = exp(-dt/tau_g), c = tau_g (1 - a)/dt, started in equilibrium (the
  discretisation of diagnose's ``lagged_temp_on_bins``).
* P(t) = 1 + k_p (t - start_time_s)/3600 (relative to the device's cavity
  pressure, clipped to [0.05, 5]); Y is the first-order sense scale factor
  (Eq 8-11: Knudsen number -> slide-film and comb damping), tabulated on
  0.25 K x 1 % of ln P and interpolated bilinearly (diagnose's
  ``DevicePhysics.pressure_factor``). The sense dynamics and the Brownian
  noise stay at the reference pressure.
* dT = T - T_ref, T_ref = ``ref_temp_c`` or the axis device's calibration
  temperature. The bias polynomial in temperature (diagnose's
  ``bias_temperature``) is the existing ``SensorConfig.bias_temp_coeff_*``
  pair (about the calibration temperature, on the die temperature).

The model adds b_x to the bias and multiplies the gain by s_x inside the
compiled kernel (:mod:`gyro_emulator.sensor.kernel`), so they pass the sense
dynamics, output filter, saturation and quantisation like the other terms.
They are evaluated block by block by a compiled pass of their own
(:func:`_evaluate`) whose state (play, lag, record time) lives in the model,
so :meth:`GyroModel.run` in any blocks equals :meth:`GyroModel.step` sample
by sample, bit for bit. In a sensor YAML (per-axis amplitudes: a number or
three)::

    extended:
      start_time_s: 0.0                 # record time of the first sample
      bias_hysteresis: {hysteresis_width_k: 2.0, bias_hysteresis_rad_s: 2.0e-3}
      pressure_drift: {pressure_rate_per_h: 0.2}
      bias_step: {step_time_s: 5000.0, bias_step_rad_s: [2.0e-3, 0, 0], enabled: false}
"""

from dataclasses import dataclass, fields
import functools
import math

from gyro_emulator.physics import first_order
from gyro_emulator.sensor.simd import vpack, vrow, vsplat, vstore4
from gyro_emulator.units import SECONDS_PER_HOUR
from gyro_emulator.validation import (
    check_range, MODEL_TEMP_RANGE_C, quote, RECORD_TIME_LIMIT_S, shorten)
import numba
import numpy as np

#: Largest |record time| accepted, s: a record's own limit (epoch seconds, 1.7e9, fit).
TIME_LIMIT_S = RECORD_TIME_LIMIT_S
#: Largest |time since the first sample| a model is put at, s (about 30 years).
ELAPSED_LIMIT_S = 1e9
#: Smallest play half width, K: below it T +- w rounds to T at any model
#: temperature (float64 resolves 3e-14 K at 200 C) long before 1/w overflows,
#: and the term would vanish or give NaN; a real hysteresis is >= 0.01 K.
MIN_WIDTH_K = 1e-6
#: Smallest time constant, s: below it exp(-dt/tau) and 1/tau leave the range of
#: float64 at any sample rate the model runs at; a thermal or warm-up time
#: constant is >= 1 ms.
MIN_TIME_CONSTANT_S = 1e-6
#: Hours per second.
PER_HOUR = 1.0 / SECONDS_PER_HOUR


def _axis(owner, name, value, low, high, unit):
    """Return a per-axis value (a number or 3) as a tuple of 3 checked floats."""
    if isinstance(value, (bool, str, np.bool_)) or (
            isinstance(value, (list, tuple)) and any(isinstance(v, (bool, str)) for v in value)):
        raise ValueError(f'{owner}.{name} = {quote(value)} is not a number or a list of 3 '
                         'numbers')
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f'{owner}.{name} = {quote(value)} is not a number or a list of 3 '
                         'numbers') from None
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    if arr.shape != (3,):
        raise ValueError(f'{owner}.{name} = {quote(value)} has shape {arr.shape}: expected a '
                         'number or a list of 3 (x, y, z)')
    check_range(owner, name, arr, low, high, unit, low_open=False)
    return tuple(float(v) for v in arr)


def _scalar(owner, name, value, low, high, unit, low_open):
    if isinstance(value, (bool, str, np.bool_)) or value is None:
        raise ValueError(f'{owner}.{name} = {quote(value)} is not a number')
    return check_range(owner, name, value, low, high, unit, low_open)


@dataclass(frozen=True)
class _Term:
    """Base of a term: fields checked against ``RANGES`` (name -> kind, low, high, unit)."""

    RANGES = {}

    def __post_init__(self):
        """Check every field against its range; per-axis fields become 3-tuples."""
        owner = type(self).__name__
        for name, (kind, low, high, unit) in self.RANGES.items():
            value = getattr(self, name)
            if kind == 'axis':
                value = _axis(owner, name, value, low, high, unit)
            elif kind == 'optional' and value is None:
                continue
            else:
                value = _scalar(owner, name, value, low, high, unit, kind == 'open')
            object.__setattr__(self, name, value)
        if not isinstance(self.enabled, (bool, np.bool_)):
            raise ValueError(f'{owner}.enabled = {quote(self.enabled)} is not allowed: '
                             'choose true or false')
        object.__setattr__(self, 'enabled', bool(self.enabled))


_T = (-TIME_LIMIT_S, TIME_LIMIT_S, 's')


@dataclass(frozen=True)
class BiasHysteresis(_Term):
    """Bias A (p - T)/w, p the play of the temperature (diagnose ``bias_hysteresis``)."""

    hysteresis_width_k: float = 1.0
    bias_hysteresis_rad_s: tuple = (0.0, 0.0, 0.0)
    enabled: bool = True
    RANGES = {'hysteresis_width_k': ('closed', MIN_WIDTH_K, 100.0, 'K'),
              'bias_hysteresis_rad_s': ('axis', -1.0, 1.0, 'rad/s')}


@dataclass(frozen=True)
class ScaleFactorTemperature(_Term):
    """Relative SF change c1 dT + c2 dT^2 (diagnose ``scale_factor_temperature``)."""

    sf_temp_coeff_per_k: tuple = (0.0, 0.0, 0.0)
    sf_temp_coeff2_per_k2: tuple = (0.0, 0.0, 0.0)
    ref_temp_c: float = None
    enabled: bool = True
    RANGES = {'sf_temp_coeff_per_k': ('axis', -0.01, 0.01, '1/K'),
              'sf_temp_coeff2_per_k2': ('axis', -1e-3, 1e-3, '1/K^2'),
              'ref_temp_c': ('optional',) + MODEL_TEMP_RANGE_C + ('C',)}


@dataclass(frozen=True)
class ScaleFactorTime(_Term):
    """Relative SF change k1 th + k2 th^2, th in hours (diagnose ``scale_factor_time``)."""

    sf_drift_per_h: tuple = (0.0, 0.0, 0.0)
    sf_drift2_per_h2: tuple = (0.0, 0.0, 0.0)
    time_origin_s: float = 0.0
    enabled: bool = True
    RANGES = {'sf_drift_per_h': ('axis', -1.0, 1.0, '1/h'),
              'sf_drift2_per_h2': ('axis', -1.0, 1.0, '1/h^2'),
              'time_origin_s': ('closed',) + _T}


@dataclass(frozen=True)
class BiasTime(_Term):
    """Warm-up A exp(-(t - t_start)/tau) plus d th (diagnose ``bias_time``)."""

    warmup_time_constant_s: float = 1.0
    warmup_rad_s: tuple = (0.0, 0.0, 0.0)
    bias_drift_rad_s_per_h: tuple = (0.0, 0.0, 0.0)
    time_origin_s: float = 0.0
    enabled: bool = True
    RANGES = {'warmup_time_constant_s': ('closed', MIN_TIME_CONSTANT_S, 1e7, 's'),
              'warmup_rad_s': ('axis', -1.0, 1.0, 'rad/s'),
              'bias_drift_rad_s_per_h': ('axis', -1.0, 1.0, 'rad/s/h'),
              'time_origin_s': ('closed',) + _T}


@dataclass(frozen=True)
class BiasStep(_Term):
    """Bias change B from the first sample at t >= step_time_s (diagnose ``bias_step``)."""

    step_time_s: float = 0.0
    bias_step_rad_s: tuple = (0.0, 0.0, 0.0)
    enabled: bool = True
    RANGES = {'step_time_s': ('closed',) + _T,
              'bias_step_rad_s': ('axis', -10.0, 10.0, 'rad/s')}


@dataclass(frozen=True)
class ScaleFactorStep(_Term):
    """Relative SF change k from t >= step_time_s (diagnose ``scale_factor_step``)."""

    step_time_s: float = 0.0
    sf_step: tuple = (0.0, 0.0, 0.0)
    enabled: bool = True
    RANGES = {'step_time_s': ('closed',) + _T,
              'sf_step': ('axis', -0.5, 0.5, '')}


@dataclass(frozen=True)
class PressureDrift(_Term):
    """Cavity pressure P = P_ref (1 + k (t - t_start)/3600), Eq 8-11 (``pressure_drift``)."""

    pressure_rate_per_h: float = 0.0
    enabled: bool = True
    RANGES = {'pressure_rate_per_h': ('closed', -3.0, 3.0, '1/h')}


@dataclass(frozen=True)
class TemperatureRateBias(_Term):
    """Bias kappa dT_g/dt, T_g the temperature through a lag (``temperature_rate_bias``)."""

    gradient_time_constant_s: float = 10.0
    bias_per_temp_rate_rad_s_per_k_s: tuple = (0.0, 0.0, 0.0)
    enabled: bool = True
    RANGES = {'gradient_time_constant_s': ('closed', MIN_TIME_CONSTANT_S, 1e5, 's'),
              'bias_per_temp_rate_rad_s_per_k_s': ('axis', -10.0, 10.0, 'rad/s per K/s')}


#: Term class of every cause id, in the order of the model's equations.
TERM_TYPES = {'bias_hysteresis': BiasHysteresis, 'bias_time': BiasTime,
              'bias_step': BiasStep, 'temperature_rate_bias': TemperatureRateBias,
              'pressure_drift': PressureDrift, 'scale_factor_temperature': ScaleFactorTemperature,
              'scale_factor_time': ScaleFactorTime, 'scale_factor_step': ScaleFactorStep}


@dataclass(frozen=True)
class ExtendedTerms:
    """
    The extended terms of a sensor (each None = off) and the record-time origin.

    Attributes
    ----------
    start_time_s : float
        Record time of the model's first sample, s (times of the terms are
        record times: diagnose's ``step_time_s``, ``time_origin_s``).
    bias_hysteresis, bias_time, ... : term or None
        One field per cause id of :data:`TERM_TYPES`.

    """

    start_time_s: float = 0.0
    bias_hysteresis: BiasHysteresis = None
    bias_time: BiasTime = None
    bias_step: BiasStep = None
    temperature_rate_bias: TemperatureRateBias = None
    pressure_drift: PressureDrift = None
    scale_factor_temperature: ScaleFactorTemperature = None
    scale_factor_time: ScaleFactorTime = None
    scale_factor_step: ScaleFactorStep = None

    def __post_init__(self):
        """Check the start time and the type of every term."""
        object.__setattr__(self, 'start_time_s', _scalar(
            'ExtendedTerms', 'start_time_s', self.start_time_s, *_T, False))
        for name, cls in TERM_TYPES.items():
            value = getattr(self, name)
            if value is not None and not isinstance(value, cls):
                raise ValueError(f'ExtendedTerms.{name} = {quote(value)} is not allowed: '
                                 f'expected a {cls.__name__} or None')

    def active(self):
        """Return the cause ids of the terms that are given and enabled."""
        return tuple(n for n in TERM_TYPES
                     if getattr(self, n) is not None and getattr(self, n).enabled)

    def get(self, name):
        """Return term ``name`` if it is active, else None."""
        term = getattr(self, name)
        return term if term is not None and term.enabled else None

    @classmethod
    def from_mapping(cls, mapping, source='extended'):
        """
        Build from parsed YAML: ``{start_time_s: s, <cause id>: {<param>: value, ...}}``.

        Unknown causes and parameters raise ValueError naming them.
        """
        if not isinstance(mapping, dict):
            raise ValueError(f'{source} = {quote(mapping)} must be a mapping of cause: '
                             'parameters')
        kwargs = {}
        for key, value in mapping.items():
            if key == 'start_time_s':
                kwargs[key] = value
                continue
            if key not in TERM_TYPES:
                raise ValueError(f'{source}: unknown term {quote(key)}; allowed: '
                                 f'start_time_s, {", ".join(TERM_TYPES)}')
            term = TERM_TYPES[key]
            if value is None:
                continue
            if not isinstance(value, dict):
                raise ValueError(f'{source}.{key} = {quote(value)} must be a mapping of '
                                 'parameters')
            allowed = [f.name for f in fields(term)]
            unknown = sorted(set(map(str, value)) - set(allowed))
            if unknown:
                raise ValueError(f'{source}.{key}: unknown parameter(s) '
                                 f'{shorten(", ".join(unknown))}; allowed: '
                                 f'{", ".join(allowed)}')
            kwargs[key] = term(**value)
        return cls(**kwargs)


# --- evaluation -----------------------------------------------------------

#: Switches (int64 0/1), scalars and per-axis rows of the compiled evaluation.
(E_HYST, E_TIME, E_BSTEP, E_GRAD, E_PRESS, E_SFT, E_SFTIME, E_SFSTEP) = range(8)
(X_DT, X_START, X_WIDTH, X_TAU_W, X_ORIGIN_B, X_T_BSTEP, X_TAU_G, X_PRATE, X_ORIGIN_S,
 X_T_SFSTEP, X_LN_P0, X_LN_P_STEP, X_T0, X_T_STEP) = range(14)
(R_HYST, R_WARM, R_DRIFT, R_BSTEP, R_GRAD, R_REF, R_C1, R_C2, R_K1, R_K2, R_SFSTEP) = range(11)
#: Mutable state: ready flag, play, lagged T, previous T, samples since the
#: last rate change, elapsed time at that change (s), warm-up factor and
#: whether it is valid (0 after a configuration change).
(Z_READY, Z_PLAY, Z_LAG, Z_PREV, Z_COUNT, Z_BASE, Z_WARM, Z_WARM_READY) = range(8)
STATE_SIZE = 8
#: The warm-up exp(-t/tau) is evaluated exactly every WARMUP_ANCHOR (a power of 2) samples
#: (of the sample count) and by its exact one-sample ratio exp(-dt/tau) in
#: between: at most WARMUP_ANCHOR roundings (< 1e-12 relative).
WARMUP_ANCHOR = 1024
#: Pressure table: ln P from ln 0.05 to ln 5 in steps of 0.01, T every 0.25 K.
LN_P = np.linspace(math.log(0.05), math.log(5.0), 461)
#: The grid's pressures and the inverse widths of its cells (piecewise linear in P).
P_CELLS = np.array([np.exp(LN_P), np.r_[1.0 / np.diff(np.exp(LN_P)), 0.0]])
TABLE_TEMP_C = np.linspace(MODEL_TEMP_RANGE_C[0], MODEL_TEMP_RANGE_C[1],
                           int(round((MODEL_TEMP_RANGE_C[1] - MODEL_TEMP_RANGE_C[0]) / 0.25)) + 1)


@functools.lru_cache(maxsize=8)
def pressure_table(device):
    """Y_sense(T, P)/Y_sense(T, P_ref) on :data:`LN_P` x :data:`TABLE_TEMP_C` (Eq 8-11)."""
    p_ref = device.gas.pressure_pa
    ref = first_order.sense_scale_factor_m_per_rad_s(device, TABLE_TEMP_C)
    rows = [first_order.sense_scale_factor_m_per_rad_s(
        device.with_gas(pressure_pa=p_ref * float(np.exp(v))), TABLE_TEMP_C) for v in LN_P]
    table = np.asarray(rows) / ref[None, :]
    table.flags.writeable = False
    return table


class ExtendedPlan:
    """Coefficients of the active extended terms for one configuration and rate."""

    def __init__(self, ext, devices, cal_temp_c, dt):
        self.active = ext.active()
        flags = np.zeros(8, dtype=np.int64)
        sc = np.zeros(14)
        ax = np.zeros((11, 3))
        sc[X_DT], sc[X_START] = dt, ext.start_time_s
        for flag, name in enumerate(TERM_TYPES):
            flags[flag] = name in self.active
        h, w, s, g = (ext.get('bias_hysteresis'), ext.get('bias_time'), ext.get('bias_step'),
                      ext.get('temperature_rate_bias'))
        if h:
            sc[X_WIDTH], ax[R_HYST] = h.hysteresis_width_k, h.bias_hysteresis_rad_s
        if w:
            sc[X_TAU_W], sc[X_ORIGIN_B] = w.warmup_time_constant_s, w.time_origin_s
            ax[R_WARM], ax[R_DRIFT] = w.warmup_rad_s, w.bias_drift_rad_s_per_h
        if s:
            sc[X_T_BSTEP], ax[R_BSTEP] = s.step_time_s, s.bias_step_rad_s
        if g:
            sc[X_TAU_G] = g.gradient_time_constant_s
            ax[R_GRAD] = g.bias_per_temp_rate_rad_s_per_k_s
        self._scale_factor(ext, devices, cal_temp_c, sc, ax)
        self.flags, self.scalars, self.axis = flags, sc, ax
        self.bias_on = bool(flags[:4].any())
        self.gain_on = bool(flags[4:].any())
        self.buffers = None

    def buffers_for(self, n):
        """
        Return (bias, gain) buffers for blocks of ``n``, (0, 3) for a kind with no term on.

        One spare row: the kernel reads each row as four doubles.
        """
        if self.buffers is None:
            self.buffers = (np.zeros((n + 1 if self.bias_on else 0, 3)),
                            np.zeros((n + 1 if self.gain_on else 0, 3)))
        return self.buffers

    def _scale_factor(self, ext, devices, cal_temp_c, sc, ax):
        st, sd, ss, p = (ext.get('scale_factor_temperature'), ext.get('scale_factor_time'),
                         ext.get('scale_factor_step'), ext.get('pressure_drift'))
        if st:
            ax[R_REF] = cal_temp_c if st.ref_temp_c is None else st.ref_temp_c
            ax[R_C1], ax[R_C2] = st.sf_temp_coeff_per_k, st.sf_temp_coeff2_per_k2
        if sd:
            sc[X_ORIGIN_S] = sd.time_origin_s
            ax[R_K1], ax[R_K2] = sd.sf_drift_per_h, sd.sf_drift2_per_h2
        if ss:
            sc[X_T_SFSTEP], ax[R_SFSTEP] = ss.step_time_s, ss.sf_step
        self.table = np.zeros((3, 2, 2))
        if p:
            sc[X_PRATE] = p.pressure_rate_per_h / SECONDS_PER_HOUR
            distinct = list(dict.fromkeys(devices))
            # one table when every axis has the same device
            self.table = np.ascontiguousarray([pressure_table(d) for d in (
                distinct if len(distinct) == 1 else devices)])
        sc[X_LN_P0], sc[X_LN_P_STEP] = LN_P[0], LN_P[1] - LN_P[0]
        sc[X_T0], sc[X_T_STEP] = TABLE_TEMP_C[0], 1.0 / (TABLE_TEMP_C[1] - TABLE_TEMP_C[0])

    def evaluate(self, temp_c, state, bias, gain):
        """
        Write the bias and gain of the samples at ``temp_c`` and advance ``state``.

        ``bias`` and ``gain`` are (>= n, 3) buffers whose first n rows are
        written (only while a term of their kind is on: see ``bias_on``,
        ``gain_on``); called block by block, the result does not depend on
        the blocks.
        """
        _evaluate(temp_c, self.flags, self.scalars, self.axis, self.table, P_CELLS, state,
                  bias, gain)


def first_non_finite(ext, devices, cal_temp_c, dt, temp_c, state):
    """
    Return the first active term of ``ext`` whose bias or gain over ``temp_c`` is not finite.

    Each term is evaluated alone from a copy of ``state`` (the model's
    extended state before these samples); None when each is finite alone.
    """
    for name in ext.active():
        alone = ExtendedTerms(start_time_s=ext.start_time_s, **{name: getattr(ext, name)})
        plan = ExtendedPlan(alone, devices, cal_temp_c, dt)
        bias, gain = plan.buffers_for(len(temp_c))
        plan.evaluate(np.ascontiguousarray(temp_c, dtype=float), state.copy(), bias, gain)
        if not (np.isfinite(bias[:len(temp_c)]).all() and np.isfinite(gain[:len(temp_c)]).all()):
            return name
    return None


def new_state():
    """Return the state of a model before its first sample."""
    return np.zeros(STATE_SIZE)


def rebase(state, old_dt):
    """Fold the samples since the last rate change into the elapsed time (rate change)."""
    state[Z_BASE] += state[Z_COUNT] * old_dt
    state[Z_COUNT] = 0.0


def set_elapsed(state, elapsed_s):
    """Put the next sample ``elapsed_s`` after the first (a jump of the time line)."""
    state[Z_BASE], state[Z_COUNT] = elapsed_s, 0.0
    state[Z_WARM_READY] = 0.0       # re-anchor the warm-up exponential


@numba.njit(cache=True, error_model='numpy')
def _evaluate(temp, on, sc, ax, table, cells, state, bias, gain):
    """One pass over the samples (equations: module docstring); updates ``state``."""
    dt, n = sc[X_DT], temp.shape[0]
    if state[Z_READY] == 0.0 and n > 0:
        state[Z_PLAY], state[Z_LAG], state[Z_PREV] = temp[0], temp[0], temp[0]
        state[Z_READY] = 1.0
    hyst, warm_on, bstep, grad = (on[E_HYST] != 0, on[E_TIME] != 0, on[E_BSTEP] != 0,
                                  on[E_GRAD] != 0)
    sft, sftime, sfstep, press = (on[E_SFT] != 0, on[E_SFTIME] != 0, on[E_SFSTEP] != 0,
                                  on[E_PRESS] != 0)
    bias_on, gain_on = hyst or warm_on or bstep or grad, sft or sftime or sfstep or press
    a_g = math.exp(-dt / sc[X_TAU_G]) if grad else 0.0
    c_g = sc[X_TAU_G] * (1.0 - a_g) / dt if grad else 0.0
    q_w = math.exp(-dt / sc[X_TAU_W]) if warm_on else 0.0
    play, lag, prev, warm = state[Z_PLAY], state[Z_LAG], state[Z_PREV], state[Z_WARM]
    base, count, start = state[Z_BASE], state[Z_COUNT], sc[X_START]
    width, tau_g, origin_b, t_bstep = sc[X_WIDTH], sc[X_TAU_G], sc[X_ORIGIN_B], sc[X_T_BSTEP]
    inv_width = 1.0 / width if hyst else 0.0
    inv_tau_g = 1.0 / tau_g if grad else 0.0
    h, w, d, s, r = (vrow(ax, R_HYST), vrow(ax, R_WARM), vrow(ax, R_DRIFT), vrow(ax, R_BSTEP),
                     vrow(ax, R_GRAD))
    zero = vsplat(0.0)
    anchored, icount = state[Z_WARM_READY] != 0.0, int(count)
    for j in range(n if bias_on else 0):
        temp_j = temp[j]
        elapsed = base + (count + j) * dt
        t = start + elapsed
        e = zero
        if hyst:
            play = min(temp_j + width, max(temp_j - width, play))
            e = h * vsplat((play - temp_j) * inv_width)
        if warm_on:
            if anchored and (icount + j) & (WARMUP_ANCHOR - 1) != 0:
                warm = warm * q_w
            else:
                warm, anchored = math.exp(-elapsed / sc[X_TAU_W]), True
            e = e + (w * vsplat(warm) + d * vsplat((t - origin_b) * PER_HOUR))
        if bstep and t >= t_bstep:
            e = e + s
        if grad:
            lag = a_g * lag + (1.0 - c_g) * temp_j + (c_g - a_g) * prev
            e = e + r * vsplat((temp_j - lag) * inv_tau_g)
        prev = temp_j
        vstore4(bias, j, e)     # the spare lane goes to the next row, written next
    if gain_on:
        _gains(temp, sft, sftime, sfstep, press, sc, ax, table, cells, base, count, gain)
    state[Z_PLAY], state[Z_LAG], state[Z_PREV], state[Z_WARM] = play, lag, prev, warm
    state[Z_WARM_READY] = 1.0 if anchored else 0.0
    state[Z_COUNT] += n


@numba.njit(cache=True, error_model='numpy')
def _pressure_cell(pressure, cells, sc):
    """Return the cell i of the ln P grid with P_i <= P < P_i+1 (the last for P = 5)."""
    p = min(max(pressure, 0.05), 5.0)
    last = cells.shape[1] - 2
    i = min(max(int((math.log(p) - sc[X_LN_P0]) / sc[X_LN_P_STEP]), 0), last)
    while i > 0 and p < cells[0, i]:
        i -= 1
    while i < last and p >= cells[0, i + 1]:
        i += 1
    return i


@numba.njit(cache=True, error_model='numpy')
def _gains(temp, sft, sftime, sfstep, press, sc, ax, table, cells, base, count, gain):
    """Write the scale-factor multiplier of every sample (equations: module docstring)."""
    ref, c1, c2 = vrow(ax, R_REF), vrow(ax, R_C1), vrow(ax, R_C2)
    k1, k2, ks, one = vrow(ax, R_K1), vrow(ax, R_K2), vrow(ax, R_SFSTEP), vsplat(1.0)
    dt, start, origin, t_step, rate = (sc[X_DT], sc[X_START], sc[X_ORIGIN_S], sc[X_T_SFSTEP],
                                       sc[X_PRATE])
    t0, t_scale, last, top = sc[X_T0], sc[X_T_STEP], cells.shape[1] - 2, table.shape[2] - 2
    ip = _pressure_cell(1.0 + rate * (base + count * dt), cells, sc) if press else 0
    shared = table.shape[0] == 1
    for j in range(temp.shape[0]):
        temp_j = temp[j]
        elapsed = base + (count + j) * dt
        t = start + elapsed
        g = one
        if sft:
            d = vsplat(temp_j) - ref
            g = g + (c1 * d + c2 * d * d)
        if sftime:
            th = vsplat((t - origin) * PER_HOUR)
            g = g + (k1 * th + k2 * th * th)
        if sfstep and t >= t_step:
            g = g + ks
        if press:       # bilinear: linear in P within a cell of the ln P grid, and in T
            p = min(max(1.0 + rate * elapsed, 0.05), 5.0)
            while ip > 0 and p < cells[0, ip]:
                ip -= 1
            while ip < last and p >= cells[0, ip + 1]:
                ip += 1
            f = min((p - cells[0, ip]) * cells[1, ip], 1.0)
            y = (temp_j - t0) * t_scale
            it = min(max(int(y), 0), top)
            u = min(max(y - it, 0.0), 1.0)
            f0 = _bilinear(table, 0, ip, it, f, u)
            if shared:  # one device on every axis: one table
                g = g * vsplat(f0)
            else:
                g = g * vpack(f0, _bilinear(table, 1, ip, it, f, u),
                              _bilinear(table, 2, ip, it, f, u))
        vstore4(gain, j, g)     # the spare lane goes to the next row, written next


@numba.njit(cache=True, error_model='numpy', inline='always')
def _bilinear(table, i, ip, it, f, u):
    lo = table[i, ip, it] * (1.0 - u) + table[i, ip, it + 1] * u
    hi = table[i, ip + 1, it] * (1.0 - u) + table[i, ip + 1, it + 1] * u
    return lo * (1.0 - f) + hi * f
