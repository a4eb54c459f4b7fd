"""Every fixed CDR layout round-trips, and agrees byte for byte with rclpy's serialiser."""

import importlib
import re

from gyro_emulator.recording import cdr
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message

LAYOUT_NAMES = sorted(cdr.LAYOUTS)
STAMPS_NS = np.array([0, 1, 1_700_000_000_123_456_789, -1_500_000_000, 2**31 * 10**9 - 1])


def _message_class(type_name):
    package, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


def _set(msg, dotted, value):
    """Set ``a.b.c`` or ``a[i]`` of a message to ``value``."""
    *parents, last = dotted.split('.')
    for part in parents:
        msg = getattr(msg, part)
    match = re.fullmatch(r'(\w+)\[(\d+)\]', last)
    if match:
        getattr(msg, match.group(1))[int(match.group(2))] = value
    else:
        setattr(msg, last, value)


def _get(msg, dotted):
    *parents, last = dotted.split('.')
    for part in parents:
        msg = getattr(msg, part)
    match = re.fullmatch(r'(\w+)\[(\d+)\]', last)
    if match:
        return float(getattr(msg, match.group(1))[int(match.group(2))])
    return float(getattr(msg, last))


def _values(layout, count, seed):
    """Distinct values per field and message, with the awkward ones included."""
    values = np.random.default_rng(seed).normal(scale=1e3, size=(count, len(layout.fields)))
    values[0, 0] = -0.0
    values[-1, -1] = 1e-300
    return values


def test_every_layout_is_tested():
    """The parametrised tests below cover all 7 layouts, not a subset."""
    assert len(LAYOUT_NAMES) == 7


@pytest.mark.parametrize('type_name', LAYOUT_NAMES)
@pytest.mark.parametrize('frame_id', ['', 'imu_link', 'a'])
def test_encode_decode_round_trip(type_name, frame_id):
    layout = cdr.LAYOUTS[type_name]
    values = _values(layout, len(STAMPS_NS), seed=len(frame_id))
    decoded = cdr.decode(type_name, cdr.encode(type_name, STAMPS_NS, values, frame_id))
    assert np.array_equal(decoded.values, values)
    assert np.array_equal(np.signbit(decoded.values), np.signbit(values))
    if layout.has_header:
        assert np.array_equal(decoded.stamp_ns, STAMPS_NS)
        assert list(decoded.frame_id) == [frame_id] * len(STAMPS_NS)
    else:
        assert not decoded.stamp_ns.any()


@pytest.mark.parametrize('type_name', LAYOUT_NAMES)
def test_encoding_agrees_with_rclpy(type_name):
    """
    Read what rclpy writes; rclpy reads what we write.

    The bytes agree but for the alignment padding, which we write as zeros
    and rclpy leaves as whatever was in its buffer.
    """
    layout = cdr.LAYOUTS[type_name]
    values = _values(layout, len(STAMPS_NS), seed=7)
    ours = cdr.encode(type_name, STAMPS_NS, values, 'base_link')
    cls = _message_class(type_name)
    theirs = []
    for stamp, row in zip(STAMPS_NS, values):
        msg = cls()
        if layout.has_header:
            sec, nanosec = divmod(int(stamp), 10**9)
            msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
            msg.header.frame_id = 'base_link'
        for name, value in zip(layout.fields, row):
            _set(msg, name, float(value))
        theirs.append(serialize_message(msg))
    assert [len(m) for m in ours] == [len(m) for m in theirs]
    for mine, other in zip(ours, theirs):
        differ = np.flatnonzero(np.frombuffer(mine, np.uint8) != np.frombuffer(other, np.uint8))
        assert not np.frombuffer(mine, np.uint8)[differ].any(), 'only padding may differ'
    decoded = cdr.decode(type_name, theirs)
    assert np.array_equal(decoded.values, values)
    assert np.array_equal(decoded.stamp_ns, STAMPS_NS if layout.has_header else 0 * STAMPS_NS)
    for mine, row in zip(ours, values):
        back = deserialize_message(mine, cls)
        assert [_get(back, name) for name in layout.fields] == list(row)


@pytest.mark.parametrize('type_name', LAYOUT_NAMES)
def test_a_payload_of_another_layout_is_refused(type_name):
    layout = cdr.LAYOUTS[type_name]
    wrong = [bytes(cdr.encode(type_name, [1], _values(layout, 1, 3), 'x')[0]) + b'\0' * 8]
    with pytest.raises(ValueError, match=type_name):
        cdr.decode(type_name, wrong)


@pytest.mark.parametrize('type_name', LAYOUT_NAMES)
def test_a_small_batch_decodes_message_by_message_to_the_same_columns(type_name):
    """The per-message path of a few messages (a node's commands) equals the column path."""
    layout = cdr.LAYOUTS[type_name]
    rng = np.random.default_rng(len(type_name))
    names = ['', 'imu_link', 'a', 'gyro_ü', 'x' * 13]
    for trial in range(40):
        count = int(rng.integers(1, cdr.SMALL_BATCH + 1))
        values = _values(layout, count, seed=trial)
        values[rng.random(values.shape) < 0.05] = np.nan
        stamps = rng.choice(STAMPS_NS, count)
        payloads = [cdr.encode(type_name, [stamp], row[None], str(rng.choice(names)))[0]
                    for stamp, row in zip(stamps, values)]
        if layout.has_header and trial % 5 == 0:     # a frame id that is not UTF-8
            head = payloads[0][:16] + b'\xff' + payloads[0][17:]
            payloads[0] = head if payloads[0][12] > 1 else payloads[0]
        each = cdr._decode_each(layout, payloads)
        columns = cdr._decode_columns(layout, payloads)
        assert each.values.tobytes() == columns.values.tobytes(), trial
        assert each.stamp_ns.tobytes() == columns.stamp_ns.tobytes(), trial
        assert list(each.frame_id) == list(columns.frame_id), trial
        assert (each.values.dtype, each.stamp_ns.dtype, each.frame_id.dtype) == \
            (columns.values.dtype, columns.stamp_ns.dtype, columns.frame_id.dtype)
    # an irregular message sends the batch to the column path, which names it
    good = cdr.encode(type_name, [1], _values(layout, 1, 3), 'x')[0]
    for bad in (good + b'\0' * 8, b'\x01\x00' + good[2:], good[:10], bytearray(good)):
        assert cdr._decode_each(layout, [good, bad]) is None
