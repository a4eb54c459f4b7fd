"""Every writer of the product goes through atomic.py: stopped half way, old file kept, no temp."""

from dataclasses import replace
import json
import os

from gyro_emulator import atomic, plotting
from gyro_emulator.analysis.fleet import config as fleet_config
from gyro_emulator.analysis.fleet import engine, sampling, state
from gyro_emulator.cli import jsonout
from gyro_emulator.recording import csvio
import numpy as np
import pytest


def _leftovers(folder):
    return sorted(n for n in os.listdir(folder) if n.endswith(atomic.TMP_SUFFIX))


def _half_json(doc, handle, **kwargs):
    """Die half way through the file, as ``json.dump`` stopped by a Ctrl-C would."""
    handle.write('{"half": ')
    handle.flush()
    raise KeyboardInterrupt


@pytest.mark.parametrize('error', [RuntimeError, KeyboardInterrupt])
def test_json_output_stopped_half_way_keeps_the_old_file(tmp_path, monkeypatch, capsys, error):
    """cli/jsonout (allan, calibrate, paper, dynamics, diagnose, truth --answer)."""
    target = tmp_path / 'out.json'
    target.write_text('old\n')

    def half(doc, handle, **kwargs):
        handle.write('{"half": ')
        raise error('stopped')
    monkeypatch.setattr(json, 'dump', half)
    with pytest.raises(error):
        jsonout.write_json(str(target), {'a': 1.0})
    assert target.read_text() == 'old\n' and _leftovers(tmp_path) == []
    monkeypatch.undo()
    jsonout.write_json(str(target), {'a': np.float64(1.5)})
    assert json.loads(target.read_text()) == {'a': 1.5} and _leftovers(tmp_path) == []
    assert capsys.readouterr().out == f'wrote {target}\n'


def _figure():
    plt = plotting.pyplot()
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.plot([0.0, 1.0, 2.0], [0.0, 1.0, 4.0], label='x')
    plotting.label(ax, 'x', 'y', 'a plot')
    return fig


def test_plot_stopped_half_way_keeps_the_old_file(tmp_path, monkeypatch):
    target = tmp_path / 'plot.png'
    target.write_bytes(b'old')
    fig = _figure()

    def half(self, fname, **kwargs):
        with open(fname, 'wb') as handle:
            handle.write(b'\x89PNG half')
        raise KeyboardInterrupt
    monkeypatch.setattr(type(fig), 'savefig', half)
    with pytest.raises(KeyboardInterrupt):
        plotting.save(fig, str(target))
    assert target.read_bytes() == b'old' and _leftovers(tmp_path) == []
    assert not plotting.pyplot().fignum_exists(fig.number)       # freed all the same


def test_plot_is_the_bytes_savefig_writes_with_its_format_from_the_name(tmp_path):
    """Staged under a .tmp name, the image is what savefig gives the name itself."""
    plt = plotting.pyplot()
    fig = _figure()
    fig.tight_layout()
    fig.savefig(tmp_path / 'direct.png', dpi=80)
    plt.close(fig)
    plotting.save(_figure(), tmp_path / 'staged.png', dpi=80)
    assert (tmp_path / 'staged.png').read_bytes() == (tmp_path / 'direct.png').read_bytes()
    plotting.save(_figure(), str(tmp_path / 'upper.PNG'))
    plotting.save(_figure(), str(tmp_path / 'vector.svg'))
    plotting.save(_figure(), str(tmp_path / 'bare'))     # matplotlib's rule: bare -> bare.png
    assert (tmp_path / 'upper.PNG').read_bytes().startswith(b'\x89PNG')
    assert b'<svg' in (tmp_path / 'vector.svg').read_bytes()
    assert (tmp_path / 'bare.png').read_bytes().startswith(b'\x89PNG')
    assert not (tmp_path / 'bare').exists() and _leftovers(tmp_path) == []


@pytest.mark.parametrize('name', ['rows.csv', 'rows.csv.gz'])
def test_csv_stopped_half_way_keeps_the_old_file(tmp_path, name):
    """recording/csvio (simulate, truth, write_measured_csv): rows flushed, then a Ctrl-C."""
    target = tmp_path / name
    csvio.write_csv(target, {'time_s': np.arange(3.0), 'gyro_rad_s': np.zeros(3)})
    old = target.read_bytes()

    def blocks():
        yield [np.arange(50_000.0), np.ones(50_000)]
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        csvio.write_csv_blocks(target, ['time_s', 'gyro_rad_s'], blocks())
    assert target.read_bytes() == old and _leftovers(tmp_path) == []
    with pytest.raises(ValueError, match='got 1 columns, expected 2'):
        with csvio.CsvWriter(target, ['time_s', 'gyro_rad_s']) as writer:
            writer.write([np.arange(4.0), np.ones(4)])
            writer.write([np.arange(4.0)])
    assert target.read_bytes() == old and _leftovers(tmp_path) == []


def test_gzip_csv_names_the_target_not_the_temporary(tmp_path):
    path = tmp_path / 'rows.csv.gz'
    assert csvio.write_csv(path, {'time_s': np.arange(3.0), 'gyro_rad_s': np.ones(3)}) == 3
    data = path.read_bytes()
    assert data[3] & 0x08 and data[10:].split(b'\0')[0] == b'rows.csv'    # FNAME
    assert csvio.read_csv(path)['gyro_rad_s'].tolist() == [1.0, 1.0, 1.0]


def test_fleet_state_stopped_half_way_keeps_the_old_file(tmp_path, monkeypatch):
    job = engine.Job(fleet_config.config_from_mapping({}), 7, 10, str(tmp_path))
    state.begin(str(tmp_path), job)
    folder = tmp_path / state.STATE_DIR
    old = (folder / 'run.json').read_bytes()
    monkeypatch.setattr(json, 'dump', _half_json)
    with pytest.raises(KeyboardInterrupt):
        state.begin(str(tmp_path), replace(job, seed=8))
    with pytest.raises(KeyboardInterrupt):
        state.save(str(tmp_path), {'blocks': [0], 'counts': {}, 'attribution': None,
                                   'sensor_runs': [], 'cpu_s': 0.0})
    assert (folder / 'run.json').read_bytes() == old
    assert os.listdir(folder) == ['run.json']


def test_a_fleet_task_stopped_half_way_leaves_no_part_file(tmp_path):
    """A task stopped after its first block: no part file; a killed one's temp is pruned."""
    cfg = fleet_config.config_from_mapping({'attribution_devices': 0})
    job = engine.Job(cfg, 7, sampling.BLOCK_DEVICES + 10, str(tmp_path))
    devices = tmp_path / 'devices'
    devices.mkdir()

    def stop(count):
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        engine.run_task(job, [0, 1], stop)
    assert os.listdir(devices) == []
    result = engine.run_task(job, [0, 1])
    assert os.listdir(devices) == ['part-000000.parquet']
    (devices / ('.part-000002.parquet.99.0a0b0c0d' + atomic.TMP_SUFFIX)).write_bytes(b'half')
    (devices / 'part-000002.parquet').write_bytes(b'another run')
    state.prune(str(tmp_path), [result])
    assert os.listdir(devices) == ['part-000000.parquet']
