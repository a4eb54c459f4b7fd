"""
``ros2 run gyro_emulator node``: the sensor model as a ROS 2 gyro driver.

With ``input_source: command`` (the default) a timer on the node clock (sim
time under ``use_sim_time``) wakes the node once per sample period,
1 / ``rate_hz`` (the part's period, with its clock drift), and the node
publishes every sample whose sample time has passed
(:mod:`gyro_emulator.emulation.sample_clock`): one per tick when the timer
keeps up, a burst stamped with each sample's own time when it was late (CPU
load, a coarse ``/clock``), or only the newest with ``overrun_policy: drop``.
Each sample takes the commands in force at its sample time. With
``input_source: imu`` the node follows a simulator instead: one sample per
``imu/ideal`` message (sensor_msgs/Imu), the time step from the stamps
(:mod:`gyro_emulator.emulation.imu_timeline`). Either way it publishes:

* ``imu/data_raw`` (sensor_msgs/Imu, REP 145/103): the gyro output in rad/s,
  ``angular_velocity_covariance`` = diag(sigma^2) of the model's white noise
  at this rate, orientation absent (``orientation_covariance[0] = -1``),
  linear acceleration absent (``[0] = -1``) unless passed through (always
  passed through from ``imu/ideal``). Stamp = sample instant + the model's
  output delay (latency and jitter).
* ``imu/temperature`` (sensor_msgs/Temperature): die temperature, deg C.
* ``~/truth/rate``, ``~/truth/bias``, ``~/truth/scale_factor``
  (geometry_msgs/Vector3Stamped, stamped at the sample instant): true rate
  (rad/s), total bias (rad/s) and total gain (ratio) of the same sample;
  ``~/truth/fault`` (diagnostic_msgs/DiagnosticArray, latched) on each change
  of the injected fault (:mod:`gyro_emulator.emulation.fault_state`).
* ``/diagnostics`` (diagnostic_msgs/DiagnosticArray), see
  :mod:`gyro_emulator.ros.diagnostics`.

It subscribes to ``cmd/angular_velocity`` (geometry_msgs/Vector3Stamped,
rad/s, sensor frame) or, with ``rate_source = odometry``, ``cmd/odom``
(nav_msgs/Odometry, twist.twist.angular), to ``cmd/temperature``
(sensor_msgs/Temperature, ambient deg C) and ``cmd/linear_acceleration``
(geometry_msgs/Vector3Stamped, m/s^2), through :mod:`.intake`; input rules:
:mod:`gyro_emulator.emulation.commands`. ``--help`` prints the parameters and
topics and exits.
"""

import functools
import sys
import threading
import time

from gyro_emulator.emulation.block_stepper import BlockStepper
from gyro_emulator.emulation.commands import (check_acceleration, check_rate, InputLimits,
                                              InputRejected, Throttle)
from gyro_emulator.emulation.fault_state import FaultState
from gyro_emulator.emulation.imu_timeline import InputTimeline, SpacingRefused, StampNotNewer
from gyro_emulator.emulation.record_clock import RecordClock
from gyro_emulator.emulation.sample_clock import SampleClock
from gyro_emulator.recording import topics
from gyro_emulator.ros import codec, diagnostics, node_help, params, spinning
from gyro_emulator.ros.intake import INBOX_DEPTH, Intake
from gyro_emulator.ros.outputs import fault_message, OutputStage
from gyro_emulator.ros.self_record import SelfRecorder
from gyro_emulator.sensor import config as sensor_config
from gyro_emulator.sensor import faults
from gyro_emulator.sensor import model as sensor_model
from gyro_emulator.sensor.streams import seed_from_name
from gyro_emulator.units import NS_PER_S
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock as RosClock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from rclpy.qos_overriding_options import QoSOverridingOptions
from rclpy.time import Time

ZERO3 = (0.0, 0.0, 0.0)


def _while_up(callback):
    """
    Wrap an executor callback: an error once the context is down is the shutdown.

    A SIGINT/SIGTERM shuts the context down from rclpy's signal handler while
    a callback may be publishing; the events executor would log that error
    with its traceback. While the context is up, errors propagate.
    """
    @functools.wraps(callback)
    def run(self, *args):
        try:
            return callback(self, *args)
        except (Exception, KeyboardInterrupt):  # noqa: B902 - after shutdown: the shutdown
            if self.context.ok():
                raise
            return None
    return run


def _warm_up():
    """Load the compiled sensor kernel (numba's cache) before ROS takes the signals."""
    config = sensor_config.SensorConfig()
    sensor_model.GyroModel(config, 100.0, np.random.default_rng(0)).step(ZERO3, 25.0)


def _appender(inbox):
    """Return a subscription callback that appends to ``inbox`` (rclpy inspects it)."""
    def append(msg):
        inbox.append(msg)
    return append


class GyroEmulatorNode(Node):
    """
    The emulated gyro driver node (see the module docstring for its topics).

    Parameters
    ----------
    kwargs
        Passed to ``rclpy.node.Node`` (e.g. ``parameter_overrides``).

    """

    def __init__(self, **kwargs):
        super().__init__(params.NODE_NAME, **kwargs)
        self._declare_node_parameters()
        p = self._p
        self.rate_hz = p['rate_hz']
        self.frame_id = p['frame_id']
        base = sensor_config.load_sensor_config(p['sensor_config'])
        self._declare_sensor_parameters(base)
        self._log_throttle = Throttle(1.0, time.monotonic)
        self.seed = p['seed']
        if self.seed == params.SEED_FROM_NAME:
            self.seed = seed_from_name(self.get_fully_qualified_name())
        rng = np.random.default_rng(self.seed)
        model = sensor_model.GyroModel(self._effective_config(), self.rate_hz, rng)
        self._fault = FaultState(self._config.range_rad_s,
                                 faults.fault_generator(rng.bit_generator.seed_seq))
        self._stepper = BlockStepper(model, p['block_samples'])
        self._book = diagnostics.DiagnosticsBook()
        self._limits = self._make_limits()
        self._imu_mode = p['input_source'] == 'imu'
        self._intake = Intake(None if self._imu_mode else topics.RATE_INPUTS[p['rate_source']],
                              p['initial_temperature_c'],
                              p['default_linear_acceleration_m_s2'],
                              p['command_queue_size'], self._reject, self._clamped)
        self._last_tick_ns = None
        self._last_stamp_ns = None
        self._stamps_clamped = 0
        self._last_sample = None
        self._record = RecordClock(p['record_start_clock_s'], self.get_logger().error)
        self._ambient_c = p['initial_temperature_c']
        self._stale = False
        self._out = OutputStage(self, self.frame_id)
        self._refresh_covariance()
        self._set_temperature_decimation(self.rate_hz)
        self._timeline = InputTimeline(self.rate_hz) if self._imu_mode else None
        self._previous_input = None
        self._rate_refused = None
        self._timer = None
        self._drain_timer = None
        self._samples = None
        if not self._imu_mode:
            self._samples = SampleClock(self._stepper.model.sample_period_s,
                                        p['overrun_policy'], p['max_burst_samples'],
                                        p['fifo_depth_samples'],
                                        not self.get_parameter('use_sim_time').value)
            # The part's clock drift sets its output data rate (sample period), so
            # the stamps stay tied to the ROS clock.
            self._timer = self.create_timer(self._stepper.model.sample_period_s, self._tick)
        self._make_inputs()
        self._set_fault(self._fault_from(p), self._now_ns())
        self._start_diagnostics()
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._warn_unknown_overrides()
        self._self_recorder = None
        if p['record_dir']:
            self._self_recorder = SelfRecorder(self, p['record_dir'])
        self._log_start()

    def _log_start(self):
        p = self._p
        lo, hi = self._limits.temp_range_c
        seed = f'seed {self.seed}' + (' (from the node name)'
                                      if p['seed'] == params.SEED_FROM_NAME else '')
        source = ('imu/ideal, one output per message' if self._imu_mode
                  else f'{self.rate_hz:g} Hz, rate from {p["rate_source"]}')
        self.get_logger().info(
            f'gyro emulator up: {source}, sensor_config {p["sensor_config"]!r}, {seed}, '
            f'frame {self.frame_id!r}, ambient range [{lo:g}, {hi:g}] C')

    # --- parameters --------------------------------------------------------

    def _declare_node_parameters(self):
        defaults = params.node_defaults()
        overrides = getattr(self, '_parameter_overrides', None)
        if isinstance(overrides, dict):
            # A params file may write 200 for a double: accept it as 200.0.
            for name, value in list(overrides.items()):
                spec = params.NODE_SPECS.get(name)
                if spec is None:
                    continue
                if spec.kind == 'double' and value.type_ == Parameter.Type.INTEGER:
                    overrides[name] = Parameter(name, Parameter.Type.DOUBLE,
                                                float(value.value))
                elif spec.kind == 'double_array' and \
                        value.type_ == Parameter.Type.INTEGER_ARRAY:
                    overrides[name] = Parameter(name, Parameter.Type.DOUBLE_ARRAY,
                                                [float(v) for v in value.value])
        self._p = {}
        for spec in params.NODE_PARAMS:
            default = defaults[spec.name]
            if spec.name == 'temperature_rate_hz':
                # The shipped 10 Hz must not refuse a slower rate_hz (1 Hz is allowed).
                default = min(default, self._p['rate_hz'])
            value = self.declare_parameter(spec.name, default,
                                           params.descriptor(spec)).value
            self._p[spec.name] = params.check_value(spec, value)
        if self._p['temperature_rate_hz'] > self._p['rate_hz']:
            raise ValueError(f'temperature_rate_hz = {self._p["temperature_rate_hz"]!r} is '
                             f'out of range: allowed (0, rate_hz = {self._p["rate_hz"]:g}]')
        self._fault_from(self._p)

    @staticmethod
    def _fault_from(p):
        """Return the Fault of the ``fault.*`` parameter values (ValueError if invalid)."""
        values = {name.split('.', 1)[1]: p[name] for name in params.FAULT_PARAMS}
        values['kind'] = values.pop('type')
        return faults.Fault(**values)

    def _declare_sensor_parameters(self, base):
        self._base_config = base
        values = {}
        for name, default in params.sensor_param_values(base).items():
            values[name] = self.declare_parameter(
                name, default, params.sensor_descriptor(name, default)).value
        self._sensor_values = values
        self._config = params.apply_sensor_params(base, values)

    def _effective_config(self, config=None, noise_enabled=None):
        config = self._config if config is None else config
        noise = self._p['noise_enabled'] if noise_enabled is None else noise_enabled
        return config if noise else params.without_noise(config)

    def _make_limits(self, p=None, config=None):
        p = self._p if p is None else p
        config = self._config if config is None else config
        low, high = self._stepper.model.temp_range_c
        heating = config.self_heating_c if config.terms.thermal_lag else 0.0
        return InputLimits(
            max_abs_rate_rad_s=p['max_abs_rate_rad_s'],
            max_abs_accel_m_s2=p['max_abs_accel_m_s2'],
            temp_range_c=(low - min(0.0, heating), high - max(0.0, heating)),
            temperature_policy=p['temperature_policy'],
            max_stamp_lead_s=p['max_stamp_lead_s'])

    def _warn_unknown_overrides(self):
        overrides = getattr(self, '_parameter_overrides', None) or {}
        for name in sorted(overrides):
            if not self.has_parameter(name) and not name.startswith('qos_overrides.'):
                self.get_logger().warning(f'parameter {name!r} is unknown and ignored')

    def _validate_parameters(self, parameters):
        p = dict(self._p)
        sensor_values = dict(self._sensor_values)
        try:
            for param in parameters:
                spec = params.NODE_SPECS.get(param.name)
                if spec is not None:
                    p[param.name] = params.check_value(spec, param.value)
                elif param.name.startswith(params.SENSOR_PREFIX):
                    sensor_values[param.name] = param.value
            config = self._config
            if sensor_values != self._sensor_values:
                config = params.apply_sensor_params(self._base_config, sensor_values)
                # Build the model's plan once to catch rate-dependent limits
                # (e.g. an output filter at or above Nyquist).
                sensor_model.GyroModel(self._effective_config(config, p['noise_enabled']),
                                       self._stepper.model.sample_rate_hz,
                                       np.random.default_rng(0))
            limits = self._make_limits(p, config)
            if p['temperature_override_enabled']:
                low, high = limits.temp_range_c
                if not low <= p['temperature_override_c'] <= high:
                    raise ValueError(
                        f'temperature_override_c = {p["temperature_override_c"]!r} is out '
                        f'of range: allowed [{low:g}, {high:g}] C for this sensor')
            fault = self._fault_from(p)
        except ValueError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        touched = any(param.name in params.FAULT_PARAMS for param in parameters)
        self._pending = (p, sensor_values, config, limits, fault if touched else None)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters):
        pending = getattr(self, '_pending', None)
        if pending is None:
            return
        self._pending = None
        p, sensor_values, config, limits, fault = pending
        old_noise = self._p['noise_enabled']
        changed_model = config is not self._config or p['noise_enabled'] != old_noise
        self._p, self._sensor_values, self._config, self._limits = (
            p, sensor_values, config, limits)
        if self._samples is not None:
            self._samples.policy = p['overrun_policy']
            self._samples.max_burst = p['max_burst_samples']
            self._samples.depth = p['fifo_depth_samples']
        if changed_model:
            self._stepper.update_config(self._effective_config())
            self._fault.range_rad_s = np.asarray(config.range_rad_s, dtype=float)
            self._refresh_covariance()
            self._retime()
        if fault is not None:
            self._set_fault(fault, self._fault_clock_ns())
        self.get_logger().info('parameters set: ' + ', '.join(
            f'{q.name} = {q.value!r}' for q in parameters))

    def _fault_clock_ns(self):
        """Return "now" on the samples' time line: the last input stamp behind a simulator."""
        if self._timeline is not None and self._timeline.last_ns is not None:
            return self._timeline.last_ns
        return self._now_ns()

    def _set_fault(self, fault, now_ns):
        self._fault.end(now_ns)
        if self._fault.changed:
            self._publish_fault(now_ns)         # the fault it replaces ends here
        self._fault.start(fault, now_ns, self._out.last_rate)
        if fault.kind != 'none':
            self.get_logger().warning(f'fault set: {fault.describe()}')
        self._publish_fault(now_ns)

    def _publish_fault(self, stamp_ns):
        state = self._fault
        state.changed = False
        stamp = Time(nanoseconds=int(stamp_ns)).to_msg()
        self._out.fault_pub.publish(fault_message(
            stamp, f'{self.get_fully_qualified_name()}: fault',
            f'gyro_emulator/{self._p["sensor_config"]}', state.fault, state.state,
            state.level, state.since_ns))

    def _retime(self):
        """Follow a new sample period (a changed clock drift) with a new timer."""
        if self._timer is None:
            return
        period_s = self._stepper.model.sample_period_s
        self._samples.set_period(period_s)
        if abs(self._timer.timer_period_ns - period_s * NS_PER_S) >= 1.0:
            self.destroy_timer(self._timer)
            self._timer = self.create_timer(period_s, self._tick)

    # --- subscriptions -------------------------------------------------------

    def _make_inputs(self):
        """
        Subscribe to the inputs on the node itself (its executor serves them).

        Commands go, still serialized, into the inboxes of :class:`Intake`
        and are taken at the next sample; each takes effect at the first
        sample at or after its stamp, so the order in which the executor
        serves the timer and the subscriptions does not change the output.
        ``imu/ideal`` is handled as it arrives: one output per message.
        """
        qos = QoSProfile(history=qos_profile_sensor_data.history, depth=INBOX_DEPTH,
                         reliability=qos_profile_sensor_data.reliability,
                         durability=qos_profile_sensor_data.durability)
        options = QoSOverridingOptions.with_default_policies
        # Default QoS event handlers would join every executor wake-up.
        quiet = SubscriptionEventCallbacks(use_default_callbacks=False)
        self._input_subscriptions = []
        for topic, inbox in self._intake.inboxes.items():
            raw = topic.type_name != topics.ODOMETRY
            self._input_subscriptions.append(self.create_subscription(
                codec.topic_class(topic), topic.name, _appender(inbox), qos, raw=raw,
                qos_overriding_options=options(), event_callbacks=quiet))
        if self._imu_mode:
            topic = topics.IMU_IDEAL_IN
            self._input_subscriptions.append(self.create_subscription(
                codec.topic_class(topic), topic.name, self._on_imu, qos,
                qos_overriding_options=options(), event_callbacks=quiet))

    def _reject(self, exc):
        self._book.reject(exc.reason)
        held = self._log_throttle(exc.reason)
        if held is not None:
            more = f' ({held} similar held back)' if held else ''
            self.get_logger().warning(f'input rejected ({exc.reason}): {exc}{more}')

    def _clamped(self, raw_c, temp_c):
        self._book.clamp('temperature_clamped')
        if self._log_throttle('temperature_clamped') is not None:
            lo, hi = self._limits.temp_range_c
            self.get_logger().warning(f'temperature {raw_c!r} C outside the model range '
                                      f'[{lo:g}, {hi:g}] C: clamped to {temp_c:g} C')

    # --- diagnostics thread and teardown -------------------------------------

    def _start_diagnostics(self):
        """Publish /diagnostics from a thread on the steady clock (also when paused)."""
        self._diag_last = time.monotonic()
        self._diag_stop = threading.Event()
        self._diag_thread = threading.Thread(target=self._diagnostics_loop, daemon=True,
                                             name='gyro_emulator_diagnostics')
        self._diag_thread.start()

    def _diagnostics_loop(self):
        period = self._p['diagnostics_period_s']
        while not self._diag_stop.wait(period):
            if not self.context.ok():
                return
            try:
                self._diagnose()
            except Exception as exc:  # noqa: B902 - a shutdown race must not kill the log
                if self.context.ok():
                    self.get_logger().error(f'diagnostics failed: {exc!r}')
                return

    def destroy_node(self):
        """Stop the diagnostics thread, finish the self-recording and destroy the node."""
        stop = getattr(self, '_diag_stop', None)
        if stop is not None:
            stop.set()
            self._diag_thread.join(5.0)
            self._diag_stop = None
        recorder = getattr(self, '_self_recorder', None)
        if recorder is not None:
            recorder.finish()
        return super().destroy_node()

    def _now_ns(self):
        return self.get_clock().now().nanoseconds

    # --- the sample loop ----------------------------------------------------

    def _refresh_covariance(self):
        self._sigma_version = self._stepper.sigma_version
        self._out.set_sigma(self._stepper.sigma_rad_s)

    def _set_temperature_decimation(self, sample_rate_hz):
        self._out.temp_every = max(1, int(round(sample_rate_hz / self._p['temperature_rate_hz'])))

    def _restart(self, why, jump_ns=0, next_ns=None):
        """Restart the filters after a discontinuity of the time line; say so."""
        self._fault.shift(jump_ns)
        self._stepper.sync()
        self._stepper.model.restart_filters()
        self._record.jumped(self._stepper.model, next_ns)    # the extended terms' time
        self._intake.reset_clock()
        self._last_stamp_ns = None
        self.get_logger().warning(f'{why}: command stamps forgotten, filters restarted')

    def _inputs(self, now_ns):
        """Return the (rate, ambient, acceleration) in force at sample time ``now_ns``."""
        p = self._p
        intake = self._intake
        rate = intake.rate.advance(now_ns)
        age = intake.rate.age_s(now_ns)
        temp = intake.temperature.advance(now_ns)
        accel = intake.accel.advance(now_ns)
        timeout = p['command_timeout_s']
        self._stale = bool(timeout > 0.0 and age is not None and age > timeout)
        if self._stale and p['stale_rate_policy'] == 'zero':
            rate = ZERO3
        return rate, self._ambient(temp), accel

    def _ambient(self, temp):
        if self._p['temperature_override_enabled']:
            return self._p['temperature_override_c']
        low, high = self._limits.temp_range_c
        return min(max(temp, low), high)

    @_while_up
    def _tick(self):
        """Publish the samples that came due since the last tick (see SampleClock)."""
        now_ns = self._now_ns()
        due = self._samples.due(now_ns)
        if due.restart == 'jump_back':
            self._restart('clock jumped back', now_ns - self._last_tick_ns, now_ns)
        elif due.restart == 'gap':
            self._restart(f'the clock jumped ahead {(now_ns - self._last_tick_ns) * 1e-9:.3f} s',
                          0, now_ns)
        self._last_tick_ns = now_ns
        self._publish_due(due, now_ns)

    @_while_up
    def _drain(self):
        """Publish the next burst of the backlog (a steady timer: also while /clock stands)."""
        if not self._samples.backlog:
            self._drain_timer.cancel()
            return
        self._publish_due(self._samples.due(self._last_tick_ns), self._last_tick_ns)

    def _publish_due(self, due, now_ns):
        """Run the model through the dropped samples and publish the due ones."""
        if self._samples.backlog:
            # The rest of the burst goes out one period later, whatever the node clock does.
            if self._drain_timer is None:
                self._drain_timer = self.create_timer(
                    self._samples.period_ns / NS_PER_S, self._drain,
                    clock=RosClock(clock_type=ClockType.STEADY_TIME))
            elif self._drain_timer.is_canceled():
                self._drain_timer.reset()
        if not due.times_ns:
            return
        self._intake.take(now_ns, self._limits)
        first_ns = due.times_ns[0] - int(round(due.skipped * self._samples.period_ns))
        self._record.first(self._stepper.model, first_ns)
        if due.skipped:
            self._book.drop(due.skipped)
            # The part sampled them: run the model through with the input held.
            rate, temp, accel = self._inputs(first_ns)
            try:
                self._stepper.skip(due.skipped, rate, temp, accel)
            except ValueError as exc:
                self._book.model_error(str(exc))
        shown_accel = self._intake.accel.accepted
        for sample_ns in due.times_ns:
            rate, temp, accel = self._inputs(sample_ns)
            self._sample(rate, temp, accel, sample_ns, sample_ns,
                         accel if shown_accel else None)

    def _sample(self, rate, temp, accel, sample_ns, base_ns, shown_accel):
        """Step the model once and publish; ``base_ns`` + output delay is the Imu stamp."""
        self._ambient_c = temp
        try:
            s = self._stepper.step(rate, temp, accel)
        except ValueError as exc:
            self._book.model_error(str(exc))
            if self._log_throttle('model_error') is not None:
                self.get_logger().error(f'model refused the sample: {exc}')
            return
        self._last_sample = s
        if self._stepper.sigma_version != self._sigma_version:
            self._refresh_covariance()
        out = self._out
        out.set_accel(shown_accel, self._p['pass_through_linear_acceleration']
                      or self._imu_mode)
        delay_ns = int(round(s.output_delay_s * NS_PER_S)) if s.output_delay_s else 0
        stamp_ns = base_ns + delay_ns
        if self._last_stamp_ns is not None and stamp_ns <= self._last_stamp_ns:
            # A shorter latency set at run time: stamps never go back (the
            # model bounds the jitter by half a period, so only this can).
            stamp_ns = self._last_stamp_ns + 1
            self._stamps_clamped += 1
        self._last_stamp_ns = stamp_ns
        value, publish, pinned = self._fault.apply(sample_ns, s.gyro_rad_s)
        out.publish(s, sample_ns, stamp_ns, value, publish, self._p['publish_truth'])
        if self._fault.changed:
            self._publish_fault(sample_ns)
        self._book.sample(s.saturated if pinned is None else s.saturated | pinned)

    # --- behind a simulator: one sample per imu/ideal message ----------------

    @_while_up
    def _on_imu(self, msg):
        stamp = msg.header.stamp
        stamp_ns = stamp.sec * NS_PER_S + stamp.nanosec
        v, a = msg.angular_velocity, msg.linear_acceleration
        try:
            rate = check_rate((v.x, v.y, v.z), self._limits)
            accel = check_acceleration((a.x, a.y, a.z), self._limits)
            step = self._timeline.advance(stamp_ns)
        except InputRejected as exc:
            self._reject(exc)
            return
        except StampNotNewer as exc:
            self._reject(InputRejected('out_of_order', str(exc)))
            return
        except SpacingRefused as exc:
            self._reject(InputRejected('stamp_spacing', str(exc)))
            return
        if step.restart:
            why = ('the input clock jumped back' if step.restart == 'jump_back'
                   else f'a gap of {step.dt_s:.3f} s in the input stamps')
            self._restart(why, int(round(step.dt_s * NS_PER_S)) if step.restart ==
                          'jump_back' else 0, stamp_ns)
        if step.rate_hz is not None:
            self._replan(step.rate_hz)
        if self._rate_refused:
            self._book.model_error(self._rate_refused)
        intake = self._intake
        self._record.first(self._stepper.model, stamp_ns)
        intake.take(stamp_ns, self._limits)
        temp = self._ambient(intake.temperature.advance(stamp_ns))
        held, self._previous_input = self._previous_input, (rate, accel)
        if step.samples > 1 and held is not None:
            # Messages lost or a sensor update skipped: the part kept sampling.
            try:
                for _ in range(step.samples - 1):
                    self._stepper.step(held[0], temp, held[1])
            except ValueError as exc:
                self._book.model_error(str(exc))
        self._sample(rate, temp, accel, stamp_ns, stamp_ns, accel)

    def _replan(self, rate_hz):
        """Run the model at the input's rate from now on (every discretisation follows)."""
        try:
            self._stepper.set_sample_rate(rate_hz)
        except ValueError as exc:
            # Reported as a model error with every sample until a rate fits.
            self._rate_refused = f'input rate {rate_hz:.6g} Hz refused: {exc}'
            self.get_logger().error(self._rate_refused)
            return
        self._rate_refused = None
        self._refresh_covariance()
        self._set_temperature_decimation(rate_hz)
        self.get_logger().info(f'input rate {rate_hz:.6g} Hz from the imu/ideal stamps: '
                               'model re-planned')

    # --- diagnostics ----------------------------------------------------------

    def situation(self):
        """Return the node's current state as diagnostics key/values."""
        now_ns = self._now_ns()
        s = self._last_sample
        p = self._p
        intake = self._intake
        if p['temperature_override_enabled']:
            source = 'override'
        elif intake.temperature.accepted:
            source = 'command'
        else:
            source = 'initial_temperature_c'
        out = {
            'stale': self._stale, 'stale_policy': p['stale_rate_policy'],
            'rate_age_s': intake.rate.age_s(now_ns),
            'input_source': p['input_source'], 'rate_source': p['rate_source'],
            'ambient_temp_c': self._ambient_c,
            'temperature_source': source,
            'die_temp_c': None if s is None else float(s.die_temp_c),
            'noise_enabled': p['noise_enabled'],
            'commands_accepted.rate': intake.rate.accepted,
            'commands_accepted.temperature': intake.temperature.accepted,
            'commands_accepted.linear_acceleration': intake.accel.accepted,
            'commands_pending': intake.pending(),
            'output_delay_s': None if s is None else float(s.output_delay_s),
            'sample_period_s': 1.0 / self._stepper.model.sample_rate_hz,
            'timer_period_s': None if self._timer is None
            else self._timer.timer_period_ns / NS_PER_S,
            'model_calls': self._stepper.model_calls,
            'model_rewinds': self._stepper.rewinds,
            'stamps_clamped': self._stamps_clamped,
            'sensor_config': p['sensor_config'],
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
        recorder = self._self_recorder
        if recorder is not None:
            out['recording'] = recorder.path
            out['recording_error'] = recorder.error
        out.update(self._fault.situation())
        return out

    def _diagnose(self):
        now = time.monotonic()
        elapsed, self._diag_last = now - self._diag_last, now
        sim = self.get_parameter('use_sim_time').value
        report = self._book.report(elapsed, self.rate_hz, self.situation(),
                                   check_rate=not (sim or self._imu_mode))
        self._out.diag_pub.publish(diagnostics.to_msg(
            report, self.get_clock().now().to_msg(), f'{self.get_fully_qualified_name()}: gyro',
            f'gyro_emulator/{self._p["sensor_config"]}'))

    def summary(self):
        """One line of totals for the shutdown log."""
        book = self._book
        line = (f'{book.samples} samples, {sum(book.rejected.values())} inputs rejected, '
                f'{sum(book.clamped.values())} clamped, {book.model_errors} model errors')
        clock = self._samples
        if clock is not None and clock.due_total:
            line += (f', {clock.caught_up} caught up, {clock.dropped} dropped '
                     f'({clock.emitted} of {clock.due_total} due samples out)')
        return line


def main(args=None):
    """Run the node until SIGINT or SIGTERM; return the exit status."""
    argv = sys.argv[1:] if args is None else list(args)
    if node_help.wants_help(argv):
        print(node_help.help_text())
        return 0
    return spinning.run_node(GyroEmulatorNode, args, 'gyro_emulator node', warm_up=_warm_up)


if __name__ == '__main__':
    sys.exit(main())
