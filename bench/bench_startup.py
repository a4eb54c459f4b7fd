"""
Benchmark the node's start: time to its first Imu message after a fresh install.

    .venv/bin/python bench/bench_startup.py                 (venv and colcon, 2 starts each)
    .venv/bin/python bench/bench_startup.py --kinds colcon --starts 3

Each kind installs the package afresh into a temporary folder, the way its
user would, then starts the node there ``--starts`` times in a row:

* ``venv``: what ``./dev.sh setup`` does to the venv, into a temporary
  prefix (``pip install --no-deps --prefix``, then ``dev.sh``'s warm step:
  ``python -m gyro_emulator.warm_cache``); the node is the prefix's
  ``gyro-emulator-node``, the dependencies the running venv's;
* ``colcon``: the package copied into ``src/`` of a temporary workspace and
  ``colcon build`` (its ``install`` step warms the cache); the node is
  ``install/gyro_emulator/lib/gyro_emulator/node``, as ``ros2 run`` finds it.

A start is timed from the node's ``Popen`` to the first ``imu/data_raw``
message that reaches a subscriber of this process (subscribed before the
node starts, on a localhost-only ROS domain of its own), with the shipped
defaults (the paper preset at 200 Hz). The first start of a fresh install
is the one a new user sees; the later ones show the rest of the start-up
(imports, the node's parameters, the model's plan, discovery). Target
(issue 34, on a quiet machine): the first sample within 3 s of the first
start, both kinds. ``--no-warm`` installs without the warm step (the
numba kernels compile at the first start, as before the step existed).
"""

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

import benchenv  # noqa: F401 - one BLAS thread, before numpy loads

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE_FILES = ('setup.py', 'setup.cfg', 'package.xml', 'resource', 'gyro_emulator',
                 'config', 'launch')
PY = f'python{sys.version_info[0]}.{sys.version_info[1]}'


def _env(**extra):
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.setdefault('ROS_DOMAIN_ID', str(10 + os.getpid() % 90))
    env['PYTHONUNBUFFERED'] = '1'
    env.pop('PYTHONPATH', None)
    env.pop('NUMBA_CACHE_DIR', None)
    env.update(extra)
    return env


def copy_package(tmp):
    """Copy the package's files into ``tmp/src/gyro_emulator`` (no caches); return it."""
    src = os.path.join(tmp, 'src', 'gyro_emulator')
    os.makedirs(src)
    for name in PACKAGE_FILES:
        path = os.path.join(ROOT, name)
        if os.path.isdir(path):
            shutil.copytree(path, os.path.join(src, name),
                            ignore=shutil.ignore_patterns('__pycache__', '*.pyc'))
        else:
            shutil.copy(path, os.path.join(src, name))
    return src


def install_venv(tmp, warm):
    """Install as ``./dev.sh setup`` does, into the prefix ``tmp/prefix``; return (exe, env)."""
    prefix = os.path.join(tmp, 'prefix')
    # --ignore-installed: without it pip uninstalls the running venv's own copy first
    subprocess.run([sys.executable, '-m', 'pip', 'install', '-q', '--disable-pip-version-check',
                    '--no-deps', '--no-build-isolation', '--ignore-installed', '--prefix', prefix,
                    copy_package(tmp)], check=True, cwd=tmp)
    env = _env(PYTHONPATH=os.path.join(prefix, 'lib', PY, 'site-packages'),
               AMENT_PREFIX_PATH=prefix + os.pathsep + sys.prefix)
    if warm:
        subprocess.run([sys.executable, '-m', 'gyro_emulator.sensor.warm_cache'], check=True,
                       env=env, cwd=prefix)
    return os.path.join(prefix, 'bin', 'gyro-emulator-node'), env


def install_colcon(tmp, warm):
    """Copy the package into a workspace and ``colcon build`` it; return (exe, env)."""
    copy_package(tmp)
    colcon = os.path.join(os.path.dirname(sys.executable), 'colcon')
    build_env = _env() if warm else _env(GYRO_EMULATOR_NO_WARM='1')
    subprocess.run([colcon, '--log-base', os.path.join(tmp, 'log'), 'build', '--base-paths',
                    os.path.join(tmp, 'src'), '--build-base', os.path.join(tmp, 'build'),
                    '--install-base', os.path.join(tmp, 'install')],
                   check=True, cwd=tmp, env=build_env, stdout=subprocess.DEVNULL)
    prefix = os.path.join(tmp, 'install', 'gyro_emulator')
    env = _env(PYTHONPATH=os.path.join(prefix, 'lib', PY, 'site-packages'),
               AMENT_PREFIX_PATH=prefix + os.pathsep + sys.prefix)
    return os.path.join(prefix, 'lib', 'gyro_emulator', 'node'), env


class Probe:
    """An rclpy subscriber to imu/data_raw in this process."""

    def __init__(self, domain_id):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import qos_profile_sensor_data
        from sensor_msgs.msg import Imu
        self.rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node('startup_probe', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.first = None
        self.node.create_subscription(Imu, 'imu/data_raw', self._on_imu,
                                      qos_profile_sensor_data, raw=True)

    def _on_imu(self, _raw):
        if self.first is None:
            self.first = time.monotonic()

    def first_sample_s(self, exe, env, timeout_s):
        """Start the node, return the seconds to its first Imu here (None: none in time)."""
        self.first = None
        log = tempfile.TemporaryFile()
        started = time.monotonic()
        proc = subprocess.Popen([exe], env=env, stdout=log, stderr=subprocess.STDOUT)
        try:
            while self.first is None and time.monotonic() - started < timeout_s:
                if proc.poll() is not None:
                    log.seek(0)
                    raise RuntimeError(f'the node exited {proc.returncode}:\n'
                                       + log.read().decode(errors='replace'))
                self.executor.spin_once(timeout_sec=0.01)
        finally:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
            log.close()
        return None if self.first is None else self.first - started

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.context)


def main():
    """Install each kind afresh, start its node --starts times; print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--kinds', nargs='+', default=['venv', 'colcon'],
                        choices=['venv', 'colcon'])
    parser.add_argument('--starts', type=int, default=2)
    parser.add_argument('--timeout', type=float, default=300.0, metavar='S',
                        help='longest wait for a first sample (default: %(default)s s)')
    parser.add_argument('--no-warm', action='store_true',
                        help='install without the warm step')
    opts = parser.parse_args()
    env = _env()
    probe = Probe(int(env['ROS_DOMAIN_ID']))
    load = os.getloadavg()[0]
    print(f'load average {load:.2f} on {os.cpu_count()} CPUs; ROS_DOMAIN_ID '
          f'{env["ROS_DOMAIN_ID"]}; warm step {"off" if opts.no_warm else "on"}')
    try:
        for kind in opts.kinds:
            with tempfile.TemporaryDirectory(prefix=f'bench_startup_{kind}_') as tmp:
                began = time.monotonic()
                install = install_venv if kind == 'venv' else install_colcon
                exe, node_env = install(tmp, not opts.no_warm)
                node_env['ROS_DOMAIN_ID'] = env['ROS_DOMAIN_ID']
                installed = time.monotonic() - began
                times = [probe.first_sample_s(exe, node_env, opts.timeout)
                         for _ in range(opts.starts)]
                shown = ', '.join('none' if t is None else f'{t:.2f} s' for t in times)
                print(f'{kind:>6}: install {installed:.1f} s; first Imu after start '
                      f'1..{opts.starts}: {shown}', flush=True)
    finally:
        probe.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
