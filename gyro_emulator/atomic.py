"""
Every file the product writes is complete or absent: one atomic write.

An output is written under a temporary name in its own folder
(``.<name>.<pid>.<random>.tmp``), flushed and ``fsync``-ed, then renamed
over the target with ``os.replace`` (atomic on POSIX within one file
system), and the folder is ``fsync``-ed so the rename survives a crash. On
any exception, ``KeyboardInterrupt`` and ``SystemExit`` included (the
command line turns SIGTERM and SIGHUP into one), the temporary is removed
and the target is left as it was.

:func:`staged` gives a temporary *path* for writers that take a path
(matplotlib, pyarrow, a bag directory); :func:`open_atomic` a file handle;
:func:`write_text`, :func:`write_bytes` and :func:`write_json` the common
cases. ``os.replace`` is called here and nowhere else in the package, apart
from ``recording/repair.py``, which swaps the files of a bag in place.

A process killed outright (SIGKILL, a power cut) cannot remove its
temporary; :func:`remove_stale` removes those whose process is proven dead,
and every command calls it on its output folders before it writes
(:func:`gyro_emulator.outputs.check`).
"""

from contextlib import contextmanager
import errno
import json
import os
import re
import secrets
import shutil

#: A full disk, a file size limit (RLIMIT_FSIZE) or a quota: said with the output's name.
_NO_ROOM = (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)
#: Suffix of every staged temporary (``.<name>.<pid>.<hex>.tmp``).
TMP_SUFFIX = '.tmp'
#: The name of a staged temporary: the target's name, the writer's pid, 8 hex digits.
_TMP_NAME = re.compile(r'^\.(?P<name>.+)\.(?P<pid>[0-9]+)\.[0-9a-f]{8}'
                       + re.escape(TMP_SUFFIX) + '$')


def temporary_name(path):
    """Return a fresh temporary path beside ``path`` (hidden, same folder)."""
    folder, name = os.path.split(os.path.abspath(path))
    return os.path.join(folder, f'.{name}.{os.getpid()}.{secrets.token_hex(4)}{TMP_SUFFIX}')


def _pid_alive(pid):
    """Whether process ``pid`` may be alive (only a failed ``kill(pid, 0)`` proves it dead)."""
    if pid <= 0:
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:         # EPERM: alive, another user's
        return True
    return True


def remove_stale(folder):
    """
    Remove the staging temporaries in ``folder`` whose writer is proven dead; return them.

    A temporary is ``.<name>.<pid>.<hex>.tmp`` (:func:`temporary_name`); it is
    removed (a file or a directory tree) only when no process ``pid`` exists.
    A live pid, even one reused by another program, keeps it: it cannot be
    proven stale.
    """
    try:
        entries = os.listdir(folder)
    except OSError:
        return []
    removed = []
    for entry in entries:
        match = _TMP_NAME.match(entry)
        if match and not _pid_alive(int(match.group('pid'))):
            remove(os.path.join(folder, entry))
            removed.append(entry)
    return removed


def _fsync_path(path):
    """``fsync`` a file, or every file of a directory tree, then the directory itself."""
    if os.path.isdir(path):
        for dirpath, _, files in os.walk(path):
            for name in files:
                _fsync_file(os.path.join(dirpath, name))
            _fsync_dir(dirpath)
    elif os.path.exists(path):
        _fsync_file(path)


def _fsync_file(path):
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(folder):
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:          # a folder that cannot be opened (no permission): nothing to sync
        return
    try:
        os.fsync(fd)
    except OSError:          # some file systems refuse fsync on a directory
        pass
    finally:
        os.close(fd)


def remove(path):
    """Remove a file or a directory tree at ``path`` if it is there."""
    if os.path.isdir(path) and not os.path.islink(path):
        shutil.rmtree(path, ignore_errors=True)
    elif os.path.lexists(path):
        try:
            os.unlink(path)
        except OSError:
            pass


@contextmanager
def staged(path):
    """
    Yield a temporary path beside ``path``; on success move it over ``path``.

    The caller writes a file (or a directory) at the yielded path. When the
    block ends normally it is synced to disk and renamed to ``path``; when
    it raises (any ``BaseException``), the temporary is removed and
    ``path`` is untouched. A directory target replaces only a missing or
    empty directory (``os.replace`` semantics).
    """
    tmp = temporary_name(path)
    try:
        yield tmp
        if not os.path.lexists(tmp):
            raise FileNotFoundError(f'{path}: nothing was written')
        _fsync_path(tmp)
        os.replace(tmp, path)
        _fsync_dir(os.path.dirname(os.path.abspath(path)))
    except OSError as exc:
        remove(tmp)
        if exc.errno in _NO_ROOM or exc.filename == tmp:
            # say which output, and that it is absent (not the temporary's name)
            raise OSError(exc.errno, f'{path} not written ({exc.strerror}); nothing of it '
                          'was left') from None
        raise
    except BaseException:
        remove(tmp)
        raise


@contextmanager
def open_atomic(path, mode='w', encoding='utf-8', newline=None):
    """
    Open ``path`` for writing so that it is complete or absent (see :func:`staged`).

    ``mode`` is ``'w'`` or ``'wb'``; the file is closed, then synced and
    renamed by :func:`staged`.
    """
    if mode not in ('w', 'wb'):
        raise ValueError(f"open_atomic mode = {mode!r}: allowed 'w' or 'wb'")
    text = mode == 'w'
    with staged(path) as tmp:
        with open(tmp, mode, encoding=encoding if text else None,
                  newline=newline if text else None) as handle:
            yield handle


def write_text(path, text):
    """Write ``text`` (UTF-8) to ``path``, complete or absent."""
    with open_atomic(path) as handle:
        handle.write(text)


def write_bytes(path, data):
    """Write ``data`` to ``path``, complete or absent."""
    with open_atomic(path, 'wb') as handle:
        handle.write(data)


def write_json(path, doc, **dump_kwargs):
    """Write ``doc`` as JSON (``json.dump`` with ``dump_kwargs``), complete or absent."""
    with open_atomic(path) as handle:
        json.dump(doc, handle, **dump_kwargs)
