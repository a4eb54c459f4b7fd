"""
``ros2 run gyro_emulator node``: the sensor model as a ROS 2 gyro driver.

A thin node over a pure driver (:class:`gyro_emulator.emulation.driver.core.Driver`):
the node declares the parameters, subscribes, runs the timers and turns the
driver's output records into messages; the driver decides which samples are
due, with which inputs, stamps and faults. With ``input_source: command``
(the default) a timer on the node clock (sim time under ``use_sim_time``)
wakes the node once per sample period, 1 / ``rate_hz`` (the part's period,
with its clock drift), and the node publishes every sample whose sample time
has passed (:mod:`gyro_emulator.emulation.driver.sample_clock`): one per tick
when the timer keeps up, a burst stamped with each sample's own time when it
was late (CPU load, a coarse ``/clock``), or only the newest with
``overrun_policy: drop``. Each sample takes the commands in force at its
sample time. With ``input_source: imu`` the node follows a simulator
instead: one sample per ``imu/ideal`` message (sensor_msgs/Imu), the time
step from the stamps (:mod:`gyro_emulator.emulation.driver.imu_timeline`).
Either way it publishes (:mod:`.outputs`):

* ``imu/data_raw`` (sensor_msgs/Imu, REP 145/103): the gyro output in rad/s
  and the accelerometer's in m/s^2 (its input the specific force of the
  attitude the driver keeps, :mod:`gyro_emulator.emulation.driver.attitude`),
  each covariance diag(sigma^2) of the model's white noise at this rate,
  orientation absent (``orientation_covariance[0] = -1``); with
  ``publish_linear_acceleration: false`` the acceleration is absent too.
  Stamp = sample instant + the model's output delay (latency and jitter);
  reliability ``qos_reliability``.
* ``imu/temperature`` (sensor_msgs/Temperature): die temperature, deg C.
* ``~/truth/rate``, ``~/truth/bias``, ``~/truth/scale_factor``
  (geometry_msgs/Vector3Stamped, stamped at the sample instant): true rate
  (rad/s), total bias (rad/s) and total gain (ratio) of the same sample;
  ``~/truth/imu`` (sensor_msgs/Imu): the true attitude, rate and specific force;
  ``~/truth/fault`` (diagnostic_msgs/DiagnosticArray, latched) on each change
  of the injected fault (:mod:`gyro_emulator.emulation.driver.fault_state`).
* ``/diagnostics`` (diagnostic_msgs/DiagnosticArray), see
  :mod:`gyro_emulator.emulation.driver.book`.

It subscribes to ``cmd/angular_velocity`` (geometry_msgs/Vector3Stamped,
rad/s, sensor frame) or, with ``rate_source = odometry``, ``cmd/odom``
(nav_msgs/Odometry, twist.twist.angular), to ``cmd/temperature``
(sensor_msgs/Temperature, ambient deg C) and ``cmd/linear_acceleration``
(geometry_msgs/Vector3Stamped, the applied linear acceleration, body frame,
m/s^2), through :mod:`.intake`; input rules:
:mod:`gyro_emulator.emulation.driver.commands`. ``--help`` prints the
parameters and topics and exits.
"""

import functools
import sys

from gyro_emulator.emulation.driver.core import Driver
from gyro_emulator.emulation.driver.parameters import SEED_FROM_NAME
from gyro_emulator.recording import topics
from gyro_emulator.ros import diagnostics, node_help, params, spinning
from gyro_emulator.ros.intake import Intake
from gyro_emulator.ros.outputs import OutputStage
from gyro_emulator.ros.self_record import SelfRecorder
from gyro_emulator.sensor.config import load_sensor_config
from gyro_emulator.sensor.streams import seed_from_name
from gyro_emulator.sensor.warm_cache import warm_up
from gyro_emulator.units import NS_PER_S
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock as RosClock, ClockType
from rclpy.node import Node


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
        values = params.declare_node_parameters(self)
        self.rate_hz = values['rate_hz']
        self.frame_id = values['frame_id']
        base = load_sensor_config(values['sensor_config'])
        sensor_values = params.declare_sensor_parameters(self, base)
        self.seed = values['seed']
        if self.seed == SEED_FROM_NAME:
            self.seed = seed_from_name(self.get_fully_qualified_name())
        self._imu_mode = values['input_source'] == 'imu'
        self._intake = Intake(None if self._imu_mode
                              else topics.RATE_INPUTS[values['rate_source']])
        self._driver = Driver(values, base, self.seed, sensor_values,
                              follow_timer=not self.get_parameter('use_sim_time').value,
                              log=self.get_logger(), commands=self._intake)
        self._pending = None
        params.check_qos_overrides(self)
        self._out = OutputStage(self, self.frame_id, values['qos_reliability'])
        # Before the first publish (the fault state at start), so the bag holds all of it.
        self._self_recorder = None
        if values['record_dir']:
            self._self_recorder = SelfRecorder(self, self._out, values['record_dir'])
        self._name = self.get_fully_qualified_name()
        self._hardware_id = f'gyro_emulator/{values["sensor_config"]}'
        self._timer = None
        self._drain_timer = None
        if not self._imu_mode:
            # The part's clock drift sets its output data rate (sample period), so
            # the stamps stay tied to the ROS clock.
            self._timer = self.create_timer(self._driver.sample_period_s, self._tick)
        self._intake.subscribe(self, self._on_imu if self._imu_mode else None)
        self._publish_faults(self._driver.start(self._now_ns()))
        self._diagnostics = diagnostics.DiagnosticsThread(
            self, values['diagnostics_period_s'], self._diagnose)
        self.add_pre_set_parameters_callback(self._screen_parameters)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        for name in params.unknown_overrides(self):
            self.get_logger().warning(f'parameter {name!r} is unknown and ignored')
        self._log_start(values)

    def _log_start(self, values):
        lo, hi = self._driver.limits.temp_range_c
        seed = f'seed {self.seed}' + (' (from the node name)'
                                      if values['seed'] == SEED_FROM_NAME else '')
        source = ('imu/ideal, one output per message' if self._imu_mode
                  else f'{self.rate_hz:g} Hz, rate from {values["rate_source"]}')
        self.get_logger().info(
            f'gyro emulator up: {source}, sensor_config {values["sensor_config"]!r}, '
            f'{seed}, frame {self.frame_id!r}, ambient range [{lo:g}, {hi:g}] C')

    def _now_ns(self):
        return self.get_clock().now().nanoseconds

    # --- parameters: validate the whole set, then apply it -------------------

    def _screen_parameters(self, parameters):
        parameters = params.integers_as_doubles(parameters)
        self._driver.screen((p.name, p.value) for p in parameters)
        return parameters

    def _validate_parameters(self, parameters):
        try:
            self._pending = self._driver.prepare((p.name, p.value) for p in parameters)
        except ValueError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters):
        change, self._pending = self._pending, None
        if change is None:
            return
        applied = self._driver.apply(change, self._now_ns())
        if applied.model_changed:
            self._retime()
        self._publish_faults(applied.faults)
        self.get_logger().info('parameters set: ' + ', '.join(
            f'{q.name} = {q.value!r}' for q in parameters))

    def _retime(self):
        """Follow a new sample period (a changed clock drift) with a new timer."""
        if self._timer is None:
            return
        period_s = self._driver.sample_period_s
        if abs(self._timer.timer_period_ns - period_s * NS_PER_S) >= 1.0:
            self.destroy_timer(self._timer)
            self._timer = self.create_timer(period_s, self._tick)

    # --- publishing ------------------------------------------------------------

    def _publish(self, outputs):
        truth = self._driver.values['publish_truth']
        for output in outputs:
            self._out.publish(output, truth)
            if output.fault is not None:
                self._publish_faults((output.fault,))

    def _publish_faults(self, reports):
        for report in reports:
            self._out.publish_fault(report, f'{self._name}: fault', self._hardware_id)

    @_while_up
    def _tick(self):
        """Publish the samples that came due since the last tick."""
        outputs = self._driver.tick(self._now_ns())
        if self._driver.backlog:
            # The rest of the burst goes out one period later, whatever the node clock does.
            if self._drain_timer is None:
                self._drain_timer = self.create_timer(
                    self._driver.backlog_period_s, self._drain,
                    clock=RosClock(clock_type=ClockType.STEADY_TIME))
            elif self._drain_timer.is_canceled():
                self._drain_timer.reset()
        self._publish(outputs)

    @_while_up
    def _drain(self):
        """Publish the next burst of the backlog (a steady timer: also while /clock stands)."""
        if not self._driver.backlog:
            self._drain_timer.cancel()
            return
        self._publish(self._driver.drain())

    @_while_up
    def _on_imu(self, msg):
        """Publish the one sample of an ``imu/ideal`` message."""
        stamp = msg.header.stamp
        v, a = msg.angular_velocity, msg.linear_acceleration
        # REP 145: covariance element 0 = -1 marks the acceleration absent (values ignored).
        accel = None if msg.linear_acceleration_covariance[0] == -1.0 else (a.x, a.y, a.z)
        self._publish(self._driver.ideal_imu(stamp.sec * NS_PER_S + stamp.nanosec,
                                             (v.x, v.y, v.z), accel))

    # --- diagnostics and teardown --------------------------------------------

    def situation(self):
        """Return the node's current state as diagnostics key/values."""
        timer = self._timer
        recorder = self._self_recorder
        return self._driver.situation(
            self._now_ns(), None if timer is None else timer.timer_period_ns / NS_PER_S,
            None if recorder is None else (recorder.path, recorder.error))

    def _diagnose(self, elapsed_s):
        sim = self.get_parameter('use_sim_time').value
        # Off the wall clock, no sample at all is said (a missing /clock bridge), not a pause.
        waiting = 'imu/ideal' if self._imu_mode else ('/clock' if sim else None)
        report = self._driver.report(elapsed_s, self.situation(),
                                     check_rate=not (sim or self._imu_mode), waiting_for=waiting)
        self._out.diag_pub.publish(diagnostics.to_msg(
            report, self.get_clock().now().to_msg(), f'{self._name}: gyro', self._hardware_id))

    def summary(self):
        """One line of totals for the shutdown log."""
        return self._driver.summary()

    def destroy_node(self):
        """Stop the diagnostics thread, finish the self-recording and destroy the node."""
        thread = getattr(self, '_diagnostics', None)
        if thread is not None:
            thread.stop()
            self._diagnostics = None
        recorder = getattr(self, '_self_recorder', None)
        if recorder is not None:
            recorder.finish()
        return super().destroy_node()


def main(args=None):
    """Run the node until SIGINT or SIGTERM; return the exit status."""
    argv = sys.argv[1:] if args is None else list(args)
    if node_help.wants_help(argv):
        print(node_help.help_text())
        return 0
    return spinning.run_node(GyroEmulatorNode, args, 'gyro_emulator node', warm_up=warm_up)


if __name__ == '__main__':
    sys.exit(main())
