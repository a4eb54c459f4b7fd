"""
Publish fixed-layout messages as serialized bytes patched in place.

At 1 kHz, converting a Python message to its C form costs more than the rest
of a sample (about 10 us for an Imu against 2 us for publishing the same
message already serialized). The node's messages have a fixed layout once
``frame_id`` is set, so :class:`RawMessage` serializes one template and
writes each sample's stamp and numbers straight into the CDR bytes.

The byte offsets are not computed from the CDR rules: each patched field is
set to distinctive sentinel values, the template is serialized and the
sentinels are located, so the offsets are whatever the installed type
support produces. If a sentinel is not found exactly once (a big-endian
host, say), the object falls back to setting the message's attributes and
:meth:`RawMessage.payload` returns the message itself. The tests compare
patched buffers with ``serialize_message`` of the equivalent messages.
"""

import struct

from gyro_emulator.units import NS_PER_S
from rclpy.serialization import serialize_message

_TIME = struct.Struct('<iI')
_DOUBLE = struct.Struct('<d')
#: Sentinel stamp: seconds and nanoseconds unlikely to occur in a template.
_SENTINEL_SEC, _SENTINEL_NSEC = 0x5A17C0DE, 0x2B0D1E5F


def _sentinel(index):
    """Return a finite float64 with a distinctive bit pattern, one per index."""
    return _DOUBLE.unpack(struct.pack('<HHI', 0x5EED, 0xC0DE + index, 0x1F2E3D4C))[0]


def _resolve(msg, path):
    obj = msg
    parts = path.split('.')
    for part in parts[:-1]:
        obj = getattr(obj, part)
    return obj, parts[-1]


def _setter(obj, attr, kind):
    """Return a function writing values into the message (the fallback path)."""
    if kind == 'time':
        stamp = getattr(obj, attr)

        def set_time(sec, nanosec):
            stamp.sec, stamp.nanosec = sec, nanosec
        return set_time
    if kind == 'vector3':
        target = getattr(obj, attr)

        def set_vector(x, y, z):
            target.x, target.y, target.z = x, y, z
        return set_vector
    if kind == 'double':
        return lambda value: setattr(obj, attr, value)
    count = kind[1]

    def set_array(*values):
        getattr(obj, attr)[:count] = values
    return set_array


class RawMessage:
    """
    A serialized message with named slots patched per sample.

    Parameters
    ----------
    msg : object
        The template message (constant fields already set).
    slots : dict
        ``{name: (path, kind)}``: ``kind`` is ``'time'`` (a
        builtin_interfaces/Time at ``path``), ``'vector3'`` (x, y, z float64
        of the object at ``path``), ``'double'`` (one float64 attribute) or
        ``('array', n)`` (the first n elements of a float64 array).

    """

    def __init__(self, msg, slots):
        self.msg = msg
        self._setters = {name: _setter(*_resolve(msg, path), kind)
                         for name, (path, kind) in slots.items()}
        self._slots = None
        self.buffer = None
        try:
            self._locate(slots)
        except ValueError:
            self._slots = None

    @property
    def raw(self):
        """Tell whether patched bytes are published (False: the fallback path)."""
        return self._slots is not None

    def _locate(self, slots):
        originals, patterns, index = {}, {}, 0
        for name, (path, kind) in slots.items():
            obj, attr = _resolve(self.msg, path)
            if kind == 'time':
                stamp = getattr(obj, attr)
                originals[name] = (stamp.sec, stamp.nanosec)
                values, layout = (_SENTINEL_SEC, _SENTINEL_NSEC), _TIME
            else:
                if kind == 'vector3':
                    target = getattr(obj, attr)
                    originals[name] = (target.x, target.y, target.z)
                elif kind == 'double':
                    originals[name] = (getattr(obj, attr),)
                else:
                    originals[name] = tuple(float(v) for v in getattr(obj, attr)[:kind[1]])
                values = tuple(_sentinel(index + i) for i in range(len(originals[name])))
                index += len(values)
                layout = struct.Struct('<' + 'd' * len(values))
            self._setters[name](*values)
            patterns[name] = (layout.pack(*values), layout)
        buffer = bytes(serialize_message(self.msg))
        for name, values in originals.items():
            self._setters[name](*values)
        found = {}
        for name, (pattern, layout) in patterns.items():
            offset = buffer.find(pattern)
            if offset < 0 or buffer.find(pattern, offset + 1) >= 0:
                raise ValueError(f'slot {name!r} not found exactly once')
            found[name] = (layout, offset)
        self.buffer = bytearray(serialize_message(self.msg))
        self._slots = found

    def put(self, name, *values):
        """Write ``values`` (a Time as sec, nanosec; else float64s) into slot ``name``."""
        if self._slots is None:
            self._setters[name](*values)
            return
        layout, offset = self._slots[name]
        layout.pack_into(self.buffer, offset, *values)

    def set_stamp_ns(self, name, stamp_ns):
        """Write a time slot from integer nanoseconds."""
        self.put(name, stamp_ns // NS_PER_S, stamp_ns % NS_PER_S)

    def payload(self):
        """Return what to publish: the serialized bytes, or the message (fallback)."""
        if self._slots is None:
            return self.msg
        return bytes(self.buffer)
