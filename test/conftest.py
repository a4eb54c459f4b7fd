"""
Shared test helpers.

ROS processes started by tests obey the network rule: discovery stays on
localhost (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) and each test gets a
private ROS_DOMAIN_ID, so concurrent test runs do not see each other.
"""

import itertools
import os
import signal
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# As ./dev.sh sets it: one BLAS thread, so results do not depend on how a run is started
# (a threaded BLAS sums in another order: the last bits of a fit move).
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
_domains = itertools.count()


def pytest_configure(config):
    """
    Give the suite a live Ctrl-C when it was started with SIGINT ignored.

    A non-interactive shell starts a background job (``cmd &``) with SIGINT
    ignored, and an ignored signal stays ignored across fork and exec: the
    tests that press Ctrl-C (in this process or in the CLI processes they
    start) would then test nothing and fail. Python's own handler is put
    back; a Python child then installs its KeyboardInterrupt as usual.
    """
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(autouse=True)
def _signal_mask_is_left_as_found():
    """
    Fail the test that leaves signals blocked or their handlers changed (then restore them).

    Every child a later test starts inherits the mask, and an ignored
    signal stays ignored through exec: a blocked SIGTERM cannot stop it
    (``test_atomic``'s writer once outlived a SIGTERM by 60 s in a full
    run; the cause was not found, and no test is known to change either
    in-process). This turns such a leak into a failure of the test that
    caused it.
    """
    watched = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
    before = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    handlers = {sig: signal.getsignal(sig) for sig in watched}
    yield
    after = signal.pthread_sigmask(signal.SIG_SETMASK, before)
    changed = sorted(sig.name for sig in watched if signal.getsignal(sig) != handlers[sig])
    for sig, handler in handlers.items():
        signal.signal(sig, handler)
    if after != before:
        pytest.fail(f'the test left signals blocked: {sorted(after - before)}')
    if changed:
        pytest.fail(f'the test left the handlers of {changed} changed')


def _next_domain():
    """
    Return the ROS_DOMAIN_ID of the next ROS test of this process.

    Domain IDs 1-100 are safe on Linux. Each pytest-xdist worker (and a run
    without workers) takes its own slice of them, so tests running at the same
    time in one run never share a domain; within a slice consecutive tests
    differ, and the process id offsets separate runs started side by side.
    """
    low, high = _domain_range()
    workers = int(os.environ.get('PYTEST_XDIST_WORKER_COUNT', '1'))
    worker = int(os.environ.get('PYTEST_XDIST_WORKER', 'gw0')[2:])
    width = max((high - low + 1) // max(workers, 1), 1)
    return low + worker * width + (os.getpid() + next(_domains)) % width


def _domain_range():
    """
    Return the (first, last) ROS_DOMAIN_ID this run may use: 1-100 by default.

    ``GYRO_TEST_DOMAINS=FIRST-LAST`` narrows it, so that suites run side by
    side (several checkouts on one machine) never share a domain.
    """
    text = os.environ.get('GYRO_TEST_DOMAINS', '1-100')
    try:
        low, high = (int(v) for v in text.split('-'))
    except ValueError:
        raise pytest.UsageError(f'GYRO_TEST_DOMAINS = {text!r}: expected FIRST-LAST, '
                                'e.g. 1-50') from None
    if not 0 <= low <= high <= 101:
        raise pytest.UsageError(f'GYRO_TEST_DOMAINS = {text!r}: allowed 0 <= FIRST <= LAST '
                                '<= 101')
    return low, high


def ros_env(**extra):
    """
    Return an environment for a ROS subprocess: localhost, private domain.

    The source tree comes first on PYTHONPATH so subprocesses run the code
    under test, and AMENT_PREFIX_PATH includes the venv prefix.
    """
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['ROS_DOMAIN_ID'] = str(_next_domain())
    env['PYTHONPATH'] = ROOT + (os.pathsep + env['PYTHONPATH'] if env.get('PYTHONPATH') else '')
    env['AMENT_PREFIX_PATH'] = sys.prefix + (
        os.pathsep + env['AMENT_PREFIX_PATH'] if env.get('AMENT_PREFIX_PATH') else '')
    env['MPLBACKEND'] = 'Agg'
    env['PYTHONUNBUFFERED'] = '1'
    env.update({k: str(v) for k, v in extra.items()})
    return env


@pytest.fixture
def ros_environment():
    """Environment dict for ROS subprocesses of one test (private domain)."""
    return ros_env()
