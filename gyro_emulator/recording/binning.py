"""
A CSV record longer than a command holds: read in blocks, averaged over time bins.

:func:`read_csv_bounded` reads a CSV block by block
(:func:`gyro_emulator.recording.csvio.iter_csv_blocks`). While its rows fit
in ``max_rows`` they are kept: the columns, the checks and the messages are
those of :func:`gyro_emulator.recording.csvio.read_csv`, value for value.
Past ``max_rows`` every column is averaged over time bins of width w: sample
n goes to bin floor((t_n - t_0) / w), w starting at the first blocks'
median step times the samples per bin the file's size foretells (at least
2) and doubling (neighbouring bins merged) while more than ``max_rows`` bins
hold samples. A bin's values are the means of its samples
(its time the mean of their times); a bin without samples does not exist, so
a gap stays a gap. Memory then follows ``max_rows`` and one block, not the
length of the record: 24 h at 100 Hz (8.64 M rows) is read in a few hundred MB.
"""

from dataclasses import dataclass
import math
import os

from gyro_emulator.recording import csvio
from gyro_emulator.recording.timing import check_increasing, check_time_base, TIME_LIMIT_S
import numpy as np


@dataclass(frozen=True)
class Binned:
    """What :func:`read_csv_bounded` did to a long file; ``str()`` says it in one line."""

    rows: int
    max_rows: int
    width_s: float
    kept: int

    def __str__(self):
        """Return the note (rows read, the bin width, rows kept)."""
        return (f'{self.rows} rows are more than the {self.max_rows} held: read in blocks and '
                f'averaged over bins of {self.width_s:.6g} s ({self.kept} kept; a spike '
                'shorter than a bin is diluted)')


class _Bins:
    """Per-bin sums and counts of every column, in time order (see the module docstring)."""

    def __init__(self, names, t0, width_s):
        self.names, self.t0, self.width_s = names, t0, width_s
        self.index = np.zeros(0, dtype=np.int64)
        self.count = np.zeros(0, dtype=np.int64)
        self.sums = {name: np.zeros(0) for name in names}

    def add(self, columns):
        """Add a block of samples (time non-decreasing, after every earlier block)."""
        index = np.floor((columns['time_s'] - self.t0) / self.width_s).astype(np.int64)
        self._append(index, np.ones(len(index), dtype=np.int64), columns)

    def _append(self, index, count, sums):
        starts = np.flatnonzero(np.r_[True, np.diff(index) != 0])
        index, count = index[starts], np.add.reduceat(count, starts)
        sums = {name: np.add.reduceat(sums[name], starts) for name in self.names}
        if len(self.index) and len(index) and index[0] == self.index[-1]:
            self.count[-1] += count[0]
            for name in self.names:
                self.sums[name][-1] += sums[name][0]
            index, count = index[1:], count[1:]
            sums = {name: values[1:] for name, values in sums.items()}
        self.index = np.concatenate([self.index, index])
        self.count = np.concatenate([self.count, count])
        self.sums = {name: np.concatenate([self.sums[name], sums[name]])
                     for name in self.names}

    def widen(self):
        """Double the bin width: neighbouring bins merged."""
        index, count, sums = self.index // 2, self.count, self.sums
        self.index = np.zeros(0, dtype=np.int64)
        self.count = np.zeros(0, dtype=np.int64)
        self.sums = {name: np.zeros(0) for name in self.names}
        self.width_s *= 2.0
        self._append(index, count, sums)

    def means(self):
        """Return the bin means of every column."""
        return {name: self.sums[name] / self.count for name in self.names}


def _check_block(path, columns, first, last_time_s, strict):
    """Check one block as read_csv checks a file, with the file's row numbers."""
    csvio.check_finite(path, columns, first)
    t = columns.get('time_s')
    if t is None or not len(t):
        return
    if last_time_s is None:
        check_increasing(t, f'{path}: time_s', strict=strict)
        check_time_base(t, f'{path}: time_s')
        return
    step = np.diff(np.r_[last_time_s, t])
    bad = np.flatnonzero(step <= 0.0 if strict else step < 0.0)
    if len(bad):
        i = int(bad[0])
        before = last_time_s if i == 0 else t[i - 1]
        raise ValueError(f'{path}: time_s does not increase at data row {first + i + 1}: '
                         f'{float(t[i])!r} after {float(before)!r}')
    beyond = np.flatnonzero(~(np.abs(t) <= TIME_LIMIT_S))
    if len(beyond):
        i = int(beyond[0])
        raise ValueError(f'{path}: time_s: data row {first + i + 1} is {float(t[i])!r}, '
                         f'beyond +-{TIME_LIMIT_S:g} s (not seconds?)')


def _samples_per_bin(path, rows, chars, max_rows):
    """
    Return the samples per bin to start from: 2, or what the file's size foretells.

    A plain file holds about size / (characters per row so far) rows; a
    compressed one does not say, and the bins double as it is read.
    """
    if str(path).endswith('.gz') or not chars:
        return 2.0
    expected = os.path.getsize(path) * rows / chars
    return max(2.0, math.ceil(1.02 * expected / max_rows))


def read_csv_bounded(path, required=(), time_order='increasing', only=None, max_rows=None,
                     block_rows=csvio.BLOCK_ROWS):
    """
    Read a CSV as :func:`~gyro_emulator.recording.csvio.read_csv` does, binned past ``max_rows``.

    Returns
    -------
    columns : dict
        Column name -> 1-D array (bin means when binned).
    binned : Binned or None
        What the binning did (rows read, bin width, rows kept), or None when
        every row was kept.

    """
    if max_rows is None:
        return csvio.read_csv(path, required, time_order, only), None
    strict = time_order == 'increasing'
    blocks, rows, chars, bins, last = [], 0, 0, None, None
    for first, columns, size in csvio.iter_csv_blocks(path, required, only, block_rows):
        rows, chars = first + len(next(iter(columns.values()))), chars + size
        if bins is None and rows <= max_rows:
            blocks.append(columns)
            continue
        if bins is None:            # past max_rows: bin what was read, then go on binning
            blocks.append(columns)
            whole = {name: np.concatenate([b[name] for b in blocks]) for name in columns}
            blocks = None
            _check_block(path, whole, 0, None, strict)
            t = whole['time_s']
            step = np.diff(t[:block_rows])
            median = float(np.median(step[step > 0.0])) if np.any(step > 0.0) else 1.0
            bins = _Bins(list(whole), float(t[0]), _samples_per_bin(path, rows, chars, max_rows)
                         * median)
            bins.add(whole)
            last = float(t[-1])
            del whole, t
        else:
            _check_block(path, columns, first, last, strict)
            bins.add(columns)
            last = float(columns['time_s'][-1])
        while len(bins.index) > max_rows:
            bins.widen()
    if bins is None:
        whole = {name: np.concatenate([b[name] for b in blocks]) for name in blocks[0]}
        csvio.check_finite(path, whole)
        if 'time_s' in whole:
            check_increasing(whole['time_s'], f'{path}: time_s', strict=strict)
            check_time_base(whole['time_s'], f'{path}: time_s')
        return whole, None
    return bins.means(), Binned(rows, max_rows, bins.width_s, len(bins.index))
