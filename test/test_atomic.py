"""One atomic write: an output is complete or absent, whatever stops the writer."""

import json
import os
import signal
import subprocess
import sys
import textwrap

from gyro_emulator import atomic
import pytest


def _leftovers(folder):
    return sorted(n for n in os.listdir(folder) if n.endswith(atomic.TMP_SUFFIX))


def test_text_bytes_json_written_whole(tmp_path):
    atomic.write_text(tmp_path / 'a.txt', 'hello\n')
    atomic.write_bytes(tmp_path / 'b.bin', b'\x00\x01')
    atomic.write_json(tmp_path / 'c.json', {'x': 1.5}, indent=1)
    assert (tmp_path / 'a.txt').read_text() == 'hello\n'
    assert (tmp_path / 'b.bin').read_bytes() == b'\x00\x01'
    assert json.loads((tmp_path / 'c.json').read_text()) == {'x': 1.5}
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize('error', [RuntimeError, KeyboardInterrupt, SystemExit])
def test_error_mid_write_leaves_the_old_file_and_no_temporary(tmp_path, error):
    target = tmp_path / 'out.yaml'
    target.write_text('old\n')
    with pytest.raises(error):
        with atomic.open_atomic(target) as handle:
            handle.write('half')
            raise error()
    assert target.read_text() == 'old\n'
    assert _leftovers(tmp_path) == []


def test_staged_directory_replaces_a_missing_target(tmp_path):
    target = tmp_path / 'bag'
    with atomic.staged(target) as tmp:
        os.makedirs(tmp)
        with open(os.path.join(tmp, 'x.mcap'), 'wb') as handle:
            handle.write(b'data')
    assert (target / 'x.mcap').read_bytes() == b'data'
    with pytest.raises(ValueError):
        with atomic.staged(tmp_path / 'other') as tmp:
            os.makedirs(tmp)
            raise ValueError('stop')
    assert not (tmp_path / 'other').exists()
    assert _leftovers(tmp_path) == []


def test_nothing_written_is_an_error_and_leaves_nothing(tmp_path):
    with pytest.raises(FileNotFoundError, match='nothing was written'):
        with atomic.staged(tmp_path / 'x.png'):
            pass
    assert os.listdir(tmp_path) == []


def test_an_output_that_cannot_be_opened_is_named_not_its_temporary(tmp_path):
    # the folder of the output is a file: opening the temporary beside it fails
    (tmp_path / 'folder').write_text('a file\n')
    target = tmp_path / 'folder' / 'out.csv'
    with pytest.raises(NotADirectoryError) as caught:
        atomic.write_text(target, 'x\n')
    assert str(caught.value) == (f'[Errno {caught.value.errno}] {target} not written (Not a '
                                 'directory); nothing of it was left')
    assert atomic.TMP_SUFFIX not in str(caught.value)


def test_full_file_size_limit_leaves_no_partial_file(tmp_path):
    """RLIMIT_FSIZE stops the write half way: the target stays absent."""
    script = textwrap.dedent(f"""
        import resource, signal, sys
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))
        sys.path.insert(0, {os.path.dirname(os.path.dirname(atomic.__file__))!r})
        from gyro_emulator import atomic
        try:
            atomic.write_text({str(tmp_path / 'big.json')!r}, 'x' * 100000)
        except OSError as exc:
            print('refused', exc.errno)
    """)
    out = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                         check=True)
    assert out.stdout.startswith('refused')
    assert os.listdir(tmp_path) == []


def test_sigterm_turned_into_an_exception_removes_the_temporary(tmp_path):
    """A writer killed by SIGTERM while its handler raises leaves nothing behind."""
    script = textwrap.dedent(f"""
        import os, signal, sys, time
        sys.path.insert(0, {os.path.dirname(os.path.dirname(atomic.__file__))!r})
        from gyro_emulator import atomic
        def stop(signum, frame):
            raise SystemExit(143)
        signal.signal(signal.SIGTERM, stop)
        with atomic.open_atomic({str(tmp_path / 'out.csv')!r}) as handle:
            handle.write('partial')
            handle.flush()
            print('writing', flush=True)
            time.sleep(60)
    """)
    proc = subprocess.Popen([sys.executable, '-c', script], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == 'writing'
    assert len(_leftovers(tmp_path)) == 1
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=60) == 143
    assert os.listdir(tmp_path) == []
