"""Build script for the gyro_emulator ament_python package."""

from glob import glob
import os

from setuptools import find_packages, setup

package_name = 'gyro_emulator'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages',
            ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        (os.path.join('share', package_name, 'config'), glob('config/*.yaml')),
        (os.path.join('share', package_name, 'launch'),
            glob('launch/*.launch.py')),
    ],
    include_package_data=True,
    package_data={package_name: ['presets/*.yaml']},
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='gyro_emulator maintainers',
    maintainer_email='gyro-emulator@example.com',
    description='A virtual MEMS vibratory gyroscope for ROS 2, built from physics.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'gyro-emulator = gyro_emulator.cli.executables:run_cli',
            'node = gyro_emulator.cli.executables:run_node',
            'scenario = gyro_emulator.cli.executables:run_scenario',
            'recorder = gyro_emulator.cli.executables:run_recorder',
            'replay = gyro_emulator.cli.executables:run_replay',
            'array = gyro_emulator.cli.executables:run_array',
        ],
    },
)
