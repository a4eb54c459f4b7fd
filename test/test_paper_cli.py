"""``gyro-emulator paper`` end to end, as a user runs it."""

import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
KEYS = ['M', 'kx', 'ky', 'fx', 'fy', 'Kn', 'C_proof', 'C_comb', 'C_drive',
        'C_sense', 'Fd', 'Xdrive', 'Ysense', 'dC']


def test_paper_command_writes_table_figures_and_json(tmp_path):
    out = tmp_path / 'paper.json'
    proc = subprocess.run(
        [sys.executable, '-m', 'gyro_emulator.cli', 'paper', '--json', str(out),
         '--out-dir', str(tmp_path)], cwd=ROOT, capture_output=True, text=True,
        env=dict(os.environ, MPLBACKEND='Agg'))
    assert proc.returncode == 0, proc.stderr
    assert 'Xdrive' in proc.stdout and 'err %' in proc.stdout
    doc = json.loads(out.read_text())
    for key in KEYS:
        assert isinstance(doc[key], float), key
    assert doc['Ysense'] == __import__('pytest').approx(6.75e-9, rel=0.01)
    assert len(doc['fig5']) == 101 and doc['fig5'][0][0] == -50.0
    temps = [t for t, _ in doc['fig6']]
    assert temps == [25.0 + 5 * i for i in range(13)]
    assert 61.8 <= doc['fig6'][-1][1] <= 62.0
    assert [t for t, _ in doc['fig6_sutherland']] == temps
    assert doc['fig6_sutherland'][-1][1] < 60.0
    for name in ('fig5.png', 'fig6.png'):
        png = (tmp_path / name).read_bytes()
        assert png[:8] == b'\x89PNG\r\n\x1a\n' and len(png) > 10000


def test_table1_prints_enough_digits_to_tell_ours_from_the_paper():
    """f_x is 13997 Hz against the paper's 14000 (-0.019 %): both show, not 1.4e+04 twice."""
    from gyro_emulator.physics import paper

    text = paper.format_table1(paper.table1_rows())
    row = {line.split()[0]: line for line in text.split('\n')[1:]}
    for key in ('fx', 'fy'):
        assert row[key].split()[-3:] == ['13997', '14000', '-0.019'], row[key]
    assert '1.4e+04' not in text
    for key, _, _, ours, theirs, _ in paper.table1_rows():
        shown = [float(v) for v in row[key].split()[-3:-1]]
        assert shown[0] == __import__('pytest').approx(ours, rel=5e-5)
        assert shown[1] == theirs
