"""
The fleet run: schedulers, output directory, progress, summary and plots.

``in-process`` runs the tasks one after the other in this process and needs
no Dask. ``local`` starts a ``dask.distributed.LocalCluster`` for the run
(one single-threaded worker process per core by default) and shuts it down
after; an address (``tcp://HOST:PORT``) uses an existing cluster, whose
workers must import this package and write to ``out_dir`` (docs/fleet.md:
worker settings). While a cluster starts, this process runs the first tasks
itself. The default is ``in-process`` below 1e6 devices and ``local`` from
there on.

Before it starts, a run checks that its output fits on the disk and its
sensor runs in memory (:mod:`.resources`). A task the cluster loses is
submitted again, :data:`TASK_ATTEMPTS` times in all, then the run stops
with one line; every finished task is kept, and ``resume`` finishes the run
(:mod:`.state`).
"""

import functools
import logging
import os
import shutil
import sys
import threading
import time

from gyro_emulator import atomic
from gyro_emulator.analysis.fleet import engine, report, resources, sampling, state
from gyro_emulator.interrupts import wait_sliced
from gyro_emulator.validation import check_range
from tqdm import tqdm

#: Times a task is submitted before a run that keeps losing it fails.
TASK_ATTEMPTS = 3

#: Fleets of at least this many devices run on a LocalCluster by default.
LOCAL_FROM_DEVICES = 1_000_000

#: Most devices in one fleet (1e10: 152 588 blocks).
MAX_DEVICES = 10_000_000_000
#: Most workers of a local cluster.
MAX_WORKERS = 1024

#: Environment of the ``local`` cluster's worker processes. Dask's default sets
#: MALLOC_TRIM_THRESHOLD_, which switches glibc's adaptive mmap threshold off:
#: every array over 128 kB is then mapped and unmapped afresh, page faults and
#: all (a block costs twice the CPU). Here arrays up to 64 MB come from the
#: heap and are reused; BLAS single-threaded, as Dask has it.
WORKER_ENVIRON = {'MALLOC_MMAP_THRESHOLD_': 1 << 26, 'MALLOC_TRIM_THRESHOLD_': 1 << 28,
                  'OMP_NUM_THREADS': 1, 'MKL_NUM_THREADS': 1, 'OPENBLAS_NUM_THREADS': 1}


def default_scheduler(n_devices):
    """Return ``in-process`` below :data:`LOCAL_FROM_DEVICES` devices, else ``local``."""
    return 'local' if n_devices >= LOCAL_FROM_DEVICES else 'in-process'


def _check_scheduler(scheduler):
    if scheduler in ('in-process', 'local') or '://' in str(scheduler):
        return scheduler
    raise ValueError(f'fleet.scheduler = {scheduler!r} is not allowed: choose in-process, '
                     'local or a Dask scheduler address such as tcp://HOST:8786')


class FleetIncomplete(RuntimeError):
    """A fleet that could not finish; its finished tasks are kept for ``--resume``."""


#: What a fleet writes in its output directory.
OUTPUTS = ('devices', 'summary.json', 'plots', state.STATE_DIR)


def _earlier(out_dir):
    return [os.path.join(out_dir, name) for name in OUTPUTS
            if os.path.exists(os.path.join(out_dir, name))]


def _start(job, tasks, overwrite, resume):
    """
    Check the run can finish, prepare ``job.out_dir``; return (finished results, tasks to run).

    Refuses (one line, nothing touched) a directory that holds another fleet
    (unless ``overwrite``) or an unfinished one (unless ``resume``), sensor
    runs that do not fit in memory and output that does not fit on the disk.
    """
    out_dir = job.out_dir
    resources.check_memory(job.config)
    earlier = _earlier(out_dir)
    unfinished = os.path.isdir(state.state_dir(out_dir))
    done = []
    if resume and unfinished and not overwrite:
        done = state.load(out_dir, job)
    elif resume and earlier and not overwrite:
        raise ValueError(f'fleet.out = {out_dir!r} holds a finished fleet: nothing to '
                         'resume; choose another directory or pass --overwrite')
    elif earlier and not overwrite:
        what = 'an unfinished fleet' if unfinished else 'a fleet'
        hint = 'pass --resume to finish it, or --overwrite' if unfinished else \
            'choose another directory or pass --overwrite'
        raise ValueError(f'fleet.out = {out_dir!r} already holds {what} ({earlier[0]}): '
                         + hint)
    todo = state.remaining(tasks, done)
    reclaimed = sum(resources.tree_bytes(p) if os.path.isdir(p) else os.path.getsize(p)
                    for p in earlier) if overwrite else 0
    parts = sum(sampling.block_size(job.n_devices, b) for blocks in todo for b in blocks)
    resources.check_disk(job.config, parts, sum(len(blocks) for blocks in todo), out_dir,
                         job.write, reclaimed)
    if done:
        state.prune(out_dir, done)
    else:
        for path in earlier:
            if os.path.isdir(path):
                shutil.rmtree(path)
            else:
                os.remove(path)
    os.makedirs(os.path.join(out_dir, 'devices'), exist_ok=True)
    os.makedirs(os.path.join(out_dir, 'plots'), exist_ok=True)
    if not done:
        state.begin(out_dir, job)
    return done, todo


def _in_process(job, tasks, bar, finished):
    results = []
    for blocks in tasks:
        results.append(engine.run_task(job, blocks, progress=bar.update))
        finished(results[-1])
    return results


def local_cluster(workers):
    """
    Start the ``local`` scheduler's ``dask.distributed.LocalCluster``.

    ``workers`` single-threaded worker processes with :data:`WORKER_ENVIRON`
    and Dask's profiler off, on free ports, quiet below critical errors (a
    worker it loses, a nanny that fails to restart one, are said by the run
    in one line: :class:`FleetIncomplete`). The caller
    closes it. A fleet can also run on it by address (``cluster.scheduler_address``),
    as on any existing cluster.
    """
    # Dask (0.25 s warm, 0.7 s cold) is imported only by a cluster run: the
    # in-process scheduler, the default below 1e6 devices, needs none of it.
    import dask
    from dask.distributed import LocalCluster

    with dask.config.set({'distributed.nanny.pre-spawn-environ': WORKER_ENVIRON,
                          'distributed.worker.profile.enabled': False}):
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                            scheduler_port=0, dashboard_address=':0',
                            silence_logs=logging.CRITICAL)


class _DaskRun:
    """
    A Dask run whose cluster starts and stops while this process works.

    The cluster (or the client of an existing one) starts in a thread; until
    it is up, this process runs tasks itself, so the 1-3 s a process cluster
    takes to start costs no time. The cluster closes in a thread too, while
    the summary and plots are written (:meth:`join` waits for it).

    The threads' ends are events (:attr:`started`, :attr:`closed`), not
    ``Thread.join``: on Python 3.11 a join that a signal's exception
    interrupts marks the thread it waited for as stopped while it still runs
    (``threading._wait_for_tstate_lock``, bpo-45274), and every later join
    and ``is_alive`` would then pass over the start or the close.
    """

    def __init__(self, scheduler, workers):
        self.scheduler, self.workers = scheduler, workers
        self.cluster = self.client = self.error = None
        self.here = self.resubmitted = 0
        self.started, self.closed = threading.Event(), None
        threading.Thread(target=self._start, daemon=True).start()

    def _start(self):
        from dask.distributed import Client  # lazy: see local_cluster

        try:
            if self.scheduler == 'local':
                self.cluster = local_cluster(self.workers)
                self.client = Client(self.cluster)
            else:
                self.client = Client(self.scheduler, timeout='20s')
        except Exception as exc:        # raised in the caller's thread by run()
            self.error = exc
        finally:
            self.started.set()

    def run(self, job, tasks, bar, finished):
        """
        Run the tasks, a few in flight per worker; return the results in block order.

        Until the cluster is up, this process runs the first blocks itself, one
        block at a time (a block is about 50 ms), and hands the rest of a task
        it has begun to the cluster: a whole task here would keep the workers
        of a cluster that is already running idle for as long as it takes.
        ``finished(result)`` is called as each task ends. A task the cluster
        loses (its worker killed more often than the scheduler's
        ``allowed-failures``, the cluster gone) is submitted again, up to
        :data:`TASK_ATTEMPTS` times in all; then :class:`FleetIncomplete`.
        """
        results = {}
        queue = list(enumerate(tasks))
        while queue and not self.started.is_set():
            index, blocks = queue.pop(0)
            results[blocks[0]] = engine.run_task(job, blocks[:1], progress=bar.update)
            finished(results[blocks[0]])
            if len(blocks) > 1:
                queue.insert(0, (index, blocks[1:]))
        self.here = len(results)
        # sliced: a signal that a Dask thread takes is handled now, not once the start ends
        wait_sliced(self.started.wait, self.started.is_set)
        try:
            if self.error is not None:
                raise self.error
            self._on_cluster(job, queue, results, bar, finished)
        except FleetIncomplete:
            raise
        except Exception as exc:     # the cluster failed to start, or went away
            raise FleetIncomplete(f'the Dask cluster failed ({_first_line(exc)}); the '
                                  f'{len(results)} finished tasks are kept in {job.out_dir}: '
                                  'run again with --resume to finish') from None
        return [results[first] for first in sorted(results)]

    def _on_cluster(self, job, queue, results, bar, finished):
        """Run the queued tasks on the cluster, a few in flight per worker."""
        limit = 2 * max(1, len(self.client.scheduler_info()['workers']))
        self._pending, self._attempts, self._tasks, self._futures = None, {}, {}, {}
        for _ in range(min(limit, len(queue))):
            self._submit(job, *queue.pop(0))
        for future in self._pending or ():
            result = self._result(job, future, len(results))
            if result is None:
                continue
            results[result['blocks'][0]] = result
            finished(result)
            bar.update(sum(sampling.block_size(job.n_devices, b) for b in result['blocks']))
            if queue:
                self._submit(job, *queue.pop(0))

    def _submit(self, job, index, blocks):
        """Submit task ``index`` (again, under a new key, when it was lost)."""
        from dask.distributed import as_completed  # lazy: see local_cluster

        if self._pending is None:
            self._pending = as_completed()
        attempt = self._attempts.get(index, 0) + 1
        self._attempts[index] = attempt
        key = f'fleet-{index}' + (f'-attempt{attempt}' if attempt > 1 else '')
        # The job goes with each task, not scattered once: data scattered to
        # workers is lost with them, and every later task would then fail.
        future = self.client.submit(engine.run_task, job, blocks, key=key, pure=False)
        self._tasks[future.key] = (index, blocks)
        self._futures[future.key] = future
        self._pending.add(future)

    def _result(self, job, future, done):
        """Return a finished task's result, or None when it was lost and submitted again."""
        self._futures.pop(future.key, None)     # in flight: the ones a stop cancels
        try:
            return future.result()
        except Exception as exc:   # lost worker, cancelled future, a task's own error
            index, blocks = self._tasks[future.key]
            if self._attempts[index] < TASK_ATTEMPTS:
                self.resubmitted += 1
                self._submit(job, index, blocks)
                return None
            # Nothing of the run goes on without it: on a shared scheduler its
            # other tasks would keep workers busy (and lose them) for no one.
            self.client.cancel(list(self._futures.values()))
            raise FleetIncomplete(
                f'the cluster lost the task of blocks {blocks[0]}-{blocks[-1]} '
                f'{TASK_ATTEMPTS} times ({_first_line(exc)}); '
                f'the {done} finished tasks are kept in {job.out_dir}: run again with '
                '--resume to finish') from None

    def close(self):
        """Close the client and the cluster in a thread (once they are up)."""
        def stop():
            try:
                self.started.wait()
                if self.client is not None:
                    self.client.close()
                if self.cluster is not None:
                    self.cluster.close()
            finally:
                closed.set()
        self.closed = closed = threading.Event()
        threading.Thread(target=stop, daemon=True).start()

    def join(self):
        """
        Wait until the cluster is closed, through a signal too (raised once it is).

        A stop by a signal ends the process without the interpreter's exit
        (:func:`gyro_emulator.interrupts.end_process`), which would
        otherwise close a cluster left half closed.
        """
        stop = None
        while self.closed is not None and not self.closed.is_set():
            try:
                wait_sliced(self.closed.wait, self.closed.is_set)
            except KeyboardInterrupt as exc:    # SIGINT, or the first SIGTERM/SIGHUP
                stop = stop or exc
        if stop is not None:
            raise stop


def _first_line(exc):
    """Return an exception's type and the first line of its message (at most 120 characters)."""
    text = (str(exc).strip().splitlines() or [''])[0]
    return f'{type(exc).__name__}: {text[:120]}' if text else type(exc).__name__


class _NoBar:
    """Stand-in for a progress bar that shows nothing."""

    def update(self, n):
        """Ignore progress."""

    def close(self):
        """Nothing to close."""


def run_fleet(config, n_devices, seed, out_dir, scheduler=None, workers=None,
              blocks_per_task=None, progress=False, overwrite=False, write=True,
              resume=False):
    """
    Run a fleet and write its Parquet rows, ``summary.json`` and plots to ``out_dir``.

    Parameters
    ----------
    config : FleetConfig
        The fleet (:func:`gyro_emulator.analysis.fleet.config.load_fleet_config`).
    n_devices : int
        Number of parts, 1 to 1e10.
    seed : int
        Root seed (non-negative): device i is the same part for the same seed.
    out_dir : str
        Output directory (``devices/``, ``summary.json``, ``plots/``).
    scheduler : str, optional
        ``in-process``, ``local`` or a Dask address; default
        :func:`default_scheduler`.
    workers : int, optional
        Workers of a ``local`` cluster (default: one per core).
    blocks_per_task : int, optional
        Blocks of 65 536 devices per task (default in-process: about four
        tasks, at most 16 blocks; on Dask: tasks of at most 16 blocks that
        shrink towards the end of the fleet). It changes no result.
    progress : bool or str
        Show a progress bar (tqdm) on stderr; ``'log'``: a line every
        :data:`LOG_PROGRESS_S` s instead (stderr a log, not a terminal).
    overwrite : bool
        Replace an earlier fleet in ``out_dir``.
    write : bool
        Write the per-device Parquet rows (False: summary and plots only).
    resume : bool
        Finish the unfinished run in ``out_dir`` (same fleet, size, seed and
        ``write``): its finished tasks are kept (:mod:`.state`).

    Returns
    -------
    dict
        The summary (also in ``summary.json``).

    Raises
    ------
    ValueError
        One line: bad arguments, an occupied ``out_dir``, output larger than
        the free disk space, sensor runs larger than the available memory.
    FleetIncomplete
        One line: the cluster lost a task :data:`TASK_ATTEMPTS` times; the
        finished tasks are kept for ``resume``.

    """
    n_devices = _whole('n_devices', n_devices, 1, MAX_DEVICES)
    seed = _whole('seed', seed, 0, 2 ** 63 - 1)
    scheduler = _check_scheduler(scheduler or default_scheduler(n_devices))
    if workers is not None:             # given: checked even where it is not used
        _whole('workers', workers, 1, MAX_WORKERS)
    if scheduler == 'in-process':
        workers = 1
    workers = _whole('workers', workers or os.cpu_count() or 1, 1, MAX_WORKERS)
    job = engine.Job(config, seed, n_devices, os.path.abspath(out_dir), write)
    tasks = _tasks(n_devices, workers, blocks_per_task, scheduler)
    with state.exclusive(job.out_dir):
        return _run(job, tasks, scheduler, workers, progress, overwrite, resume)


def _run(job, tasks, scheduler, workers, progress, overwrite, resume):
    """Run the fleet in ``job.out_dir``, held by this run (see :func:`run_fleet`)."""
    n_devices, out_dir = job.n_devices, job.out_dir
    done, todo = _start(job, tasks, overwrite, resume)
    for result in done:
        result['sample'] = engine.sample_blocks(job, result['blocks'])
    bar = _bar(n_devices, sum(r['counts']['devices'] for r in done), progress)
    start = time.perf_counter()
    dask_run = None if scheduler == 'in-process' or not todo else _DaskRun(scheduler, workers)
    finished = functools.partial(state.save, job.out_dir)
    try:
        try:
            if dask_run is None:
                results = _in_process(job, todo, bar, finished)
            else:
                results = dask_run.run(job, todo, bar, finished)
        finally:
            bar.close()
            if dask_run is not None:
                dask_run.close()
        wall = time.perf_counter() - start
        results = sorted(done + results, key=lambda r: r['blocks'][0])
        run = {'scheduler': scheduler, 'workers': workers,
               'blocks_per_task': max(len(blocks) for blocks in tasks),
               'tasks': len(results), 'tasks_here': len(results) if dask_run is None else
               dask_run.here + len(done), 'wall_s': wall}
        if done:
            run['tasks_resumed'] = len(done)
        if dask_run is not None and dask_run.resubmitted:
            run['tasks_resubmitted'] = dask_run.resubmitted
        summary = report.summary(job, results, run)
        atomic.write_json(os.path.join(out_dir, 'summary.json'), summary, indent=2)
        report.plots(job, results, summary, os.path.join(out_dir, 'plots'))
        state.finish(job.out_dir)
    finally:
        if dask_run is not None:
            dask_run.join()
    return summary


def _tasks(n_devices, workers, blocks_per_task, scheduler):
    """
    Return the tasks (lists of blocks) of a run.

    ``blocks_per_task`` given: tasks of that many blocks. Otherwise
    in-process: :func:`engine.default_blocks_per_task`; on Dask: guided
    tasks that shrink towards the end (:func:`engine.guided_tasks`).
    """
    if blocks_per_task is not None:
        size = _whole('blocks_per_task', blocks_per_task, 1, 1 << 20)
    elif scheduler == 'in-process':
        size = engine.default_blocks_per_task(n_devices, workers)
    else:
        return engine.guided_tasks(n_devices, workers)
    return engine.tasks_of(n_devices, size)


def _whole(name, value, low, high):
    if isinstance(value, bool) or not float(value).is_integer():
        raise ValueError(f'fleet.{name} = {value!r} is not a whole number')
    check_range('fleet', name, value, low, high, '', low_open=False)
    return int(value)


def _bar(total, initial, progress):
    """Return the run's progress: a bar (True), lines for a log ('log'), or none (False)."""
    if progress == 'log':
        return LogProgress(total, initial)
    if progress:
        return tqdm(total=total, initial=initial, unit='dev', unit_scale=True, desc='fleet',
                    smoothing=0.1)
    return _NoBar()


#: Seconds between two progress lines of :class:`LogProgress`.
LOG_PROGRESS_S = 60.0


class LogProgress:
    """
    Progress for a log (stderr not a terminal): one line every ``every_s`` s.

    The devices done (``initial`` of them from an earlier run, kept), their
    share of ``total``, the rate of this run and the time left at that
    rate; nothing for a run shorter than ``every_s``. ``clock`` (s) and
    ``stream`` are injected for tests.
    """

    def __init__(self, total, initial=0, every_s=LOG_PROGRESS_S, clock=time.monotonic,
                 stream=None):
        self.total, self.done, self.initial = total, initial, initial
        self.every_s, self.clock = every_s, clock
        self.stream = sys.stderr if stream is None else stream
        self.start = self.last = clock()

    def update(self, n):
        """Count ``n`` more devices; print a line when ``every_s`` has passed."""
        self.done += n
        now = self.clock()
        if now - self.last < self.every_s:
            return
        self.last = now
        rate = (self.done - self.initial) / (now - self.start)
        left = f'{(self.total - self.done) / rate:.0f} s' if rate > 0 else 'unknown'
        print(f'fleet: {self.done:.4g} of {self.total:.4g} devices '
              f'({100.0 * self.done / self.total:.1f} %), {rate:.3g} devices/s, '
              f'time left at that rate {left}', file=self.stream, flush=True)

    def close(self):
        """Nothing to close."""
