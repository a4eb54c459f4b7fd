"""A Ctrl-C during start-up is deferred, never lost (gyro_emulator.interrupts)."""

import os
import signal
import subprocess
import sys

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


#: Raises SIGINT once, at the AT-th profile event (a call or a return) inside a
#: flag's wait, for every AT the wait has, with flag_signals' handler setting the
#: flag; a wait that deadlocks is ended by faulthandler (status 1).
_SIGNAL_IN_A_WAIT = """
import faulthandler, signal, sys, threading
from gyro_emulator.interrupts import SignalFlag
from gyro_emulator.ros.spinning import flag_signals
kind = {'SignalFlag': SignalFlag, 'Event': threading.Event}[sys.argv[1]]

def wait_signalled_at(at):
    stop = kind()
    flag_signals(stop)
    seen = [0]
    def profile(frame, event, arg):
        seen[0] += 1
        if seen[0] == at:
            signal.raise_signal(signal.SIGINT)
    sys.setprofile(profile)
    stop.wait(0.05)
    sys.setprofile(None)
    return seen[0], stop.is_set()

events, _ = wait_signalled_at(0)
for at in range(1, events + 1):
    faulthandler.dump_traceback_later(5.0, exit=True)
    assert wait_signalled_at(at)[1], at
print(events, 'points', flush=True)
"""


@pytest.mark.parametrize('kind', ['SignalFlag', 'Event'])
def test_a_signal_at_any_point_of_a_wait_sets_the_flag_without_a_deadlock(kind, ros_environment):
    # The control: threading.Event.set takes the lock its wait holds between
    # bytecodes, where Python runs the handler (replay --delay hung so).
    run = subprocess.run([sys.executable, '-c', _SIGNAL_IN_A_WAIT, kind], env=ros_environment,
                         capture_output=True, text=True, timeout=120)
    if kind == 'Event':
        assert run.returncode == 1 and 'Timeout' in run.stderr, run.stderr
    else:
        assert run.returncode == 0, run.stderr
        assert int(run.stdout.split()[0]) >= 5, run.stdout
