"""
What a fleet needs before it starts: disk for its Parquet rows, memory for its sensor runs.

A fleet that cannot finish should say so before it begins, with the figure,
not after an hour of writing or at the kernel's OOM killer.

* Disk: every row holds one float32 per drawn parameter, metric and grid
  temperature, one bit per flag (``valid``, ``clipped``, ``pass_<spec>``,
  ``pass``, ``check_<metric>``) and a delta-encoded ``device_id`` (a few
  bytes a block); each block's row group and each task's file add their
  page headers and footer (:data:`COLUMN_BYTES_PER_BLOCK` per column and
  block, generous). The study fleet's rows are 137.4 bytes a part measured
  (:func:`output_bytes` says 137.3 plus the headers; ``test_fleet.py``
  holds it within 2 % of a real run). The summary and plots take
  :data:`SUMMARY_BYTES` at most. The estimate is checked against the free
  space of the output directory's file system.
* Memory: a sensor run holds its whole record (the model's output, the
  static profile, the Allan sums): :data:`SENSOR_RUN_BYTES_PER_SAMPLE`
  bytes a sample at its peak, measured with ``tracemalloc`` (165 at 1e6 and
  2e6 samples). The parts run one after another, so the need is one part's
  record, checked against the memory available on this machine
  (``MemAvailable`` of ``/proc/meminfo``).
"""

import os
import shutil

from gyro_emulator.analysis.fleet.engine import metric_names

#: Peak bytes a sample of one sensor run holds (measured: 165; rounded up).
SENSOR_RUN_BYTES_PER_SAMPLE = 170

#: Page headers and footer bytes per column and block (measured: about 340
#: for a 44-column block; generous).
COLUMN_BYTES_PER_BLOCK = 512

#: summary.json and the four plots, at most.
SUMMARY_BYTES = 2 << 20


def _gb(n_bytes):
    """Format a size in GB, or TB from 1 TB on (three figures)."""
    return f'{n_bytes / 1e12:.3g} TB' if n_bytes >= 1e12 else f'{n_bytes / 1e9:.3g} GB'


def columns_of(config):
    """Return (float32 columns, flag columns) of a fleet's Parquet rows."""
    floats = len(config.varied) + len(metric_names(config)) + len(config.temperatures_c)
    flags = 3 + len(config.specs) + len(config.model_checks)      # valid, clipped, pass
    return floats, flags


def output_bytes(config, n_devices, blocks, write=True):
    """
    Estimated bytes a fleet writes: Parquet rows (when ``write``), summary and plots.

    Parameters
    ----------
    config : FleetConfig
        The fleet.
    n_devices : int
        Parts still to write.
    blocks : int
        Blocks they fill (each adds its row group's headers).
    write : bool
        Whether the Parquet rows are written.

    """
    if not write:
        return SUMMARY_BYTES
    floats, flags = columns_of(config)
    per_row = 4.0 * floats + flags / 8.0
    headers = COLUMN_BYTES_PER_BLOCK * (floats + flags + 1) * blocks
    return int(n_devices * per_row + headers) + SUMMARY_BYTES


def free_bytes(path):
    """Free bytes of the file system that holds ``path`` (or its nearest existing parent)."""
    path = os.path.abspath(path)
    while not os.path.exists(path):
        path = os.path.dirname(path)
    return shutil.disk_usage(path).free


def available_memory_bytes():
    """Memory available to a new process on this machine (MemAvailable), bytes."""
    try:
        with open('/proc/meminfo', encoding='ascii') as handle:
            for line in handle:
                if line.startswith('MemAvailable:'):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf('SC_AVPHYS_PAGES') * os.sysconf('SC_PAGE_SIZE')


def check_disk(config, n_devices, blocks, out_dir, write=True, reclaimed=0):
    """
    Refuse a fleet whose output would not fit on the disk (one line, with the figures).

    ``reclaimed``: bytes of an earlier fleet in ``out_dir`` that the run
    deletes first (``--overwrite``).
    """
    need = output_bytes(config, n_devices, blocks, write)
    free = free_bytes(out_dir) + reclaimed
    if need > free:
        per_part = (need - SUMMARY_BYTES) / max(n_devices, 1)
        raise ValueError(
            f'fleet.out = {out_dir!r}: {n_devices} parts need about {_gb(need)} '
            f'({per_part:.0f} bytes a part) but {_gb(free)} is free: free space, choose '
            f'another directory, write fewer parts or pass --no-parquet')
    return need


def check_memory(config):
    """Refuse sensor runs whose record does not fit in this machine's memory (one line)."""
    runs = config.sensor_runs
    if runs is None:
        return 0
    samples = int(round(runs.duration_s * runs.rate_hz))
    need = samples * SENSOR_RUN_BYTES_PER_SAMPLE
    have = available_memory_bytes()
    if need > have:
        most = have // SENSOR_RUN_BYTES_PER_SAMPLE
        raise ValueError(
            f'sensor_runs: one part of {runs.duration_s:g} s at {runs.rate_hz:g} Hz holds '
            f'{samples} samples, about {_gb(need)} ({SENSOR_RUN_BYTES_PER_SAMPLE} bytes a '
            f'sample), but {_gb(have)} of memory is available: allowed duration_s x rate_hz '
            f'<= {most} here')
    return need


def tree_bytes(path):
    """Bytes of the files under ``path`` (0 when absent)."""
    total = 0
    for root, _, files in os.walk(path):
        for name in files:
            try:
                total += os.path.getsize(os.path.join(root, name))
            except OSError:
                pass
    return total
