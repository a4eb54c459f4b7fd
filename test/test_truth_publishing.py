"""The node's truth topics are built only for a subscriber (volatile QoS: nothing is lost)."""

import time

from conftest import ros_env
from geometry_msgs.msg import Vector3Stamped
from gyro_emulator.emulation.driver.records import AccelChannel, GyroChannel, Output
from gyro_emulator.ros.outputs import OutputStage
import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import qos_profile_sensor_data


def _output(k):
    """Return the k-th sample of a made-up record (only the truth fields matter here)."""
    rate = np.array([0.1 * k, -0.2, 0.3])
    return Output(k * 1000, k * 1000, True, 25.0, False,
                  GyroChannel((0.0, 0.0, 0.0), (0.0,) * 9, rate, 0.5 * rate, 1.0 + rate,
                              np.zeros(3, dtype=bool)),
                  AccelChannel((0.0, 0.0, 9.8), (0.0,) * 9, (0.0, 0.0, 9.8)), True,
                  (1.0, 0.0, 0.0, 0.0), None)


def _wait(condition, executor, timeout_s=20.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, 'timed out'
        executor.spin_once(timeout_sec=0.05)


def test_a_truth_topic_is_built_only_while_someone_subscribes_and_then_every_sample():
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=int(ros_env()['ROS_DOMAIN_ID']))
    try:
        node = rclpy.create_node('gyro_emulator', context=context)
        stage = OutputStage(node, 'imu_link')
        pubs = [*stage.truth_pubs, stage.truth_imu_pub]
        assert all(pub.qos_profile.durability.name == 'VOLATILE' for pub in pubs)
        built = [0] * len(pubs)
        for i, pub in enumerate(pubs):
            def counted(payload, i=i, publish=pub.publish):
                built[i] += 1
                publish(payload)
            pub.publish = counted
        for k in range(3):
            stage.publish(_output(k))
        assert built == [0, 0, 0, 0]                    # nobody listens: nothing built
        probe = rclpy.create_node('probe', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(probe)
        got = []
        probe.create_subscription(Vector3Stamped, '/gyro_emulator/truth/bias', got.append,
                                  qos_profile_sensor_data)
        _wait(lambda: stage.truth_pubs[1].get_subscription_count() == 1, executor)
        for k in range(3, 8):
            stage.publish(_output(k))
        assert built == [0, 5, 0, 0]                    # the subscribed one, every sample
        _wait(lambda: len(got) == 5, executor)
        assert [m.vector.x for m in got] == [0.5 * (0.1 * k) for k in range(3, 8)]
        stage.publish(_output(8), truth=False)
        assert built == [0, 5, 0, 0]                    # publish_truth false: none
    finally:
        rclpy.try_shutdown(context=context)
