"""
Reading records, one way: CSV or bag, which topic plays a role, which time a message has.

Every reader of measured or recorded data (``replay``, ``diagnose``,
``allan``) opens its input with :func:`load_record` (a CSV file through
:func:`gyro_emulator.recording.csvio.read_csv`, a bag directory or ``.mcap``
file through :class:`gyro_emulator.recording.bag.BagReader`, tolerant of
damage), finds its topics with :func:`find_topic` and reads a topic with
:func:`read_stream`, so a record means the same thing to all of them.
Default topic names come from :mod:`gyro_emulator.recording.topics`.

The stamp rule. A message's time is its ``header.stamp``, the time the
sensor sampled, unless the stream does not carry one: when every stamp of
the stream is zero (a publisher that never sets it), the stream uses the
bag's log (receive) time. A stream that starts at a zero stamp on a sim
clock keeps its stamps. ``use_log_time=True`` asks for
log times always. Streams are returned in time order (a stable sort, so
messages with equal times keep the bag's order).
"""

from dataclasses import dataclass
import os

from gyro_emulator.recording import bag, csvio
import numpy as np


def _resolve_name(topics, name):
    """Return the topic called ``name``: exact, with a leading '/', or a unique suffix."""
    for candidate in (name, '/' + name.lstrip('/')):
        if candidate in topics:
            return candidate
    tail = [t for t in topics if t.endswith('/' + name.lstrip('/'))]
    return tail[0] if len(tail) == 1 else None


def find_topic(reader, role, name=None, default=None, types=None):
    """
    Return the bag topic that plays ``role``, or None when a default is absent.

    Parameters
    ----------
    reader : gyro_emulator.recording.bag.BagReader
        The bag.
    role : str
        What the topic is for, for error messages (e.g. ``'rate'``).
    name : str, optional
        The user's choice: the exact topic, the topic with a leading ``/``,
        or the one topic whose name ends with ``/name``. A name that matches
        nothing, or a topic of a type outside ``types``, raises ValueError.
    default : str, optional
        Without ``name``: the topics named ``default`` or ending with
        ``/default`` (a namespace prefix is allowed) that have messages and a
        type in ``types``; the first in name order, or None.
    types : sequence of str, optional
        Allowed message types (``pkg/msg/Type``); None allows any.

    Returns
    -------
    str or None

    """
    topics = reader.topics
    if name:
        found = _resolve_name(topics, name)
        if found is None:
            raise ValueError(f'bag {reader.path}: no topic {name!r} for the {role}; topics: '
                             f'{", ".join(sorted(topics)) or "(none)"}')
        actual = topics[found].type_name
        if types is not None and actual not in types:
            raise ValueError(f'{role} topic {found} has type {actual}: expected '
                             f'{" or ".join(types)}')
        return found
    if default is None:
        return None
    key = default.lstrip('/')
    found = sorted(t for t, info in topics.items()
                   if (t.lstrip('/') == key or t.endswith('/' + key)) and info.message_count
                   and (types is None or info.type_name in types))
    return found[0] if found else None


def stream_times_ns(arrays, use_log_time=False):
    """
    Return ``(times_ns, order)``: the stream's message times, sorted, and the sort order.

    ``arrays`` is a :class:`gyro_emulator.recording.reader.TopicArrays`;
    the times follow the module's stamp rule. Index the decoded columns with
    ``order`` to put them in time order.
    """
    stamps = np.asarray(arrays.stamp_ns, dtype=np.int64)
    if use_log_time or not np.any(stamps):
        stamps = np.asarray(arrays.log_time_ns, dtype=np.int64)
    order = np.argsort(stamps, kind='stable')
    return stamps[order], order


@dataclass(frozen=True)
class Stream:
    """
    One bag topic, decoded and in time order (the module's stamp rule).

    Attributes
    ----------
    topic : str
        Topic name in the bag.
    type_name : str
        Message type, ``pkg/msg/Type``.
    times_ns : numpy.ndarray of int64
        Message times, ns, sorted.
    order : numpy.ndarray of int
        Bag order -> time order: index the decoded columns with it.
    arrays : gyro_emulator.recording.bag.TopicArrays
        The decoded columns in bag order.

    """

    topic: str
    type_name: str
    times_ns: np.ndarray
    order: np.ndarray
    arrays: object

    def __len__(self):
        """Return the number of messages."""
        return len(self.times_ns)

    def field(self, name):
        """Return a float64 column or block in time order, e.g. ``angular_velocity``."""
        return self.arrays.field(name)[self.order]


def read_stream(reader, topic, use_log_time=False):
    """Return :class:`Stream` ``topic`` of ``reader`` (a BagReader), in time order."""
    arrays = reader.read_arrays(topic)
    times_ns, order = stream_times_ns(arrays, use_log_time)
    return Stream(topic, reader.topics[topic].type_name, times_ns, order, arrays)


def is_bag(path):
    """Return whether ``path`` is a bag (a directory or an ``.mcap`` file), else a CSV file."""
    return os.path.isdir(path) or str(path).endswith('.mcap')


@dataclass(frozen=True)
class Record:
    """
    A loaded record: the columns of a CSV file, or an open bag.

    Attributes
    ----------
    path : str
        Where it was read from.
    columns : dict or None
        CSV: column name -> float array (see :func:`csvio.read_csv`); None for a bag.
    reader : gyro_emulator.recording.bag.BagReader or None
        Bag: the tolerant reader; None for a CSV file.

    """

    path: str
    columns: dict = None
    reader: object = None

    @property
    def recovery(self):
        """Return what a damaged bag lost, one note each; () for CSV or a sound bag."""
        return () if self.reader is None else tuple(self.reader.problems)

    def find_topic(self, role, name=None, default=None, types=None):
        """Return the bag topic that plays ``role`` (see :func:`find_topic`)."""
        return find_topic(self.reader, role, name, default, types)

    def stream(self, topic, use_log_time=False):
        """Return the bag topic ``topic`` in time order (see :func:`read_stream`)."""
        return read_stream(self.reader, topic, use_log_time)


def load_record(path, required=(), time_order='increasing', only=None):
    """
    Open a record: a bag directory or ``.mcap`` file, else a CSV file.

    Parameters
    ----------
    path : str or os.PathLike
        The record.
    required, time_order, only
        CSV only: see :func:`gyro_emulator.recording.csvio.read_csv`.

    Returns
    -------
    Record
        ``reader`` set for a bag (opened tolerant: damage is in
        ``recovery``), ``columns`` for a CSV file.

    """
    path = os.fspath(path)
    if is_bag(path):
        return Record(path, reader=bag.BagReader(path, tolerant=True))
    return Record(path, columns=csvio.read_csv(path, required, time_order, only))
