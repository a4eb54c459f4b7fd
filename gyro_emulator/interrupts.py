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
"""

import signal

#: Exit status of a program stopped by SIGINT (128 + 2, the shell's convention).
INTERRUPTED_STATUS = 130


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
