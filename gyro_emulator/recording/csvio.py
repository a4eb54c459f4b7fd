"""
CSV input and output for gyro records, with clear errors.

Files are plain comma-separated text with one header row (``#`` comment lines
before it are skipped), optionally gzip-compressed (``.gz``). Values are SI;
column names carry their units (``time_s``, ``gyro_x_rad_s``, ``temp_c``).
Standard CSV quoting is read (:data:`QUOTE`): a quoted header
(``"time_s","gyro_x_rad_s"``, as pandas with quoting or a spreadsheet
writes it) and quoted numbers (``"0.01"``).

Errors name the file, the column, the row (1-based line number in the file)
and the offending value: a missing column, a value that is not a number, a
non-finite value, a ``time_s`` column that does not increase, or one that is
not in seconds (:func:`gyro_emulator.recording.timing.check_time_base`). A truncated
or corrupt ``.gz`` file is one line too, never a traceback.
"""

import csv
import gzip
import io
import itertools
import os
import warnings
import zlib

from gyro_emulator import atomic
from gyro_emulator.recording.timing import check_increasing, check_time_base
from gyro_emulator.units import AXES
from gyro_emulator.validation import quote
import numpy as np

#: Gyro column layouts accepted by :func:`read_gyro_csv`.
GYRO_SINGLE = 'gyro_rad_s'
GYRO_AXES = ('gyro_x_rad_s', 'gyro_y_rad_s', 'gyro_z_rad_s')


#: How a CSV is read: UTF-8, a leading byte-order mark (Excel's "CSV UTF-8") skipped.
READ_ENCODING = 'utf-8-sig'
#: The quote character of standard CSV (RFC 4180; Python's ``csv``, pandas, spreadsheets).
QUOTE = '"'


def _cells(text, path, lineno, header=False):
    """
    Return the cells of one CSV line, standard quoting read, each stripped of spaces.

    A header's cells may start with spaces before their quote (``time_s,
    "temp_c"``); a data cell is read as ``numpy.loadtxt`` reads it. A quote
    left open, or text after a closing quote, is refused in one line naming
    the file and the row.
    """
    try:
        return [cell.strip() for cell in next(csv.reader(
            [text], quotechar=QUOTE, strict=True, skipinitialspace=header))]
    except csv.Error as exc:
        raise ValueError(f'{path}: row {lineno} {quote(text, 80)} is not valid CSV ({exc}): '
                         'allowed plain cells or cells quoted whole with "') from None


def _open_text(path, mode):
    """Open a CSV (``.gz``: gunzipped) as text to read, :data:`READ_ENCODING`."""
    if str(path).endswith('.gz'):
        return io.TextIOWrapper(gzip.open(path, mode + 'b'), encoding=READ_ENCODING,
                                newline='')
    return open(path, mode, encoding=READ_ENCODING, newline='')


def _open_staged(tmp, path):
    """
    Open ``tmp`` to be written as ``path`` would be; return (text handle, raw file or None).

    A ``.gz`` ``path`` is gzip with ``path``'s name in its header (not the
    temporary's); the raw file under the gzip stream is closed after it.
    """
    if not str(path).endswith('.gz'):
        return open(tmp, 'w', encoding='utf-8', newline=''), None
    raw = open(tmp, 'wb')
    try:
        stream = gzip.GzipFile(filename=os.fspath(path), mode='wb', fileobj=raw)
        return io.TextIOWrapper(stream, encoding='utf-8', newline=''), raw
    except BaseException:
        raw.close()
        raise


def column_names(path):
    """Return the header's column names of a CSV file (all of them, read or not)."""
    return _header(path)[0]


def _header(path):
    """Return (header names, number of lines before the data)."""
    skipped = 0
    with _open_text(path, 'r') as handle:
        for line in handle:
            skipped += 1
            text = line.strip()
            if not text or text.startswith('#'):
                continue
            names = _cells(text, path, skipped, header=True)
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
            try:
                cells = _cells(text, path, lineno)
            except ValueError as exc:
                return str(exc)
            if len(cells) != len(names):
                return (f'{path}: row {lineno} has {len(cells)} values, the header has '
                        f'{len(names)} ({", ".join(names)})')
            for name, cell in zip(names, cells):
                if wanted is not None and name not in wanted:
                    continue
                try:
                    float(cell)
                except ValueError:
                    return f'{path}: row {lineno}, column {name}: {cell!r} is not a number'
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


def _wanted_columns(path, required, only):
    """
    Return (header names, lines before the data, the columns read, their indices).

    A required column the header lacks is refused in one line that lists
    what the file has; ``only`` None reads every column.
    """
    names, skip = _header(path)
    missing = [c for c in required if c not in names]
    if missing:
        raise ValueError(f'{path}: missing required column(s) {", ".join(missing)}; the file '
                         f'has {", ".join(names)}')
    wanted = names if only is None else [n for n in names if n in only]
    return names, skip, wanted, [names.index(n) for n in wanted]


def _loadtxt(source, **options):
    """
    Return ``numpy.loadtxt`` of CSV lines: floats, 2-D, ``#`` comments.

    Data rows absent give an empty array without numpy's UserWarning (the
    callers say it in one line: "no data rows after the header").
    """
    with warnings.catch_warnings():
        warnings.filterwarnings('ignore', 'loadtxt: input contained no data', UserWarning)
        return np.loadtxt(source, delimiter=',', comments='#', quotechar=QUOTE, ndmin=2,
                          dtype=float, **options)


def _read_columns(path, required, time_order, only):
    """Read the columns (see :func:`read_csv`); decompression errors pass through."""
    names, skip, wanted, index = _wanted_columns(path, required, only)
    try:
        with _open_text(path, 'r') as handle:
            data = _loadtxt(handle, skiprows=skip, usecols=None if only is None else index)
    except ValueError:
        raise ValueError(_find_bad_cell(path, names, skip, wanted)) from None
    if data.size == 0:
        raise ValueError(f'{path}: no data rows after the header')
    if data.shape[1] != len(wanted):
        raise ValueError(_find_bad_cell(path, names, skip, wanted))
    columns = {name: data[:, i].copy() for i, name in enumerate(wanted)}
    check_finite(path, columns)
    if 'time_s' in columns:
        check_increasing(columns['time_s'], f'{path}: time_s',
                         strict=time_order == 'increasing')
        check_time_base(columns['time_s'], f'{path}: time_s')
    return columns


#: Rows parsed at a time by :func:`iter_csv_blocks`.
BLOCK_ROWS = 500_000


def iter_csv_blocks(path, required=(), only=None, block_rows=BLOCK_ROWS):
    """
    Yield ``(first data row, columns, characters)`` blocks of a CSV, for files too long to hold.

    Missing columns and cells that are not numbers are refused as
    :func:`read_csv` refuses them (the file's own row numbers); the caller
    checks the values (:func:`check_finite`) and the time order.
    """
    path = os.fspath(path)
    try:
        names, skip, wanted, index = _wanted_columns(path, required, only)
        first = 0
        with _open_text(path, 'r') as handle:
            for _ in range(skip):
                next(handle)
            while True:
                lines = list(itertools.islice(handle, block_rows))
                if not lines:
                    break
                columns = _parse_block(path, names, skip, wanted, index, lines, first)
                yield first, columns, sum(map(len, lines))
                first += len(columns[wanted[0]])
        if first == 0:
            raise ValueError(f'{path}: no data rows after the header')
    except (EOFError, zlib.error, gzip.BadGzipFile, UnicodeDecodeError) as exc:
        raise ValueError(f'{path}: cannot read the file: it is truncated or corrupt '
                         f'({type(exc).__name__}: {exc})') from None


def _parse_block(path, names, skip, wanted, index, lines, first):
    """Parse the data lines of one block into columns (see :func:`iter_csv_blocks`)."""
    try:
        data = _loadtxt(lines, usecols=index)
    except ValueError:
        raise ValueError(_find_bad_cell(path, names, skip, wanted)) from None
    if data.size and data.shape[1] != len(wanted):
        raise ValueError(_find_bad_cell(path, names, skip, wanted))
    return {name: np.ascontiguousarray(data[:, i]) for i, name in enumerate(wanted)}


def check_finite(path, columns, first=0):
    """Raise ValueError naming the first value that is not finite (column by column)."""
    for name, values in columns.items():
        bad = ~np.isfinite(values)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f'{path}: data row {first + i + 1}, column {name}: '
                             f'{float(values[i])!r} is not finite')


def gyro_columns(columns, path=''):
    """
    Return ``{axis: column}`` of the gyro columns present, in x, y, z order.

    A single-axis file's ``gyro_rad_s`` counts as axis x; otherwise every
    ``gyro_<axis>_rad_s`` present (one, two or three of them). Raises
    ValueError naming the accepted columns when there is none.
    """
    if GYRO_SINGLE in columns:
        return {'x': GYRO_SINGLE}
    present = {a: c for a, c in zip(AXES, GYRO_AXES) if c in columns}
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
    if axis not in AXES:
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


class CsvWriter:
    """
    Write columns of numbers to CSV in blocks (context manager), complete or absent.

    The rows go to a temporary beside ``path`` that replaces ``path`` when
    the writer finishes (:func:`gyro_emulator.atomic.staged`); leaving the
    ``with`` block by an exception (a signal turned into one included)
    removes the temporary and leaves ``path`` as it was. ``finish()`` (also
    on leaving the ``with`` block normally) is safe to call twice.

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
        self._stage = atomic.staged(self.path)
        tmp = self._stage.__enter__()
        self._handle = self._raw = None
        try:
            self._handle, self._raw = _open_staged(tmp, self.path)
            self._handle.write(','.join(self.names) + '\n')
        except BaseException as exc:
            self._close(exc)
            raise
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

    def _close(self, exc=None):
        """Close the files; then move the file into place, or (``exc`` given) remove it."""
        stage, self._stage = self._stage, None
        files = (self._handle, self._raw)
        self._handle = self._raw = None
        try:
            for item in files:
                if item is not None:
                    item.close()
        except BaseException as error:
            if exc is None:          # not flushed whole: remove it and say why
                stage.__exit__(type(error), error, error.__traceback__)
                raise
        if exc is None:
            stage.__exit__(None, None, None)
        else:
            stage.__exit__(type(exc), exc, exc.__traceback__)

    def finish(self):
        """Close the file and move it into place (idempotent)."""
        if self._stage is not None:
            self._close()

    def abort(self, exc=None):
        """Close and remove the unfinished file, leaving ``path`` as it was (idempotent)."""
        if self._stage is not None:
            self._close(exc or RuntimeError(f'{self.path}: writing was abandoned'))

    def __enter__(self):
        """Return the writer."""
        return self

    def __exit__(self, exc_type, exc, traceback):
        """Finish the file, or remove it when the block raised."""
        if exc_type is None:
            self.finish()
        else:
            self.abort(exc)
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
