"""
Ctrl-C during a program's start-up: never lost, never a traceback, never a crash.

A SIGINT normally raises ``KeyboardInterrupt`` wherever Python is. During
start-up that is often inside library code that swallows it, converts it or
is left half done by it: llvmlite's ctypes callbacks (numba loading its
cache) print "Exception ignored" and carry on, and a compiled module's init
turns it into ``ImportError: initialization failed``. The program then
prints a traceback, starts up as if nothing happened, or carries on with a
library in a broken state.

:class:`StartupInterrupt` defers the signal instead: inside the block a
SIGINT only sets a flag, and the caller stops cleanly at the end of the block.
A library left half done can also crash the interpreter's exit, so a command
that a signal stopped ends without it (:func:`end_process`).
"""

import math
import os
import signal
import sys
import time

#: Exit status of a program stopped by SIGINT (128 + 2, the shell's convention).
INTERRUPTED_STATUS = 130
#: Longest blocking wait of a main thread between two looks at pending signals, s.
SIGNAL_POLL_S = 0.1


def wait_sliced(wait, done, timeout_s=math.inf):
    """
    Call ``wait(slice_s)`` until ``done()`` or ``timeout_s``; return ``done()``.

    In slices of :data:`SIGNAL_POLL_S`: a signal the kernel delivers to
    another thread of the process (DDS and Dask start several) only marks
    the Python handler pending and does not wake a main thread blocked in
    one long wait, so the handler would run only once that wait ends (a
    ``replay --delay 600`` once slept on through SIGINT). For an event:
    ``wait_sliced(event.wait, event.is_set, t)``. For a thread, an event it
    sets as it ends: on Python 3.11 a ``Thread.join`` that a signal's
    exception interrupts marks the thread as stopped while it still runs.
    """
    deadline = time.monotonic() + timeout_s
    while not done():
        left = deadline - time.monotonic()
        if left <= 0.0:
            return False
        wait(min(left, SIGNAL_POLL_S))
    return True


class SignalFlag:
    """
    A flag that a signal handler sets and a main loop reads: ``set``, ``is_set``, ``wait``.

    Not a ``threading.Event``: its ``set`` takes the lock that its ``wait``
    holds over several bytecodes, and Python runs a signal handler in the
    main thread between bytecodes, so a handler that sets the event while
    the main thread is inside its ``wait`` waits for the main thread, i.e.
    for itself, forever (``replay --delay``, sent SIGINT as its wait began,
    hung so on a loaded machine). Here ``set`` is one assignment and
    ``wait`` sleeps in slices (:func:`wait_sliced`): no lock is taken.
    """

    def __init__(self):
        self._set = False

    def set(self):  # noqa: A003 - threading.Event's name, as every caller uses
        """Raise the flag (safe in a signal handler)."""
        self._set = True

    def clear(self):
        """Lower the flag."""
        self._set = False

    def is_set(self):
        """Return whether the flag is raised."""
        return self._set

    def wait(self, timeout_s=math.inf):
        """Wait up to ``timeout_s`` for the flag; return whether it is raised."""
        return wait_sliced(time.sleep, self.is_set, timeout_s)


class StartupInterrupt:
    """
    Context manager that defers SIGINT until the end of a start-up phase.

    Inside the block a SIGINT sets :attr:`interrupted` and nothing else, so
    no library code is interrupted half way. On leaving, the previous
    handler is restored. The caller then stops with
    :data:`INTERRUPTED_STATUS` if :attr:`interrupted` is set. The phase
    should be short (imports, loading compiled code): a second Ctrl-C is
    deferred too.
    """

    def __init__(self):
        self.interrupted = False
        self._previous = None

    def _on_sigint(self, signum, frame):
        self.interrupted = True

    def __enter__(self):
        """Install the deferring SIGINT handler."""
        self._previous = signal.signal(signal.SIGINT, self._on_sigint)
        return self

    def __exit__(self, kind, error, traceback):
        """Restore the previous handler; exceptions pass."""
        signal.signal(signal.SIGINT, self._previous)
        return False


class Terminated(KeyboardInterrupt):
    """
    SIGTERM or SIGHUP turned into an exception, so that the writes in flight are undone.

    A subclass of ``KeyboardInterrupt``: every handler that undoes a
    half-done step on a Ctrl-C (:func:`gyro_emulator.atomic.staged` removes
    its temporary, a fleet keeps its finished tasks) does the same on a
    SIGTERM or SIGHUP. :attr:`status` is the exit status the shell expects
    (128 + the signal number: 143, 129).
    """

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum
        self.name = signal.Signals(signum).name
        self.status = 128 + signum


#: The signals :class:`TerminateOnSignal` turns into :class:`Terminated`.
TERMINATING_SIGNALS = (signal.SIGTERM, signal.SIGHUP)


class TerminateOnSignal:
    """
    Context manager: inside it, SIGTERM and SIGHUP raise :class:`Terminated`.

    The first such signal raises; any later one is ignored, so that the
    clean-up the exception sets off is not cut short. On leaving, the
    previous handlers are restored. :attr:`received` keeps the exception
    raised: a library that swallows exceptions in its callbacks (llvmlite
    loading numba's cache) can lose it, and the caller then still knows.

    With ``defer`` the handlers only record the signal until :meth:`arm`
    (a start-up phase: parsing the command line), which then raises it at
    once; :meth:`restore` gives the signals back to their previous handlers
    early (a program with its own handling).
    """

    def __init__(self, signals=TERMINATING_SIGNALS, defer=False):
        self.signals = tuple(signals)
        self._previous = {}
        self._deferring = defer
        self.received = None
        self._hook = None

    def _unraisable(self, unraisable):
        """
        Keep quiet about the :class:`Terminated` a callback could not raise.

        Raised inside a callback that cannot pass it on (a weakref callback
        during garbage collection, a ctypes callback), Python would print
        "Exception ignored in ..." and a traceback; :attr:`received` keeps
        it, and the caller raises it when the work returns. Anything else
        goes to the previous hook.
        """
        if unraisable.exc_value is not None and unraisable.exc_value is self.received:
            return
        self._hook(unraisable)

    def _on_signal(self, signum, frame):
        if self.received is not None:
            return
        self.received = Terminated(signum)
        if not self._deferring:
            raise self.received

    def arm(self):
        """Raise from now on; a signal that came while deferring is raised here."""
        self._deferring = False
        if self.received is not None:
            raise self.received

    def close(self):
        """
        End the work: the signals are ignored until the process exits.

        A signal that came before is raised here; one that comes later is
        ignored, and the process, whose outputs are then complete, ends
        with the command's status. Without this, a signal during the
        interpreter's exit either killed the process (the default handler
        back) or ran this handler while Python was finalizing (a crash, not
        one line). Ignored, not blocked: a mask is one thread's, and the
        kernel hands a process's signal to any thread that does not block
        it (DDS's, Dask's). The previous handlers are not restored on leaving.
        """
        if self.signals:
            self.restore()
            for sig in self.signals:
                signal.signal(sig, signal.SIG_IGN)
        if self.received is not None and not self._deferring:
            raise self.received

    def restore(self):
        """Give the signals back to their previous handlers (and the unraisable hook)."""
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous = {}
        if self._hook is not None and sys.unraisablehook == self._unraisable:
            sys.unraisablehook = self._hook
        self._hook = None

    def __enter__(self):
        """Install the handlers."""
        self._previous = {sig: signal.signal(sig, self._on_signal) for sig in self.signals}
        if self.signals:
            self._hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
        return self

    def __exit__(self, kind, error, traceback):
        """Restore the previous handlers; exceptions pass."""
        self.restore()
        return False


def end_process(status):
    """
    End the process at once with ``status``: no interpreter finalization, no exit hooks.

    For a command a signal stopped, once its clean-up has run (its
    unfinished outputs removed, its cluster closed). The signal may have
    cut a compiled library short anywhere (see the module docstring), and
    the exit that follows runs that library's C exit hooks and static
    destructors after Python is gone: in CI, ``fleet`` stopped by SIGTERM
    died there ("PyThreadState_Get ... Python runtime state: finalizing",
    SIGABRT) instead of ending with 143. Python's own exit hooks
    (``atexit``) are skipped too, so nothing that needs them may be left
    open: the standard streams are flushed here, and anything else is
    closed by the command before it returns.
    """
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):           # a closed pipe or stream: nothing to keep
            pass
    os._exit(status)
