"""
How the ROS programs start, spin and stop: safe against SIGINT/SIGTERM at every step.

:func:`run_node` is a node's whole ``main`` past its own options, the demos
talker's ``rclpy.init``, ``spin`` and ``except (KeyboardInterrupt,
ExternalShutdownException)`` with the start-up made safe: a Ctrl-C while
compiled code loads is deferred, a signal while the node is built ends the
run quietly, and the spin loop sees the context go down instead of a
traceback. Its parts :func:`spin_once` and :func:`close` also serve the
recorder, the replay and the scenario player; :func:`flag_signals` serves
the two players, whose loops read a flag between steps.
"""

import signal
import sys
import threading

from gyro_emulator.interrupts import INTERRUPTED_STATUS, SignalFlag, StartupInterrupt
import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.experimental.events_executor import EventsExecutor

#: Longest wait of the executor between checks for shutdown, s.
SHUTDOWN_POLL_S = 0.25
#: Exit status of a run stopped by bad arguments, parameters or files.
ERROR_STATUS = 2
#: Errors of a node's construction that are the user's input, reported as one line.
INPUT_ERRORS = (ValueError, ParameterException, OSError)
#: Set by the SIGINT handler under rclpy's (:func:`_quiet_sigint`): a SIGINT that
#: came before ``rclpy.init`` installed its handler reached only that one.
_SIGINT_SEEN = SignalFlag()


def flag_signals(stop):
    """
    Make SIGINT and SIGTERM only set ``stop`` (a SignalFlag); return their handlers.

    For a loop that reads ``stop`` between its steps, with rclpy initialised
    with ``SignalHandlerOptions.NO``: raised inside rclpy, an interrupt can
    leave a step half done or come out of a pybind11 call as an unrelated
    RuntimeError ("Unable to convert call argument"). Off the main thread,
    where signal handlers cannot be set, nothing changes and {} is returned.
    """
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {signum: signal.signal(signum, lambda *_: stop.set())
            for signum in (signal.SIGINT, signal.SIGTERM)}


def spin_once(executor, timeout_sec):
    """
    Spin ``executor`` once; return False once its context has shut down.

    rclpy's SIGINT/SIGTERM handler shuts the context down asynchronously, so
    the wait set of the next spin, or a publish inside a callback, can raise
    ``RCLError`` ("the given context is not valid"). An error raised after
    the shutdown is the shutdown itself and ends the loop; an error while the
    context is still valid is re-raised.

    Parameters
    ----------
    executor : rclpy.executors.Executor
        The executor to spin.
    timeout_sec : float
        Longest wait for work, s (also how often the context is re-checked,
        since the signal handler's wake-up can be missed).

    """
    context = executor.context
    if not context.ok():
        return False
    try:
        executor.spin_once(timeout_sec=timeout_sec)
    except Exception:  # noqa: B902 - any error after shutdown is the shutdown
        if context.ok():
            raise
        return False
    return context.ok()


def close(node):
    """Destroy ``node`` (if any) and shut rclpy down, however the run ended."""
    if node is not None:
        node.destroy_node()
    rclpy.try_shutdown()


def run_node(make_node, args, program, warm_up=None):
    """
    Start ROS, build a node, spin it until SIGINT/SIGTERM, close; return the exit status.

    Parameters
    ----------
    make_node : callable
        Builds the node (after ``rclpy.init``); the node's ``summary()`` is
        the line logged when it shuts down.
    args : list of str or None
        Arguments for ``rclpy.init`` (None: ``sys.argv``).
    program : str
        Name that prefixes an error line, e.g. ``gyro_emulator node``.
    warm_up : callable or None
        Loads compiled code before ROS takes the signals.

    Returns
    -------
    int
        0 after a signal, :data:`ERROR_STATUS` for bad input,
        :data:`~gyro_emulator.interrupts.INTERRUPTED_STATUS` for a Ctrl-C
        during ``warm_up``.

    """
    status = _start_ros(args, program, warm_up)
    if status is not None:
        return status
    node = None
    try:
        try:
            node = make_node()
        except INPUT_ERRORS as exc:
            print(f'{program}: error: {first_line(exc)}', file=sys.stderr)
            return ERROR_STATUS
        except Exception:  # noqa: B902 - a SIGINT/SIGTERM while the node starts up
            if rclpy.ok():
                raise
            print('[gyro_emulator] shutting down: stopped while starting', file=sys.stderr)
            return 0
        # The events executor serves a callback for about 1.5 us instead of the
        # ~100 us of a SingleThreadedExecutor wait set (``bench/bench_node.py``, command floods).
        executor = EventsExecutor()
        executor.add_node(node)
        # Waiting at most SHUTDOWN_POLL_S re-checks the context even if the
        # signal handler's wake-up is missed while nothing else is due (a paused /clock).
        while spin_once(executor, SHUTDOWN_POLL_S):
            pass
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            _log_shutdown(node)
        close(node)
    return 0


def _start_ros(args, program, warm_up):
    """Warm up with Ctrl-C deferred, then ``rclpy.init``; return a status to stop with, or None."""
    # numba loads its cache through ctypes callbacks that swallow a
    # KeyboardInterrupt (and may be left half done): a Ctrl-C is deferred.
    with StartupInterrupt() as startup:
        if warm_up is not None:
            warm_up()
    if startup.interrupted:
        return INTERRUPTED_STATUS
    # rclpy's SIGINT handler shuts the context down, then calls the Python
    # handler it found: with Python's default that raises KeyboardInterrupt
    # inside whatever callback runs, which the events executor logs with its
    # traceback. With this one the spin loop just sees the context go down.
    _SIGINT_SEEN.clear()
    signal.signal(signal.SIGINT, _quiet_sigint)
    try:
        rclpy.init(args=args)
    except Exception as exc:  # noqa: B902 - rcl reports bad arguments and params files so
        print(f'{program}: error: cannot start ROS: {first_line(exc)}', file=sys.stderr)
        return ERROR_STATUS
    if _SIGINT_SEEN.is_set():
        # A Ctrl-C between the two handlers (a loaded machine widens the gap): rclpy
        # never saw it, and the node would run on until a second one.
        rclpy.try_shutdown()
        return INTERRUPTED_STATUS
    return None


def _log_shutdown(node):
    """Log the node's last line: to rosout while the context is up, else to stderr."""
    line = f'shutting down: {node.summary()}'
    if rclpy.ok():
        node.get_logger().info(line)
    else:
        # The signal handler already shut the context down: no rosout.
        print(f'[gyro_emulator] {line}', file=sys.stderr)


def _quiet_sigint(signum, frame):
    """
    Python's SIGINT handler under rclpy's: rclpy already shut the context down.

    Before ``rclpy.init`` installed rclpy's handler, this one alone ran: it
    notes the signal, which :func:`_start_ros` acts on after the init.
    """
    _SIGINT_SEEN.set()


def first_line(exc):
    """Return an exception's message on one line (rcl appends source locations)."""
    text = str(exc).split(', at /')[0]
    return ' '.join(text.split())
