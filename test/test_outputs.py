"""The one output check, stale temporaries, signals as exceptions, bounded YAML, long CSVs."""

import os
import signal
import subprocess
import sys
import time

from gyro_emulator import atomic, outputs
from gyro_emulator.interrupts import Terminated, TerminateOnSignal
from gyro_emulator.recording import binning, csvio
from gyro_emulator.resources import load_yaml_text, MAX_YAML_NODES, read_yaml
from gyro_emulator.validation import check_record_values, quote
import numpy as np
import pytest


def _files(folder):
    return sorted(os.listdir(folder))


# --- outputs.check ------------------------------------------------------------

def test_an_output_that_is_an_input_is_refused_through_a_link_too(tmp_path):
    log = tmp_path / 'log.csv'
    log.write_text('time_s\n0\n')
    link = tmp_path / 'link.csv'
    link.symlink_to(log)
    for path in (log, link, tmp_path / 'sub' / '..' / 'log.csv'):
        with pytest.raises(ValueError, match=r'--json .* is the input .*log.csv: an output '
                                             'never replaces an input'):
            outputs.check([outputs.file('--json', str(path))], inputs=[str(log)],
                          overwrite=True)
    assert log.read_text() == 'time_s\n0\n'


def test_outputs_inside_or_holding_an_input_directory_are_refused(tmp_path):
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'bag_0.mcap').write_bytes(b'x')
    with pytest.raises(ValueError, match='lies inside the input'):
        outputs.check([outputs.file('--json', str(bag / 'metadata.yaml'))], inputs=[str(bag)])
    with pytest.raises(ValueError, match='holds the input .* would delete the input'):
        outputs.check([outputs.directory('--out', str(tmp_path))], inputs=[str(bag)],
                      overwrite=True)
    with pytest.raises(ValueError, match='is the input'):
        outputs.check([outputs.inside('--out', str(tmp_path), ('bag',))], inputs=[str(bag)],
                      overwrite=True)
    with pytest.raises(ValueError, match=r'--out .*tmp.* holds the input'):
        outputs.check([outputs.inside('--out', str(tmp_path.parent), (tmp_path.name,))],
                      inputs=[str(bag / 'bag_0.mcap')], overwrite=True)
    # a folder of named outputs that only sits beside the input is fine
    outputs.check([outputs.inside('--out', str(tmp_path), ('report.md',))], inputs=[str(bag)])


def test_two_outputs_of_one_name_existing_outputs_and_bad_folders(tmp_path):
    a = str(tmp_path / 'a.json')
    with pytest.raises(ValueError, match='--json and --write-config both write'):
        outputs.check([outputs.file('--json', a), outputs.file('--write-config', a)])
    (tmp_path / 'a.json').write_text('{}')
    with pytest.raises(ValueError, match=r'--json .*a.json exists: pass --overwrite'):
        outputs.check([outputs.file('--json', a)])
    outputs.check([outputs.file('--json', a)], overwrite=True)
    (tmp_path / 'file').write_text('')
    with pytest.raises(ValueError, match=r'file is a file, not a folder'):
        outputs.check([outputs.file('--json', str(tmp_path / 'file' / 'deeper' / 'x.json'))])
    with pytest.raises(ValueError, match='is a directory: give a file name'):
        outputs.check([outputs.file('--json', str(tmp_path))], overwrite=True)
    with pytest.raises(ValueError, match='no file name'):
        outputs.check([outputs.file('--json', str(tmp_path / 'new') + '/')])
    with pytest.raises(ValueError, match='is a file, not a folder'):
        outputs.check([outputs.inside('--report', str(tmp_path / 'file'), ('report.md',))])
    (tmp_path / 'rep').mkdir()
    (tmp_path / 'rep' / 'report.md').write_text('old')
    with pytest.raises(ValueError, match=r'--report .*report.md exists'):
        outputs.check([outputs.inside('--report', str(tmp_path / 'rep'), ('report.md', 'x'))])
    outputs.check([None, outputs.file('--plot', None)])      # options not given


def test_a_plot_format_matplotlib_cannot_write_is_refused_before_the_work(tmp_path, capsys):
    """
    Before, ``calibrate noise --plot p.txt`` wrote its export, then failed on the plot (exit 2).

    The image's name is what ``savefig`` writes: no extension gets ``.png``.
    """
    from gyro_emulator import cli
    assert outputs.image('--plot', str(tmp_path / 'adev')).path == str(tmp_path / 'adev.png')
    with pytest.raises(ValueError, match=r"--plot .*p.txt: 'txt' is not an image format; "
                                         'allowed: .*png'):
        outputs.image('--plot', str(tmp_path / 'p.txt'))
    log = tmp_path / 'log.csv'
    rng = np.random.default_rng(3)
    csvio.write_csv(str(log), {'time_s': np.arange(6000) / 100.0,
                               'gyro_rad_s': rng.normal(0.0, 1e-3, 6000)})
    out = tmp_path / 'imu.yaml'
    code = cli.main(['calibrate', 'noise', str(log), '--format', 'kalibr', '-o', str(out),
                     '--plot', str(tmp_path / 'p.txt')])
    err = capsys.readouterr().err
    assert code == 2 and "'txt' is not an image format" in err
    assert len(err.strip().splitlines()) == 1 and 'Traceback' not in err
    assert _files(tmp_path) == ['log.csv']


def test_a_folder_that_cannot_be_written_is_refused_before_the_work(tmp_path):
    if os.geteuid() == 0:
        pytest.skip('root writes anywhere')
    locked = tmp_path / 'locked'
    locked.mkdir()
    locked.chmod(0o500)
    try:
        with pytest.raises(ValueError, match='cannot write in'):
            outputs.check([outputs.file('--json', str(locked / 'x.json'))])
    finally:
        locked.chmod(0o700)


def _dead_pid():
    """Return the pid of a process that has exited (and was reaped)."""
    proc = subprocess.Popen([sys.executable, '-c', 'pass'])
    proc.wait()
    return proc.pid


def test_stale_temporaries_of_dead_writers_are_removed_live_ones_kept(tmp_path):
    dead = _dead_pid()
    stale_file = tmp_path / f'.out.csv.{dead}.0a1b2c3d{atomic.TMP_SUFFIX}'
    stale_file.write_text('half')
    stale_dir = tmp_path / f'.bag.{dead}.deadbeef{atomic.TMP_SUFFIX}'
    stale_dir.mkdir()
    (stale_dir / 'bag_0.mcap').write_bytes(b'half')
    live = tmp_path / f'.out.csv.{os.getpid()}.0a1b2c3d{atomic.TMP_SUFFIX}'
    live.write_text('writing')
    other = tmp_path / f'.notes.{dead}.tmp'            # not the staging pattern: kept
    other.write_text('mine')
    outputs.check([outputs.file('--out', str(tmp_path / 'out.csv'))])
    assert _files(tmp_path) == sorted([live.name, other.name])


# --- SIGTERM and SIGHUP -------------------------------------------------------------

@pytest.mark.parametrize('signum', [signal.SIGTERM, signal.SIGHUP])
def test_a_signal_inside_the_guard_raises_terminated_and_staged_cleans_up(tmp_path, signum):
    target = tmp_path / 'out.bin'
    guard = TerminateOnSignal()
    with pytest.raises(Terminated) as caught:
        with guard:
            with atomic.open_atomic(str(target), 'wb') as handle:
                handle.write(b'half')
                os.kill(os.getpid(), signum)
                time.sleep(5)                   # the handler raises long before
    assert caught.value.status == 128 + signum and guard.received is caught.value
    assert isinstance(caught.value, KeyboardInterrupt)
    assert _files(tmp_path) == []
    assert signal.getsignal(signum) is not guard._on_signal       # restored


# --- the bounded YAML loader -------------------------------------------------------

def _bomb(levels, width=9):
    text = 'a0: &a0 [' + ', '.join(['0'] * width) + ']\n'
    for i in range(1, levels):
        text += f'a{i}: &a{i} [' + ', '.join([f'*a{i - 1}'] * width) + ']\n'
    return text


def test_alias_bombs_deep_nesting_and_recursion_are_refused_fast():
    with pytest.raises(ValueError, match=f'expand to more than {MAX_YAML_NODES} nodes'):
        load_yaml_text(_bomb(9), 'bomb.yaml')
    with pytest.raises(ValueError, match='nested more than'):
        load_yaml_text('[' * 10_000 + ']' * 10_000, 'deep.yaml')
    with pytest.raises(ValueError, match='refers to itself'):
        load_yaml_text('a: &a [1, *a]\n', 'loop.yaml')
    with pytest.raises(ValueError, match='aliases are refused here'):
        load_yaml_text('a: &a 1\nb: *a\n', 'meta.yaml', aliases=False)
    # small aliases are YAML: they stay allowed
    assert load_yaml_text('a: &a [1, 2]\nb: *a\n', 'ok.yaml') == {'a': [1, 2], 'b': [1, 2]}


@pytest.mark.parametrize('text, line, key', [
    ('a: 1\na: 2\n', 2, 'a'),
    ('device:\n  preset: paper\n  seed: 1\n  preset: consumer\n', 4, 'preset'),
    ('parts:\n  - {k: 1, k: 2}\n', 2, 'k'),
])
def test_a_key_given_twice_is_refused_not_dropped(text, line, key):
    # The YAML loader keeps the last value of a repeated key and drops the
    # first silently: a fleet's tolerance or a sensor field would vanish.
    with pytest.raises(ValueError, match=f"f.yaml: line {line}: key '{key}' is given twice "
                                         'in one mapping') as caught:
        load_yaml_text(text, 'f.yaml')
    assert '\n' not in str(caught.value)


def test_the_same_key_in_different_mappings_is_yaml():
    text = ('a: {x: 1}\nb: {x: 2}\nl:\n  - {x: 1}\n  - {x: 2}\n'
            'base: &b {x: 1}\nd:\n  <<: *b\n  y: 2\n')
    assert load_yaml_text(text, 'ok.yaml') == {
        'a': {'x': 1}, 'b': {'x': 2}, 'l': [{'x': 1}, {'x': 2}], 'base': {'x': 1},
        'd': {'x': 1, 'y': 2}}


def test_read_yaml_bounds_size_and_names_the_file(tmp_path):
    big = tmp_path / 'big.yaml'
    big.write_text('a: ' + 'x' * 100 + '\n')
    with pytest.raises(ValueError, match='big.yaml is over 0 MiB'):
        read_yaml(str(big), max_bytes=50)
    bad = tmp_path / 'bad.yaml'
    bad.write_bytes(b'a: \xff\xfe\n')
    with pytest.raises(ValueError, match='bad.yaml: cannot read: not UTF-8'):
        read_yaml(str(bad))
    broken = tmp_path / 'broken.yaml'
    broken.write_text('a: [' + 'x, ' * 10_000 + '\n')
    with pytest.raises(ValueError, match='broken.yaml: malformed YAML') as caught:
        read_yaml(str(broken))
    assert len(str(caught.value)) < 600


def test_quote_cuts_large_values_and_keeps_small_ones_as_repr():
    assert quote([1.0, 2.0]) == repr([1.0, 2.0]) and quote('a') == "'a'"
    nested = [[0.0] * 9] * 9
    for _ in range(5):
        nested = [nested] * 9
    text = quote(nested)          # 9^6 lists: the repr is built only as far as shown
    assert len(text) < 300 and text.endswith('(a large value, shown in part)')
    assert len(quote('x' * 10_000)) < 260


def test_one_rule_for_a_record_s_values():
    check_record_values('MeasuredData', 'rate_cmd_rad_s', np.array([0.0, 999.0]), 'rate')
    with pytest.raises(ValueError, match=r'log.csv.rate = 5000.0 at sample 2 \(data row 3\) is '
                                         r'beyond \[-1000, 1000\] rad/s'):
        check_record_values('log.csv', 'rate', np.array([[0, 0, 0], [1, 2, 3],
                                                         [0, 5000.0, 0]]), 'rate')
    with pytest.raises(ValueError, match='temp = -80.0 at sample 0'):
        check_record_values('log.csv', 'temp', np.array([-80.0]), 'temp')


# --- a CSV longer than a command holds ---------------------------------------------

def _write_log(path, n, step=0.01, gap_at=None):
    t = np.arange(n) * step
    if gap_at is not None:
        t[gap_at:] += 50.0
    rng = np.random.default_rng(4)
    csvio.write_csv(str(path), {'time_s': t, 'rate_cmd_rad_s': np.sin(t / 30.0),
                                'temp_c': 25.0 + t / 1000.0,
                                'gyro_rad_s': 1e-3 * rng.standard_normal(n)}, '%.12g')
    return t


@pytest.mark.parametrize('name', ['log.csv', 'log.csv.gz'])
def test_a_log_that_fits_is_read_value_for_value(tmp_path, name):
    path = tmp_path / name
    _write_log(path, 2500)
    whole = csvio.read_csv(str(path), ('time_s',), 'nondecreasing')
    columns, note = binning.read_csv_bounded(str(path), ('time_s',), 'nondecreasing',
                                             max_rows=2500, block_rows=700)
    assert note is None and list(columns) == list(whole)
    for key in whole:
        np.testing.assert_array_equal(columns[key], whole[key])


@pytest.mark.parametrize('name', ['log.csv', 'log.csv.gz'])
def test_a_longer_log_is_averaged_over_time_bins_in_blocks(tmp_path, name):
    path = tmp_path / name
    t = _write_log(path, 10_000, gap_at=6000)
    whole = csvio.read_csv(str(path), ('time_s',), 'nondecreasing')
    columns, note = binning.read_csv_bounded(str(path), ('time_s',), 'nondecreasing',
                                             max_rows=1000, block_rows=1500)
    assert str(note).startswith('10000 rows are more than the 1000 held')
    n = len(columns['time_s'])
    assert 400 < n <= 1000 and note.kept == n and note.rows == 10_000
    index = np.floor((whole['time_s'] - t[0]) / note.width_s).astype(int)
    for key, values in whole.items():         # each bin is the mean of its samples
        kept, inverse = np.unique(index, return_inverse=True)
        expected = np.bincount(inverse, weights=values) / np.bincount(inverse)
        np.testing.assert_allclose(columns[key], expected, rtol=1e-12, atol=1e-15)
    step = np.diff(columns['time_s'])
    assert step.max() > 45.0                   # the gap stays a gap


def test_a_bad_row_of_a_long_log_is_named_with_the_file_s_row(tmp_path):
    path = tmp_path / 'log.csv'
    _write_log(path, 5000)
    lines = path.read_text().splitlines()
    lines[4001] = lines[4001].replace(lines[4001].split(',')[3], 'nan')
    path.write_text('\n'.join(lines) + '\n')
    with pytest.raises(ValueError, match='data row 4001, column gyro_rad_s: nan is not finite'):
        binning.read_csv_bounded(str(path), ('time_s',), 'nondecreasing', max_rows=1000,
                                 block_rows=1500)
    lines[4001] = lines[4001].replace('nan', '0.0').replace(lines[4001].split(',')[0], '1.0')
    path.write_text('\n'.join(lines) + '\n')
    with pytest.raises(ValueError, match='time_s does not increase at data row 4001'):
        binning.read_csv_bounded(str(path), ('time_s',), 'nondecreasing', max_rows=1000,
                                 block_rows=1500)


def test_a_signal_while_deferring_is_raised_when_armed(tmp_path):
    """The command line is parsed with the signals deferred; arming acts on one that came."""
    guard = TerminateOnSignal(defer=True)
    with pytest.raises(Terminated) as caught:
        with guard:
            os.kill(os.getpid(), signal.SIGHUP)
            time.sleep(0.05)                    # deferred: nothing raised here
            assert guard.received is not None
            guard.arm()
    assert caught.value.status == 129


def _python(script):
    """Run ``script`` in a new Python with the checkout on its path; return the finished run."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    return subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                          timeout=60, env=dict(os.environ, PYTHONPATH=root))


def test_after_close_a_signal_is_ignored_and_the_status_is_the_command_s():
    """A signal once the work is done neither kills the process nor runs during its exit."""
    script = (
        'import os, signal, time\n'
        'from gyro_emulator.interrupts import TerminateOnSignal\n'
        'with TerminateOnSignal() as guard:\n'
        '    guard.close()\n'
        '    os.kill(os.getpid(), signal.SIGTERM)\n'
        '    os.kill(os.getpid(), signal.SIGHUP)\n'
        '    time.sleep(0.05)\n'
        'os.kill(os.getpid(), signal.SIGTERM)\n'
        'print("finished", guard.received)\n'
        'raise SystemExit(3)\n')
    proc = _python(script)
    assert (proc.returncode, proc.stdout, proc.stderr) == (3, 'finished None\n', '')


def test_after_close_a_signal_another_thread_takes_is_ignored_too():
    """A signal mask is one thread's: one that a library's thread takes must not end the run."""
    script = (
        'import signal, threading\n'
        'from gyro_emulator.interrupts import TerminateOnSignal\n'
        'go = threading.Event()\n'
        'def other():\n'
        '    go.wait()\n'
        '    for sig in (signal.SIGTERM, signal.SIGHUP):\n'
        '        signal.pthread_kill(threading.get_ident(), sig)\n'
        'thread = threading.Thread(target=other)\n'
        'thread.start()\n'
        'with TerminateOnSignal() as guard:\n'
        '    guard.close()\n'
        'go.set()\n'
        'thread.join()\n'
        'print("finished", guard.received)\n'
        'raise SystemExit(3)\n')
    proc = _python(script)
    assert (proc.returncode, proc.stdout, proc.stderr) == (3, 'finished None\n', '')


#: A native exit hook that needs the interpreter, as a compiled library that a signal
#: cut short can leave: a ctypes callback that the C library runs at exit(), after
#: Python's finalization.
_EXIT_HOOK = (
    'import ctypes\n'
    'hook = ctypes.CFUNCTYPE(None, ctypes.c_void_p)(lambda _: None)\n'
    'ctypes.CDLL("libc.so.6").__cxa_atexit(hook, None, None)\n')


def test_a_command_stopped_by_a_signal_ends_without_the_interpreter_s_exit(tmp_path):
    """A stopped command ends with its status, even where a library's exit would crash."""
    out = tmp_path / 'truth.csv'
    script = _EXIT_HOOK + (
        'import os, signal, sys\n'
        'from gyro_emulator.cli import main\n'
        # SIGTERM after 0.05 s of CPU: while the command line is parsed (its modules
        # imported) or the truth is drawn, always after the guard is in place
        'signal.signal(signal.SIGPROF, lambda *_: os.kill(os.getpid(), signal.SIGTERM))\n'
        'signal.setitimer(signal.ITIMER_PROF, 0.05)\n'
        f'sys.exit(main(["truth", {str(out)!r}, "--seed", "3", "--profile", "static", '
        '"--duration", "3000", "--rate", "50"], signals=True))\n')
    proc = _python(script)
    assert proc.returncode == 143, proc.stderr
    assert proc.stderr == ('gyro-emulator truth: stopped by SIGTERM; unfinished outputs '
                           'removed\n') and _files(tmp_path) == []
    # the hook is a real hazard: an exit through the interpreter's finalization dies of it
    proc = _python(_EXIT_HOOK + 'raise SystemExit(3)\n')
    assert proc.returncode < 0, (proc.returncode, proc.stderr)


def test_a_signal_raised_inside_a_callback_is_kept_without_a_traceback():
    """A weakref callback cannot pass the exception on: no 'Exception ignored', it is kept."""
    script = (
        'import os, signal, weakref\n'
        'from gyro_emulator.interrupts import TerminateOnSignal\n'
        'class Part:\n'
        '    pass\n'
        'def callback(_):\n'
        '    os.kill(os.getpid(), signal.SIGTERM)\n'
        '    for _ in range(10 ** 6):\n'
        '        pass\n'                                  # the handler raises in here
        'with TerminateOnSignal() as guard:\n'
        '    part = Part()\n'
        '    ref = weakref.ref(part, callback)\n'
        '    del part\n'
        '    print("kept", guard.received.status)\n')
    proc = _python(script)
    assert (proc.returncode, proc.stdout, proc.stderr) == (0, 'kept 143\n', '')
