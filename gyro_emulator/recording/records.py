"""
Reading records, one way: which topic plays a role, and which time a message has.

Every reader of measured or recorded data (``replay``, ``diagnose``,
``allan``) finds its topics with :func:`find_topic` and stamps its
messages with :func:`stream_times_ns`, so a bag means the same thing to
all of them. CSV files are read by :func:`gyro_emulator.recording.csvio.read_csv`.

The stamp rule. A message's time is its ``header.stamp``, the time the
sensor sampled, unless the stream does not carry one: when every stamp of
the stream is zero (a publisher that never sets it), the stream uses the
bag's log (receive) time. A stream that starts at a zero stamp on a sim
clock keeps its stamps. ``use_log_time=True`` asks for
log times always. Streams are returned in time order (a stable sort, so
messages with equal times keep the bag's order).
"""

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
