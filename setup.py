"""
Build script for the gyro_emulator ament_python package.

The ROS executables have two names. ``ros2 run gyro_emulator node`` finds
``<prefix>/lib/gyro_emulator/node``: the directory setup.cfg's
``script_dir``/``install_scripts`` points colcon at, as for any ament_python
package. A pip install puts console scripts on PATH (``.venv/bin``), where
``node`` would hide Node.js; there they are ``gyro-emulator-node`` and so on.
The console_scripts entries carry the PATH names, and the two commands that
write them (``install_scripts`` for ``colcon build``, ``develop`` for
``colcon build --symlink-install``) drop the ``gyro-emulator-`` prefix when
they write into ``lib/gyro_emulator``. Wheels (pip) contain no entry-point
scripts: pip writes them into ``bin`` under their entry names.

``setup.py install`` (what ``colcon build`` runs) ends by compiling the
sensor kernel into numba's cache beside the installed modules
(``python -m gyro_emulator.sensor.warm_cache``), so the first ``ros2 run
gyro_emulator node`` of a fresh install loads it instead of compiling; a
failure there only warns (the first start compiles then).
``GYRO_EMULATOR_NO_WARM=1`` skips it. A wheel build (pip) is not an
install: ``./dev.sh setup`` warms its venv after pip.
"""

from glob import glob
import os
import subprocess
import sys

from setuptools import find_packages, setup
from setuptools.command.develop import develop
from setuptools.command.install import install
from setuptools.command.install_scripts import install_scripts

package_name = 'gyro_emulator'

#: ``ros2 run gyro_emulator <name>`` -> entry point (gyro_emulator.cli.executables).
ROS_EXECUTABLES = {
    'node': 'run_node',
    'scenario': 'run_scenario',
    'recorder': 'run_recorder',
    'replay': 'run_replay',
    'array': 'run_array',
}
#: Prefix of the ROS executables' names on PATH.
PATH_PREFIX = 'gyro-emulator-'


def ament_script_name(directory, script_name):
    """Return the name ``script_name`` gets in ``directory`` (short in lib/<package>)."""
    in_ament_layout = os.path.normpath(directory).split(os.sep)[-2:] == ['lib', package_name]
    short = script_name[len(PATH_PREFIX):]
    if in_ament_layout and script_name.startswith(PATH_PREFIX) and short in ROS_EXECUTABLES:
        return short
    return script_name


class InstallScripts(install_scripts):
    """``setup.py install`` (colcon build): short names in lib/gyro_emulator."""

    def write_script(self, script_name, contents, mode='t', *ignored):
        """Write the script under its ament name (see the module docstring)."""
        super().write_script(ament_script_name(self.install_dir, script_name), contents, mode,
                             *ignored)


class Develop(develop):
    """``setup.py develop`` (colcon build --symlink-install): the same names."""

    def write_script(self, script_name, contents, mode='t', blockers=()):
        """Write the script under its ament name (see the module docstring)."""
        super().write_script(ament_script_name(self.script_dir, script_name), contents, mode,
                             blockers)


class Install(install):
    """``setup.py install`` (colcon build): then warm the kernel cache of the installed copy."""

    def run(self):
        """Install, then compile the sensor kernel into the install's numba cache."""
        super().run()
        if self.root is not None or os.environ.get('GYRO_EMULATOR_NO_WARM'):
            return          # a wheel's staging folder (pip), or asked not to
        env = dict(os.environ)
        env['PYTHONPATH'] = self.install_lib + (os.pathsep + env['PYTHONPATH']
                                                if env.get('PYTHONPATH') else '')
        # cwd: the install, so that ``-m`` imports the installed copy, not the source.
        done = subprocess.run([sys.executable, '-m', 'gyro_emulator.sensor.warm_cache'],
                              cwd=self.install_lib, env=env, check=False)
        if done.returncode:
            print('gyro_emulator: warning: the sensor kernel was not cached; the first '
                  'start compiles it', file=sys.stderr)


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
    cmdclass={'install': Install, 'install_scripts': InstallScripts, 'develop': Develop},
    entry_points={
        'console_scripts': [
            'gyro-emulator = gyro_emulator.cli.executables:run_cli',
        ] + [f'{PATH_PREFIX}{name} = gyro_emulator.cli.executables:{function}'
             for name, function in ROS_EXECUTABLES.items()],
    },
)
