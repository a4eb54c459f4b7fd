"""
The main job when the node is slow to start, or never runs (a loaded machine's first run).

A fresh clone's first ``./dev.sh main`` on a loaded machine once started the
scenario before the node ran: the recorder's subscriptions were taken for the
node, the player waited at most 30 s for an Imu message, and steps 0-4 came
out as NaN with exit 1 and no word why. Here the node's start is held back
by a ``sitecustomize`` on the node process's path (it sleeps before the node
module runs, as a slow import or compile would), with the recorder started
at once. The main job must wait for the node itself and its first sample,
say so while it waits, measure every step and say its exit status in one
line. A node that dies before it runs ends the wait at once, named.
"""

import json
import os
import re
import subprocess
import sys

from conftest import ros_env
import pytest
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
pytestmark = [pytest.mark.ros, pytest.mark.slow]

#: A sitecustomize that holds back (or fails) only the node's process.
HOOK = """
import os, sys, time
if 'gyro_emulator.ros.node' in getattr(sys, 'orig_argv', ()):
    {action}
"""


def run_main(tmp_path, action, *options):
    """Run the main job on a 2-step profile with the node's start hooked; return it done."""
    hook = tmp_path / 'hook'
    hook.mkdir()
    (hook / 'sitecustomize.py').write_text(HOOK.format(action=action))
    profile = tmp_path / 'short.yaml'
    profile.write_text(yaml.safe_dump({
        'name': 'short', 'grid': {'temps_c': [25.0], 'rates_rpm': [0.0, 40.0],
                                  'hold_s': 0.8, 'settle_s': 0.3}}))
    env = ros_env()
    env['PYTHONPATH'] = str(hook) + os.pathsep + env['PYTHONPATH']
    return subprocess.run(
        [sys.executable, '-m', 'gyro_emulator.cli.main_job', '--skip-paper', '--profile',
         str(profile), '--out-dir', str(tmp_path / 'out'), *options],
        env=env, cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_a_node_that_starts_60_s_late_is_waited_for_and_every_step_measured(tmp_path):
    proc = run_main(tmp_path, 'time.sleep(60.0)')
    text = proc.stdout + proc.stderr
    assert proc.returncode == 0, text
    # The recorder ran from the start: its subscriptions did not pass for the node.
    waits = [line for line in proc.stdout.splitlines()
             if line.startswith('main: waiting for the emulator node (')]
    assert len(waits) >= 5, text                          # one every 10 s, 60 s and more
    assert waits[0] == ('main: waiting for the emulator node (10 s, at most 300 s): no node '
                        'yet subscribes to /cmd/angular_velocity and /cmd/temperature and '
                        'publishes /imu/data_raw'), waits[0]
    doc = json.loads((tmp_path / 'out' / 'summary.json').read_text())
    assert [s['samples'] > 50 for s in doc['steps']] == [True, True], doc
    assert 'unmeasured' not in doc and 'nan' not in proc.stdout.lower()
    assert re.fullmatch(r'main: exit status 0: all 2 steps measured \(\d+ Imu samples\)',
                        proc.stdout.strip().splitlines()[-1]), proc.stdout
    assert os.path.isdir(tmp_path / 'out' / 'bag')


def test_a_node_that_dies_before_it_runs_ends_the_wait_at_once(tmp_path):
    proc = run_main(tmp_path, 'os._exit(3)', '--no-record')
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert lines[-2].startswith('main: the node exited with status 3 after '), lines
    assert lines[-1] == 'main: exit status 1: the emulator node did not run (above)'
    assert 'Traceback' not in proc.stderr


@pytest.mark.parametrize('wait', ['-1', 'nan', 'inf'])
def test_a_wait_that_is_not_a_duration_is_refused_at_once(wait):
    """``scenario --wait nan`` waited forever ("at most nan s"), -1 tried and failed."""
    proc = subprocess.run([sys.executable, '-m', 'gyro_emulator.ros.scenario', '--wait', wait],
                          env=ros_env(), cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert proc.stderr.strip() == (f'scenario: error: --wait = {float(wait):g} is out of '
                                   'range: allowed [0, inf) s'), proc.stderr
