"""``gyro-emulator dynamics`` end to end, as a user runs it."""

import json
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
KEYS = ('first_order_m', 'exact_m', 'time_domain_m', 'ratio_exact_to_first_order')


def run_cli(*args):
    env = dict(os.environ, MPLBACKEND='Agg',
               PYTHONPATH=ROOT + os.pathsep + os.environ.get('PYTHONPATH', ''))
    return subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', 'dynamics',
                           *args], cwd=ROOT, capture_output=True, text=True,
                          env=env)


def test_json_has_the_three_amplitudes_and_the_ratio(tmp_path):
    out = tmp_path / 'split50.json'
    proc = run_cli('--split-hz', '50', '--rate-dps', '30', '--json', str(out))
    assert proc.returncode == 0, proc.stderr
    assert 'first order' in proc.stdout and 'bandwidth' in proc.stdout
    doc = json.loads(out.read_text())
    for key in KEYS:
        assert isinstance(doc[key], float), key
    # First order at 30 deg/s is half Table 1's 6.75 nm.
    assert doc['first_order_m'] == pytest.approx(6.75e-9 / 2, rel=0.01)
    assert doc['ratio_exact_to_first_order'] == pytest.approx(
        doc['exact_m'] / doc['first_order_m'], rel=1e-12)
    assert 0.95 <= doc['ratio_exact_to_first_order'] <= 0.96
    assert doc['time_domain_m'] == pytest.approx(doc['exact_m'], rel=1e-4)
    assert doc['split_hz'] == 50.0 and doc['preset'] == 'paper'
    assert [row['split_hz'] for row in doc['first_order_error_vs_split']] == [
        10.0, 50.0, 100.0, 500.0]


def test_plot_writes_three_pngs(tmp_path):
    proc = run_cli('--split-hz', '-80', '--plot', str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    for name in ('sense_vs_split.png', 'step_response.png', 'rate_channel_bode.png'):
        png = (tmp_path / name).read_bytes()
        assert png[:8] == b'\x89PNG\r\n\x1a\n' and len(png) > 10000, name


def test_bad_split_is_a_clean_error():
    proc = run_cli('--split-hz', '-20000')
    assert proc.returncode == 2
    assert 'split_hz' in proc.stderr and 'Traceback' not in proc.stderr
