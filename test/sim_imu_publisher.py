"""
A stand-in simulator for the tests: ``/clock`` and an ideal IMU on sim time.

    python test/sim_imu_publisher.py OUT.json --subscribers N [--topic imu/ideal]

It waits until ``N`` subscribers match ``/clock`` and the Imu topic, then
plays its phases at ``--rate-hz`` of sim time. Each message: ``/clock`` set
to the sample's sim time, then a sensor_msgs/Imu stamped with it (z rate
``--rate-z``, specific force +1 g on z plus 1e-4 k m/s^2 on x for message k,
so every message can be told apart). Phases: ``--fast`` messages at 2x real
time, a ``cmd/temperature`` of ``--temp-c``, ``--slow`` messages at 0.5x, a
pause of ``--pause-s`` wall seconds with the clock stopped, then the clock
jumps back ``--jump-s`` and ``--after`` more messages follow at 1x. It
writes what it sent (stamps in ns, the index where each phase began) to
OUT.json once every reliable subscriber has acknowledged it.
"""

import argparse
import json
import sys
import time

NS = 1_000_000_000


def main(argv=None):
    """Play the phases; return 0 (1 if subscribers never matched)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('out')
    parser.add_argument('--subscribers', type=int, default=1)
    parser.add_argument('--topic', default='imu/ideal')
    parser.add_argument('--rate-hz', type=float, default=250.0)
    parser.add_argument('--rate-z', type=float, default=0.5)
    parser.add_argument('--fast', type=int, default=250)
    parser.add_argument('--slow', type=int, default=100)
    parser.add_argument('--after', type=int, default=150)
    parser.add_argument('--pause-s', type=float, default=0.5)
    parser.add_argument('--jump-s', type=float, default=2.0)
    parser.add_argument('--temp-c', type=float, default=40.0)
    opts = parser.parse_args(argv)

    import rclpy
    from rclpy.duration import Duration
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Imu, Temperature

    rclpy.init()
    node = rclpy.create_node('sim')
    deep = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5000,
                      reliability=ReliabilityPolicy.RELIABLE)
    clock_pub = node.create_publisher(Clock, '/clock', 10)
    imu_pub = node.create_publisher(Imu, opts.topic, deep)
    temp_pub = node.create_publisher(Temperature, 'cmd/temperature', 10)
    deadline = time.monotonic() + 60.0
    while (imu_pub.get_subscription_count() < opts.subscribers or
           clock_pub.get_subscription_count() < opts.subscribers):
        if time.monotonic() > deadline:
            return 1
        time.sleep(0.02)
    dt_ns = int(round(NS / opts.rate_hz))
    t_ns = 50 * NS
    sent, phases = [], {}
    clock, imu = Clock(), Imu()
    imu.header.frame_id = 'sim_imu'

    def publish(speed):
        nonlocal t_ns
        clock.clock.sec, clock.clock.nanosec = divmod(t_ns, NS)
        clock_pub.publish(clock)
        imu.header.stamp = clock.clock
        imu.angular_velocity.z = opts.rate_z
        imu.linear_acceleration.x = 1e-4 * len(sent)
        imu.linear_acceleration.z = 9.80665
        imu_pub.publish(imu)
        sent.append(t_ns)
        t_ns += dt_ns
        time.sleep(dt_ns / NS / speed)

    phases['fast'] = len(sent)
    for _ in range(opts.fast):
        publish(2.0)
    temp = Temperature(temperature=opts.temp_c)
    temp.header.stamp = clock.clock
    temp_pub.publish(temp)
    phases['slow'] = len(sent)
    for _ in range(opts.slow):
        publish(0.5)
    phases['pause'] = len(sent)
    time.sleep(opts.pause_s)
    t_ns -= int(opts.jump_s * NS)
    phases['jump'] = len(sent)
    for _ in range(opts.after):
        publish(1.0)
    imu_pub.wait_for_all_acked(Duration(seconds=20))
    with open(opts.out, 'w') as handle:
        json.dump({'stamps_ns': sent, 'phases': phases, 'dt_ns': dt_ns}, handle)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
