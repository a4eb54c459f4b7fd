"""
The IMU as a sensor: the gyro and its accelerometer, on one compiled kernel.

:class:`ImuModel` runs a :class:`~gyro_emulator.sensor.model.GyroModel` and
the part's accelerometer (:attr:`SensorConfig.accelerometer
<gyro_emulator.sensor.config.SensorConfig.accelerometer>`, equations in
:mod:`gyro_emulator.sensor.accel`) side by side. The accelerometer is a
sense channel of its own (:class:`~gyro_emulator.sensor.channel.SenseChannel`)
on the same compiled kernel and plan as the gyro
(:func:`gyro_emulator.sensor.plan.accel_channel`): its input is the
specific force f, its temperature the gyro's die temperature of the same
sample (after the thermal lag), and the gyro's g-sensitivity sees the same f.

Random numbers: the accelerometer has its own streams (turn-on bias, white,
flicker and random walk per axis), spawned from the SeedSequence of the
gyro's first stream (:mod:`gyro_emulator.sensor.streams`). Neither the
gyro's streams nor the injected generator's spawn counter change, so the
gyro's samples are bit for bit those of a ``GyroModel`` on the same seed,
and anything spawned after the model from the same generator (a fault
schedule's noise bursts) draws what it drew before.

:meth:`ImuModel.run` (a record) and :meth:`ImuModel.step` (one sample)
call the same kernels, so they give identical samples however a record is
split into calls.
"""

import copy
from dataclasses import dataclass
import math

from gyro_emulator.physics.kinematics import MAX_GRAVITY_M_S2
from gyro_emulator.sensor import kernel
from gyro_emulator.sensor.channel import new_outputs, NONE_ROWS, SenseChannel
from gyro_emulator.sensor.model import (GyroModel, kernel_input, NonFiniteOutput, SensorBatch,
                                        SensorSample)
from gyro_emulator.sensor.plan import accel_channel, Plan
from gyro_emulator.validation import MODEL_TEMP_RANGE_C
import numpy as np

__all__ = ['ImuBatch', 'ImuModel', 'ImuSample', 'MAX_APPLIED_ACCEL_M_S2',
           'MAX_SPECIFIC_FORCE_M_S2']

#: Largest specific force the model takes, m/s^2 (about 100,000 g: beyond any
#: shock a part survives; it keeps every output finite).
MAX_SPECIFIC_FORCE_M_S2 = 1e6
#: Largest applied linear acceleration per axis (gravity excluded) that every
#: input takes, m/s^2: with gravity at most MAX_GRAVITY_M_S2 on any axis, the
#: specific force f = a_body + g R(q)^T e_z stays within MAX_SPECIFIC_FORCE_M_S2
#: at every attitude, so an accepted acceleration never stops the model.
MAX_APPLIED_ACCEL_M_S2 = MAX_SPECIFIC_FORCE_M_S2 - MAX_GRAVITY_M_S2


@dataclass(frozen=True)
class ImuSample(SensorSample):
    """
    One 6-axis output sample: the :class:`SensorSample` fields and the accelerometer's.

    Attributes
    ----------
    accel_m_s2 : numpy.ndarray
        Accelerometer output (x, y, z), m/s^2.
    true_specific_force_m_s2 : numpy.ndarray
        True specific force, m/s^2.
    accel_bias_m_s2 : numpy.ndarray
        Total accelerometer bias of this sample (no white noise), m/s^2.
    accel_scale_factor : numpy.ndarray
        Total accelerometer gain: temperature ratio times (1 + scale-factor error).
    accel_saturated : numpy.ndarray
        True where the accelerometer output hit its range limit.

    """

    accel_m_s2: np.ndarray = None
    true_specific_force_m_s2: np.ndarray = None
    accel_bias_m_s2: np.ndarray = None
    accel_scale_factor: np.ndarray = None
    accel_saturated: np.ndarray = None


#: The accelerometer's fields of ImuSample and ImuBatch, in order.
ACCEL_FIELDS = ('accel_m_s2', 'true_specific_force_m_s2', 'accel_bias_m_s2',
                'accel_scale_factor', 'accel_saturated')


@dataclass(frozen=True)
class ImuBatch(SensorBatch):
    """
    The fields of :class:`ImuSample` for N samples: (N, 3) or (N,) arrays.

    ``true_specific_force_m_s2`` is the specific force passed in (a read-only
    view of it when it was a C-contiguous float64 (N, 3) array).
    """

    accel_m_s2: np.ndarray = None
    true_specific_force_m_s2: np.ndarray = None
    accel_bias_m_s2: np.ndarray = None
    accel_scale_factor: np.ndarray = None
    accel_saturated: np.ndarray = None

    def sample(self, index):
        """Return sample ``index`` as an :class:`ImuSample` (built once: the node's hot path)."""
        return ImuSample(*self.sample_values(index), self.accel_m_s2[index],
                         self.true_specific_force_m_s2[index], self.accel_bias_m_s2[index],
                         self.accel_scale_factor[index], self.accel_saturated[index])


class ImuModel:
    """
    Stateful 6-axis IMU (gyro + accelerometer): batch :meth:`run` and streaming :meth:`step`.

    Parameters
    ----------
    config : SensorConfig
        The error model of both (``config.accelerometer`` for the accelerometer).
    sample_rate_hz : float
        Output data rate, Hz.
    rng : numpy.random.Generator
        Source of every random number (module docstring).

    """

    def __init__(self, config, sample_rate_hz, rng):
        self._gyro = GyroModel(config, sample_rate_hz, rng)
        self._accel = SenseChannel(self._gyro.stream_parent())
        self._accel.apply(self._accel_plan(config, self._gyro.sample_rate_hz))

    def _accel_plan(self, config, sample_rate_hz):
        """Return the accelerometer's plan of ``config`` at ``sample_rate_hz``."""
        return Plan(config, sample_rate_hz, self._accel.turn_on_z, accel_channel(config))

    def copy(self):
        """Return an independent copy: same configuration, states and streams (plans shared)."""
        memo = self._gyro.shared_plans()
        memo[id(self._accel.plan)] = self._accel.plan
        return copy.deepcopy(self, memo)

    def snapshot(self):
        """Return both sensors' states and streams for :meth:`restore` (as the gyro's)."""
        return self._gyro.snapshot(), self._accel.snapshot()

    def restore(self, snapshot):
        """Put both sensors back to a :meth:`snapshot` (ValueError: re-planned since)."""
        gyro, accel = snapshot
        self._gyro.restore(gyro)        # checks its plan first: a refusal changes nothing
        self._accel.restore(accel)

    # --- what the gyro model has ------------------------------------------

    @property
    def gyro(self):
        """Return the gyro's :class:`GyroModel` (its state is this model's)."""
        return self._gyro

    @property
    def config(self):
        """Return the active :class:`SensorConfig`."""
        return self._gyro.config

    @property
    def sample_rate_hz(self):
        """Return the output data rate, Hz."""
        return self._gyro.sample_rate_hz

    @property
    def dt_s(self):
        """Return the nominal sample period 1 / sample_rate_hz, s."""
        return self._gyro.dt_s

    @property
    def sample_period_s(self):
        """Return the part's true sample period, s (:attr:`GyroModel.sample_period_s`)."""
        return self._gyro.sample_period_s

    @property
    def temp_range_c(self):
        """Ambient/die temperatures the model accepts, deg C."""
        return self._gyro.temp_range_c

    @property
    def die_temp_c(self):
        """Die temperature after the last sample (None before the first)."""
        return self._gyro.die_temp_c

    @property
    def sample_index(self):
        """Return the number of samples produced so far."""
        return self._gyro.sample_index

    @property
    def white_noise_sigma_rad_s(self):
        """Per-sample sigma of the gyro's white noise, rad/s (GyroModel's)."""
        return self._gyro.white_noise_sigma_rad_s

    @property
    def accel_white_noise_sigma_m_s2(self):
        """
        Per-sample sigma of the accelerometer's white noise at the output, m/s^2, (3,).

        sqrt((N(T_die) sqrt(f_s) g)^2 + LSB^2 / 12): the white density N
        (physics and electronics in quadrature) at the current die
        temperature (before the first sample: ``initial_die_temp_c``, else
        the calibration temperature), g the output filter's RMS noise gain,
        and the quantisation noise of the LSB (0 without quantisation). Use
        diag(sigma^2) as sensor_msgs/Imu ``linear_acceleration_covariance``.
        """
        return self.accel_white_noise_sigma_at(None)

    def accel_white_noise_sigma_at(self, die_temp_c):
        """
        Return :attr:`accel_white_noise_sigma_m_s2` with the die at ``die_temp_c``, deg C.

        None: the current die temperature. The accelerometer's die is the
        gyro's (no lag of its own).
        """
        white = self._accel.white_sigma(self.config.initial_die_temp_c, die_temp_c)
        lsb = self._accel.plan.axis[kernel.A_LSB]
        return np.sqrt(white ** 2 + lsb ** 2 / 12.0)

    def white_noise_sigma_at(self, die_temp_c):
        """Return the gyro's :attr:`white_noise_sigma_rad_s` with the die at ``die_temp_c``."""
        return self._gyro.white_noise_sigma_at(die_temp_c)

    def die_temp_after_c(self, die_temp_c, ambient_temp_c, count):
        """Return the die temperature ``count`` samples on (:meth:`GyroModel.die_temp_after_c`)."""
        return self._gyro.die_temp_after_c(die_temp_c, ambient_temp_c, count)

    def update_config(self, config):
        """
        Apply a new configuration to both sensors at run time, keeping their states.

        As :meth:`GyroModel.update_config`; a configuration either sensor
        refuses changes neither.
        """
        plan = self._accel_plan(config, self.sample_rate_hz)
        self._gyro.update_config(config)
        self._accel.apply(plan)

    def set_sample_rate(self, sample_rate_hz):
        """Run both sensors at a new output data rate (:meth:`GyroModel.set_sample_rate`)."""
        rate = float(sample_rate_hz) if np.isscalar(sample_rate_hz) else float('nan')
        if not (math.isfinite(rate) and 0.0 < rate <= 1e6):
            raise ValueError(f'ImuModel.sample_rate_hz = {sample_rate_hz!r} is out of '
                             'range: allowed (0, 1e6] Hz')
        plan = self._accel_plan(self.config, rate)
        self._gyro.set_sample_rate(rate)
        self._accel.apply(plan)

    def restart_filters(self):
        """Restart both sensors' filters from steady state at the next input."""
        self._gyro.restart_filters()
        self._accel.restart_filters()

    def set_elapsed_s(self, elapsed_s):
        """Put the next sample ``elapsed_s`` after the first, for the gyro's extended terms."""
        self._gyro.set_elapsed_s(elapsed_s)

    # --- the two APIs ----------------------------------------------------

    def step(self, rate_rad_s, ambient_temp_c, specific_force_m_s2=None):
        """
        Produce one sample (the kernels of :meth:`run` on a record of one).

        Parameters
        ----------
        rate_rad_s : array_like
            True body rate (x, y, z), rad/s.
        ambient_temp_c : float
            Ambient temperature, deg C.
        specific_force_m_s2 : array_like, optional
            True specific force (x, y, z), m/s^2: the accelerometer's input
            and the gyro's g-sensitivity's; None = 0 (free fall).

        Returns
        -------
        ImuSample

        """
        rows = _plain_rows(rate_rad_s, ambient_temp_c, specific_force_m_s2)
        if rows is not None:        # the driver's case, checked at once
            out = self._gyro._advance(*rows)
            accel = self._advance_accel(rows[2], out[2])
            return ImuSample(out[0][0], out[1][0], float(out[2][0]), out[3][0], out[4][0],
                             out[5][0], float(out[6][0]), *(v[0] for v in accel))
        force = _specific_force(specific_force_m_s2, 1, 'step')
        gyro = self._gyro.step(rate_rad_s, ambient_temp_c,
                               None if specific_force_m_s2 is None else force[0])
        fields = self._advance_accel(force, np.array([gyro.die_temp_c]))
        return ImuSample(**gyro.__dict__, **{n: v[0] for n, v in zip(ACCEL_FIELDS, fields)})

    def run(self, rate_rad_s, ambient_temp_c, specific_force_m_s2=None):
        """
        Produce N samples at once (identical to N :meth:`step` calls).

        Parameters
        ----------
        rate_rad_s : array_like
            True body rates, rad/s, shape (N, 3).
        ambient_temp_c : array_like or float
            Ambient temperatures, deg C, shape (N,) (a scalar is held).
        specific_force_m_s2 : array_like, optional
            True specific force, m/s^2, shape (N, 3) or (3,) (held); None = 0.

        Returns
        -------
        ImuBatch

        """
        rate = np.asarray(rate_rad_s, dtype=float)
        if rate.ndim != 2 or rate.shape[1] != 3:
            raise ValueError(f'ImuModel.run: rate_rad_s has shape {rate.shape}: expected (N, 3)')
        force = _specific_force(specific_force_m_s2, len(rate), 'run')
        held = force[0] if len(force) != len(rate) else force      # (3,): held
        gyro = self._gyro.run(rate, ambient_temp_c, None if specific_force_m_s2 is None else held)
        if len(force) != len(gyro):
            force = np.broadcast_to(force, (len(gyro), 3))
        fields = self._advance_accel(force, gyro.die_temp_c)
        return ImuBatch(**gyro.__dict__, **dict(zip(ACCEL_FIELDS, fields)))

    def _advance_accel(self, force, die_c):
        """Run the accelerometer's kernel over ``force`` at the die temperatures; its fields."""
        n = len(die_c)
        force, die_c = kernel_input(force), kernel_input(die_c)
        out = new_outputs(n)
        if n:
            self._accel.advance(force, die_c, NONE_ROWS, out)
            if not math.isfinite(np.add.reduce(out.gyro, axis=None)):
                self._non_finite(out.gyro)
        return out.gyro, force, out.bias, out.gain, out.sat

    def _non_finite(self, values):
        """Stop on, or count, accelerometer samples that are not finite (as the gyro's)."""
        gyro = self._gyro
        rows = ~np.isfinite(values).all(axis=1)
        cause = ('the accelerometer gives a non-finite specific force (its configuration is '
                 'degenerate)')
        gyro.non_finite_samples += int(rows.sum())
        gyro.non_finite_cause = cause
        if gyro.on_non_finite != 'flag':
            raise NonFiniteOutput(f'ImuModel: accelerometer sample '
                                  f'{gyro.sample_index - len(rows) + int(np.argmax(rows))} '
                                  f'would be {values[int(np.argmax(rows))].tolist()} m/s^2, not '
                                  f'finite: {cause}', cause)


def _plain_rows(rate, temp, force):
    """
    Return read-only (1, 3), (1,), (1, 3) arrays of one sample's inputs if plainly valid.

    That is three finite floats of rate, a float ambient in the model range
    and three floats of specific force within range, as :meth:`ImuModel.step`
    would accept them; None otherwise (then ``step`` checks each and names
    what is wrong).
    """
    if not (isinstance(temp, float) and isinstance(rate, (tuple, list))
            and isinstance(force, (tuple, list)) and len(rate) == 3 and len(force) == 3
            and all(isinstance(v, float) for v in rate)
            and all(isinstance(v, float) for v in force)):
        return None
    lo, hi = MODEL_TEMP_RANGE_C
    top = MAX_SPECIFIC_FORCE_M_S2
    if not (math.isfinite(sum(rate)) and lo <= temp <= hi
            and all(-top <= v <= top for v in force)):
        return None
    rows = np.array((rate,)), np.array((temp,)), np.array((force,))
    for row in rows:
        row.flags.writeable = False
    return rows


def _specific_force(value, n, call):
    """Return the specific force as checked (n, 3) or (1, 3) float rows (None: zeros)."""
    if value is None:
        return np.zeros((n, 3))
    try:
        force = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f'ImuModel.{call}: specific_force_m_s2 = {value!r} is not numbers'
                         ) from None
    if force.shape == (3,):
        force = force.reshape(1, 3)
    if force.ndim != 2 or force.shape[1] != 3 or (call == 'run' and len(force) not in (1, n)):
        raise ValueError(f'ImuModel.{call}: specific_force_m_s2 has shape {np.shape(value)}: '
                         f'expected ({n}, 3) or (3,)')
    bad = ~(np.abs(force) <= MAX_SPECIFIC_FORCE_M_S2)
    if np.any(bad):
        where = np.flatnonzero(bad.ravel())[0]
        raise ValueError(f'ImuModel: specific_force_m_s2 = {float(force.ravel()[where])!r} '
                         f'(element {where}) is out of range: allowed finite numbers in '
                         f'[-{MAX_SPECIFIC_FORCE_M_S2:g}, {MAX_SPECIFIC_FORCE_M_S2:g}] m/s^2')
    return force
