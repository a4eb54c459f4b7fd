"""
Start N gyro emulator nodes from an array spec (redundant IMUs).

    ros2 launch gyro_emulator gyro_array.launch.py
    ros2 launch gyro_emulator gyro_array.launch.py spec:=my_array.yaml use_sim_time:=true

The spec (default ``config/gyro_array.yaml``) gives each instance its preset,
parameters and tolerances (``gyro_emulator.ros.gyro_array``). Without the ``ros2``
CLI (the pip-only venv), ``gyro-emulator ros launch gyro_emulator gyro_array.launch.py``
reads this file, and ``gyro-emulator-array [SPEC]`` starts the same nodes.
"""

import os

from ament_index_python.packages import get_package_share_directory
from gyro_emulator.ros import gyro_array
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def _nodes(context):
    spec = LaunchConfiguration('spec').perform(context)
    sim = LaunchConfiguration('use_sim_time').perform(context).lower() == 'true'
    return [Node(package='gyro_emulator', executable='node', name='gyro_emulator',
                 namespace=instance.namespace,
                 parameters=[dict(instance.parameters, use_sim_time=sim)],
                 output='screen', emulate_tty=True)
            for instance in gyro_array.load_spec(spec)]


def generate_launch_description():
    """Return the launch description: one emulator node per instance of the spec."""
    default_spec = os.path.join(get_package_share_directory('gyro_emulator'), 'config',
                                'gyro_array.yaml')
    return LaunchDescription([
        DeclareLaunchArgument('spec', default_value=default_spec,
                              description='array spec (a copy of gyro_array.yaml)'),
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='follow /clock'),
        OpaqueFunction(function=_nodes),
    ])
