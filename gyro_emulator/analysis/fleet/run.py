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
"""

import json
import logging
import os
import shutil
import threading
import time

from gyro_emulator.analysis.fleet import engine, report, sampling
from gyro_emulator.validation import check_range
from tqdm import tqdm

#: Fleets of at least this many devices run on a LocalCluster by default.
LOCAL_FROM_DEVICES = 1_000_000

#: Most devices in one fleet (1e10: 152 588 blocks).
MAX_DEVICES = 10_000_000_000

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


def _prepare(out_dir, overwrite):
    """Create the output directory; refuse to mix with an earlier fleet unless told to."""
    parts = os.path.join(out_dir, 'devices')
    earlier = [os.path.join(out_dir, name) for name in ('devices', 'summary.json', 'plots')
               if os.path.exists(os.path.join(out_dir, name))]
    if earlier and not overwrite:
        raise ValueError(f'fleet.out = {out_dir!r} already holds a fleet ({earlier[0]}): '
                         'choose another directory or pass --overwrite')
    for path in earlier:
        if os.path.isdir(path):
            shutil.rmtree(path)
        else:
            os.remove(path)
    os.makedirs(parts, exist_ok=True)
    os.makedirs(os.path.join(out_dir, 'plots'), exist_ok=True)


def _in_process(job, tasks, bar):
    return [engine.run_task(job, blocks, progress=bar.update) for blocks in tasks]


def local_cluster(workers):
    """
    Start the ``local`` scheduler's ``dask.distributed.LocalCluster``.

    ``workers`` single-threaded worker processes with :data:`WORKER_ENVIRON`
    and Dask's profiler off, on free ports, quiet below errors. The caller
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
                            silence_logs=logging.ERROR)


class _DaskRun:
    """
    A Dask run whose cluster starts and stops while this process works.

    The cluster (or the client of an existing one) starts in a thread; until
    it is up, this process runs tasks itself, so the 1-3 s a process cluster
    takes to start costs no time. The cluster closes in a thread too, while
    the summary and plots are written (:meth:`join` waits for it).
    """

    def __init__(self, scheduler, workers):
        self.scheduler, self.workers = scheduler, workers
        self.cluster = self.client = self.error = self.closer = None
        self.here = 0
        self.starter = threading.Thread(target=self._start, daemon=True)
        self.starter.start()

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

    def run(self, job, tasks, bar):
        """
        Run the tasks, a few in flight per worker; return the results in block order.

        Until the cluster is up, this process runs the first blocks itself, one
        block at a time (a block is about 50 ms), and hands the rest of a task
        it has begun to the cluster: a whole task here would keep the workers
        of a cluster that is already running idle for as long as it takes.
        """
        from dask.distributed import as_completed  # lazy: see local_cluster

        results = {}
        queue = list(enumerate(tasks))
        while queue and self.starter.is_alive():
            index, blocks = queue.pop(0)
            results[blocks[0]] = engine.run_task(job, blocks[:1], progress=bar.update)
            if len(blocks) > 1:
                queue.insert(0, (index, blocks[1:]))
        self.here = len(results)
        self.starter.join()
        if self.error is not None:
            raise self.error
        client = self.client
        shared = client.scatter(job, broadcast=True)
        limit = 2 * max(1, len(client.scheduler_info()['workers']))
        pending = as_completed()
        for _ in range(min(limit, len(queue))):
            index, blocks = queue.pop(0)
            pending.add(client.submit(engine.run_task, shared, blocks, key=f'fleet-{index}'))
        for future in pending:
            result = future.result()
            results[result['blocks'][0]] = result
            bar.update(sum(sampling.block_size(job.n_devices, b) for b in result['blocks']))
            if queue:
                index, blocks = queue.pop(0)
                pending.add(client.submit(engine.run_task, shared, blocks,
                                          key=f'fleet-{index}'))
        return [results[first] for first in sorted(results)]

    def close(self):
        """Close the client and the cluster in a thread."""
        def stop():
            self.starter.join()
            if self.client is not None:
                self.client.close()
            if self.cluster is not None:
                self.cluster.close()
        self.closer = threading.Thread(target=stop, daemon=True)
        self.closer.start()

    def join(self):
        """Wait until the cluster is closed."""
        if self.closer is not None:
            self.closer.join()


class _NoBar:
    """Stand-in for a progress bar that shows nothing."""

    def update(self, n):
        """Ignore progress."""

    def close(self):
        """Nothing to close."""


def run_fleet(config, n_devices, seed, out_dir, scheduler=None, workers=None,
              blocks_per_task=None, progress=False, overwrite=False, write=True):
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
    progress : bool
        Show a progress bar (tqdm) on stderr.
    overwrite : bool
        Replace an earlier fleet in ``out_dir``.
    write : bool
        Write the per-device Parquet rows (False: summary and plots only).

    Returns
    -------
    dict
        The summary (also in ``summary.json``).

    """
    n_devices = _whole('n_devices', n_devices, 1, MAX_DEVICES)
    seed = _whole('seed', seed, 0, 2 ** 63 - 1)
    scheduler = _check_scheduler(scheduler or default_scheduler(n_devices))
    if scheduler == 'in-process':
        workers = 1
    workers = _whole('workers', workers or os.cpu_count() or 1, 1, 1024)
    tasks = _tasks(n_devices, workers, blocks_per_task, scheduler)
    _prepare(out_dir, overwrite)
    job = engine.Job(config, seed, n_devices, os.path.abspath(out_dir), write)
    bar = _bar(n_devices) if progress else _NoBar()
    start = time.perf_counter()
    dask_run = None if scheduler == 'in-process' else _DaskRun(scheduler, workers)
    try:
        try:
            if dask_run is None:
                results = _in_process(job, tasks, bar)
            else:
                results = dask_run.run(job, tasks, bar)
        finally:
            bar.close()
            if dask_run is not None:
                dask_run.close()
        wall = time.perf_counter() - start
        run = {'scheduler': scheduler, 'workers': workers,
               'blocks_per_task': max(len(blocks) for blocks in tasks),
               'tasks': len(results), 'tasks_here': len(results) if dask_run is None else
               dask_run.here, 'wall_s': wall}
        summary = report.summary(job, results, run)
        with open(os.path.join(out_dir, 'summary.json'), 'w', encoding='utf-8') as handle:
            json.dump(summary, handle, indent=2)
        report.plots(job, results, summary, os.path.join(out_dir, 'plots'))
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


def _bar(total):
    return tqdm(total=total, unit='dev', unit_scale=True, desc='fleet', smoothing=0.1)
