"""
A fleet run's progress on disk, so that a run that stopped can be finished (``--resume``).

While a fleet runs, ``DIR/.fleet-state/`` holds ``run.json`` (what the run
is: a digest of the fleet, the seed, the number of parts, whether rows are
written) and one ``task-<first block>.json`` per finished task: its
blocks, counts, attribution and sensor runs (what it returned but the
quantile samples, which are recomputed from their blocks: the same draws
give the same float64 metrics). Each file is written whole and then
renamed into place (:mod:`gyro_emulator.atomic`), as is each task's Parquet
file (``part-<first block>.parquet``), so neither ever exists half written.
A finished run deletes the directory.

Resuming keeps the Parquet files of the finished tasks, deletes any other
(a task lost half way leaves none: at most the hidden temporary of its
Parquet file, ``.part-<first block>.parquet.<pid>.<hex>.tmp``, when its
process was killed outright; deleted too), and runs the blocks no finished
task holds. The rows and the summary are those of an uninterrupted run
(``test_fleet.py``), because part i is the same part whatever the
partitioning.

One run at a time writes a directory: a run holds an exclusive lock on
``DIR`` itself (:func:`exclusive`, ``flock``, released when the process
ends, however it ends), and a second run on the same ``DIR`` is refused
in one line before it touches anything.
"""

import contextlib
from dataclasses import replace
import fcntl
import glob
import hashlib
import json
import os
import shutil

from gyro_emulator import atomic
from gyro_emulator.analysis.fleet.sampling import BLOCK_DEVICES

#: The state directory inside a fleet's output directory.
STATE_DIR = '.fleet-state'


@contextlib.contextmanager
def exclusive(out_dir):
    """
    Hold ``out_dir`` for one fleet run: a second run on it is refused in one line.

    The lock is ``flock`` on the directory itself, so it leaves no file
    behind and the kernel releases it when the holder ends (a Ctrl-C, a
    ``kill -9``). A directory made here and still empty at the end (a run
    refused before it wrote) is removed again. On a file system that cannot
    lock (some NFS mounts) the run goes on unguarded.
    """
    made = not os.path.isdir(out_dir)
    try:
        os.makedirs(out_dir, exist_ok=True)
        handle = os.open(out_dir, os.O_RDONLY | os.O_DIRECTORY)
    except OSError as exc:
        raise ValueError(f'fleet.out = {out_dir!r} cannot be used: {exc.strerror}') from None
    try:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise ValueError(f'fleet.out = {out_dir!r} is being written by another fleet run '
                             'now: wait for it to end (then --resume or --overwrite if it '
                             'stopped) or choose another directory') from None
        except OSError:
            pass                        # a file system without locks (some NFS): unguarded
        yield
    finally:
        os.close(handle)
        if made:
            with contextlib.suppress(OSError):
                os.rmdir(out_dir)


def state_dir(out_dir):
    """Return the state directory of ``out_dir``."""
    return os.path.join(out_dir, STATE_DIR)


def fingerprint(job):
    """Return a digest of what makes the rows: the fleet (not its path), seed, size."""
    what = repr((replace(job.config, source=''), job.seed, job.n_devices, job.write,
                 BLOCK_DEVICES))
    if job.config.extended is not None:
        what += repr(job.config.extended)
    return hashlib.sha256(what.encode('utf-8')).hexdigest()


def begin(out_dir, job):
    """Record what the run is (before its first task)."""
    os.makedirs(state_dir(out_dir), exist_ok=True)
    atomic.write_json(os.path.join(state_dir(out_dir), 'run.json'),
                      {'fingerprint': fingerprint(job), 'devices': job.n_devices,
                       'seed': job.seed})


def save(out_dir, result):
    """Record a finished task (its result without the quantile samples)."""
    doc = {key: result[key] for key in ('blocks', 'counts', 'attribution', 'sensor_runs',
                                        'cpu_s')}
    atomic.write_json(os.path.join(state_dir(out_dir), f'task-{result["blocks"][0]:06d}.json'),
                      doc)


def load(out_dir, job):
    """
    Return the finished tasks of an unfinished run in ``out_dir`` (results without samples).

    Raises ValueError (one line) when ``out_dir`` holds a run of another
    fleet, seed or size.
    """
    with open(os.path.join(state_dir(out_dir), 'run.json'), encoding='utf-8') as handle:
        run = json.load(handle)
    if run.get('fingerprint') != fingerprint(job):
        raise ValueError(
            f'fleet.out = {out_dir!r} holds an unfinished run of another fleet, seed or '
            f'size ({run.get("devices")} parts, seed {run.get("seed")}): --resume needs '
            'the same FLEET.yaml, --devices, --seed and --no-parquet; or pass --overwrite')
    results = []
    for path in sorted(glob.glob(os.path.join(state_dir(out_dir), 'task-*.json'))):
        with open(path, encoding='utf-8') as handle:
            result = json.load(handle)
        result['sample'] = []
        results.append(result)
    return results


def prune(out_dir, results):
    """Delete the Parquet files of tasks not in ``results`` and every temporary of one."""
    keep = {f'part-{r["blocks"][0]:06d}.parquet' for r in results}
    devices = os.path.join(out_dir, 'devices')
    for path in glob.glob(os.path.join(devices, 'part-*')):
        if os.path.basename(path) not in keep:
            os.remove(path)
    for path in glob.glob(os.path.join(devices, '.part-*' + atomic.TMP_SUFFIX)):
        atomic.remove(path)


def finish(out_dir):
    """Delete the state of a finished run."""
    shutil.rmtree(state_dir(out_dir), ignore_errors=True)


def remaining(tasks, results):
    """Return the tasks minus the finished blocks, each split into runs of consecutive blocks."""
    done = {b for r in results for b in r['blocks']}
    out = []
    for blocks in tasks:
        run = []
        for block in blocks:
            if block in done:
                if run:
                    out.append(run)
                run = []
            else:
                run.append(block)
        if run:
            out.append(run)
    return out
