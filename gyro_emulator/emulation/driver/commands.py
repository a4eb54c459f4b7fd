"""
Validation and scheduling of the commands the node receives (no ROS imports).

Every command (rate, ambient temperature, specific force) passes through a
check here before it can reach the sensor model. A bad command is either
*rejected* (dropped, the previous value stays in force) or *clamped* (a
temperature outside the model's range, when the policy is ``clamp``); each
outcome is counted by reason so the node can report it in ``/diagnostics``.

Rules (documented in docs/node.md, "Bad input, stale commands, diagnostics"):

* rate: every element finite and ``|omega_i| <= max_abs_rate_rad_s``, else
  rejected (``non_finite_rate`` / ``rate_too_large``). Rates above the
  sensor's full-scale range are accepted: the model saturates them.
* temperature: finite (``non_finite_temperature``), above absolute zero
  (``below_absolute_zero``), then inside the model range: ``clamp`` moves it
  to the nearest bound (``temperature_clamped``), ``reject`` drops it
  (``temperature_out_of_range``).
* specific force: finite and ``|a_i| <= max_abs_accel_m_s2``.
* stamps: a command applies at the first sample whose time is at or after
  its ``header.stamp`` (a zero stamp means "on receipt"). A stamp earlier
  than the newest accepted one on the same stream is ``out_of_order``; a
  stamp more than ``max_stamp_lead_s`` ahead of the node clock is
  ``future_stamp`` (typically a use_sim_time mismatch).
"""

import bisect
from collections import deque
from dataclasses import dataclass
import math

from gyro_emulator.units import AXES, NS_PER_S, ZERO_CELSIUS_K

#: Every reason an input can be rejected, in report order.
REJECT_REASONS = (
    'non_finite_rate', 'rate_too_large', 'non_finite_temperature',
    'below_absolute_zero', 'temperature_out_of_range',
    'non_finite_acceleration', 'acceleration_too_large', 'out_of_order',
    'future_stamp', 'queue_overflow', 'stamp_spacing')

#: Inputs accepted after modification.
CLAMP_REASONS = ('temperature_clamped',)

TEMPERATURE_POLICIES = ('clamp', 'reject')
#: The command streams of a node (:class:`Commands`), by name.
STREAMS = ('rate', 'temperature', 'linear_acceleration')


class InputRejected(ValueError):
    """A command failed validation; ``reason`` is one of :data:`REJECT_REASONS`."""

    def __init__(self, reason, message):
        super().__init__(message)
        self.reason = reason


@dataclass(frozen=True)
class InputLimits:
    """
    Limits applied to incoming commands.

    Attributes
    ----------
    max_abs_rate_rad_s : float
        Largest accepted |rate| per axis, rad/s.
    max_abs_accel_m_s2 : float
        Largest accepted |specific force| per axis, m/s^2.
    temp_range_c : tuple of float
        (low, high) ambient temperatures the model accepts, deg C.
    temperature_policy : str
        ``clamp`` or ``reject`` for temperatures outside ``temp_range_c``.
    max_stamp_lead_s : float
        Largest accepted lead of a command stamp over the node clock, s.

    """

    max_abs_rate_rad_s: float = 100.0
    max_abs_accel_m_s2: float = 1000.0
    temp_range_c: tuple = (-60.0, 200.0)
    temperature_policy: str = 'clamp'
    max_stamp_lead_s: float = 1.0

    def __post_init__(self):
        """Check the limits (positive, ordered range, known policy)."""
        for name in ('max_abs_rate_rad_s', 'max_abs_accel_m_s2', 'max_stamp_lead_s'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f'InputLimits.{name} = {value!r} is out of range: '
                                 'allowed (0, inf)')
        low, high = self.temp_range_c
        if not low < high:
            raise ValueError(f'InputLimits.temp_range_c = {self.temp_range_c!r} is not '
                             'an increasing (low, high) pair')
        if self.temperature_policy not in TEMPERATURE_POLICIES:
            raise ValueError(
                f'InputLimits.temperature_policy = {self.temperature_policy!r} is not '
                f'allowed: choose one of {", ".join(TEMPERATURE_POLICIES)}')


def _vector(values, name, limit, unit, nan_reason, large_reason):
    out = tuple(float(v) for v in values)
    for axis, value in zip(AXES, out):
        if not math.isfinite(value):
            raise InputRejected(nan_reason, f'{name}.{axis} = {value!r} is not finite: '
                                'allowed finite numbers')
        if abs(value) > limit:
            raise InputRejected(large_reason, f'{name}.{axis} = {value!r} is out of '
                                f'range: allowed [-{limit:g}, {limit:g}] {unit}')
    return out


def _within(values, limit):
    """
    Return ``values`` as (x, y, z) float tuples if each number is finite and within the limit.

    None when any is not (or a row is not three numbers): then the values
    are checked one by one (:func:`check_rate`, :func:`check_acceleration`),
    which name the first bad one.
    """
    try:
        if any(len(row) != 3 for row in values):
            return None
        flat = [float(v) for row in values for v in row]
    except (TypeError, ValueError):
        return None
    # a finite sum: no NaN and no infinity among them
    if not (math.isfinite(sum(flat)) and -limit <= min(flat) and max(flat) <= limit):
        return None
    return list(zip(flat[0::3], flat[1::3], flat[2::3]))


def check_rate(values, limits):
    """Return the rate (x, y, z) in rad/s as a tuple, or raise InputRejected."""
    return _vector(values, 'angular_velocity', limits.max_abs_rate_rad_s, 'rad/s',
                   'non_finite_rate', 'rate_too_large')


def check_acceleration(values, limits):
    """Return the specific force (x, y, z) in m/s^2, or raise InputRejected."""
    return _vector(values, 'linear_acceleration', limits.max_abs_accel_m_s2, 'm/s^2',
                   'non_finite_acceleration', 'acceleration_too_large')


def check_temperature(temp_c, limits):
    """
    Validate an ambient temperature against absolute zero and the model range.

    Parameters
    ----------
    temp_c : float
        Ambient temperature, deg C.
    limits : InputLimits
        Range and policy.

    Returns
    -------
    tuple of (float, bool)
        The temperature to use, deg C, and whether it was clamped.

    """
    value = float(temp_c)
    low, high = limits.temp_range_c
    if not math.isfinite(value):
        raise InputRejected('non_finite_temperature', f'temperature = {value!r} is not '
                            f'finite: allowed [{low:g}, {high:g}] C')
    if value <= -ZERO_CELSIUS_K:
        raise InputRejected('below_absolute_zero', f'temperature = {value!r} C is at or '
                            f'below absolute zero (-{ZERO_CELSIUS_K} C): allowed '
                            f'[{low:g}, {high:g}] C')
    if low <= value <= high:
        return value, False
    if limits.temperature_policy == 'reject':
        raise InputRejected('temperature_out_of_range', f'temperature = {value!r} C is '
                            f'out of the model range: allowed [{low:g}, {high:g}] C')
    return min(max(value, low), high), True


class CommandStream:
    """
    One command stream: stamp-ordered queue, current value and arrival time.

    A command applies at the first sample whose time is at or after its stamp
    (zero stamp: its arrival time), so a recorded or simulated sequence
    replays sample-exactly. :meth:`offer` validates stamps and queues the
    command in stamp order, :meth:`advance` moves commands whose time has
    come into :attr:`value`. A command stamped ahead (up to the lead limit)
    waits for its time without blocking the commands stamped before it; only
    a command older than the one already in force is out of order.

    Parameters
    ----------
    name : str
        Stream name used in messages.
    initial : object
        Value in force before the first command (None: none).
    capacity : int
        Most commands waiting for their stamp; the oldest is dropped beyond.

    """

    def __init__(self, name, initial=None, capacity=1000):
        self.name = name
        self.value = initial
        self.capacity = int(capacity)
        self.pending = deque()
        self.newest_stamp_ns = None
        self.applied_stamp_ns = None
        self.last_arrival_ns = None
        self.accepted = 0

    def offer(self, value, stamp_ns, now_ns, max_lead_ns):
        """
        Queue a validated command; return the reason if it was dropped, else None.

        Parameters
        ----------
        value : object
            The validated command value.
        stamp_ns : int
            Its header stamp, ns (0 = on receipt).
        now_ns : int
            Node clock at arrival, ns.
        max_lead_ns : int
            Largest accepted lead of ``stamp_ns`` over ``now_ns``, ns.

        """
        effective = now_ns if stamp_ns == 0 else stamp_ns
        if self.applied_stamp_ns is not None and effective < self.applied_stamp_ns:
            raise InputRejected(
                'out_of_order', f'{self.name}: stamp {effective * 1e-9:.9f} s is older '
                f'than the command in force since {self.applied_stamp_ns * 1e-9:.9f} s')
        if effective - now_ns > max_lead_ns:
            raise InputRejected(
                'future_stamp', f'{self.name}: stamp {effective * 1e-9:.9f} s is '
                f'{(effective - now_ns) * 1e-9:.3f} s ahead of the node clock '
                f'(allowed {max_lead_ns * 1e-9:g} s; use_sim_time mismatch?)')
        self.newest_stamp_ns = max(effective, self.newest_stamp_ns or effective)
        self.last_arrival_ns = now_ns
        self.accepted += 1
        dropped = None
        if len(self.pending) >= self.capacity:
            self.pending.popleft()
            dropped = 'queue_overflow'
        if self.pending and effective < self.pending[-1][0]:
            # stamp order; equal stamps keep their arrival order
            index = bisect.bisect_right([stamp for stamp, _ in self.pending], effective)
            self.pending.insert(index, (effective, value))
        else:
            self.pending.append((effective, value))
        return dropped

    def extend(self, stamps_ns, values, now_ns, max_lead_ns, overflow):
        """
        Queue checked commands (``values``) at once if :meth:`offer` would queue each in turn.

        That is when their stamps (0: ``now_ns``) are in order, none older
        than the last queued or the one in force, none too far ahead; then the
        result is that of :meth:`offer` for each in turn (``overflow(self)``
        once per command dropped from the full queue) and True comes back.
        Otherwise nothing changes and False comes back (offer them one by one).
        """
        effective = [now_ns if stamp == 0 else stamp for stamp in stamps_ns]
        floor = self.pending[-1][0] if self.pending else self.applied_stamp_ns
        if (floor is not None and effective[0] < floor) or len(self.pending) > self.capacity \
                or effective[-1] - now_ns > max_lead_ns \
                or any(b < a for a, b in zip(effective, effective[1:])):
            return False
        self.newest_stamp_ns = max(effective[-1], self.newest_stamp_ns or effective[-1])
        self.last_arrival_ns = now_ns
        self.accepted += len(effective)
        pending = self.pending
        pending.extend(zip(effective, values))
        for _ in range(len(pending) - self.capacity):
            pending.popleft()
            overflow(self)
        return True

    def advance(self, now_ns):
        """Apply every queued command due at ``now_ns``; return the value in force."""
        pending = self.pending
        while pending and pending[0][0] <= now_ns:
            self.applied_stamp_ns, self.value = pending.popleft()
        return self.value

    def age_s(self, now_ns):
        """Seconds since the last accepted command arrived (None: never)."""
        if self.last_arrival_ns is None:
            return None
        return (now_ns - self.last_arrival_ns) * 1e-9

    def reset_clock(self):
        """Forget stamps after the clock jumped back (e.g. a restarted simulation)."""
        self.pending.clear()
        self.newest_stamp_ns = None
        self.applied_stamp_ns = None
        self.last_arrival_ns = None


class Commands:
    """
    A node's command streams: every command checked, then queued at its stamp.

    Parameters
    ----------
    initial_temperature_c : float
        Ambient temperature before the first command, deg C.
    initial_accel_m_s2 : tuple of float
        Specific force before the first command, m/s^2.
    capacity : int
        Commands per stream waiting for their stamp.
    reject : callable
        ``reject(InputRejected)``: count and log a refused command.
    clamp : callable
        ``clamp(raw_temp_c, temp_c)``: count and log a clamped temperature.

    Attributes
    ----------
    rate, temperature, accel : CommandStream
        The streams (:data:`STREAMS`, in that order); the rate is zero
        before its first command.

    """

    def __init__(self, initial_temperature_c, initial_accel_m_s2, capacity, reject, clamp):
        self.rate = CommandStream('rate', (0.0, 0.0, 0.0), capacity)
        self.temperature = CommandStream('temperature', initial_temperature_c, capacity)
        self.accel = CommandStream('linear_acceleration', tuple(initial_accel_m_s2),
                                   capacity)
        self._reject, self._clamp = reject, clamp
        self._by_name = {stream.name: stream for stream in self.streams}

    @property
    def streams(self):
        """Return the rate, temperature and acceleration streams, in that order."""
        return (self.rate, self.temperature, self.accel)

    def offer(self, name, stamps_ns, values, now_ns, limits):
        """
        Check and queue commands of one stream that arrived by ``now_ns``.

        Parameters
        ----------
        name : str
            The stream, one of :data:`STREAMS`.
        stamps_ns : sequence of int
            Their stamps, ns (0: on receipt).
        values : sequence
            Their values: (x, y, z) rad/s or m/s^2, or deg C.
        now_ns : int
            The clock at arrival, ns.
        limits : InputLimits
            The checks in force.

        """
        stream = self._by_name[name]
        lead_ns = int(limits.max_stamp_lead_s * NS_PER_S)
        if stream is not self.temperature and len(values) > 1:
            limit = (limits.max_abs_rate_rad_s if stream is self.rate
                     else limits.max_abs_accel_m_s2)
            rows = _within(values, limit)
            if rows is not None and stream.extend(stamps_ns, rows, now_ns, lead_ns,
                                                  self._overflow):
                return
        for stamp_ns, value in zip(stamps_ns, values):
            try:
                checked = self._check(stream, value, limits)
                if stream.offer(checked, stamp_ns, now_ns, lead_ns):
                    self._overflow(stream)
            except InputRejected as exc:
                self._reject(exc)

    def _overflow(self, stream):
        self._reject(InputRejected(
            'queue_overflow', f'{stream.name}: more than {stream.capacity} '
            'commands wait for their stamp: the oldest was dropped'))

    def _check(self, stream, value, limits):
        if stream is self.rate:
            return check_rate(value, limits)
        if stream is self.accel:
            return check_acceleration(value, limits)
        temp, clamped = check_temperature(value, limits)
        if clamped:
            self._clamp(value, temp)
        return temp

    def pending(self):
        """Return how many commands wait for their stamp, over all streams."""
        return sum(len(stream.pending) for stream in self.streams)

    def reset_clock(self):
        """Forget every stamp (the clock jumped)."""
        for stream in self.streams:
            stream.reset_clock()


class CommandInbox:
    """
    Commands waiting for the driver, as plain values (the node's inboxes hold messages).

    :meth:`take` returns what arrived since the previous call, as
    ``(stream name, stamps, values)`` batches in arrival order (one batch
    per run of commands of one stream), which is what the driver reads from
    any command source.
    """

    def __init__(self):
        self._waiting = []

    def push(self, name, stamp_ns, value):
        """Add one command of stream ``name`` (:data:`STREAMS`) stamped ``stamp_ns``."""
        if name not in STREAMS:
            raise ValueError(f'command stream {name!r} is not allowed: choose one of '
                             f'{", ".join(STREAMS)}')
        waiting = self._waiting
        if waiting and waiting[-1][0] == name:      # one batch per run of a stream, as a node's
            waiting[-1][1].append(int(stamp_ns))
            waiting[-1][2].append(value)
        else:
            waiting.append((name, [int(stamp_ns)], [value]))

    def take(self):
        """Return and forget the commands that arrived, as (name, stamps, values) batches."""
        waiting, self._waiting = self._waiting, []
        return waiting


class Throttle:
    """
    At most one log line per key per ``period_s``, counting what it held back.

    Parameters
    ----------
    period_s : float
        Minimum time between two lines of one key, s.
    clock : callable
        Returns the current time in s (e.g. ``time.monotonic``).

    """

    def __init__(self, period_s, clock):
        self.period_s = float(period_s)
        self.clock = clock
        self._last = {}
        self._held = {}

    def __call__(self, key):
        """Return None to stay quiet, or how many lines were held back since the last."""
        now = self.clock()
        last = self._last.get(key)
        if last is not None and now - last < self.period_s:
            self._held[key] = self._held.get(key, 0) + 1
            return None
        self._last[key] = now
        return self._held.pop(key, 0)
