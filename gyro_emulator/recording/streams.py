"""
One bag topic read as a stream: its times by the stamp rule, in time order.

The stamp rule. A message's time is its ``header.stamp``, the time the
sensor sampled, unless the stream does not carry one: when every stamp of
the stream is zero (a publisher that never sets it), the stream uses the
bag's log (receive) time. A stream that starts at a zero stamp on a sim
clock keeps its stamps. ``use_log_time=True`` asks for
log times always. Streams are returned in time order (a stable sort, so
messages with equal times keep the bag's order). What the rule did that a
reader should know (log times used, times stepping back) is said
(:func:`stamp_notes`).
"""

from dataclasses import dataclass

import numpy as np


def on_log_times(stamps_ns, use_log_time=False):
    """Tell whether a stream is read on its log times (the stamp rule): asked, or no stamp."""
    return use_log_time or not np.any(stamps_ns)


def stream_times_ns(arrays, use_log_time=False):
    """
    Return ``(times_ns, order)``: the stream's message times, sorted, and the sort order.

    ``arrays`` is a :class:`gyro_emulator.recording.reader.TopicArrays`;
    the times follow the module's stamp rule. Index the decoded columns with
    ``order`` to put them in time order.
    """
    stamps = np.asarray(arrays.stamp_ns, dtype=np.int64)
    if on_log_times(stamps, use_log_time):
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
    notes : tuple of str
        How the times differ from the header stamps in bag order
        (:func:`stamp_notes`).

    """

    topic: str
    type_name: str
    times_ns: np.ndarray
    order: np.ndarray
    arrays: object
    notes: tuple = ()

    def __len__(self):
        """Return the number of messages."""
        return len(self.times_ns)

    def field(self, name):
        """Return a float64 column or block in time order, e.g. ``angular_velocity``."""
        return self.arrays.field(name)[self.order]


def stamp_notes(topic, arrays, use_log_time=False):
    """
    Return what the stamp rule did to a stream that a reader is told, one note each.

    A stream whose stamps are all zero is read on its log times, and one
    whose times step back in bag order (messages out of order, a clock set
    back) is put in time order: both are said, with the count and the largest
    step back. Equal times are not (a FIFO shares a stamp; the record's
    :class:`gyro_emulator.recording.timing.Timing` counts them).
    """
    notes = []
    stamps = np.asarray(arrays.stamp_ns, dtype=np.int64)
    on_log = on_log_times(stamps, use_log_time)
    if on_log and not use_log_time and stamps.size > 1:
        notes.append(f'{topic}: every header stamp is zero: its log (receive) times are used')
    steps = np.diff(np.asarray(arrays.log_time_ns if on_log else stamps, dtype=np.int64))
    if np.any(steps < 0):
        notes.append(f'{topic}: its {"log times" if on_log else "header stamps"} step back '
                     f'{int(np.sum(steps < 0))} time(s) in bag order (at most '
                     f'{-int(steps.min()) * 1e-9:.6g} s): read in time order')
    return tuple(notes)


def read_stream(reader, topic, use_log_time=False):
    """Return :class:`Stream` ``topic`` of ``reader`` (a BagReader), in time order."""
    arrays = reader.read_arrays(topic)
    times_ns, order = stream_times_ns(arrays, use_log_time)
    return Stream(topic, reader.topics[topic].type_name, times_ns, order, arrays,
                  stamp_notes(topic, arrays, use_log_time))
