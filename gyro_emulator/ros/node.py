"""
``ros2 run gyro_emulator node``: the sensor model as a ROS 2 gyro driver.

A timer on the node clock (sim time under ``use_sim_time``) advances the
error model one sample per tick, 1 / ``rate_hz`` each, with the commands in
force at that tick, and publishes:

* ``imu/data_raw`` (sensor_msgs/Imu, REP 145/103): the gyro output in rad/s,
  ``angular_velocity_covariance`` = diag(sigma^2) of the model's white noise
  at this rate, orientation absent (``orientation_covariance[0] = -1``),
  linear acceleration absent (``[0] = -1``) unless passed through.
  Stamp = tick time + the model's output delay (latency, jitter, drift).
* ``imu/temperature`` (sensor_msgs/Temperature): die temperature, deg C.
* ``~/truth/rate``, ``~/truth/bias``, ``~/truth/scale_factor``
  (geometry_msgs/Vector3Stamped, stamped at the tick): true rate (rad/s),
  total bias (rad/s) and total gain (ratio) of the same sample.
* ``/diagnostics`` (diagnostic_msgs/DiagnosticArray), see
  :mod:`gyro_emulator.ros.diagnostics`.

It subscribes to ``cmd/angular_velocity`` (geometry_msgs/Vector3Stamped,
rad/s, sensor frame) or, with ``rate_source = odometry``, ``cmd/odom``
(nav_msgs/Odometry, twist.twist.angular), to ``cmd/temperature``
(sensor_msgs/Temperature, ambient deg C) and ``cmd/linear_acceleration``
(geometry_msgs/Vector3Stamped, m/s^2). Input rules: :mod:`.inputs`.
"""

import sys
import threading
import time

from gyro_emulator.recording import topics
from gyro_emulator.ros import codec, diagnostics, params
from gyro_emulator.ros.inputs import (check_acceleration, check_rate, check_temperature,
                                      CommandStream, InputLimits, InputRejected, Throttle)
from gyro_emulator.ros.rawmsg import RawMessage
from gyro_emulator.ros.spinning import close, spin_once
from gyro_emulator.ros.stepper import BlockStepper
from gyro_emulator.sensor import config as sensor_config
from gyro_emulator.sensor import model as sensor_model
from gyro_emulator.units import NS_PER_S
import numpy as np
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from rclpy.qos_overriding_options import QoSOverridingOptions

ZERO3 = (0.0, 0.0, 0.0)
#: Messages each command subscription keeps until the executor serves them.
INPUT_DEPTH = 100
#: Longest wait of the executor between checks for shutdown, s.
SHUTDOWN_POLL_S = 0.25


def _stamp_ns(header):
    return header.stamp.sec * NS_PER_S + header.stamp.nanosec


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
        model = sensor_model.GyroModel(self._effective_config(), self.rate_hz,
                                       np.random.default_rng(p['seed']))
        self._stepper = BlockStepper(model, p['block_samples'])
        self._book = diagnostics.DiagnosticsBook()
        self._limits = self._make_limits()
        capacity = p['command_queue_size']
        self._rate_cmd = CommandStream('rate', ZERO3, capacity)
        self._temp_cmd = CommandStream('temperature', p['initial_temperature_c'], capacity)
        self._accel_cmd = CommandStream('linear_acceleration', None, capacity)
        self._last_tick_ns = None
        self._last_sample = None
        self._ambient_c = p['initial_temperature_c']
        self._stale = False
        self._make_publishers()
        self._temp_every = max(1, int(round(self.rate_hz / p['temperature_rate_hz'])))
        self._tick_count = 0
        # The part's clock drift sets its output data rate (sample period), so
        # the stamps stay tied to the ROS clock (issue 14).
        self._timer = self.create_timer(self._stepper.model.sample_period_s, self._tick)
        self._make_inputs()
        self._start_diagnostics()
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._warn_unknown_overrides()
        self._self_recorder = None
        if p['record_dir']:
            from gyro_emulator.ros.self_record import SelfRecorder
            self._self_recorder = SelfRecorder(self, p['record_dir'])
        lo, hi = self._limits.temp_range_c
        self.get_logger().info(
            f'gyro emulator up: {self.rate_hz:g} Hz, sensor_config '
            f'{p["sensor_config"]!r}, seed {p["seed"]}, frame {self.frame_id!r}, '
            f'rate from {p["rate_source"]}, ambient range [{lo:g}, {hi:g}] C')

    # --- parameters --------------------------------------------------------

    def _declare_node_parameters(self):
        defaults = params.node_defaults()
        overrides = getattr(self, '_parameter_overrides', None)
        if isinstance(overrides, dict):
            # A params file may write 200 for a double: accept it as 200.0.
            for name, value in list(overrides.items()):
                spec = params.NODE_SPECS.get(name)
                if spec is not None and spec.kind == 'double' and \
                        value.type_ == Parameter.Type.INTEGER:
                    overrides[name] = Parameter(name, Parameter.Type.DOUBLE,
                                                float(value.value))
        self._p = {}
        for spec in params.NODE_PARAMS:
            value = self.declare_parameter(spec.name, defaults[spec.name],
                                           params.descriptor(spec)).value
            self._p[spec.name] = params.check_value(spec, value)
        if self._p['temperature_rate_hz'] > self._p['rate_hz']:
            raise ValueError(f'temperature_rate_hz = {self._p["temperature_rate_hz"]!r} is '
                             f'out of range: allowed (0, rate_hz = {self._p["rate_hz"]:g}]')

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
                                       self.rate_hz, np.random.default_rng(0))
            limits = self._make_limits(p, config)
            if p['temperature_override_enabled']:
                low, high = limits.temp_range_c
                if not low <= p['temperature_override_c'] <= high:
                    raise ValueError(
                        f'temperature_override_c = {p["temperature_override_c"]!r} is out '
                        f'of range: allowed [{low:g}, {high:g}] C for this sensor')
        except ValueError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self._pending = (p, sensor_values, config, limits)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters):
        pending = getattr(self, '_pending', None)
        if pending is None:
            return
        self._pending = None
        p, sensor_values, config, limits = pending
        old_noise = self._p['noise_enabled']
        changed_model = config is not self._config or p['noise_enabled'] != old_noise
        self._p, self._sensor_values, self._config, self._limits = (
            p, sensor_values, config, limits)
        if changed_model:
            self._stepper.update_config(self._effective_config())
            self._refresh_covariance()
            self._retime()
        self.get_logger().info('parameters set: ' + ', '.join(
            f'{q.name} = {q.value!r}' for q in parameters))

    def _retime(self):
        """Follow a new sample period (a changed clock drift) with a new timer."""
        period_s = self._stepper.model.sample_period_s
        if abs(self._timer.timer_period_ns - period_s * NS_PER_S) >= 1.0:
            self.destroy_timer(self._timer)
            self._timer = self.create_timer(period_s, self._tick)

    # --- publishers and subscriptions -------------------------------------

    def _make_publishers(self):
        # Each publisher's QoS event handlers (incompatible QoS / type warnings)
        # join every executor wake-up; only imu/data_raw, the output that
        # drivers' users subscribe to, keeps them.
        qos_options = QoSOverridingOptions.with_default_policies
        quiet = PublisherEventCallbacks(use_default_callbacks=False)
        self._imu_pub = self._publisher(topics.IMU_OUT, qos_overriding_options=qos_options())
        self._temp_pub = self._publisher(topics.DIE_TEMPERATURE_OUT, event_callbacks=quiet,
                                         qos_overriding_options=qos_options())
        self._truth_pubs = [
            self._publisher(topic, qos_overriding_options=qos_options(), event_callbacks=quiet)
            for topic in topics.TRUTH_TOPICS.values()]
        self._diag_pub = self._publisher(topics.DIAGNOSTICS, event_callbacks=quiet)
        imu = codec.topic_class(topics.IMU_OUT)()
        imu.header.frame_id = self.frame_id
        imu.orientation_covariance[0] = -1.0
        imu.linear_acceleration_covariance[0] = -1.0
        self._imu = RawMessage(imu, {
            'stamp': ('header.stamp', 'time'), 'rate': ('angular_velocity', 'vector3'),
            'cov': ('angular_velocity_covariance', ('array', 9)),
            'accel': ('linear_acceleration', 'vector3'),
            'accel_cov0': ('linear_acceleration_covariance', ('array', 1))})
        self._accel_shown = False
        self._sigma_shown = None
        self._refresh_covariance()
        temp = codec.topic_class(topics.DIE_TEMPERATURE_OUT)()
        temp.header.frame_id = self.frame_id
        self._temp_msg = RawMessage(temp, {'stamp': ('header.stamp', 'time'),
                                           'value': ('temperature', 'double')})
        self._truth_msgs = []
        for topic in topics.TRUTH_TOPICS.values():
            msg = codec.topic_class(topic)()
            msg.header.frame_id = self.frame_id
            self._truth_msgs.append(RawMessage(msg, {'stamp': ('header.stamp', 'time'),
                                                     'value': ('vector', 'vector3')}))

    def _publisher(self, topic, **kwargs):
        """Return a publisher of a topic-table entry with its type and QoS."""
        return self.create_publisher(codec.topic_class(topic), topic.name,
                                     codec.topic_qos(topic), **kwargs)

    def _make_inputs(self):
        """
        Subscribe to the commands on the node itself (its executor serves them).

        A command goes into its stamped queue (:class:`CommandStream`) when it
        arrives and takes effect at the first sample at or after its stamp,
        so the order in which the executor serves the timer and the
        subscriptions does not change the output. Each subscription keeps the
        last ``INPUT_DEPTH`` messages.
        """
        qos = QoSProfile(history=qos_profile_sensor_data.history, depth=INPUT_DEPTH,
                         reliability=qos_profile_sensor_data.reliability,
                         durability=qos_profile_sensor_data.durability)
        options = QoSOverridingOptions.with_default_policies
        # As for the publishers: default QoS event handlers would join every
        # executor wake-up (three waitables per subscription).
        quiet = SubscriptionEventCallbacks(use_default_callbacks=False)
        handlers = {topics.RATE_CMD: self._on_rate, topics.ODOM_CMD: self._on_odometry,
                    topics.TEMPERATURE_CMD: self._on_temperature,
                    topics.ACCEL_CMD: self._on_accel}
        inputs = (topics.RATE_INPUTS[self._p['rate_source']], topics.TEMPERATURE_CMD,
                  topics.ACCEL_CMD)
        self._input_subscriptions = [
            self.create_subscription(codec.topic_class(topic), topic.name, handlers[topic], qos,
                                     qos_overriding_options=options(), event_callbacks=quiet)
            for topic in inputs]

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

    def _reject(self, exc):
        self._book.reject(exc.reason)
        held = self._log_throttle(exc.reason)
        if held is not None:
            more = f' ({held} similar held back)' if held else ''
            self.get_logger().warning(f'input rejected ({exc.reason}): {exc}{more}')

    def _offer(self, stream, value, stamp_ns):
        dropped = stream.offer(value, stamp_ns, self._now_ns(),
                               int(self._limits.max_stamp_lead_s * NS_PER_S))
        if dropped:
            self._reject(InputRejected(dropped, f'{stream.name}: more than '
                                       f'{stream.capacity} commands wait for their '
                                       'stamp: the oldest was dropped'))

    def _on_rate_vector(self, vector, header):
        try:
            rate = check_rate((vector.x, vector.y, vector.z), self._limits)
            self._offer(self._rate_cmd, rate, _stamp_ns(header))
        except InputRejected as exc:
            self._reject(exc)

    def _on_rate(self, msg):
        self._on_rate_vector(msg.vector, msg.header)

    def _on_odometry(self, msg):
        self._on_rate_vector(msg.twist.twist.angular, msg.header)

    def _on_temperature(self, msg):
        try:
            temp, clamped = check_temperature(msg.temperature, self._limits)
            if clamped:
                self._book.clamp('temperature_clamped')
                if self._log_throttle('temperature_clamped') is not None:
                    lo, hi = self._limits.temp_range_c
                    self.get_logger().warning(
                        f'temperature {msg.temperature!r} C outside the model range '
                        f'[{lo:g}, {hi:g}] C: clamped to {temp:g} C')
            self._offer(self._temp_cmd, temp, _stamp_ns(msg.header))
        except InputRejected as exc:
            self._reject(exc)

    def _on_accel(self, msg):
        v = msg.vector
        try:
            accel = check_acceleration((v.x, v.y, v.z), self._limits)
            self._offer(self._accel_cmd, accel, _stamp_ns(msg.header))
        except InputRejected as exc:
            self._reject(exc)

    # --- the sample loop ----------------------------------------------------

    def _refresh_covariance(self):
        self._sigma_version = self._stepper.sigma_version
        sigma = self._stepper.sigma_rad_s
        if self._sigma_shown is not None and np.array_equal(sigma, self._sigma_shown):
            return
        cov = np.zeros(9)
        cov[[0, 4, 8]] = sigma * sigma
        self._imu.put('cov', *cov.tolist())
        self._sigma_shown = sigma

    def _inputs(self, now_ns):
        p = self._p
        rate = self._rate_cmd.advance(now_ns)
        age = self._rate_cmd.age_s(now_ns)
        temp = self._temp_cmd.advance(now_ns)
        accel = self._accel_cmd.advance(now_ns)
        timeout = p['command_timeout_s']
        self._stale = bool(timeout > 0.0 and age is not None and age > timeout)
        if self._stale and p['stale_rate_policy'] == 'zero':
            rate = ZERO3
        if p['temperature_override_enabled']:
            temp = p['temperature_override_c']
        else:
            low, high = self._limits.temp_range_c
            temp = min(max(temp, low), high)
        return rate, temp, accel

    def _tick(self):
        now_ns = self._now_ns()
        if self._last_tick_ns is not None and now_ns < self._last_tick_ns:
            for stream in (self._rate_cmd, self._temp_cmd, self._accel_cmd):
                stream.reset_clock()
            self.get_logger().warning('clock jumped back: command stamps forgotten')
        self._last_tick_ns = now_ns
        rate, temp, accel = self._inputs(now_ns)
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
        imu = self._imu
        delay_ns = int(round(s.output_delay_s * NS_PER_S)) if s.output_delay_s else 0
        imu.set_stamp_ns('stamp', now_ns + delay_ns)
        imu.put('rate', *s.gyro_rad_s.tolist())
        if self._p['pass_through_linear_acceleration'] and accel is not None:
            imu.put('accel', *accel)
            if not self._accel_shown:
                imu.put('accel_cov0', 0.0)
                self._accel_shown = True
        elif self._accel_shown:
            imu.put('accel', 0.0, 0.0, 0.0)
            imu.put('accel_cov0', -1.0)
            self._accel_shown = False
        self._imu_pub.publish(imu.payload())
        if self._p['publish_truth']:
            for pub, msg, vec in zip(self._truth_pubs, self._truth_msgs,
                                     (s.true_rate_rad_s, s.bias_rad_s, s.scale_factor)):
                msg.set_stamp_ns('stamp', now_ns)
                msg.put('value', *vec.tolist())
                pub.publish(msg.payload())
        self._tick_count += 1
        if self._tick_count % self._temp_every == 0:
            self._temp_msg.set_stamp_ns('stamp', now_ns)
            self._temp_msg.put('value', float(s.die_temp_c))
            self._temp_pub.publish(self._temp_msg.payload())
        self._book.sample(s.saturated)

    # --- diagnostics ----------------------------------------------------------

    def situation(self):
        """Return the node's current state as diagnostics key/values."""
        now_ns = self._now_ns()
        s = self._last_sample
        p = self._p
        if p['temperature_override_enabled']:
            source = 'override'
        elif self._temp_cmd.accepted:
            source = 'command'
        else:
            source = 'initial_temperature_c'
        return {
            'stale': self._stale, 'stale_policy': p['stale_rate_policy'],
            'rate_age_s': self._rate_cmd.age_s(now_ns),
            'rate_source': p['rate_source'],
            'ambient_temp_c': self._ambient_c,
            'temperature_source': source,
            'die_temp_c': None if s is None else float(s.die_temp_c),
            'noise_enabled': p['noise_enabled'],
            'commands_accepted.rate': self._rate_cmd.accepted,
            'commands_accepted.temperature': self._temp_cmd.accepted,
            'commands_accepted.linear_acceleration': self._accel_cmd.accepted,
            'commands_pending': sum(len(c.pending) for c in (
                self._rate_cmd, self._temp_cmd, self._accel_cmd)),
            'output_delay_s': None if s is None else float(s.output_delay_s),
            'model_calls': self._stepper.model_calls,
            'model_rewinds': self._stepper.rewinds,
            'sensor_config': p['sensor_config'],
            'seed': p['seed'],
        }

    def _diagnose(self):
        now = time.monotonic()
        elapsed, self._diag_last = now - self._diag_last, now
        sim = self.get_parameter('use_sim_time').value
        report = self._book.report(elapsed, self.rate_hz, self.situation(),
                                   check_rate=not sim)
        self._diag_pub.publish(diagnostics.to_msg(
            report, self.get_clock().now().to_msg(), f'{self.get_fully_qualified_name()}: gyro',
            f'gyro_emulator/{self._p["sensor_config"]}'))

    def summary(self):
        """One line of totals for the shutdown log."""
        book = self._book
        return (f'{book.samples} samples, {sum(book.rejected.values())} inputs rejected, '
                f'{sum(book.clamped.values())} clamped, {book.model_errors} model errors')


def _first_line(exc):
    """Return an exception's message on one line (rcl appends source locations)."""
    text = str(exc).split(', at /')[0]
    return ' '.join(text.split())


def main(args=None):
    """Run the node until SIGINT or SIGTERM; return the exit status."""
    try:
        rclpy.init(args=args)
    except Exception as exc:  # noqa: B902 - rcl reports bad arguments and params files so
        print(f'gyro_emulator node: error: cannot start ROS: {_first_line(exc)}',
              file=sys.stderr)
        return 2
    node = None
    try:
        try:
            node = GyroEmulatorNode()
        except (ValueError, ParameterException, OSError) as exc:
            print(f'gyro_emulator node: error: {_first_line(exc)}', file=sys.stderr)
            return 2
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        # rclpy's SIGINT/SIGTERM handler shuts the context down and wakes the
        # executor. Waiting at most SHUTDOWN_POLL_S re-checks the context even if
        # that wake-up is missed while nothing else is due (a paused /clock).
        while spin_once(executor, SHUTDOWN_POLL_S):
            pass
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            line = f'shutting down: {node.summary()}'
            if rclpy.ok():
                node.get_logger().info(line)
            else:
                # The signal handler already shut the context down: no rosout.
                print(f'[gyro_emulator] {line}', file=sys.stderr)
        close(node)
    return 0


if __name__ == '__main__':
    sys.exit(main())
