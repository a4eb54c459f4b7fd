"""
Vectorised CDR encoding and decoding of fixed-layout ROS 2 messages.

A ROS 2 message serialised by rmw_fastrtps is an encapsulation header
(``00 01 00 00`` for little-endian plain CDR, OMG DDS-XTypes 1.3 7.6.3.1.2)
followed by the CDR body, whose primitives are aligned to their own size
relative to the start of the body. The messages the emulator publishes are a
``std_msgs/Header`` (int32 sec, uint32 nanosec, a string frame_id) followed by
a run of float64 fields, so one message is a fixed-width row once the frame
id is known::

    offset 0   encapsulation (4 bytes)
    offset 4   stamp.sec int32, stamp.nanosec uint32
    offset 12  frame_id length n (uint32, includes the NUL), n bytes
    offset 4 + align8(12 + n)   the float64 fields, little-endian

Encoding a whole recording is then one numpy array of rows; decoding a topic
is a ``frombuffer`` and a column view. A batch of a few messages (a node's
commands at a sample) is read message by message with ``struct`` instead,
into the same columns (the column path's fixed cost is a few tens of numpy
calls); an irregular message sends it to the column path, which names it.
Padding bytes are written as zeros. Messages in other encodings
(big-endian, XCDR2) raise ``ValueError`` in :func:`decode`; :func:`decode_any`
(the bag reader's) then decodes them with a generic decoder from the bag's
schema into the same columns.
"""

from dataclasses import dataclass
import struct

from gyro_emulator.units import AXES, NS_PER_S
import numpy as np

#: Encapsulation header of little-endian plain CDR (what rclpy produces).
CDR_LE_HEADER = b'\x00\x01\x00\x00'
#: Batches of at most this many messages are decoded one message at a time.
SMALL_BATCH = 16
#: stamp.sec, stamp.nanosec and the frame id's length, after the encapsulation.
_HEADER = struct.Struct('<iII')


def _xyz(prefix):
    return tuple(f'{prefix}.{axis}' for axis in AXES)


def _matrix(prefix):
    return tuple(f'{prefix}[{i}]' for i in range(9))


@dataclass(frozen=True)
class FixedLayout:
    """
    A message type made of an optional Header and float64 fields only.

    Attributes
    ----------
    type_name : str
        ROS 2 type name, e.g. ``sensor_msgs/msg/Imu``.
    fields : tuple of str
        Dotted names of the float64 fields in serialisation order.
    has_header : bool
        Whether the message starts with a ``std_msgs/Header``.

    """

    type_name: str
    fields: tuple
    has_header: bool = True

    def index(self, name):
        """Return the column of field ``name`` (e.g. ``angular_velocity.x``)."""
        try:
            return self.fields.index(name)
        except ValueError:
            raise ValueError(
                f'{self.type_name} has no float64 field {name!r}: fields are '
                f'{", ".join(self.fields)}') from None

    def columns(self, prefix):
        """Return the columns whose field names start with ``prefix``."""
        cols = [i for i, f in enumerate(self.fields)
                if f == prefix or f.startswith(prefix + '.') or f.startswith(prefix + '[')]
        if not cols:
            raise ValueError(f'{self.type_name} has no field {prefix!r}')
        return slice(cols[0], cols[-1] + 1)


#: The fixed-layout types this module encodes and decodes.
LAYOUTS = {layout.type_name: layout for layout in (
    FixedLayout('sensor_msgs/msg/Imu',
                ('orientation.x', 'orientation.y', 'orientation.z', 'orientation.w')
                + _matrix('orientation_covariance')
                + _xyz('angular_velocity') + _matrix('angular_velocity_covariance')
                + _xyz('linear_acceleration') + _matrix('linear_acceleration_covariance')),
    FixedLayout('sensor_msgs/msg/Temperature', ('temperature', 'variance')),
    FixedLayout('geometry_msgs/msg/Vector3Stamped', _xyz('vector')),
    FixedLayout('geometry_msgs/msg/AccelStamped',
                _xyz('accel.linear') + _xyz('accel.angular')),
    FixedLayout('geometry_msgs/msg/TwistStamped',
                _xyz('twist.linear') + _xyz('twist.angular')),
    FixedLayout('geometry_msgs/msg/Vector3', ('x', 'y', 'z'), has_header=False),
    FixedLayout('std_msgs/msg/Float64', ('data',), has_header=False),
)}


def layout_of(type_name):
    """Return the :class:`FixedLayout` of ``type_name`` or raise ValueError."""
    try:
        return LAYOUTS[type_name]
    except KeyError:
        raise ValueError(
            f'no fixed CDR layout for {type_name!r}: supported types are '
            f'{", ".join(sorted(LAYOUTS))}') from None


@dataclass(frozen=True)
class Decoded:
    """
    The columns of a batch of decoded messages.

    Attributes
    ----------
    layout : FixedLayout
        The message layout.
    stamp_ns : numpy.ndarray of int64, shape (N,)
        ``header.stamp`` in integer nanoseconds (zeros without a header).
    frame_id : numpy.ndarray of object, shape (N,)
        ``header.frame_id`` of each message ('' without a header).
    values : numpy.ndarray of float64, shape (N, len(layout.fields))
        The float64 fields in serialisation order.

    """

    layout: FixedLayout
    stamp_ns: np.ndarray
    frame_id: np.ndarray
    values: np.ndarray

    def field(self, name):
        """Return the float64 column ``name`` (or the block of a vector/matrix)."""
        if name in self.layout.fields:
            return self.values[:, self.layout.index(name)]
        return self.values[:, self.layout.columns(name)]


def _body_offset(frame_bytes, has_header):
    """Return the offset of the first float64 from the start of the message."""
    if not has_header:
        return 4
    n = len(frame_bytes) + 1
    return 4 + ((12 + n + 7) & ~7)


def encode_rows(type_name, stamp_ns, values, frame_id=''):
    """
    Serialise a batch of messages into one array of fixed-width rows.

    Parameters
    ----------
    type_name : str
        A type of :data:`LAYOUTS`.
    stamp_ns : array_like of int, shape (N,)
        ``header.stamp`` of each message, integer nanoseconds (ignored without
        a header).
    values : array_like of float, shape (N, len(fields))
        The float64 fields in serialisation order.
    frame_id : str
        ``header.frame_id``, the same for every message.

    Returns
    -------
    numpy.ndarray of uint8, shape (N, row_bytes)
        One serialised message per row (CDR little-endian, zero padding).

    """
    layout = layout_of(type_name)
    values = np.asarray(values, dtype='<f8')
    if values.ndim == 1 and len(layout.fields) == 1:
        values = values[:, None]
    if values.ndim != 2 or values.shape[1] != len(layout.fields):
        raise ValueError(
            f'{type_name} values must have shape (N, {len(layout.fields)}), '
            f'got {values.shape}')
    count = values.shape[0]
    frame_bytes = frame_id.encode('utf-8') if layout.has_header else b''
    if b'\x00' in frame_bytes:
        raise ValueError(f'frame_id {frame_id!r} contains a NUL character')
    offset = _body_offset(frame_bytes, layout.has_header)
    row_bytes = offset + 8 * len(layout.fields)
    rows = np.zeros((count, row_bytes), dtype=np.uint8)
    rows[:, :4] = np.frombuffer(CDR_LE_HEADER, dtype=np.uint8)
    if layout.has_header:
        stamp_ns = np.asarray(stamp_ns, dtype=np.int64).reshape(-1)
        if stamp_ns.shape != (count,):
            raise ValueError(
                f'stamp_ns must have shape ({count},), got {stamp_ns.shape}')
        sec = np.floor_divide(stamp_ns, NS_PER_S)
        if count and (sec.min() < -2**31 or sec.max() >= 2**31):
            raise ValueError('stamp_ns is outside the int32 seconds of builtin_interfaces/Time')
        head = np.empty((count, 3), dtype='<u4')
        head[:, 0] = sec.astype('<i4').view('<u4')
        head[:, 1] = stamp_ns - sec * NS_PER_S
        head[:, 2] = len(frame_bytes) + 1
        rows[:, 4:16] = head.view(np.uint8).reshape(count, 12)
        if frame_bytes:
            rows[:, 16:16 + len(frame_bytes)] = np.frombuffer(frame_bytes, dtype=np.uint8)
    rows[:, offset:] = np.ascontiguousarray(values).view(np.uint8).reshape(count, -1)
    return rows


def encode(type_name, stamp_ns, values, frame_id=''):
    """
    Serialise a batch of messages; return a list of ``bytes``, one per message.

    Parameters are those of :func:`encode_rows`.
    """
    rows = encode_rows(type_name, stamp_ns, values, frame_id)
    blob = rows.tobytes()
    width = rows.shape[1]
    return [blob[i:i + width] for i in range(0, len(blob), width)]


def _decode_group(layout, rows):
    """Decode rows of identical width and frame-id length."""
    count, width = rows.shape
    if layout.has_header:
        head = np.ascontiguousarray(rows[:, 4:16]).view('<u4')
        sec = head[:, 0].view('<i4').astype(np.int64)
        stamp_ns = sec * NS_PER_S + head[:, 1].astype(np.int64)
        n = int(head[0, 2])
        offset = 4 + ((12 + n + 7) & ~7)
        names = rows[:, 16:16 + n - 1]
        if count and (names == names[0]).all():
            frame_id = np.full(count, bytes(names[0]).decode('utf-8', 'replace'), object)
        else:
            unique, inverse = np.unique(names, axis=0, return_inverse=True)
            decoded_names = np.array(
                [bytes(u).decode('utf-8', 'replace') for u in unique] or [''], dtype=object)
            frame_id = decoded_names[inverse.reshape(-1)] if count else np.empty(0, object)
    else:
        stamp_ns = np.zeros(count, dtype=np.int64)
        frame_id = np.full(count, '', dtype=object)
        offset = 4
    expected = offset + 8 * len(layout.fields)
    if width != expected:
        raise ValueError(
            f'{layout.type_name}: a {width}-byte message does not match the fixed '
            f'layout ({expected} bytes); it is not plain little-endian CDR of this type')
    values = np.ascontiguousarray(rows[:, offset:]).view('<f8')
    return stamp_ns, frame_id, values


def _decode_each(layout, payloads):
    """
    Decode a few messages one at a time into the columns of :func:`decode`.

    The same fields, bit for bit, with a few calls per message instead of
    the column path's fixed cost of a few tens of numpy calls (a node takes
    a handful of commands at a sample). None when any message is not a
    regular one of the layout: the column path then decodes or refuses the
    batch, with its message.
    """
    width = len(layout.fields)
    fields = struct.Struct(f'<{width}d')
    stamps, names, values = [], [], []
    for payload in payloads:
        if not isinstance(payload, bytes) or payload[:2] != CDR_LE_HEADER[:2]:
            return None
        if layout.has_header:
            if len(payload) < 16:
                return None
            sec, nanosec, n = _HEADER.unpack_from(payload, 4)
            offset = 4 + ((12 + n + 7) & ~7)
            stamps.append(sec * NS_PER_S + nanosec)
            names.append(payload[16:15 + n].decode('utf-8', 'replace'))
        else:
            offset = 4
            stamps.append(0)
            names.append('')
        if len(payload) != offset + 8 * width:
            return None
        values.append(fields.unpack_from(payload, offset))
    frame_id = np.empty(len(names), dtype=object)
    frame_id[:] = names
    return Decoded(layout, np.array(stamps, dtype=np.int64), frame_id,
                   np.array(values, dtype=np.float64))


def decode(type_name, payloads):
    """
    Decode a batch of serialised messages of one type into columns.

    Parameters
    ----------
    type_name : str
        A type of :data:`LAYOUTS`.
    payloads : sequence of bytes
        Serialised messages (CDR little-endian with encapsulation header).

    Returns
    -------
    Decoded
        Stamps, frame ids and the float64 fields, in the order of ``payloads``.

    Raises
    ------
    ValueError
        If a message is not little-endian plain CDR of this layout.

    """
    layout = layout_of(type_name)
    count = len(payloads)
    width = len(layout.fields)
    if count == 0:
        return Decoded(layout, np.zeros(0, np.int64), np.empty(0, object),
                       np.zeros((0, width)))
    if count <= SMALL_BATCH:
        decoded = _decode_each(layout, payloads)
        if decoded is not None:
            return decoded
    return _decode_columns(layout, payloads)


def decode_any(type_name, payloads, schema_text, what):
    """
    Decode a batch like :func:`decode`, and what it refuses with the schema.

    Messages in another encoding than plain little-endian CDR (big-endian
    CDR, XCDR2) are decoded one by one by mcap-ros2-support's generic
    decoder from ``schema_text`` (the ros2msg schema of the bag) and read into
    the same columns (:func:`from_messages`).

    Raises
    ------
    ValueError
        One line naming ``what`` (the topic) and the message that is not
        CDR of its schema either.

    """
    try:
        return decode(type_name, payloads)
    except ValueError as exc:
        fast_error = exc
    from mcap.records import Schema         # the generic path only (mcap: 40 ms to import)
    from mcap_ros2.decoder import DecoderFactory

    schema = Schema(id=1, name=type_name, encoding='ros2msg', data=schema_text.encode('utf-8'))
    try:
        decoder = DecoderFactory().decoder_for('cdr', schema)
    except Exception as exc:  # noqa: B902 - the library's own errors, said in one line
        raise ValueError(f'{what}: {fast_error}, and its schema does not parse '
                         f'({type(exc).__name__}: {exc})') from None
    messages = []
    for i, payload in enumerate(payloads):
        try:
            messages.append(decoder(payload))
        except Exception as exc:  # noqa: B902 - a payload that is not CDR of the schema
            raise ValueError(f'{what}: message {i} is not CDR of {type_name} ({fast_error}; '
                             f'generic decoder: {type(exc).__name__}: {exc})') from None
    return from_messages(type_name, messages)


def from_messages(type_name, messages):
    """
    Return the :class:`Decoded` columns of messages a generic decoder gave.

    The path for encodings :func:`decode` refuses (big-endian CDR, XCDR2):
    ``messages`` are objects with attribute access (mcap-ros2-support's
    decoder, rclpy messages), read field by field.

    Parameters
    ----------
    type_name : str
        A type of :data:`LAYOUTS`.
    messages : sequence
        The decoded messages, in order.

    """
    layout = layout_of(type_name)
    count = len(messages)
    stamp_ns = np.zeros(count, dtype=np.int64)
    frame_id = np.full(count, '', dtype=object)
    values = np.empty((count, len(layout.fields)), dtype=np.float64)
    for i, message in enumerate(messages):
        if layout.has_header:
            stamp = message.header.stamp
            stamp_ns[i] = int(stamp.sec) * NS_PER_S + int(stamp.nanosec)
            frame_id[i] = str(message.header.frame_id)
        values[i] = [_field_of(message, name) for name in layout.fields]
    return Decoded(layout, stamp_ns, frame_id, values)


def _field_of(message, name):
    """Return field ``a.b`` or ``a[i]`` of a decoded message as a float."""
    value = message
    for part in name.split('.'):
        attr, _, index = part.partition('[')
        value = getattr(value, attr)
        if index:
            value = value[int(index[:-1])]
    return float(value)


def _decode_columns(layout, payloads):
    """Decode a batch as rows of columns (:func:`decode`; any batch, and every error)."""
    type_name = layout.type_name
    count = len(payloads)
    width = len(layout.fields)
    lengths = np.fromiter(map(len, payloads), dtype=np.int64, count=count)
    stamp_ns = np.empty(count, dtype=np.int64)
    frame_id = np.empty(count, dtype=object)
    values = np.empty((count, width), dtype=np.float64)
    uniform = bool((lengths == lengths[0]).all())
    groups = [(None, int(lengths[0]))] if uniform else [
        (np.flatnonzero(lengths == size), int(size)) for size in np.unique(lengths)]
    for index, size in groups:
        chunk = payloads if index is None else [payloads[i] for i in index]
        rows = np.frombuffer(b''.join(chunk), dtype=np.uint8).reshape(len(chunk), size)
        if size < 4 or (rows[:, 1] != 1).any() or (rows[:, 0] != 0).any():
            raise ValueError(
                f'{type_name}: a message is not little-endian plain CDR '
                '(encapsulation 00 01)')
        if layout.has_header:
            if size < 16:
                raise ValueError(f'{type_name}: a {size}-byte message is too short')
            name_len = np.ascontiguousarray(rows[:, 12:16]).view('<u4')[:, 0]
            subgroups = [None] if (name_len == name_len[0]).all() else [
                np.flatnonzero(name_len == n) for n in np.unique(name_len)]
        else:
            subgroups = [None]
        for sub in subgroups:
            s, f, v = _decode_group(layout, rows if sub is None else rows[sub])
            target = (slice(None) if index is None else index) if sub is None else (
                sub if index is None else index[sub])
            stamp_ns[target] = s
            frame_id[target] = f
            values[target] = v
    return Decoded(layout, stamp_ns, frame_id, values)
