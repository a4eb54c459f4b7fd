"""
CSV input and output for gyro records, with clear errors.

Files are plain comma-separated text with one header row (``#`` comment lines
before it are skipped), optionally gzip-compressed (``.gz``). Values are SI;
column names carry their units (``time_s``, ``gyro_x_rad_s``, ``temp_c``).

Errors name the file, the column, the row (1-based line number in the file)
and the offending value: a missing column, a value that is not a number, a
non-finite value, or a ``time_s`` column that does not increase. A truncated
or corrupt ``.gz`` file is one line too, never a traceback.
"""

import gzip
import io
import os
import zlib

import numpy as np

#: Gyro column layouts accepted by :func:`read_gyro_csv`.
GYRO_SINGLE = 'gyro_rad_s'
GYRO_AXES = ('gyro_x_rad_s', 'gyro_y_rad_s', 'gyro_z_rad_s')
AXIS_NAMES = ('x', 'y', 'z')


def _open_text(path, mode):
    if str(path).endswith('.gz'):
        return io.TextIOWrapper(gzip.open(path, mode + 'b'), encoding='utf-8',
                                newline='')
    return open(path, mode, encoding='utf-8', newline='')


def _header(path):
    """Return (header names, number of lines before the data)."""
    skipped = 0
    with _open_text(path, 'r') as handle:
        for line in handle:
            skipped += 1
            text = line.strip()
            if not text or text.startswith('#'):
                continue
            names = [n.strip() for n in text.split(',')]
            if any(not n for n in names):
                raise ValueError(f'{path}: header row {skipped} has an empty column name')
            if len(set(names)) != len(names):
                dup = sorted({n for n in names if names.count(n) > 1})
                raise ValueError(f'{path}: duplicate column(s) {", ".join(dup)} in the '
                                 'header')
            return names, skipped
    raise ValueError(f'{path}: the file is empty (no header row)')


def _find_bad_cell(path, names, skip, wanted=None):
    """Slow scan for the first cell (of the ``wanted`` columns) that is not a number."""
    with _open_text(path, 'r') as handle:
        for lineno, line in enumerate(handle, start=1):
            if lineno <= skip:
                continue
            text = line.strip()
            if not text or text.startswith('#'):
                continue
            cells = text.split(',')
            if len(cells) != len(names):
                return (f'{path}: row {lineno} has {len(cells)} values, the header has '
                        f'{len(names)} ({", ".join(names)})')
            for name, cell in zip(names, cells):
                if wanted is not None and name not in wanted:
                    continue
                try:
                    float(cell)
                except ValueError:
                    return (f'{path}: row {lineno}, column {name}: {cell.strip()!r} is '
                            'not a number')
    return f'{path}: could not parse the data rows'


def read_csv(path, required=(), time_order='increasing', only=None):
    """
    Read a numeric CSV file into a dict of column name -> float array.

    Parameters
    ----------
    path : str or os.PathLike
        The file (``.gz`` for gzip).
    required : sequence of str
        Columns that must be present.
    time_order : str
        ``'increasing'`` (default): ``time_s`` must strictly increase;
        ``'nondecreasing'``: repeated timestamps are accepted.
    only : sequence of str, optional
        Read only these columns (those present); the others may hold
        anything, even text. Default: every column, all numeric.

    Returns
    -------
    dict
        Column name -> 1-D numpy array, in file order.

    Raises
    ------
    ValueError
        Missing columns, non-numeric or non-finite values, or a ``time_s``
        column that does not strictly increase (the message names the file,
        row, column and value).
    OSError
        The file cannot be read.

    """
    path = os.fspath(path)
    try:
        return _read_columns(path, required, time_order, only)
    except (EOFError, zlib.error, gzip.BadGzipFile, UnicodeDecodeError) as exc:
        raise ValueError(f'{path}: cannot read the file: it is truncated or corrupt '
                         f'({type(exc).__name__}: {exc})') from None


def _read_columns(path, required, time_order, only):
    """Read the columns (see :func:`read_csv`); decompression errors pass through."""
    names, skip = _header(path)
    missing = [c for c in required if c not in names]
    if missing:
        raise ValueError(f'{path}: missing required column(s) {", ".join(missing)}; the file '
                         f'has {", ".join(names)}')
    wanted = names if only is None else [n for n in names if n in only]
    index = [names.index(n) for n in wanted]
    try:
        with _open_text(path, 'r') as handle:
            data = np.loadtxt(handle, delimiter=',', skiprows=skip, comments='#',
                              ndmin=2, dtype=float, usecols=None if only is None else index)
    except ValueError:
        raise ValueError(_find_bad_cell(path, names, skip, wanted)) from None
    if data.size == 0:
        raise ValueError(f'{path}: no data rows after the header')
    if data.shape[1] != len(wanted):
        raise ValueError(_find_bad_cell(path, names, skip, wanted))
    columns = {name: data[:, i].copy() for i, name in enumerate(wanted)}
    for name, values in columns.items():
        bad = ~np.isfinite(values)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f'{path}: data row {i + 1}, column {name}: '
                             f'{float(values[i])!r} is not finite')
    if 'time_s' in columns:
        check_increasing(columns['time_s'], f'{path}: time_s',
                         strict=time_order == 'increasing')
    return columns


def check_increasing(time_s, what='time_s', strict=True):
    """Raise ValueError naming the first data row where ``time_s`` does not increase."""
    time_s = np.asarray(time_s, dtype=float)
    step = np.diff(time_s)
    bad = np.flatnonzero(step <= 0.0 if strict else step < 0.0)
    if len(bad):
        i = int(bad[0])
        hint = '' if not strict or np.any(step < 0.0) else ' (repeated timestamp)'
        raise ValueError(f'{what} does not increase at data row {i + 2}: '
                         f'{float(time_s[i + 1])!r} after {float(time_s[i])!r}{hint}')


def gyro_columns(columns, path=''):
    """
    Return ``{axis: column}`` of the gyro columns present, in x, y, z order.

    A single-axis file's ``gyro_rad_s`` counts as axis x; otherwise every
    ``gyro_<axis>_rad_s`` present (one, two or three of them). Raises
    ValueError naming the accepted columns when there is none.
    """
    if GYRO_SINGLE in columns:
        return {'x': GYRO_SINGLE}
    present = {a: c for a, c in zip(AXIS_NAMES, GYRO_AXES) if c in columns}
    if present:
        return present
    raise ValueError(f'{path}: no gyro columns: need {GYRO_SINGLE} or one or more of '
                     f'{", ".join(GYRO_AXES)}; the file has {", ".join(columns)}')


def gyro_column_of(found, axis, path=''):
    """
    Return the column of ``axis`` among ``found`` (:func:`gyro_columns`).

    ``axis`` None picks the first present; a single-axis file's ``gyro_rad_s``
    is returned whatever the axis. Raises ValueError for an unknown axis or
    one the file does not have.
    """
    if GYRO_SINGLE in found.values():
        return GYRO_SINGLE
    axis = next(iter(found)) if axis is None else axis
    if axis not in AXIS_NAMES:
        raise ValueError(f'axis = {axis!r} is not allowed: choose x, y or z')
    if axis not in found:
        raise ValueError(f'{path}: no gyro column for axis {axis!r}; the file has '
                         f'{", ".join(found.values())}')
    return found[axis]


def read_gyro_csv(path, axis=None, time_order='increasing'):
    """
    Read a gyro record: ``time_s`` plus one rate column.

    Parameters
    ----------
    path : str or os.PathLike
        CSV with ``time_s`` and ``gyro_rad_s`` or any of ``gyro_{x,y,z}_rad_s``.
    axis : str, optional
        ``'x'``, ``'y'`` or ``'z'`` (default: the first axis the file has);
        ignored for a single-axis ``gyro_rad_s`` file.
    time_order : str
        See :func:`read_csv`.

    Returns
    -------
    time_s : numpy.ndarray
        Sample times, s (strictly increasing).
    rate_rad_s : numpy.ndarray
        The selected rate column, rad/s.
    column : str
        The column read.

    """
    columns = read_csv(path, required=('time_s',), time_order=time_order)
    name = gyro_column_of(gyro_columns(columns, path), axis, path)
    return columns['time_s'], columns[name], name


#: Median and mean time step agreeing within this share: the median is the step.
STEP_AGREEMENT = 1e-3


def sample_rate_and_segments(time_s, gap_factor=3.0):
    """
    Nominal sample rate and the contiguous segments of a record.

    A step longer than ``gap_factor`` times the median positive step
    starts a new segment (a gap in the record). The rate is 1 / that median,
    or 1 / the mean step within the segments when the two differ by more
    than :data:`STEP_AGREEMENT`: stamps rounded to a coarse clock (a 416.7 Hz
    part stamped in whole milliseconds steps 2 and 3 ms, median 2) or shared
    by a FIFO batch (steps 0, 0, 3 dt) have the right mean, not median.

    Returns
    -------
    rate_hz : float
        Nominal sample rate, Hz.
    bounds : list of (int, int)
        Start and stop index of each segment.

    """
    dt, within, bounds = _median_step_and_segments(time_s, gap_factor)
    mean = float(np.mean(within)) if len(within) else dt
    if mean > 0.0 and abs(mean / dt - 1.0) > STEP_AGREEMENT:
        lost = dropped_samples(within, dt)
        dt = mean if lost is None else lost[1]
    return 1.0 / dt, bounds


def _median_step_and_segments(time_s, gap_factor):
    """Return the median positive step, the steps within segments, and the segments."""
    t = np.asarray(time_s, dtype=float)
    if len(t) < 2:
        raise ValueError(f'time_s has {len(t)} samples: need >= 2')
    step = np.diff(t)
    positive = step[step > 0.0]
    if not len(positive):
        raise ValueError('time_s: no time step is positive')
    dt = float(np.median(positive))
    gap = step > gap_factor * dt
    cuts = np.flatnonzero(gap) + 1
    edges = np.concatenate(([0], cuts, [len(t)]))
    return dt, step[~gap], [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


#: Long steps off a whole number of nominal steps by more than this (median): not drops.
WHOLE_STEP_TOLERANCE = 0.25
#: More long steps than this share of all: a slower clock, not dropped samples.
MAX_LONG_STEP_SHARE = 0.5
#: Long steps whose spacings take two values this often recur at a beat (a coarse clock).
BEAT_SHARE = 0.9


def dropped_samples(step, dt):
    """
    Read steps as whole numbers of the nominal step with samples missing, or None.

    Samples lost on the way (a serial link, a USB buffer) leave steps of k
    whole nominal steps (k >= 2, k = the step / ``dt`` rounded) scattered
    among single ones. A faster part stamped by a coarse clock (900 Hz in
    whole milliseconds: steps of 1 and 2 ms) leaves the same two lengths,
    but its long steps recur at a beat: nearly all their spacings take one
    or two values. So the steps read as drops when none rounds to zero (a
    FIFO sharing a stamp is not a drop), at most
    :data:`MAX_LONG_STEP_SHARE` are long, the long ones lie within
    :data:`WHOLE_STEP_TOLERANCE` of whole numbers (median; stamps rounded to
    a clock leave 1.5 steps), and, when there are ten or more, fewer than
    :data:`BEAT_SHARE` of their spacings take the two commonest values
    (random losses spread them geometrically).

    Returns
    -------
    (int, float) or None
        The samples missing, sum(k - 1), and the step, sum(step) / sum(k);
        None when the steps are not drops.

    """
    step = np.asarray(step, dtype=float)
    whole = np.rint(step / dt)
    if not len(step) or np.any(whole < 1.0):
        return None
    long = np.flatnonzero(whole >= 2.0)
    if len(long) > MAX_LONG_STEP_SHARE * len(step):
        return None
    if len(long) and np.median(np.abs(step[long] / dt - whole[long])) > WHOLE_STEP_TOLERANCE:
        return None
    if len(long) >= 10:
        counts = np.sort(np.unique(np.diff(long), return_counts=True)[1])
        if np.sum(counts[-2:]) >= BEAT_SHARE * (len(long) - 1):
            return None
    return int(np.sum(whole - 1.0)), float(np.sum(step) / np.sum(whole))


def missing_samples(time_s, gap_factor=3.0):
    """
    Return the samples missing inside the segments of a record (0 when none read as drops).

    The segments and the median step are those of
    :func:`sample_rate_and_segments`; see :func:`dropped_samples` (counted
    even when so few are missing that the mean step agrees with the median).
    """
    dt, within, _ = _median_step_and_segments(time_s, gap_factor)
    lost = dropped_samples(within, dt)
    return 0 if lost is None else lost[0]


class CsvWriter:
    """
    Write columns of numbers to CSV in blocks (context manager).

    ``finish()`` (also on leaving the ``with`` block) is safe to call twice.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; ``.gz`` compresses.
    names : sequence of str
        Column names (the header).
    fmt : str or sequence of str
        printf format per column (default ``%.10g``).

    """

    def __init__(self, path, names, fmt='%.10g'):
        self.path = os.fspath(path)
        self.names = list(names)
        self.fmt = [fmt] * len(self.names) if isinstance(fmt, str) else list(fmt)
        directory = os.path.dirname(os.path.abspath(self.path))
        os.makedirs(directory, exist_ok=True)
        self._handle = _open_text(self.path, 'w')
        self._handle.write(','.join(self.names) + '\n')
        self.rows = 0

    def write(self, columns):
        """Append rows: ``columns`` is a sequence of equal-length 1-D arrays."""
        if self._handle is None:
            raise ValueError(f'{self.path}: writer is finished')
        if len(columns) != len(self.names):
            raise ValueError(f'{self.path}: got {len(columns)} columns, expected '
                             f'{len(self.names)}')
        block = np.column_stack([np.asarray(c, dtype=float) for c in columns])
        row = ','.join(self.fmt) + '\n'
        for start in range(0, len(block), 20000):
            part = block[start:start + 20000]
            self._handle.write((row * len(part)) % tuple(part.ravel().tolist()))
        self.rows += len(block)

    def finish(self):
        """Flush and close the file (idempotent)."""
        if self._handle is not None:
            self._handle.close()
            self._handle = None

    def __enter__(self):
        """Return the writer."""
        return self

    def __exit__(self, *exc):
        """Close the file."""
        self.finish()
        return False


def write_csv(path, columns, fmt='%.10g'):
    """
    Write a dict of name -> 1-D array as one CSV file.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; ``.gz`` compresses.
    columns : dict
        Column name -> values (equal lengths), in column order.
    fmt : str or sequence of str
        printf format per column.

    Returns
    -------
    int
        Rows written.

    """
    return write_csv_blocks(path, list(columns), [list(columns.values())], fmt)


def write_csv_blocks(path, names, blocks, fmt='%.10g', progress=None, total=None):
    """
    Write blocks of rows as one CSV file (bounded memory for long records).

    Parameters
    ----------
    path, names, fmt
        The file (``.gz`` compresses), the column names and the printf
        formats, as for :class:`CsvWriter`.
    blocks : iterable
        Each a sequence of equal-length 1-D arrays, one per column, written in turn.
    progress : callable, optional
        ``progress(done, total)`` after each block, ``done`` the rows so far.
    total : int, optional
        Total rows, passed to ``progress``.

    Returns
    -------
    int
        Rows written.

    """
    with CsvWriter(path, names, fmt) as writer:
        for block in blocks:
            writer.write(block)
            if progress is not None:
                progress(writer.rows, total)
        return writer.rows
