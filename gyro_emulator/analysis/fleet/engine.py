"""
Running a fleet: blocks of devices as tasks, in-process or on Dask, to Parquet.

Blocks of :data:`~gyro_emulator.analysis.fleet.sampling.BLOCK_DEVICES`
devices are grouped into tasks (``blocks_per_task``). A task draws,
evaluates and judges its blocks one at a time and streams them into its own
Parquet file (``devices/part-<first block>.parquet``, one row group per
block, one row per device), so memory stays bounded whatever the fleet
size; it returns only counts, the metrics of the blocks kept for the
quantiles (the first :data:`QUANTILE_BLOCKS`), and, for block 0, the
attribution and the sensor-level runs. The same code runs in this process
(``in-process``: no Dask), on a ``dask.distributed.LocalCluster``
(``local``) or on an existing cluster (``tcp://HOST:PORT``); the rows, and
the summary but for its timing figures, are bit for bit the same.
"""

from dataclasses import dataclass
import os
import time

from gyro_emulator import atomic
from gyro_emulator.analysis.fleet import evaluate as fleet_eval
from gyro_emulator.analysis.fleet import sampling
from gyro_emulator.analysis.fleet.config import EXACT_METRICS, METRICS
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

#: Blocks whose metrics come back for the quantiles (the first 131 072 parts).
QUANTILE_BLOCKS = 2

#: Most blocks in one task (about a million devices).
MAX_BLOCKS_PER_TASK = 16


@dataclass(frozen=True)
class Job:
    """What every task of a run shares (pickled to the workers)."""

    config: object
    seed: int
    n_devices: int
    out_dir: str
    write: bool = True


def temperature_label(temp_c):
    """Column suffix of a grid temperature: -40 -> ``m40c``, 25 -> ``25c``, 2.5 -> ``2p5c``."""
    text = f'{abs(temp_c):g}'.replace('.', 'p')
    return ('m' if temp_c < 0 else '') + text + 'c'


def metric_names(config):
    """Return the per-device metrics of this fleet, in column order."""
    return tuple(m for m in METRICS if config.exact or m not in EXACT_METRICS)


def _table(job, block, values, invalid, clipped, metrics, per_spec, ok, per_check):
    """One block as a pyarrow Table (float32 values; flags computed in float64)."""
    config = job.config
    n = len(ok)
    first = block * sampling.BLOCK_DEVICES
    columns = {'device_id': pa.array(np.arange(first, first + n, dtype=np.int64)),
               'valid': pa.array(~invalid), 'clipped': pa.array(clipped)}
    for name in config.varied:
        columns[name] = pa.array(values[name].astype(np.float32))
    for name in metric_names(config):
        columns[name] = pa.array(metrics[name].astype(np.float32))
    for row, temp in zip(metrics['sf_ratio'], config.temperatures_c):
        columns['sf_ratio_' + temperature_label(temp)] = pa.array(row.astype(np.float32))
    for spec in config.specs:
        columns['pass_' + spec.metric] = pa.array(per_spec[spec.metric])
    columns['pass'] = pa.array(ok)
    for metric, flag in per_check.items():
        columns['check_' + metric] = pa.array(flag)
    return pa.table(columns)


def _counts(config, invalid, clipped, per_spec, ok, per_check):
    counts = {'devices': int(len(ok)), 'invalid': int(invalid.sum()),
              'clipped': int(clipped.sum()), 'pass': int(ok.sum()),
              'spec_pass': {m: int(flag.sum()) for m, flag in per_spec.items()}}
    if per_check:
        counts['check_pass'] = {m: int(flag.sum()) for m, flag in per_check.items()}
    return counts


def add_counts(total, part):
    """Add the (nested) counts of ``part`` into ``total``, in place."""
    for key, value in part.items():
        if isinstance(value, dict):
            add_counts(total.setdefault(key, {}), value)
        else:
            total[key] = total.get(key, 0) + value


def _sample(metrics, values, invalid):
    """Return what a quantile block sends back: its metrics and drawn values."""
    keep = {name: arr.copy() for name, arr in metrics.items()}
    keep.update({'param:' + name: np.asarray(arr, dtype=float).copy()
                 for name, arr in values.items()})
    keep['valid'] = ~invalid
    return keep


def attribution(config, draw):
    """
    Which variation source drives each spec: pass counts with each one left at nominal.

    On the first ``attribution_devices`` parts of block 0, the same draws are
    evaluated again with one source (a tolerance, or a factor) removed; a
    source whose removal turns many failing parts into passing ones drives
    the yield. Returns counts: ``all`` (nothing removed) and one entry per
    source, each {'pass': n, 'spec_pass': {metric: n}}; a source's entry
    also counts the parts whose verdict its removal changes, either way
    (``flips``, and ``spec_flips`` per spec): the paired comparison's
    discordant parts, from which the gain's uncertainty follows.
    """
    n = min(config.attribution_devices, draw.n)
    if n == 0 or not config.specs:
        return None
    head = sampling.Draw(n, draw.nominal, {src: {k: v[:n] for k, v in parts.items()}
                                           for src, parts in draw.contributions.items()})
    out = {'devices': n}
    base = None
    for source in (None,) + config.sources():
        _, invalid, _, _, per_spec, ok = fleet_eval.evaluate_draw(config, head, source)
        entry = {'pass': int(ok.sum()), 'invalid': int(invalid.sum()),
                 'spec_pass': {m: int(f.sum()) for m, f in per_spec.items()}}
        if base is None:
            base = ok, per_spec
        else:
            entry['flips'] = int(np.count_nonzero(ok != base[0]))
            entry['spec_flips'] = {m: int(np.count_nonzero(f != base[1][m]))
                                   for m, f in per_spec.items()}
        out['all' if source is None else source] = entry
    return out


def run_task(job, blocks, progress=None):
    """
    Draw, evaluate and write ``blocks``; return their counts and samples.

    ``progress(n)`` (in-process runs) is called after each block. The
    Parquet file is written whole or not at all
    (:func:`gyro_emulator.atomic.staged`): a task lost half way leaves at
    most a hidden temporary, which a resumed run deletes (:mod:`.state`).
    """
    t0 = time.thread_time()
    result = {'blocks': list(blocks), 'counts': {}, 'sample': [], 'attribution': None,
              'sensor_runs': []}
    if job.write:
        with atomic.staged(part_path(job.out_dir, blocks[0])) as tmp:
            _run_blocks(job, blocks, result, progress, tmp)
    else:
        _run_blocks(job, blocks, result, progress, None)
    result['cpu_s'] = time.thread_time() - t0
    return result


def _run_blocks(job, blocks, result, progress, path):
    """Evaluate ``blocks`` into ``result``; stream their rows into Parquet ``path`` if given."""
    config = job.config
    writer = None
    try:
        for block in blocks:
            n = sampling.block_size(job.n_devices, block)
            draw = sampling.draw_block(config, job.seed, block, n)
            values, invalid, clipped, metrics, per_spec, ok = fleet_eval.evaluate_draw(
                config, draw)
            per_check = fleet_eval.within(config.model_checks, metrics, invalid)
            if path is not None:
                table = _table(job, block, values, invalid, clipped, metrics, per_spec, ok,
                               per_check)
                writer = writer or _writer(path, table.schema)
                writer.write_table(table)
            add_counts(result['counts'], _counts(config, invalid, clipped, per_spec, ok,
                                                 per_check))
            if block < QUANTILE_BLOCKS:
                result['sample'].append((block, _sample(metrics, values, invalid)))
            if block == 0:
                result['attribution'] = attribution(config, draw)
                result['sensor_runs'] = _sensor_runs(config, values, metrics, invalid,
                                                     job.seed)
            if progress is not None:
                progress(n)
    finally:
        if writer is not None:
            writer.close()


def sample_blocks(job, blocks):
    """Return the quantile samples of ``blocks`` (recomputed: the same draws, the same metrics)."""
    out = []
    for block in blocks:
        if block < QUANTILE_BLOCKS:
            draw = sampling.draw_block(job.config, job.seed, block,
                                       sampling.block_size(job.n_devices, block))
            values, invalid, _, metrics, _, _ = fleet_eval.evaluate_draw(job.config, draw)
            out.append((block, _sample(metrics, values, invalid)))
    return out


def _sensor_runs(config, values, metrics, invalid, seed):
    """Sensor-level runs of block 0 (the sensor model is imported only when asked for)."""
    if config.sensor_runs is None:
        return []
    # The numba sensor model costs 0.9 s (2.5 s cold) a fleet without sensor runs never pays.
    from gyro_emulator.analysis.fleet import sensor_runs
    return sensor_runs.run_parts(config, values, metrics, invalid, seed)


def part_path(out_dir, first_block):
    """Return the Parquet file of the task that starts at ``first_block``."""
    return os.path.join(out_dir, 'devices', f'part-{first_block:06d}.parquet')


def _writer(path, schema):
    """Open a Parquet writer of the fleet's rows at ``path``."""
    # Drawn values and metrics are continuous float32 whose mantissas do not
    # compress: LZ4 saved 5 % of the bytes for 35 % more write time (21 ->
    # 14 ms a block), dictionary encoding saves nothing and costs 5x, and
    # min/max statistics of unordered columns prune no row group. So: no
    # compression, no dictionary, statistics only on device_id (ordered),
    # and device_id delta-encoded (consecutive integers: a few bytes a block).
    return pq.ParquetWriter(path, schema, compression='none', use_dictionary=False,
                            write_statistics=['device_id'],
                            column_encoding={'device_id': 'DELTA_BINARY_PACKED'})


def tasks_of(n_devices, blocks_per_task):
    """Group the blocks of a fleet into tasks of ``blocks_per_task`` consecutive blocks."""
    count = sampling.block_count(n_devices)
    return [list(range(start, min(start + blocks_per_task, count)))
            for start in range(0, count, blocks_per_task)]


def default_blocks_per_task(n_devices, workers):
    """About four tasks per worker, one block at least, :data:`MAX_BLOCKS_PER_TASK` at most."""
    count = sampling.block_count(n_devices)
    return int(min(MAX_BLOCKS_PER_TASK, max(1, count // (4 * max(1, workers)))))


def guided_tasks(n_devices, workers):
    """
    Group the blocks into tasks that shrink towards the end of the fleet (guided).

    Each task takes a ``4 * workers``-th of the blocks still unassigned (one
    at least, :data:`MAX_BLOCKS_PER_TASK` at most), so the workers start on
    large tasks (little overhead per device) and finish on small ones: the
    last worker to finish waits for others by one small task at most
    instead of a large one (with ten 16-block tasks on 2 workers, the tail
    alone cost 10 % of the wall time).
    """
    count, share = sampling.block_count(n_devices), 4 * max(1, workers)
    tasks, start = [], 0
    while start < count:
        size = min(MAX_BLOCKS_PER_TASK, max(1, -(-(count - start) // share)))
        tasks.append(list(range(start, min(start + size, count))))
        start += size
    return tasks
