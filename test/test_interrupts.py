"""A Ctrl-C during start-up is deferred, never lost (gyro_emulator.interrupts)."""

import os
import signal

from gyro_emulator.interrupts import StartupInterrupt
import pytest


def _library_mid_work(steps):
    """Stand-in for library code (numba loading its cache) that a signal must not cut."""
    done = []
    for step in range(steps):
        if step == 1:
            os.kill(os.getpid(), signal.SIGINT)
        done.append(step)
    return done


def test_a_sigint_in_the_block_interrupts_nothing_and_is_recorded():
    with StartupInterrupt() as startup:
        done = _library_mid_work(5)
    assert done == list(range(5))
    assert startup.interrupted


def test_without_a_signal_errors_pass_and_the_handler_is_restored():
    before = signal.getsignal(signal.SIGINT)
    with pytest.raises(ImportError):
        with StartupInterrupt() as startup:
            raise ImportError('a real missing module')
    assert not startup.interrupted
    assert signal.getsignal(signal.SIGINT) is before


def test_after_the_block_a_sigint_raises_again():
    with StartupInterrupt():
        pass
    with pytest.raises(KeyboardInterrupt):
        os.kill(os.getpid(), signal.SIGINT)
        _library_mid_work(0)
