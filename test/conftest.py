"""
Shared test helpers.

ROS processes started by tests obey the network rule: discovery stays on
localhost (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) and each test gets a
private ROS_DOMAIN_ID, so concurrent test runs do not see each other.
"""

import itertools
import os
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_domains = itertools.count()


def ros_env(**extra):
    """
    Return an environment for a ROS subprocess: localhost, private domain.

    The source tree comes first on PYTHONPATH so subprocesses run the code
    under test, and AMENT_PREFIX_PATH includes the venv prefix.
    """
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    # ROS 2 domain IDs 0-101 are safe on Linux; 13 and 101 are coprime, so
    # consecutive tests of one run never share a domain.
    env['ROS_DOMAIN_ID'] = str(1 + (os.getpid() * 13 + next(_domains)) % 101)
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
