"""
The gyro driver without ROS: from times and inputs to the samples to publish.

:class:`Driver` owns everything between the inputs a node receives and the
samples it publishes. A ROS node (:mod:`gyro_emulator.ros.node`) declares
the parameters, subscribes, runs the timers and turns each :class:`Output
<gyro_emulator.emulation.driver.records.Output>` into messages; the driver
decides, on integer-nanosecond times:

* which samples are due at a tick, and the catch-up bursts, the FIFO backlog
  and the drops of the overrun policy (:mod:`.sample_clock`); dropped samples
  are run through the model with the input held;
* behind a simulator (``input_source: imu``), one sample per input message,
  the model's rate from the stamps and lost messages run through
  (:mod:`.imu_timeline`);
* the inputs in force at each sample: commands checked and applied at their
  stamps (:mod:`.commands`); a rate command older than ``command_timeout_s``
  is stale and ``stale_rate_policy`` gives zero or the last rate; the
  ambient temperature is clamped to the model's range or overridden;
* the output stamp: the sample instant plus the model's output delay
  (latency, jitter clipped to +-0.45 periods by the model, clock drift),
  never at or before the previous stamp;
* a clock that jumps back, or ahead beyond the longest gap, restarts the
  filters and forgets the command stamps; the fault clock and the extended
  terms' record time (:mod:`.record_clock`) follow the jump, or the record
  time is re-anchored when it cannot (a jump of 1e9 s); each jump is
  counted and said once on ``/diagnostics``;
* the attitude and the specific force each sample senses
  (:mod:`.attitude`): the true rate integrated from
  ``initial_attitude_rpy_rad``, gravity turned into the sensor frame plus
  the applied ``cmd/linear_acceleration`` (behind a simulator, its
  acceleration as it is); the model is the 6-axis
  :class:`~gyro_emulator.sensor.imu.ImuModel` (gyro and accelerometer);
* a sample the model gives with a NaN or an infinity anywhere in what
  would be published (the acceleration and the attitude included) is
  withheld: counted, logged (throttled) and an ERROR on ``/diagnostics``;
* the start-up bias calibration (``startup_bias_calibration``,
  :mod:`.bias_calibration`);
* the injected fault (:mod:`.fault_state`) and its changes;
* the model, stepped at block cost (:mod:`.block_stepper`);
* parameter changes as one transaction: :meth:`Driver.prepare` validates
  every value of a set together, :meth:`Driver.apply` applies all of them
  (or, when preparing failed, nothing changes);
* the counters of ``/diagnostics`` (:mod:`.book`).
"""

import logging
import math
import time

from gyro_emulator.emulation.driver import parameters
from gyro_emulator.emulation.driver.attitude import AttitudeState, initial_attitude
from gyro_emulator.emulation.driver.bias_calibration import (rest_spread_rad_s,
                                                             StartupBiasCalibration)
from gyro_emulator.emulation.driver.block_stepper import BlockStepper
from gyro_emulator.emulation.driver.book import DiagnosticsBook, OK, WARN
from gyro_emulator.emulation.driver.commands import (check_acceleration, check_rate, Commands,
                                                     InputRejected, Throttle)
from gyro_emulator.emulation.driver.fault_state import FaultState
from gyro_emulator.emulation.driver.imu_timeline import (InputTimeline, SpacingRefused,
                                                         StampNotNewer)
from gyro_emulator.emulation.driver.record_clock import RecordClock
from gyro_emulator.emulation.driver.records import (AccelChannel, Applied, FaultReport,
                                                    GyroChannel, Inputs, Output,
                                                    ParameterChange)
from gyro_emulator.emulation.driver.sample_clock import SampleClock
from gyro_emulator.sensor import faults
from gyro_emulator.sensor.imu import ImuModel
from gyro_emulator.units import NS_PER_S
import numpy as np

ZERO3 = (0.0, 0.0, 0.0)


def _covariance(sigma):
    """Return diag(sigma^2) as 9 numbers, row-major (sigma in rad/s or m/s^2)."""
    sigma = np.asarray(sigma, dtype=float)
    cov = np.zeros(9)
    cov[[0, 4, 8]] = sigma * sigma
    return tuple(cov.tolist())


class _NoCommands:
    """A command source that never has any (:class:`Driver`'s default)."""

    @staticmethod
    def take():
        return ()


class Driver:
    """
    The emulated IMU (gyro and accelerometer) between its inputs and its samples.

    Parameters
    ----------
    values : dict
        Every node parameter (:data:`parameters.NODE_PARAMS`), checked.
    base_config : gyro_emulator.sensor.config.SensorConfig
        The ``sensor_config`` the ``sensor.*`` parameters modify.
    seed : int
        Seed of every noise term and of the fault's random draws.
    sensor_values : dict or None
        The ``sensor.*`` parameter values; None: those of ``base_config``.
    follow_timer : bool
        The ticks come from a wall-clock timer (False on a simulator's clock):
        see :class:`.sample_clock.SampleClock`.
    log : object or None
        Has ``info``, ``warning`` and ``error`` methods taking one line
        (a ROS logger, a ``logging.Logger``); None: the ``gyro_emulator.driver``
        logger of ``logging``.
    commands : object or None
        Has ``take()``, returning the commands that arrived as
        ``(stream name, stamps ns, values)`` batches
        (:class:`.commands.CommandInbox`); it is read when a sample needs
        its inputs. None: no commands.
    monotonic : callable
        Steady clock of the log throttle, s.

    Attributes
    ----------
    values : dict
        The node parameter values in force (replaced whole by :meth:`apply`).
    limits : gyro_emulator.emulation.driver.commands.InputLimits
        The input checks in force.
    streams : gyro_emulator.emulation.driver.commands.Commands
        The command streams (rate, temperature, specific force).
    book : gyro_emulator.emulation.driver.book.DiagnosticsBook
        The counters of ``/diagnostics``.
    imu_mode : bool
        One sample per simulator message (``input_source: imu``), no ticks.
    seed : int
        The seed.

    """

    def __init__(self, values, base_config, seed, sensor_values=None, follow_timer=False,
                 log=None, commands=None, monotonic=time.monotonic):
        self.values = dict(values)
        self.seed = int(seed)
        self._log = logging.getLogger('gyro_emulator.driver') if log is None else log
        self._commands = _NoCommands() if commands is None else commands
        self._throttle = Throttle(1.0, monotonic)
        self._base_config = base_config
        if sensor_values is None:
            sensor_values = parameters.sensor_param_values(base_config)
        self._sensor_values = dict(sensor_values)
        self._config = parameters.apply_sensor_params(base_config, self._sensor_values)
        rng = np.random.default_rng(self.seed)
        model = ImuModel(self._effective_config(), values['rate_hz'], rng)
        self._fault = FaultState(self._config.range_rad_s,
                                 faults.fault_generator(rng.bit_generator.seed_seq))
        self._stepper = BlockStepper(model, values['block_samples'])
        self.book = DiagnosticsBook()
        self.limits = self._limits(self.values, self._config)
        self.imu_mode = values['input_source'] == 'imu'
        self.streams = Commands(values['initial_temperature_c'],
                                values['default_linear_acceleration_m_s2'],
                                values['command_queue_size'], self._reject, self._clamped)
        self._last_tick_ns = None
        self._last_stamp_ns = None
        self._stamps_clamped = 0
        self._last_sample = None
        self._record = RecordClock(values['record_start_clock_s'], self._log.error)
        self._calibration = StartupBiasCalibration(
            values['startup_bias_calibration'], self._rest_spread, self._calibrated)
        self._ambient_c = values['initial_temperature_c']
        self._stale = False
        self._sigma_version = None
        self._covariance = None
        self._accel_covariance = None
        self._attitude = AttitudeState(initial_attitude(values['initial_attitude_rpy_rad']),
                                       values['gravity_m_s2'], self._upcoming)
        self._refresh_covariance()
        self._count = 0
        self._set_temperature_decimation(values['rate_hz'])
        self._last_rate = None
        self._timeline = InputTimeline(values['rate_hz']) if self.imu_mode else None
        self._previous_input = None
        self._rate_refused = None
        self._samples = None
        if not self.imu_mode:
            self._samples = SampleClock(model.sample_period_s, values['overrun_policy'],
                                        values['max_burst_samples'],
                                        values['fifo_depth_samples'], follow_timer)

    # --- what the node reads -----------------------------------------------

    @property
    def model(self):
        """Return the ImuModel (gyro and accelerometer); it advances only through the driver."""
        return self._stepper.model

    @property
    def attitude_wxyz(self):
        """Return the true attitude (w, x, y, z) at the last sample, sensor to ENU world."""
        return self._attitude.attitude_wxyz

    @property
    def sample_period_s(self):
        """Return the part's sample period (its clock drift included), s."""
        return self._stepper.model.sample_period_s

    @property
    def backlog(self):
        """Return the due samples still waiting in the FIFO (0 behind a simulator)."""
        return 0 if self._samples is None else self._samples.backlog

    @property
    def backlog_period_s(self):
        """Return the period at which the FIFO backlog is handed out, s."""
        return self._samples.period_ns / NS_PER_S

    def _upcoming(self, sample_ns, count):
        """Return the next ``count`` sample instants after ``sample_ns`` on the grid, ns."""
        samples = self._samples
        return [] if samples is None else samples.upcoming(sample_ns, count)

    # --- the parameter transaction -----------------------------------------

    def _effective_config(self, config=None, noise_enabled=None):
        config = self._config if config is None else config
        noise = self.values['noise_enabled'] if noise_enabled is None else noise_enabled
        return parameters.effective_config(config, noise)

    def _limits(self, values, config):
        return parameters.input_limits(values, config, self._stepper.model.temp_range_c)

    def screen(self, changes):
        """
        Say a parameter set that :meth:`prepare` refuses, on the log and in the next report.

        Called before the middleware's own checks of a set (a value outside
        a parameter's declared range is refused there, before :meth:`prepare`
        sees it): whoever sent the set gets the reason, and the node's log
        and diagnostics (WARN, once) say it too. Changes nothing.
        """
        try:
            self.prepare(changes)
        except ValueError as exc:
            text = f'parameter set refused: {exc}'
            self._log.warning(text)
            self.book.event(WARN, text)

    def prepare(self, changes):
        """
        Validate a set of parameter changes together; return a :class:`ParameterChange`.

        Parameters
        ----------
        changes : iterable of (str, object)
            (name, value) pairs; names that are neither node nor ``sensor.*``
            parameters are ignored.

        Raises
        ------
        ValueError
            Naming the first value that is refused (alone, or with the others:
            a filter above the Nyquist rate, an override outside the range).
            Nothing is changed.

        """
        changes = list(changes)
        values = dict(self.values)
        sensor_values = dict(self._sensor_values)
        for name, value in changes:
            spec = parameters.NODE_SPECS.get(name)
            if spec is not None:
                values[name] = parameters.check_value(spec, value)
            elif name.startswith(parameters.SENSOR_PREFIX):
                sensor_values[name] = value
        config = self._config
        if sensor_values != self._sensor_values:
            config = parameters.apply_sensor_params(self._base_config, sensor_values)
            # Build the model's plan once to catch rate-dependent limits
            # (e.g. an output filter at or above Nyquist).
            ImuModel(self._effective_config(config, values['noise_enabled']),
                     self._stepper.model.sample_rate_hz, np.random.default_rng(0))
        limits = self._limits(values, config)
        if values['temperature_override_enabled']:
            low, high = limits.temp_range_c
            if not low <= values['temperature_override_c'] <= high:
                raise ValueError(
                    f'temperature_override_c = {values["temperature_override_c"]!r} is out '
                    f'of range: allowed [{low:g}, {high:g}] C for this sensor')
        fault = parameters.fault_from(values)
        touched = any(name in parameters.FAULT_PARAMS for name, _ in changes)
        return ParameterChange(values, sensor_values, config, limits,
                               fault if touched else None)

    def apply(self, change, now_ns):
        """
        Apply a :class:`ParameterChange` whole at clock ``now_ns``; return :class:`Applied`.

        A changed error model keeps the model's states (``GyroModel.update_config``)
        and a new sample period applies from the next sample on. A set fault
        starts at ``now_ns`` (behind a simulator: the last input stamp).
        """
        changed_model = (change.config is not self._config
                         or change.values['noise_enabled'] != self.values['noise_enabled'])
        self.values, self._sensor_values = change.values, change.sensor_values
        self._config, self.limits = change.config, change.limits
        samples = self._samples
        if samples is not None:
            samples.policy = change.values['overrun_policy']
            samples.max_burst = change.values['max_burst_samples']
            samples.depth = change.values['fifo_depth_samples']
        if changed_model:
            self._stepper.update_config(self._effective_config())
            self._fault.range_rad_s = np.asarray(change.config.range_rad_s, dtype=float)
            self._refresh_covariance()
            if samples is not None:
                samples.set_period(self._stepper.model.sample_period_s)
        reports = ()
        if change.fault is not None:
            timeline = self._timeline
            if timeline is not None and timeline.last_ns is not None:
                now_ns = timeline.last_ns       # "now" on the samples' time line
            reports = self._set_fault(change.fault, now_ns)
        return Applied(changed_model, reports)

    def start(self, now_ns):
        """Put the parameters' fault in force at ``now_ns``; return the fault reports."""
        return self._set_fault(parameters.fault_from(self.values), now_ns)

    def _set_fault(self, fault, now_ns):
        state = self._fault
        reports = []
        state.end(now_ns)
        if state.changed:
            reports.append(self._fault_report(now_ns))     # the fault it replaces ends here
        state.start(fault, now_ns, self._last_rate)
        if fault.kind != 'none':
            self._log.warning(f'fault set: {fault.describe()}')
        reports.append(self._fault_report(now_ns))
        return tuple(reports)

    def _fault_report(self, stamp_ns):
        state = self._fault
        state.changed = False
        return FaultReport(int(stamp_ns), state.fault, state.state, state.level,
                           state.since_ns)

    # --- inputs --------------------------------------------------------------

    def _reject(self, exc):
        self.book.reject(exc.reason)
        held = self._throttle(exc.reason)
        if held is not None:
            more = f' ({held} similar held back)' if held else ''
            self._log.warning(f'input rejected ({exc.reason}): {exc}{more}')

    def _clamped(self, raw_c, temp_c):
        self.book.clamp('temperature_clamped')
        if self._throttle('temperature_clamped') is not None:
            lo, hi = self.limits.temp_range_c
            self._log.warning(f'temperature {raw_c!r} C outside the model range '
                              f'[{lo:g}, {hi:g}] C: clamped to {temp_c:g} C')

    def _take(self, now_ns):
        """Check and queue every command that arrived; ``now_ns`` is the clock."""
        for name, stamps_ns, values in self._commands.take():
            self.streams.offer(name, stamps_ns, values, now_ns, self.limits)

    def _inputs(self, sample_ns):
        """Return the :class:`Inputs` in force at sample time ``sample_ns``."""
        values = self.values
        streams = self.streams
        rate = streams.rate.advance(sample_ns)
        age = streams.rate.age_s(sample_ns)
        temp = streams.temperature.advance(sample_ns)
        accel = streams.accel.advance(sample_ns)
        timeout = values['command_timeout_s']
        self._stale = bool(timeout > 0.0 and age is not None and age > timeout)
        if self._stale and values['stale_rate_policy'] == 'zero':
            rate = ZERO3
        return Inputs(rate, self._ambient(temp), accel)

    def _ambient(self, temp_c):
        if self.values['temperature_override_enabled']:
            return self.values['temperature_override_c']
        low, high = self.limits.temp_range_c
        return min(max(temp_c, low), high)

    # --- the sample loop ------------------------------------------------------

    def _refresh_covariance(self):
        self._sigma_version = self._stepper.sigma_version
        self._covariance = _covariance(self._stepper.sigma_rad_s)
        self._accel_covariance = _covariance(self._stepper.accel_sigma_m_s2)

    def _set_temperature_decimation(self, sample_rate_hz):
        self._temp_every = max(1, int(round(sample_rate_hz
                                            / self.values['temperature_rate_hz'])))

    def _restart(self, why, shift_ns, next_ns):
        """
        Restart the filters after a discontinuity of the time line; count it and say so.

        ``shift_ns`` moves the fault's clock with the time line (a jump back,
        negative: said in the line); ``next_ns`` is the clock of the next sample.
        """
        self._fault.shift(shift_ns)
        self._stepper.sync()
        self._stepper.model.restart_filters()
        self._attitude.restart()
        line = f'{why}: command stamps forgotten, filters restarted'
        if shift_ns:
            line += f' ({-shift_ns / NS_PER_S:.9g} s back, to {next_ns / NS_PER_S:.9g} s)'
        reanchored = self._record.jumped(self._stepper.model, next_ns)   # extended terms
        if reanchored and self._config.extended.active():
            line += f'; {reanchored}'
        self.streams.reset_clock()
        self._last_stamp_ns = None
        self._log.warning(line)
        self.book.clock_jump(line)

    def tick(self, now_ns):
        """
        Return the :class:`Output` samples due at a timer tick at ``now_ns`` (clock, ns).

        A clock that went back since the previous tick, or ahead beyond the
        longest gap, restarts the filters first. At most ``max_burst_samples``
        come out (``fifo``); the rest wait in the :attr:`backlog` for
        :meth:`drain`.
        """
        due = self._samples.due(now_ns)
        if due.restart == 'jump_back':
            self._restart('clock jumped back', now_ns - self._last_tick_ns, now_ns)
        elif due.restart == 'gap':
            self._restart(f'the clock jumped ahead {(now_ns - self._last_tick_ns) * 1e-9:.3f} s',
                          0, now_ns)
        self._last_tick_ns = now_ns
        return self._run_due(due, now_ns)

    def drain(self):
        """Return the next burst of the backlog (the clock stands at the last tick)."""
        return self._run_due(self._samples.due(self._last_tick_ns), self._last_tick_ns)

    def _run_due(self, due, now_ns):
        """Run the model through the dropped samples; return the due ones."""
        if not due.times_ns:
            return []
        self._take(now_ns)
        first_ns = due.times_ns[0] - int(round(due.skipped * self._samples.period_ns))
        self._record.first(self._stepper.model, first_ns)
        if due.skipped:
            self.book.drop(due.skipped)
            # The part sampled them: run the model through with the input held.
            held = self._inputs(first_ns)
            try:
                self._stepper.skip(due.skipped, held.rate_rad_s, held.ambient_temp_c,
                                   self._attitude.specific_force(held.accel_m_s2))
            except ValueError as exc:
                self.book.model_error(str(exc))
        outputs = []
        for sample_ns in due.times_ns:
            out = self._sample(self._inputs(sample_ns), sample_ns)
            if out is not None:
                outputs.append(out)
        return outputs

    def _sample(self, inputs, sample_ns):
        """Step the model once; return its :class:`Output` (None: refused or withheld)."""
        self._ambient_c = inputs.ambient_temp_c
        attitude = self._attitude.advance(sample_ns, inputs.rate_rad_s)
        # Behind a simulator its acceleration is the specific force; else gravity turns in.
        if self.imu_mode:
            force, course = self._ideal_force(inputs.accel_m_s2), None
        else:
            force, course = self._attitude.specific_force(inputs.accel_m_s2), self._attitude
        try:
            s = self._stepper.step(inputs.rate_rad_s, inputs.ambient_temp_c, force, course)
        except ValueError as exc:
            self.book.model_error(str(exc))
            if self._throttle('model_error') is not None:
                self._log.error(f'model refused the sample: {exc}')
            return None
        # One sum: a NaN or an infinity anywhere in what would go out makes it non-finite.
        if not math.isfinite(sum(s.gyro_rad_s.tolist()) + s.die_temp_c + s.output_delay_s
                             + sum(s.bias_rad_s.tolist()) + sum(s.scale_factor.tolist())
                             + sum(s.accel_m_s2.tolist()) + sum(force) + sum(attitude)):
            self._withhold(s, attitude)
            return None
        self._last_sample = s
        if self._stepper.sigma_version != self._sigma_version:
            self._refresh_covariance()
        delay_ns = int(round(s.output_delay_s * NS_PER_S)) if s.output_delay_s else 0
        stamp_ns = sample_ns + delay_ns
        if self._last_stamp_ns is not None and stamp_ns <= self._last_stamp_ns:
            # A shorter latency set at run time: stamps never go back (the
            # model bounds the jitter by half a period, so only this can).
            stamp_ns = self._last_stamp_ns + 1
            self._stamps_clamped += 1
        self._last_stamp_ns = stamp_ns
        rate, published, pinned = self._fault.apply(sample_ns, s.gyro_rad_s)
        if published:
            self._last_rate = rate
            rate = self._calibration.take(rate, inputs.rate_rad_s,
                                          self._stepper.model.dt_s)
        self._count += 1
        saturated = s.saturated if pinned is None else s.saturated | pinned
        out = Output(
            sample_ns, stamp_ns, published, float(s.die_temp_c),
            published and self._count % self._temp_every == 0,
            GyroChannel(rate, self._covariance, s.true_rate_rad_s, s.bias_rad_s,
                        s.scale_factor, saturated),
            AccelChannel(tuple(s.accel_m_s2.tolist()), self._accel_covariance, force),
            self.values['publish_linear_acceleration'] and inputs.accel_m_s2 is not None,
            attitude,
            self._fault_report(sample_ns) if self._fault.changed else None)
        self.book.sample(saturated)
        return out

    def _withhold(self, s, attitude):
        """Count, log (throttled) and report a sample with a NaN or an infinity."""
        text = (f'the model gave a non-finite sample (rate {tuple(s.gyro_rad_s.tolist())}, '
                f'die temperature {s.die_temp_c!r} C, bias {tuple(s.bias_rad_s.tolist())}, '
                f'scale factor {tuple(s.scale_factor.tolist())}, output delay '
                f'{s.output_delay_s!r} s, acceleration {tuple(s.accel_m_s2.tolist())} m/s^2, '
                f'attitude {attitude}): not published')
        self.book.non_finite(text)
        held = self._throttle('nonfinite')
        if held is not None:
            more = f' ({held} similar held back)' if held else ''
            self._log.error(text + more)

    def _rest_spread(self, duration_s):
        """Return the spread per axis of the model in force at rest over ``duration_s``."""
        return rest_spread_rad_s(self._effective_config(), self._stepper.sigma_rad_s,
                                 duration_s)

    def _calibrated(self, applied, line):
        """Say the end of the start-up bias calibration (log and /diagnostics)."""
        if applied:
            self._log.info(line)
        else:
            self._log.warning(line)
        self.book.event(OK if applied else WARN, line)

    # --- behind a simulator: one sample per imu/ideal message ----------------

    def ideal_imu(self, stamp_ns, rate_rad_s, accel_m_s2):
        """
        Return the :class:`Output` of one simulator message stamped ``stamp_ns`` (ns).

        ``rate_rad_s`` and ``accel_m_s2`` are the ideal IMU's (x, y, z);
        ``accel_m_s2`` None: the message has none (REP 145: its covariance
        element 0 is -1, its values are ignored), the model senses gravity
        at the attitude integrated from the rates and the sample's
        acceleration is marked absent. An empty list: the message was
        refused (a bad value, a repeated or too close stamp) or the model
        refused the sample; both are counted.
        """
        try:
            rate = check_rate(rate_rad_s, self.limits)
            accel = None if accel_m_s2 is None else check_acceleration(accel_m_s2, self.limits)
            step = self._timeline.advance(stamp_ns)
        except InputRejected as exc:
            self._reject(exc)
            return []
        except StampNotNewer as exc:
            self._reject(InputRejected('out_of_order', str(exc)))
            return []
        except SpacingRefused as exc:
            self._reject(InputRejected('stamp_spacing', str(exc)))
            return []
        if step.restart == 'jump_back':
            self._restart('the input clock jumped back', int(round(step.dt_s * NS_PER_S)),
                          stamp_ns)
        elif step.restart:
            self._restart(f'a gap of {step.dt_s:.3f} s in the input stamps', 0, stamp_ns)
        if step.rate_hz is not None:
            self._replan(step.rate_hz)
        if self._rate_refused:
            self.book.model_error(self._rate_refused)
        self._record.first(self._stepper.model, stamp_ns)
        self._take(stamp_ns)
        temp = self._ambient(self.streams.temperature.advance(stamp_ns))
        held, self._previous_input = self._previous_input, (rate, accel)
        if step.samples > 1 and held is not None:
            # Messages lost or a sensor update skipped: the part kept sampling.
            try:
                for _ in range(step.samples - 1):
                    self._stepper.step(held[0], temp, self._ideal_force(held[1]))
            except ValueError as exc:
                self.book.model_error(str(exc))
        out = self._sample(Inputs(rate, temp, accel), stamp_ns)
        return [] if out is None else [out]

    def _ideal_force(self, accel_m_s2):
        """Return a simulator's specific force, or gravity at the attitude where it gave none."""
        return self._attitude.specific_force(ZERO3) if accel_m_s2 is None else accel_m_s2

    def _replan(self, rate_hz):
        """Run the model at the input's rate from now on (every discretisation follows)."""
        try:
            self._stepper.set_sample_rate(rate_hz)
        except ValueError as exc:
            # Reported as a model error with every sample until a rate fits.
            self._rate_refused = f'input rate {rate_hz:.6g} Hz refused: {exc}'
            self._log.error(self._rate_refused)
            return
        self._rate_refused = None
        self._refresh_covariance()
        self._set_temperature_decimation(rate_hz)
        self._log.info(f'input rate {rate_hz:.6g} Hz from the imu/ideal stamps: '
                       'model re-planned')

    # --- diagnostics ----------------------------------------------------------

    def situation(self, now_ns, timer_period_s=None, recording=None):
        """
        Return the driver's current state as diagnostics key/values.

        Parameters
        ----------
        now_ns : int
            The clock, ns (for the age of the rate command).
        timer_period_s : float or None
            The node's sample timer period, s, shown beside the sample period.
        recording : tuple of (str, str or None) or None
            The self-recording's bag path and write error, if one runs.

        """
        s = self._last_sample
        values = self.values
        streams = self.streams
        if values['temperature_override_enabled']:
            source = 'override'
        elif streams.temperature.accepted:
            source = 'command'
        else:
            source = 'initial_temperature_c'
        out = {
            'stale': self._stale, 'stale_policy': values['stale_rate_policy'],
            'rate_age_s': streams.rate.age_s(now_ns),
            'input_source': values['input_source'], 'rate_source': values['rate_source'],
            'ambient_temp_c': self._ambient_c,
            'temperature_source': source,
            'die_temp_c': None if s is None else float(s.die_temp_c),
            'noise_enabled': values['noise_enabled'],
            'commands_accepted.rate': streams.rate.accepted,
            'commands_accepted.temperature': streams.temperature.accepted,
            'commands_accepted.linear_acceleration': streams.accel.accepted,
            'commands_pending': streams.pending(),
            'output_delay_s': None if s is None else float(s.output_delay_s),
            'sample_period_s': 1.0 / self._stepper.model.sample_rate_hz,
            'timer_period_s': timer_period_s,
            'model_calls': self._stepper.model_calls,
            'model_rewinds': self._stepper.rewinds,
            'stamps_clamped': self._stamps_clamped,
            'record_time_reanchors': self._record.reanchors,
            'sensor_config': values['sensor_config'],
            'seed': self.seed,
        }
        clock = self._samples
        if clock is not None:
            # one snapshot: the executor thread moves the counters while this reads
            out.update({'overrun_policy': clock.policy, **clock.counts})
        if self._timeline is not None:
            out.update({'input_rate_hz': self._timeline.rate_hz,
                        'input_restarts': self._timeline.restarts,
                        'input_replans': self._timeline.replans,
                        'input_gap_samples': self._timeline.filled})
        if recording is not None:
            out['recording'], out['recording_error'] = recording
        out.update(self._fault.situation())
        out.update(self._calibration.situation())
        return out

    def report(self, elapsed_s, situation, check_rate=True, waiting_for=None):
        """Close a diagnostics period of ``elapsed_s`` s; return its :class:`.book.Report`."""
        return self.book.report(elapsed_s, self.values['rate_hz'], situation,
                                check_rate=check_rate, waiting_for=waiting_for)

    def summary(self):
        """One line of totals for the shutdown log."""
        book = self.book
        line = (f'{book.samples} samples, {sum(book.rejected.values())} inputs rejected, '
                f'{sum(book.clamped.values())} clamped, {book.model_errors} model errors, '
                f'{book.nonfinite} non-finite withheld, {book.clock_jumps} clock jumps')
        clock = self._samples
        if clock is not None and clock.due_total:
            line += (f', {clock.caught_up} caught up, {clock.dropped} dropped '
                     f'({clock.emitted} of {clock.due_total} due samples out)')
        return line
