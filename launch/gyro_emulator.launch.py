"""
Start the gyro emulator node with its configuration.

    ros2 launch gyro_emulator gyro_emulator.launch.py
    ros2 launch gyro_emulator gyro_emulator.launch.py params_file:=my_gyro.yaml \
        namespace:=gyro use_sim_time:=true

Needs the ROS 2 ``launch`` and ``launch_ros`` packages (a ROS 2 Jazzy
install). They are not on PyPI; in the pip-only venv
``gyro-emulator ros launch gyro_emulator gyro_emulator.launch.py [NAME:=VALUE ...]``
reads this file and starts the node it names, with the same arguments.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    """Return the launch description: one emulator node, parameters from YAML."""
    default_params = os.path.join(
        get_package_share_directory('gyro_emulator'), 'config', 'gyro_emulator.yaml')
    params_file = LaunchConfiguration('params_file')
    namespace = LaunchConfiguration('namespace')
    use_sim_time = LaunchConfiguration('use_sim_time')
    return LaunchDescription([
        DeclareLaunchArgument('params_file', default_value=default_params,
                              description='node parameters (a copy of gyro_emulator.yaml)'),
        DeclareLaunchArgument('namespace', default_value='',
                              description='namespace of the node and its topics'),
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='follow /clock'),
        Node(
            package='gyro_emulator',
            executable='node',
            name='gyro_emulator',
            namespace=namespace,
            parameters=[params_file, {'use_sim_time': use_sim_time}],
            output='screen',
            emulate_tty=True,
        ),
    ])
