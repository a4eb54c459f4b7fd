"""
Console-script entry points: ``gyro-emulator`` and the ROS executables.

Each entry point first limits the BLAS thread pool, then imports the module
that does the work. The models run many small matrix operations (ZOH
discretisation, matrix exponentials of 6x6 to 42x42 matrices), which a BLAS
thread pool slows down on a loaded machine: a 42x42 ``scipy.linalg.expm``
takes 12.6 ms with OpenBLAS's default pool against 0.14 ms single-threaded
on 2 cores. OpenBLAS reads ``OPENBLAS_NUM_THREADS`` when numpy loads it
(OpenBLAS README, environment variables), so the limit lives here, at
process start, and a user's own setting wins.
"""

import importlib
import os
import sys

from gyro_emulator.interrupts import INTERRUPTED_STATUS, StartupInterrupt

#: ROS executable (``ros2 run gyro_emulator <name>``) -> the module whose ``main`` runs it.
#: On PATH (the venv's bin) each is ``gyro-emulator-<name>`` (setup.py).
ROS_EXECUTABLES = {
    'node': 'gyro_emulator.ros.node',
    'scenario': 'gyro_emulator.ros.scenario',
    'recorder': 'gyro_emulator.ros.recorder',
    'replay': 'gyro_emulator.ros.replay',
    'array': 'gyro_emulator.ros.gyro_array',
}

#: Environment variables that size the BLAS thread pools numpy may load.
BLAS_THREAD_VARIABLES = ('OPENBLAS_NUM_THREADS',)


def limit_blas_threads(environ=None):
    """Set each BLAS thread-pool size to 1 unless the user set it."""
    environ = os.environ if environ is None else environ
    for name in BLAS_THREAD_VARIABLES:
        environ.setdefault(name, '1')


def _run(module_name):
    limit_blas_threads()
    # A Ctrl-C while the heavy imports run (about 1 s) is deferred to their
    # end: no library is cut half way, and the program stops without a traceback.
    with StartupInterrupt() as startup:
        module = importlib.import_module(module_name)
    if startup.interrupted:
        return INTERRUPTED_STATUS
    try:
        return module.main()
    except KeyboardInterrupt:
        return INTERRUPTED_STATUS


def run_executable(name, args):
    """Run ROS executable ``name`` with ``args`` in this process (``gyro-emulator ros run``)."""
    sys.argv = [name] + list(args)
    return _run(ROS_EXECUTABLES[name])


def run_cli():
    """Run ``gyro-emulator``, the command line (:mod:`gyro_emulator.cli`)."""
    limit_blas_threads()
    # Imported after the limit, as every entry point's work is (the module docstring).
    from gyro_emulator.cli import main
    return main(signals=True)


def run_node():
    """Run the emulator node (``gyro-emulator-node``, ``ros2 run gyro_emulator node``)."""
    return _run(ROS_EXECUTABLES['node'])


def run_scenario():
    """Run the scenario player (``gyro-emulator-scenario``; ros2 run: ``scenario``)."""
    return _run(ROS_EXECUTABLES['scenario'])


def run_recorder():
    """Run the bag recorder (``gyro-emulator-recorder``, ``ros2 run gyro_emulator recorder``)."""
    return _run(ROS_EXECUTABLES['recorder'])


def run_replay():
    """Run the ROS replay (``gyro-emulator-replay``, ``ros2 run gyro_emulator replay``)."""
    return _run(ROS_EXECUTABLES['replay'])


def run_array():
    """Run N emulator nodes from an array spec (``gyro-emulator-array``; ros2 run: ``array``)."""
    return _run(ROS_EXECUTABLES['array'])


if __name__ == '__main__':
    sys.exit(run_cli())
