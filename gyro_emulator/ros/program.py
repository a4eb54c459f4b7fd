"""
What the ROS programs ``recorder`` and ``replay`` share: arguments, errors, the end.

Each parses its options from the command line without the ROS arguments
(``--ros-args ...``, which ``rclpy.init`` reads), reports bad input as one
line ``<program>: error: ...`` with exit status 2, ends quietly on SIGINT or
SIGTERM, and however the run ends cleans up, destroys its node and shuts
rclpy down (:class:`Run`).
"""

import math
import sys

from gyro_emulator.ros.spinning import close, ERROR_STATUS
from rclpy.executors import ExternalShutdownException


def parse_arguments(parser, program, args=None):
    """
    Return the argument list for ``rclpy.init`` and the parsed options.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The program's own options.
    program : str
        Program name, the first entry of the argument list.
    args : list of str or None
        Arguments after the program name (None: ``sys.argv``).

    Returns
    -------
    tuple
        ``(argv, options)``; ``argv`` keeps the ROS arguments.

    """
    argv = list(sys.argv) if args is None else [program] + list(args)
    own, ros = split_ros_args(argv[1:])
    # The program's own options first: an option value may hold ":=" (replay's
    # --remap FROM:=TO), which rclpy.utilities.remove_ros_args would take away
    # as a remap rule in the deprecated syntax. Only what the options leave of
    # that syntax goes on to rcl, as before.
    opts, rest = parser.parse_known_args(own)
    legacy = [a for a in rest if ':=' in a and not a.startswith('-')]
    unknown = [a for a in rest if a not in legacy]
    if unknown:
        parser.error(f'unrecognized arguments: {" ".join(unknown)}')
    return [argv[0]] + ros + legacy, opts


def split_ros_args(items):
    """
    Split arguments into the program's own and the ROS ones (``--ros-args`` blocks).

    A block runs from ``--ros-args`` to the next ``--`` (which ends it and
    is dropped) or to the end, as rcl reads it.
    """
    own, ros, inside = [], [], False
    for item in items:
        if item == '--ros-args':
            inside = True
            ros.append(item)
        elif inside and item == '--':
            inside = False
        else:
            (ros if inside else own).append(item)
    return own, ros


def add_seconds_options(parser, options):
    """Add options that take a duration in seconds: ``{flag: (default, help)}``."""
    for flag, (default, text) in options.items():
        parser.add_argument(flag, type=float, default=default, metavar='S', help=text)


def check_seconds(flag, value, low_open=False, high=math.inf):
    """
    Refuse a duration option in one line unless it is finite and in range (None passes).

    The range is ``[0, high]`` (``(0, high]`` with ``low_open``), ``high``
    infinite by default, itself never allowed: a wait or a duration of
    ``inf`` or ``nan`` is refused, as ``scenario --wait`` refuses it.
    """
    if value is None:
        return
    low_ok = value > 0 if low_open else value >= 0
    if not (math.isfinite(value) and low_ok and value <= high):
        top = f'{high:g}]' if math.isfinite(high) else 'inf)'
        raise ValueError(f'{flag} = {value} is out of range: allowed {"(" if low_open else "["}0, '
                         f'{top} s')


class Run:
    """
    One run of a ROS program: its node, its exit status and its clean-up.

    Use as ``with Run('replay') as run:``; set ``run.node`` once the node
    exists and register clean-ups with :meth:`on_exit`. On leaving the block,
    SIGINT/SIGTERM (``KeyboardInterrupt``, ``ExternalShutdownException``)
    end the run quietly, a ``ValueError`` or ``OSError`` is printed as one
    line and sets :attr:`status` to
    :data:`~gyro_emulator.ros.spinning.ERROR_STATUS`; then the clean-ups run
    in order, the node is destroyed and rclpy is shut down.

    Parameters
    ----------
    program : str
        Name that prefixes the error line.

    """

    def __init__(self, program):
        self.program = program
        self.node = None
        self.status = 0
        self._cleanups = []

    def on_exit(self, cleanup):
        """Call ``cleanup()`` when the run ends, before the node is destroyed."""
        self._cleanups.append(cleanup)

    def __enter__(self):
        """Return the run."""
        return self

    def __exit__(self, kind, error, traceback):
        """Report the error (if any), clean up, close; say whether the error was handled."""
        handled = kind is not None and issubclass(
            kind, (KeyboardInterrupt, ExternalShutdownException))
        if kind is not None and issubclass(kind, (ValueError, OSError)):
            print(f'{self.program}: error: {error}', file=sys.stderr)
            self.status = ERROR_STATUS
            handled = True
        try:
            for cleanup in self._cleanups:
                cleanup()
        finally:
            close(self.node)
        return handled
