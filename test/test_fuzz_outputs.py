"""
Every command that writes, fuzzed on its outputs (issue 34).

* Output paths: the same as an input, a link to the input, a directory, a
  file as folder, an existing output without ``--overwrite``, two outputs of
  one name, an output inside an input bag. Each is refused in one line
  before any work (nothing printed, nothing written) and the input is
  untouched.
* A size limit (RLIMIT_FSIZE, SIGXFSZ ignored: writes fail with EFBIG, as on
  a full disk), SIGTERM and SIGHUP in the middle of the work. Each run ends
  in one line and an exit status of 2, 143 or 129; every output is complete
  (the bytes of an undisturbed run, or for JSON its keys) or absent, and no
  staging temporary is left.
"""

import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import time

from conftest import ROOT
from gyro_emulator import atomic, cli
import psutil
import pytest

PY = sys.executable
FLEET = os.path.join(ROOT, 'config', 'fleet_paper_etch2.yaml')


def _run_cli(args, cwd):
    return subprocess.run([PY, '-m', 'gyro_emulator.cli', *args], cwd=cwd, capture_output=True,
                          text=True, timeout=600, env=dict(os.environ, PYTHONPATH=ROOT))


@pytest.fixture(scope='module')
def inputs(tmp_path_factory):
    """Write a 3-axis static log, a thermal ramp, bags and the presets fitted to them."""
    folder = tmp_path_factory.mktemp('inputs')

    def make(*args):
        proc = _run_cli(args, folder)
        assert proc.returncode == 0, proc.stderr
    make('simulate', '--config', 'consumer', '--duration-s', '600', '--rate-hz', '100', '--seed',
         '1', '--out', 'log.csv')
    ramp = folder / 'ramp.yaml'
    ramp.write_text('segments:\n  - {duration_s: 600, rate_deg_s: 0, temp_c: [5, 45]}\n')
    make('simulate', '--config', 'consumer', '--profile', str(ramp), '--duration-s', '600',
         '--rate-hz', '100', '--seed', '2', '--out', 'thermal.csv')
    make('simulate', '--config', 'consumer', '--profile', 'steps', '--duration-s', '30',
         '--rate-hz', '100', '--seed', '3', '--out', 'bag', '--start-time', '0')
    make('calibrate', 'noise', 'log.csv', '--format', 'preset', '-o', 'twin.yaml')
    make('calibrate', 'thermal', 'thermal.csv', '--format', 'preset', '-o', 'tpreset.yaml')
    shutil.copytree(folder / 'bag', folder / 'broken')
    mcap = folder / 'broken' / 'bag_0.mcap'
    mcap.write_bytes(mcap.read_bytes()[:60_000])
    (folder / 'broken' / 'metadata.yaml').unlink()
    shutil.copy(FLEET, folder / 'fleet.yaml')
    return folder


#: name -> (arguments with IN/ for the inputs and OUT/ for the outputs, the outputs).
COMMANDS = {
    'paper': (['paper', '--json', 'OUT/paper.json', '--out-dir', 'OUT/figs'],
              ['paper.json', 'figs/fig5.png', 'figs/fig6.png']),
    'dynamics': (['dynamics', '--split-hz', '50', '--json', 'OUT/dyn.json', '--plot', 'OUT/dyn'],
                 ['dyn.json', 'dyn/sense_vs_split.png', 'dyn/step_response.png',
                  'dyn/rate_channel_bode.png']),
    'simulate-csv': (['simulate', '--config', 'consumer', '--duration-s', '400', '--rate-hz',
                      '500', '--out', 'OUT/sim.csv'], ['sim.csv']),
    'simulate-bag': (['simulate', '--config', 'consumer', '--duration-s', '200', '--rate-hz',
                      '500', '--out', 'OUT/simbag', '--start-time', '0'], ['simbag']),
    'allan': (['allan', 'IN/log.csv', '--json', 'OUT/a.json', '--plot', 'OUT/a.png'],
              ['a.json', 'a.png']),
    'calibrate-noise': (['calibrate', 'noise', 'IN/log.csv', '--format', 'kalibr', '-o',
                         'OUT/imu.yaml', '--accel-noise-density', '2e-3', '--accel-random-walk',
                         '3e-3', '--json', 'OUT/n.json'], ['imu.yaml', 'n.json']),
    'calibrate-thermal': (['calibrate', 'thermal', 'IN/thermal.csv', '--format', 'px4', '-o',
                           'OUT/tc.params', '--json', 'OUT/t.json', '--plot', 'OUT/t.png'],
                          ['tc.params', 't.json', 't.png']),
    'check-noise': (['calibrate', 'check-noise', 'IN/log.csv', '--config', 'IN/twin.yaml',
                     '--seeds', '2', '--json', 'OUT/cn.json', '--plot', 'OUT/cn.png'],
                    ['cn.json', 'cn.png']),
    'check-thermal': (['calibrate', 'check-thermal', 'IN/thermal.csv', '--config',
                       'IN/tpreset.yaml', '--json', 'OUT/ct.json', '--plot', 'OUT/ct.png'],
                      ['ct.json', 'ct.png']),
    'diagnose': (['diagnose', 'IN/thermal.csv', '--static', '--axis', 'x', '--json',
                  'OUT/d.json', '--report', 'OUT/rep', '--write-config', 'OUT/part.yaml'],
                 ['d.json', 'rep/report.md', 'rep/residuals_temperature.png',
                  'rep/residuals_time.png', 'part.yaml']),
    'replay': (['replay', 'IN/bag', '--out', 'OUT/rp'],
               ['rp/emulated', 'rp/report.md', 'rp/report.json', 'rp/rates.png',
                'rp/residual.png', 'rp/allan.png']),
    'truth': (['truth', 'OUT/truth.csv', '--seed', '3', '--profile', 'static', '--duration',
               '3000', '--rate', '50', '--answer', 'OUT/truth.json'], ['truth.csv', 'truth.json']),
    'fleet': (['fleet', 'IN/fleet.yaml', '--devices', '3000', '--seed', '1', '--out', 'OUT/fl'],
              ['fl/summary.json', 'fl/devices', 'fl/plots']),
    'bag-repair': (['bag', 'repair', 'IN/broken', '--out', 'OUT/repaired'], ['repaired']),
}


def _args(name, inputs, out):
    args, _ = COMMANDS[name]
    return [a.replace('IN/', f'{inputs}/').replace('OUT/', f'{out}/') for a in args]


def _tree(folder):
    """Every path under ``folder`` with its bytes (directories as None)."""
    found = {}
    for dirpath, dirs, files in os.walk(folder):
        for name in dirs:
            found[os.path.relpath(os.path.join(dirpath, name), folder)] = None
        for name in files:
            path = os.path.join(dirpath, name)
            with open(path, 'rb') as handle:
                found[os.path.relpath(path, folder)] = handle.read()
    return found


def _temporaries(folder):
    return [p for p in _tree(folder) if os.path.basename(p).endswith(atomic.TMP_SUFFIX)]


# --- output paths: refused in one line before any work -------------------------------

def _path_cases(name, inputs, tmp_path):
    """Yield (label, argument list) of bad output paths for command ``name``."""
    args = _args(name, inputs, tmp_path)
    outs = [i for i, a in enumerate(args) if a.startswith(str(tmp_path))]
    first = outs[0]
    ins = [a for a in args if a.startswith(str(inputs))]
    (tmp_path / 'a_file').write_text('not a folder')
    (tmp_path / 'a_dir').mkdir(exist_ok=True)
    if ins:
        yield 'same as the input', _with(args, first, ins[0])
        link = tmp_path / 'link'
        if not link.exists():
            link.symlink_to(ins[0])
        yield 'a link to the input', _with(args, first, str(link))
        if os.path.isdir(ins[0]):
            yield 'inside the input', _with(args, first, os.path.join(ins[0], 'x'))
    yield 'a file as folder', _with(args, first, str(tmp_path / 'a_file' / 'x'))
    files = [i for i in outs if os.path.splitext(args[i])[1] in ('.json', '.png', '.yaml')]
    if len(files) > 1:
        yield 'two outputs of one name', _with(args, files[1], args[files[0]])
    target = args[first]
    if os.path.splitext(target)[1]:                 # a file
        os.makedirs(os.path.dirname(target), exist_ok=True)
        if not os.path.exists(target):
            with open(target, 'w') as handle:
                handle.write('old')
    else:                                           # a folder: what the command writes there
        os.makedirs(target, exist_ok=True)
        inside = os.path.basename(COMMANDS[name][1][1 if name == 'paper' else 0])
        with open(os.path.join(target, inside), 'w') as handle:
            handle.write('old')
    yield 'an existing output', list(args)


def _with(args, index, value):
    out = list(args)
    out[index] = value
    return out


@pytest.mark.parametrize('name', sorted(COMMANDS))
def test_bad_output_paths_are_refused_before_any_work(inputs, tmp_path, capsys, name):
    before = _tree(inputs)
    cases = 0
    for label, args in _path_cases(name, inputs, tmp_path):
        existing = _tree(tmp_path)
        assert cli.main(args) == 2, label
        out, err = capsys.readouterr()
        assert out == '', (label, out)              # refused before the work printed anything
        lines = err.strip().splitlines()
        assert len(lines) == 1 and ': error: ' in lines[0], (label, err)
        assert _tree(tmp_path) == existing, label    # nothing written, nothing removed
        cases += 1
    assert _tree(inputs) == before
    assert cases >= 2


def test_a_dir_output_that_holds_the_input_is_refused_even_with_overwrite(
        inputs, tmp_path, capsys):
    bag = tmp_path / 'bag'
    shutil.copytree(inputs / 'bag', bag)
    before = _tree(tmp_path)
    assert cli.main(['simulate', '--profile', str(bag), '--out', str(tmp_path),
                     '--overwrite']) == 2
    assert 'holds the input' in capsys.readouterr().err
    assert cli.main(['replay', str(bag), '--out', str(bag), '--overwrite']) == 2
    assert 'inside the input' in capsys.readouterr().err
    assert _tree(tmp_path) == before


# --- RLIMIT_FSIZE, SIGTERM, SIGHUP in the middle of the work -----------------------------

def _complete(path, reference):
    """Whether the output at ``path`` is whole: the reference's bytes, or for JSON its keys."""
    if os.path.isdir(path):
        got, want = _tree(path), _tree(reference)
        if path.endswith(('devices', 'plots')):
            return set(got) <= set(want)            # parts are whole files, some may be absent
        if any(name.endswith('.json') or name.endswith('metadata.yaml') for name in want):
            return set(got) == set(want)
        return got.keys() == want.keys()
    with open(path, 'rb') as handle:
        data = handle.read()
    if path.endswith('.json'):
        with open(reference) as handle:
            return json.loads(data).keys() == json.load(handle).keys()
    if path.endswith('.png'):
        return data.startswith(b'\x89PNG') and data.endswith(b'IEND\xaeB`\x82')
    if path.endswith('.md'):
        return data.endswith(b'\n')
    with open(reference, 'rb') as handle:
        return data == handle.read()


def _check_outcome(name, out, reference, proc, status):
    # a crash's report (faulthandler: the threads' stacks) before its module list
    fatal = max(proc.stderr.find('Fatal Python error'), 0)
    assert proc.returncode == status, (name, proc.returncode, proc.stderr[fatal:fatal + 4000])
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith('gyro-emulator ') and 'Traceback' not in proc.stderr, proc.stderr
    for rel in COMMANDS[name][1]:
        path = os.path.join(out, rel)
        if os.path.lexists(path):
            assert _complete(path, os.path.join(reference, rel)), (name, rel, last)
    assert _temporaries(out) == [], (name, _temporaries(out))
    return last


def _limited(limit):
    def before():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return before


def _cpu_s(proc):
    try:
        times = psutil.Process(proc.pid).cpu_times()
    except psutil.Error:
        return None
    return times.user + times.system


def _signalled(args, cwd, signum, cpu_s):
    """
    Run ``args``; send ``signum`` once the process has used ``cpu_s`` of CPU; wait.

    Returns the finished process, or None when it ended before it used that
    much, or had finished its work when the signal came (it is then
    ignored, and the run ends with the command's own status: the caller
    tries again with less).
    """
    # PYTHONFAULTHANDLER: a crash leaves its stacks in stderr (fleet died in CI in the
    # interpreter's exit after a stop: SIGSEGV once, SIGABRT once; a stopped command now
    # ends without it, interrupts.end_process)
    proc = subprocess.Popen([PY, '-m', 'gyro_emulator.cli', *args], cwd=cwd, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env=dict(os.environ, PYTHONPATH=ROOT, PYTHONFAULTHANDLER='1'))
    sent = False
    deadline = time.monotonic() + 600
    while proc.poll() is None and time.monotonic() < deadline:
        used = _cpu_s(proc)
        if used is not None and used >= cpu_s:
            proc.send_signal(signum)
            sent = True
            break
        time.sleep(0.01)
    out, err = proc.communicate(timeout=600)
    if sent and proc.returncode in (0, 1) and 'stopped by' not in err:
        sent = False                                # the work was done: the signal was ignored
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err) if sent else None


@pytest.mark.parametrize('name', sorted(COMMANDS))
def test_a_size_limit_or_a_signal_leaves_outputs_complete_or_absent(inputs, tmp_path, name):
    reference = tmp_path / 'reference'
    reference.mkdir()
    started = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = _run_cli(_args(name, inputs, reference), tmp_path)
    # a check's verdict is its status: 1 for a twin that misses the log, outputs written
    assert proc.returncode in ((0, 1) if name.startswith('check') else (0,)), proc.stderr
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = used.ru_utime + used.ru_stime - started.ru_utime - started.ru_stime
    sizes = [os.path.getsize(os.path.join(p, f)) for rel in COMMANDS[name][1]
             for p, _, files in os.walk(reference / rel) for f in files] + [
        os.path.getsize(reference / rel) for rel in COMMANDS[name][1]
        if os.path.isfile(reference / rel)]
    # a limit below the largest output: it (at least) fails with EFBIG, as on a full disk
    limit = max(256, max(sizes) // 2)
    out = tmp_path / 'limited'
    out.mkdir()
    args = _args(name, inputs, out)
    proc = subprocess.run([PY, '-m', 'gyro_emulator.cli', *args], cwd=tmp_path, text=True,
                          capture_output=True, timeout=600, preexec_fn=_limited(limit),
                          env=dict(os.environ, PYTHONPATH=ROOT))
    last = _check_outcome(name, str(out), str(reference), proc, 2)
    assert 'not written' in last or 'File too large' in last, last
    for signum in (signal.SIGTERM, signal.SIGHUP):
        share = 0.6
        for attempt in range(4):            # the first run may have compiled (more CPU)
            out = tmp_path / f'signal{int(signum)}_{attempt}'
            out.mkdir()
            proc = _signalled(_args(name, inputs, out), tmp_path, signum, share * cpu_s)
            if proc is not None:
                break
            share /= 2
        assert proc is not None, name
        last = _check_outcome(name, str(out), str(reference), proc, 128 + signum)
        assert f'stopped by {signal.Signals(signum).name}' in last, last
