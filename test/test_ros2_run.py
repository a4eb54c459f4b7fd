"""
``ros2 run gyro_emulator node`` works: colcon build, resolve, run, receive.

The package is built with colcon (from PyPI) into a temporary workspace. The
executable is then found exactly as ``ros2 run`` finds it: the package prefix
from the ament index (``ament_index_python.get_package_prefix`` over
``AMENT_PREFIX_PATH``), then ``<prefix>/lib/gyro_emulator/<executable>``. The
installed node and scenario run from that install, not from the source tree.

The executables are named twice (issue 25): ``lib/gyro_emulator/node`` and
its siblings for ``ros2 run``, from both ``colcon build`` and ``colcon build
--symlink-install``; ``gyro-emulator-node`` and so on in the venv's ``bin``,
where a bare ``node`` would hide Node.js.
"""

import os
import shutil
import signal
import subprocess
import sys

from conftest import ros_env
import pytest
from test_node import Probe
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE_FILES = ('setup.py', 'setup.cfg', 'package.xml', 'resource', 'gyro_emulator',
                 'config', 'launch')
pytestmark = pytest.mark.ros


#: ``ros2 run gyro_emulator <name>``: what lib/gyro_emulator holds after colcon build.
ROS_EXECUTABLES = ('array', 'node', 'recorder', 'replay', 'scenario')


def colcon_build(ws, *options, base='install'):
    """Run ``colcon build`` of ws/src into ws/<base>; assert it succeeded."""
    colcon = os.path.join(os.path.dirname(sys.executable), 'colcon')
    proc = subprocess.run(
        [colcon, '--log-base', str(ws / 'log'), 'build', '--base-paths', str(ws / 'src'),
         '--build-base', str(ws / ('build-' + base)), '--install-base', str(ws / base)]
        + list(options), cwd=ws, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr


@pytest.fixture(scope='module')
def workspace(tmp_path_factory):
    """Copy the package into src/ of a fresh workspace and colcon build it."""
    ws = tmp_path_factory.mktemp('ws')
    src = ws / 'src' / 'gyro_emulator'
    src.mkdir(parents=True)
    for name in PACKAGE_FILES:
        path = os.path.join(ROOT, name)
        if os.path.isdir(path):
            shutil.copytree(path, src / name,
                            ignore=shutil.ignore_patterns('__pycache__', '*.pyc'))
        else:
            shutil.copy(path, src / name)
    colcon_build(ws)
    return ws


def installed_site(workspace):
    """Return the install's site-packages folder."""
    return os.path.join(str(workspace / 'install' / 'gyro_emulator'), 'lib',
                        f'python{sys.version_info[0]}.{sys.version_info[1]}', 'site-packages')


def installed_env(workspace, monkeypatch):
    """Environment of a shell that sourced the temporary install (and the venv)."""
    prefix = str(workspace / 'install' / 'gyro_emulator')
    site = installed_site(workspace)
    ament = prefix + os.pathsep + sys.prefix
    monkeypatch.setenv('AMENT_PREFIX_PATH', ament)
    env = ros_env()
    env['AMENT_PREFIX_PATH'] = ament
    env['PYTHONPATH'] = site
    return env, site


def ros2_run_path(executable):
    """Resolve ``ros2 run gyro_emulator <executable>`` like ros2run does."""
    from ament_index_python.packages import get_package_prefix
    return os.path.join(get_package_prefix('gyro_emulator'), 'lib', 'gyro_emulator',
                        executable)


def test_ros2_run_node_publishes_imu_from_the_colcon_install(workspace, monkeypatch,
                                                             tmp_path):
    env, site = installed_env(workspace, monkeypatch)
    node_exe = ros2_run_path('node')
    assert node_exe == str(workspace / 'install' / 'gyro_emulator' / 'lib' /
                           'gyro_emulator' / 'node')
    assert os.access(node_exe, os.X_OK)
    assert os.access(ros2_run_path('scenario'), os.X_OK)
    share = workspace / 'install' / 'gyro_emulator' / 'share' / 'gyro_emulator'
    for name in ('config/gyro_emulator.yaml', 'config/scenario_paper_validation.yaml',
                 'launch/gyro_emulator.launch.py', 'package.xml'):
        assert (share / name).is_file(), name
    log = tmp_path / 'node.log'
    with open(log, 'w') as handle:  # the shipped defaults: the paper preset at 200 Hz
        proc = subprocess.Popen([node_exe, '--ros-args', '-p', 'frame_id:=installed'],
                                env=env, cwd=str(tmp_path), stdout=handle,
                                stderr=subprocess.STDOUT)
    probe = Probe(env)
    try:
        from sensor_msgs.msg import Imu
        got = probe.listen(Imu, 'imu/data_raw')
        # A hang guard, not a speed limit (bench/bench_startup.py times the start).
        probe.spin_until(lambda: len(got) >= 10, 600.0, 'Imu from the installed node')
        assert all(m.header.frame_id == 'installed' for m in got)
        # The installed scenario executable plays a short profile onto it.
        profile = tmp_path / 'short.yaml'
        profile.write_text(yaml.safe_dump({'name': 'short', 'segments': [
            # 2 s steps: a node stalled for a few hundred ms by a loaded machine
            # still leaves samples in each step's measured second
            {'duration_s': 2.0, 'rate_deg_s': 0.0, 'temp_c': 25.0, 'settle_s': 1.0},
            {'duration_s': 2.0, 'rate_deg_s': 90.0, 'temp_c': 25.0,
             'settle_s': 1.0}]}))
        scenario = subprocess.run([ros2_run_path('scenario'), str(profile), '--summary'],
                                  env=env, cwd=str(tmp_path), capture_output=True,
                                  text=True, timeout=60)
    finally:
        probe.close()
        proc.send_signal(signal.SIGINT)
        code = proc.wait(120)
    assert scenario.returncode == 0, scenario.stderr
    rows = [line.split() for line in scenario.stdout.splitlines()
            if line.strip().startswith(('0 ', '1 '))]
    assert len(rows) == 2 and rows[1][3:6] == ['90', 'deg/s', '90.000']
    assert abs(float(rows[1][6]) - 90.0) < 1.0  # measured deg/s at the calibration temp
    text = log.read_text()
    assert code == 0 and 'Traceback' not in text, text
    # It ran the installed copy: its modules come from the workspace install.
    check = subprocess.run([sys.executable, '-c', 'import gyro_emulator.ros.node as n; '
                            'print(n.__file__)'], env=env, cwd=str(tmp_path),
                           capture_output=True, text=True)
    assert check.stdout.strip().startswith(site)


def test_colcon_build_compiles_the_sensor_kernel_into_the_installs_cache(workspace):
    """
    Issue 34: ``setup.py install`` ends with ``python -m gyro_emulator.sensor.warm_cache``.

    numba's cache is keyed to the source file's path, so a fresh install has
    none; the build writes it beside the installed kernel (and byte-compiles
    the modules), so the first ``ros2 run`` only loads it.
    """
    package = os.path.join(installed_site(workspace), 'gyro_emulator')
    cache = os.listdir(os.path.join(package, 'sensor', '__pycache__'))
    assert any(name.startswith('kernel.advance-') and name.endswith('.nbi') for name in cache)
    assert any(name.startswith('kernel.advance-') and name.endswith('.nbc') for name in cache)
    assert any(name.startswith('node.') and name.endswith('.pyc')
               for name in os.listdir(os.path.join(package, 'ros', '__pycache__')))


def test_sourcing_install_setup_sh_finds_the_package_and_its_executables(workspace, tmp_path):
    """
    Issue 15: colcon-core writes ``install/setup.sh`` (no ``setup.bash`` without colcon-bash).

    Sourced in the dev shell's environment (``ros_env``: the venv on PATH and in
    AMENT_PREFIX_PATH), it puts the install first, so ``ros2 run`` would find
    ``lib/gyro_emulator/array`` and ``node``; ``node --help`` runs from there.
    """
    assert (workspace / 'install' / 'setup.sh').is_file()
    env = ros_env()
    env['PATH'] = os.path.dirname(sys.executable) + os.pathsep + env.get('PATH', '')
    script = ('. "$WS/install/setup.sh" && python -c "from ament_index_python.packages '
              'import get_package_prefix as p; print(p(\'gyro_emulator\'))" && '
              '"$(python -c "from ament_index_python.packages import get_package_prefix '
              'as p; print(p(\'gyro_emulator\'))")/lib/gyro_emulator/node" --help')
    proc = subprocess.run(['sh', '-c', script], env=dict(env, WS=str(workspace)),
                          cwd=str(tmp_path), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    prefix = proc.stdout.splitlines()[0]
    assert prefix == str(workspace / 'install' / 'gyro_emulator')
    assert 'imu/data_raw' in proc.stdout and 'fault.type' in proc.stdout
    assert os.access(os.path.join(prefix, 'lib', 'gyro_emulator', 'array'), os.X_OK)


@pytest.mark.parametrize('options,base', [((), 'install'),
                                          (('--symlink-install',), 'install-symlink')])
def test_lib_holds_the_ros2_run_names_and_the_venv_bin_the_prefixed_ones(workspace, options,
                                                                         base, tmp_path):
    """
    Both colcon builds: setup.py install, and setup.py develop (--symlink-install).

    lib/gyro_emulator holds ``node`` and its siblings (plus ``gyro-emulator``);
    the pip-installed venv's bin holds ``gyro-emulator-node`` and no bare
    ``node``, ``array``, ``recorder``, ``replay`` or ``scenario``.
    """
    if base != 'install':
        colcon_build(workspace, *options, base=base)
    lib = workspace / base / 'gyro_emulator' / 'lib' / 'gyro_emulator'
    assert sorted(os.listdir(lib)) == sorted(ROS_EXECUTABLES + ('gyro-emulator',))
    assert all(os.access(lib / name, os.X_OK) for name in ROS_EXECUTABLES)
    proc = subprocess.run([str(lib / 'array'), '--help'], env=ros_env(), cwd=str(tmp_path),
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and 'spec' in proc.stdout, proc.stderr
    venv_bin = os.path.join(sys.prefix, 'bin')
    for name in ROS_EXECUTABLES:
        assert not os.path.exists(os.path.join(venv_bin, name)), name
        assert os.access(os.path.join(venv_bin, 'gyro-emulator-' + name), os.X_OK), name


def test_the_venv_node_command_is_the_gyro_node_by_its_long_name(tmp_path):
    """``gyro-emulator-node --help`` from the venv's bin prints the node's parameters."""
    proc = subprocess.run([os.path.join(sys.prefix, 'bin', 'gyro-emulator-node'), '--help'],
                          env=ros_env(), cwd=str(tmp_path), capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0 and 'imu/data_raw' in proc.stdout, proc.stderr


@pytest.mark.parametrize('args,message', [
    (['--ros-args', '--params-file', 'BAD'], 'cannot start ROS: failed to initialize rcl'),
    (['--ros-args', '-p', 'record_dir:=/proc/no/such/dir'],
     "record_dir = '/proc/no/such/dir': cannot write a bag there"),
])
def test_node_start_errors_are_one_line_not_tracebacks(tmp_path, args, message):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('gyro: [1, 2\n')
    args = [str(bad) if a == 'BAD' else a for a in args]
    proc = subprocess.run([sys.executable, '-m', 'gyro_emulator.ros.node'] + args,
                          env=ros_env(), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert message in proc.stderr and 'Traceback' not in proc.stderr, proc.stderr
    ours = [line for line in proc.stderr.splitlines() if 'gyro_emulator node: error' in line]
    assert len(ours) == 1
