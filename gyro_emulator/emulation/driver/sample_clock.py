"""
The sensor's own sample clock under the node's timer (no ROS imports).

A real IMU samples on its own clock and keeps the samples in a FIFO until
its driver reads them; a late read gets every sample since the last one,
each with its true sample time. The node does the same. Its timer only says
"now is ``now_ns``"; :class:`SampleClock` answers which samples are due: the
instants ``anchor + k * period`` (the part's period, clock drift included)
at or before ``now_ns`` that have not been handed out yet. So neither a
coarse ``/clock`` (use_sim_time; a simulator at 10 ms steps wakes a 200 Hz
timer once per step) nor a wall timer that skipped ticks under CPU load
loses samples or stamps them late.

What a tick hands out depends on the overrun policy:

* ``fifo`` (default): the due samples oldest first, at most ``max_burst``
  per tick; the rest wait for the next tick (the FIFO backlog). A backlog
  longer than ``depth`` samples overflows: the oldest are dropped and
  counted, as a sensor FIFO in stream mode overwrites its oldest entries.
* ``drop``: only the newest due sample; the older ones are dropped and
  counted.

Dropped samples are still run through the model (:attr:`Due.skipped`, with
the input held), so its noise processes see the time that passed. Timing
rules:

* The first tick anchors the grid at its ``now_ns``; a sample time is never
  in the future. On a wall clock (``follow_timer``), a tick that finds no
  sample due while the next one is less than half a period ahead moves the
  grid back to ``now_ns``: the timer fired earlier than the grid (its
  latency dropped below the first tick's), and a grid anchored at the
  least latency gives exactly one sample per tick to a timer in step. On a
  simulator's clock the ticks come at the ``/clock`` instants, so the grid
  stays where it is.
* A clock that jumps back (``now_ns`` before the previous tick), or forward
  by more than :data:`MAX_GAP_S`, re-anchors the grid at ``now_ns``
  (:attr:`Due.restart`); the samples of a forward jump are not run.
* A new period (:meth:`SampleClock.set_period`) takes effect from the next
  sample on.
"""

from dataclasses import dataclass
import math

from gyro_emulator.units import NS_PER_S

#: Values of the ``overrun_policy`` node parameter.
OVERRUN_POLICIES = ('fifo', 'drop')
#: Longest clock step whose samples are run through; longer ones re-anchor, s.
MAX_GAP_S = 10.0


@dataclass(frozen=True)
class Due:
    """
    The samples one tick hands out.

    Attributes
    ----------
    times_ns : tuple of int
        Sample instants to publish, oldest first (may be empty).
    skipped : int
        Samples before them that are run through the model but dropped.
    restart : str or None
        ``jump_back`` or ``gap``: the grid was re-anchored at this tick.

    """

    times_ns: tuple = ()
    skipped: int = 0
    restart: str = None


class SampleClock:
    """
    The grid of sample instants and the FIFO between the sensor and its driver.

    Parameters
    ----------
    period_s : float
        Sample period, s.
    policy : str
        ``fifo`` or ``drop`` (see the module docstring).
    max_burst : int
        Most samples published by one tick (``fifo``).
    depth : int
        Most samples waiting in the backlog (``fifo``); older ones are dropped.
    follow_timer : bool
        Move the grid back to an early tick (wall clock; False under sim time).

    Attributes
    ----------
    ticks, overruns : int
        Ticks seen; ticks that found more than one sample due.
    due_total, emitted, caught_up, dropped : int
        Samples that came due, that were handed out, that were handed out
        late (beyond the first of their tick), that were dropped.
    largest_burst, backlog : int
        Most samples handed out by one tick; samples due but still waiting.
    restarts : int
        Re-anchorings after a clock jump.
    counts : dict
        The counters as /diagnostics reports them, replaced whole at the end
        of each :meth:`due`: a thread that reads it (the node's diagnostics)
        never sees a burst counted due and not yet handed out.

    """

    def __init__(self, period_s, policy='fifo', max_burst=32, depth=1000, follow_timer=True):
        self.period_ns = float(period_s) * NS_PER_S
        self.policy = policy
        self.max_burst = max(1, int(max_burst))
        self.depth = max(1, int(depth))
        self.follow_timer = bool(follow_timer)
        self._anchor = None
        self._k = 0
        self._last_now = None
        self._last_ns = None
        self.ticks = self.overruns = 0
        self.due_total = self.emitted = self.caught_up = self.dropped = 0
        self.largest_burst = self.backlog = self.restarts = 0
        self._store_counts()

    def _time(self, k):
        return self._anchor + int(round(k * self.period_ns))

    def upcoming(self, after_ns, count):
        """
        Return the next ``count`` grid instants after ``after_ns``, ns (a forecast).

        They are the samples :meth:`due` hands out next while the grid stays
        (no re-anchoring, no new period, nothing dropped); empty before the
        first tick.
        """
        if self._anchor is None or count < 1:
            return []
        k = int(math.floor((after_ns - self._anchor) / self.period_ns))
        while self._time(k) > after_ns:
            k -= 1                                  # rounding of the float period
        while self._time(k + 1) <= after_ns:
            k += 1
        return [self._time(k + i) for i in range(1, count + 1)]

    @property
    def last_ns(self):
        """Return the instant of the last sample handed out, ns (None before one)."""
        return self._last_ns

    @property
    def emitted_ratio(self):
        """Return samples handed out / samples due (1.0 before any)."""
        return self.emitted / self.due_total if self.due_total else 1.0

    def set_period(self, period_s):
        """Use a new sample period from the next sample on."""
        if self._anchor is not None:
            self._anchor, self._k = self._time(self._k), 0
        self.period_ns = float(period_s) * NS_PER_S

    def _reanchor(self, now_ns, why):
        self._anchor, self._k = now_ns, 0
        self.restarts += 1
        self.backlog = 0
        return why

    def due(self, now_ns):
        """Return the :class:`Due` samples of a tick at ``now_ns`` (node clock, ns)."""
        now_ns = int(now_ns)
        self.ticks += 1
        restart = None
        if self._anchor is None:
            self._anchor, self._k = now_ns, 0
        elif now_ns < self._last_now:
            restart = self._reanchor(now_ns, 'jump_back')
            self._last_ns = None
        self._last_now = now_ns
        following = self._time(self._k)
        if following > now_ns:
            newer = self._last_ns is None or now_ns > self._last_ns
            if not (self.follow_timer and newer and following - now_ns < 0.5 * self.period_ns):
                self.backlog = 0
                self._store_counts()
                return Due(restart=restart)
            self._anchor, self._k = now_ns, 0       # the timer runs ahead of the grid
        count = int(math.floor((now_ns - self._anchor) / self.period_ns)) - self._k + 1
        while count > 0 and self._time(self._k + count - 1) > now_ns:
            count -= 1                              # rounding of the float period
        while self._time(self._k + count) <= now_ns:
            count += 1
        if count * self.period_ns > MAX_GAP_S * NS_PER_S:
            restart = self._reanchor(now_ns, 'gap')
            count = 1
        if self.policy == 'drop':
            skipped, emit = count - 1, 1
        else:
            skipped = max(0, count - self.depth)
            emit = min(count - skipped, self.max_burst)
        times = tuple(self._time(self._k + skipped + i) for i in range(emit))
        self._k += skipped + emit
        fresh = count - self.backlog if count > self.backlog else 0
        self.due_total += fresh
        self.emitted += emit
        self.dropped += skipped
        self.caught_up += emit - 1
        self.backlog = count - skipped - emit
        if count > 1:
            self.overruns += 1
        self.largest_burst = max(self.largest_burst, emit)
        self._last_ns = times[-1]
        self._store_counts()
        return Due(times, skipped, restart)

    def _store_counts(self):
        """Keep the counters as one object, which another thread reads whole (:attr:`counts`)."""
        self.counts = {'overruns': self.overruns, 'samples_due': self.due_total,
                       'samples_caught_up': self.caught_up, 'samples_dropped': self.dropped,
                       'emitted_ratio': self.emitted_ratio,
                       'largest_burst': self.largest_burst, 'backlog': self.backlog,
                       'clock_restarts': self.restarts}
