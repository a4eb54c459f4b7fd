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
* H_sense is the exact discretisation of the sense-mode envelope at the
  output's sample instants (:func:`gyro_emulator.physics.dynamics.rate_channel_discrete`:
  the rate over each sample period, the envelope read at the end of it,
  DC gain 1, no delay of the samples) at the calibration temperature and
  the configured mode split; H_filter is the ASIC's digital Butterworth
  low-pass (the part's own group delay, configured). Both run as
  transposed direct form II recursions (the arithmetic of
  ``scipy.signal.lfilter``), started in steady state at their first input.
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
* The extended terms (``SensorConfig.extended``, all off by default: the
  causes diagnose names, :mod:`gyro_emulator.sensor.extensions`) add a bias
  b_x to b_i and multiply g_i by s_x; with none on, that stage is skipped.
* Latency, timestamp jitter and clock drift do not change the samples; they
  are reported per sample in ``output_delay_s`` for the publisher to stamp.

One implementation: a single compiled kernel (:mod:`gyro_emulator.sensor.kernel`,
numba) runs every term sample by sample in one pass, on coefficients
precomputed by :class:`gyro_emulator.sensor.plan.Plan`. :meth:`GyroModel.run`
calls it on the whole record and :meth:`GyroModel.step` on one sample, so both
give IDENTICAL samples for the same seed and inputs, however a record is
split into calls.

Random numbers: every noise term and axis has its own stream (turn-on bias,
timestamp jitter, white x3, flicker x3, rate random walk x3), a
``numpy.random.Generator(numpy.random.SFC64(child))`` on a child
``SeedSequence`` spawned from the injected ``numpy.random.Generator``
(:mod:`gyro_emulator.sensor.streams`). The streams are drawn in blocks (each
generator's ``standard_normal`` compiled by numba: numpy's numbers, bit for
bit) and the kernel reads the blocks in order; a stream is used only while
its term is on.
"""

import copy
from dataclasses import dataclass
import math

from gyro_emulator.sensor import extensions, streams
from gyro_emulator.sensor.channel import new_outputs, NONE_ROWS, SenseChannel
from gyro_emulator.sensor.config import SensorConfig
from gyro_emulator.sensor.plan import Plan, TemperatureTable
from gyro_emulator.validation import MODEL_TEMP_RANGE_C
import numpy as np

__all__ = ['GyroModel', 'NonFiniteOutput', 'SensorBatch', 'SensorSample', 'TemperatureTable']


class NonFiniteOutput(ValueError):
    """
    The model would emit a sample that is not finite; :attr:`cause` names the term.

    A valid configuration never does (every field has a physical range); this
    is the guard behind the ranges. Offline commands stop with its one-line
    message; a node sets ``GyroModel.on_non_finite = 'flag'`` and withholds
    such samples instead.
    """

    def __init__(self, message, cause):
        super().__init__(message)
        self.cause = cause


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
    """
    The fields of :class:`SensorSample` for N samples: (N, 3) or (N,) arrays.

    From :meth:`GyroModel.run`, ``true_rate_rad_s`` is the rate passed in: a
    read-only view of it when it was a C-contiguous float64 array (no copy).
    """

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
        return SensorSample(*self.sample_values(index))

    def sample_values(self, index):
        """Return the :class:`SensorSample` fields of sample ``index``, in field order."""
        return (self.gyro_rad_s[index], self.true_rate_rad_s[index],
                float(self.die_temp_c[index]), self.bias_rad_s[index],
                self.scale_factor[index], self.saturated[index],
                float(self.output_delay_s[index]))

    @classmethod
    def concatenate(cls, batches):
        """Join batches in time order (of this class: a subclass joins its own fields)."""
        return cls(**{n: np.concatenate([getattr(b, n) for b in batches])
                      for n in cls.__dataclass_fields__})


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
        Source of every random number: one SFC64 child generator per noise
        term and axis is spawned from its SeedSequence
        (:mod:`gyro_emulator.sensor.streams`).

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
        self._gyro = SenseChannel(rng)
        self._extended = extensions.new_state()
        self._ext = None
        #: ``'raise'``: a non-finite sample raises :class:`NonFiniteOutput`; ``'flag'``:
        #: it is counted (:attr:`non_finite_samples`) and left in the batch.
        self.on_non_finite = 'raise'
        self.non_finite_samples = 0
        self.non_finite_cause = None
        self.update_config(config)

    def copy(self):
        """
        Return an independent copy: same configuration, states and streams.

        The copy and the original then produce identical samples for the same
        inputs. The precomputed plan is immutable, so the copy shares it.
        """
        return copy.deepcopy(self, self.shared_plans())

    def snapshot(self):
        """
        Return the model's state and streams as they are now, for :meth:`restore`.

        What :meth:`copy` would keep, without the copy: restoring it (any
        number of times) puts this model back here, so the samples that
        follow are those that followed the snapshot, bit for bit. It holds
        while the configuration and the rate stay (a change refuses it).
        """
        return (self._gyro.snapshot(), self._extended.copy(), self.non_finite_samples,
                self.non_finite_cause)

    def restore(self, snapshot):
        """Put the model back to a :meth:`snapshot` (ValueError: re-planned since)."""
        channel, extended, self.non_finite_samples, self.non_finite_cause = snapshot
        self._gyro.restore(channel)
        self._extended = extended.copy()

    def shared_plans(self):
        """Return the ``copy.deepcopy`` memo that shares the immutable plan with a copy."""
        return {id(self._gyro.plan): self._gyro.plan}

    def stream_parent(self):
        """
        Return the generator of the gyro's first stream (its turn-on bias).

        An IMU spawns its accelerometer's streams from this generator's
        SeedSequence (:mod:`gyro_emulator.sensor.imu`): the gyro's own
        streams and the injected generator's spawn counter stay as they are.
        """
        return self._gyro.normals.generators[streams.TURN_ON]

    # --- configuration ---------------------------------------------------

    @property
    def config(self):
        """Return the active :class:`SensorConfig`."""
        return self._gyro.plan.config

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
        plan = Plan(config, self.sample_rate_hz, self._gyro.turn_on_z)
        self._gyro.apply(plan)
        self._ext = None
        self._extended[extensions.Z_WARM_READY] = 0.0     # re-anchor the warm-up exponential
        if config.extended.active():
            self._ext = extensions.ExtendedPlan(config.extended, config.device,
                                                plan.cal_temp_c, self.dt_s)

    def set_sample_rate(self, sample_rate_hz):
        """
        Run at a new output data rate from the next sample on, keeping the model's states.

        The plan is rebuilt at the new rate (every exact discretisation
        follows the new dt), as :meth:`update_config` does for a new
        configuration: die temperature and random walk carry over, a filter
        whose coefficients change restarts from steady state at its next
        input, and the flicker states are redrawn for the new dt.
        """
        rate = float(sample_rate_hz) if np.isscalar(sample_rate_hz) else float('nan')
        if not (math.isfinite(rate) and 0.0 < rate <= 1e6):
            raise ValueError(f'GyroModel.sample_rate_hz = {sample_rate_hz!r} is out of '
                             'range: allowed (0, 1e6] Hz')
        old = self.sample_rate_hz, self.dt_s
        self.sample_rate_hz, self.dt_s = rate, 1.0 / rate
        try:
            self.update_config(self.config)
        except ValueError:
            self.sample_rate_hz, self.dt_s = old
            raise
        extensions.rebase(self._extended, old[1])

    def restart_filters(self):
        """
        Restart the sense-mode and output filters from steady state at the next input.

        For a discontinuity of the input's time line (a simulation reset): the
        filters forget their past instead of ringing across the jump. Noise
        states, random walk and die temperature carry on.
        """
        self._gyro.restart_filters()

    def set_elapsed_s(self, elapsed_s):
        """
        Put the next sample ``elapsed_s`` after the first one, for the extended terms.

        Their record time is ``extended.start_time_s`` + the time since the
        first sample (:mod:`gyro_emulator.sensor.extensions`), counted in
        samples; after a jump of the input's time line (the node's clock
        jumped) this puts it back on that time line. The play, lag and
        other states carry on; the warm-up is re-anchored.
        """
        number = isinstance(elapsed_s, (int, float, np.integer, np.floating))
        value = float(elapsed_s) if number and not isinstance(elapsed_s, bool) else math.nan
        limit = extensions.ELAPSED_LIMIT_S
        if not abs(value) <= limit:
            raise ValueError(f'GyroModel.elapsed_s = {elapsed_s!r} is out of range: allowed '
                             f'[-{limit:g}, {limit:g}] s')
        extensions.set_elapsed(self._extended, value)

    @property
    def white_noise_sigma_rad_s(self):
        """
        Per-sample sigma of the white rate noise at the output, rad/s, (3,).

        N(T_die) sqrt(f_s) times the output filter's RMS noise gain, at the
        current die temperature (the calibration temperature before the first
        sample). Use diag(sigma^2) as sensor_msgs/Imu angular_velocity_covariance.
        """
        return self._gyro.white_sigma(self.config.initial_die_temp_c)

    def white_noise_sigma_at(self, die_temp_c):
        """Return :attr:`white_noise_sigma_rad_s` with the die at ``die_temp_c``, deg C."""
        return self._gyro.white_sigma(self.config.initial_die_temp_c, die_temp_c)

    def die_temp_after_c(self, die_temp_c, ambient_temp_c, count):
        """
        Return the die temperature ``count`` samples after one at ``die_temp_c``, deg C.

        The thermal lag of :meth:`run` with the ambient held at
        ``ambient_temp_c``, deg C; the model does not move. None: it would
        leave the model range.
        """
        return self._gyro.die_temp_after_c(die_temp_c, ambient_temp_c, count)

    @property
    def sample_period_s(self):
        """
        Return the part's true sample period, s: 1 / (f_s (1 + clock_drift_ppm 1e-6)).

        A part's clock error changes its output data rate, not the stamps of
        its samples: a driver stamps each sample when it arrives, so the
        stamps stay tied to the host clock within the latency and jitter. A
        positive drift is a fast clock (more samples per second). Every
        sample is the same computation as at the nominal rate (the part's
        filters run on its own clock); what changes is when it happens.
        """
        c = self.config
        drift = c.clock_drift_ppm * 1e-6 if c.terms.clock_drift else 0.0
        return self.dt_s / (1.0 + drift)

    @property
    def die_temp_c(self):
        """Die temperature after the last sample (None before the first)."""
        return self._gyro.die_temp_c

    @property
    def sample_index(self):
        """Return the number of samples produced so far."""
        return self._gyro.sample_index

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
        """
        Run the kernel over validated inputs; return the SensorBatch fields in order.

        The true rate is the kernel's input itself (a read-only view of ``rate``
        when that is already a C-contiguous float64 array): no copy.
        """
        n = rate.shape[0]
        rate, temp = kernel_input(rate), kernel_input(temp)
        out = new_outputs(n)
        fields = (out.gyro, rate, out.die, out.bias, out.gain, out.sat, out.delay)
        if n == 0:
            return fields
        accel = NONE_ROWS if accel is None else kernel_input(accel)
        ext = self._ext
        extended = None
        if ext is not None:     # evaluated on a copy of the state, kept on success
            extended = (ext, self._extended.copy())
        bad = self._gyro.advance(rate, temp, accel, out, extended)
        if bad:
            raise_die_out_of_range(out.die[bad - 1])
        before = self._extended
        if ext is None:     # the record time runs on while the extended terms are off
            self._extended[extensions.Z_COUNT] += n
        else:
            self._extended = extended[1]
        if not math.isfinite(np.add.reduce(out.gyro, axis=None)):
            self._non_finite(out, temp, before if ext is not None else None)
        return fields

    def _non_finite(self, out, temp, before):
        """
        Account for samples of which some are not finite (NaN or inf).

        With :attr:`on_non_finite` ``'raise'`` (the default) raise
        :class:`NonFiniteOutput` naming the first such sample and the term that
        gave it; with ``'flag'`` count them in :attr:`non_finite_samples`, keep
        the cause in :attr:`non_finite_cause` and leave them in the batch, for
        a caller that publishes only finite samples. ``before`` is the
        extended terms' state before these samples (None when they are off).
        """
        rows = ~np.isfinite(out.gyro).all(axis=1)
        first = int(np.flatnonzero(rows)[0])
        cause = self._cause(out, first, temp, before)
        self.non_finite_samples += int(rows.sum())
        self.non_finite_cause = cause
        if self.on_non_finite != 'flag':
            index = self.sample_index - len(rows) + first
            raise NonFiniteOutput(f'GyroModel: sample {index} would be '
                                  f'{out.gyro[first].tolist()} rad/s, not finite: {cause}',
                                  cause)

    def _cause(self, out, first, temp, before):
        """Name the term that made sample ``first`` non-finite (see :meth:`_non_finite`)."""
        config = self.config
        if before is not None:
            term = extensions.first_non_finite(config.extended, config.device,
                                               self._gyro.plan.cal_temp_c, self.dt_s, temp,
                                               before)
            if term is not None:
                return (f'the extended term {term} gives a non-finite bias or gain '
                        f'({getattr(config.extended, term)})')
        if not np.isfinite(out.bias[first]).all():
            return 'the bias terms give a non-finite bias (the configuration is degenerate)'
        if not np.isfinite(out.gain[first]).all():
            return ('the scale factor is not finite (the device physics or '
                    'scale_factor_error is degenerate)')
        return 'the sense dynamics, output filter or output stage diverge'

    def _check_temp(self, temp):
        lo, hi = MODEL_TEMP_RANGE_C
        if temp.min() < lo or temp.max() > hi:
            bad = float(temp[(temp < lo) | (temp > hi)][0])
            raise ValueError(f'GyroModel: ambient_temp_c = {bad!r} is out of range: '
                             f'allowed [{lo}, {hi}] C')


def raise_die_out_of_range(die_c):
    """Raise the one-line error of a die temperature outside the model range."""
    lo, hi = MODEL_TEMP_RANGE_C
    raise ValueError(f'GyroModel: die temperature {float(die_c):g} C (ambient + '
                     f'self_heating_c) is out of range: allowed [{lo}, {hi}] C')


def kernel_input(arr):
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
    """
    Raise ValueError naming the first NaN or inf in ``arr``; return ``arr``.

    A finite sum proves every element finite (a NaN or inf makes the sum NaN
    or inf) at a quarter of the cost of ``isfinite``; only a sum that is not
    finite (a bad element, or an overflow) needs the element-wise test.
    """
    with np.errstate(over='ignore', invalid='ignore'):
        total = np.add.reduce(arr, axis=None)
    if not np.isfinite(total) and not np.all(np.isfinite(arr)):
        bad = np.flatnonzero(~np.isfinite(arr.ravel()))[0]
        raise ValueError(f'GyroModel: {name} = {float(arr.ravel()[bad])!r} (element {bad}) is '
                         'not finite: allowed finite numbers')
    return arr
