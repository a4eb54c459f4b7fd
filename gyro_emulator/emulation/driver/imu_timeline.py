"""
The time line of a simulator's ideal IMU (``input_source: imu``; no ROS imports).

Behind a simulator the node publishes one ``imu/data_raw`` per ``imu/ideal``
message, and the time step of the error model comes from the input stamps,
not from a timer. :class:`InputTimeline` turns each stamp into what the
model has to do:

* The model's sample period follows the mean spacing of the stamps over the
  last :data:`WINDOW` messages. The first spacing sets the rate directly;
  after that, when the mean of a full window moves more than
  :data:`REPLAN_TOLERANCE` from the model's period, the model is re-planned
  at the new rate (``GyroModel.set_sample_rate``: every exact
  discretisation follows the new dt). Stamps that alternate (a 300 Hz
  sensor on a 1 ms physics step: 3, 3, 4 ms ...) give their mean rate, not
  a re-plan each.
* A spacing of about k periods (k >= 2: messages lost, or a skipped sensor
  update) advances the model k samples, the first k - 1 with the previous
  input held, so the noise processes see the time that passed.
* A stamp older than the previous one is a simulation reset (the clock
  jumped back): the filters restart, with a warning. A gap longer than
  :data:`MAX_GAP_S` restarts them too, instead of running through it. A
  repeated stamp is refused: it carries no new time.
* A spacing shorter than 1 / :data:`MAX_RATE_HZ` (the top of ``rate_hz``'s
  range) is refused (:class:`SpacingRefused`, counted by the node as
  ``stamp_spacing``) and the stamp is not taken: the model's period stays
  within the allowed rates, so two messages 1 ns apart cannot set a 1 GHz
  period. A faster input is thinned to that rate. The longest spacing
  that sets a period is :data:`MAX_GAP_S` (1 Hz, the bottom of the range).
* A paused simulation sends nothing, so nothing is published.
"""

from collections import deque
from dataclasses import dataclass

from gyro_emulator.units import NS_PER_S

#: Relative change of the mean input period that re-plans the model.
REPLAN_TOLERANCE = 0.01
#: Spacings averaged for the mean input period.
WINDOW = 32
#: Longest gap between stamps that the model runs through, s.
MAX_GAP_S = 1.0
#: Highest input rate followed (``rate_hz``'s upper limit), Hz: closer stamps are refused.
MAX_RATE_HZ = 5000.0


@dataclass(frozen=True)
class Advance:
    """
    What the model does for one input message.

    Attributes
    ----------
    samples : int
        Model samples to run (>= 1); all but the last hold the previous input.
    rate_hz : float or None
        New model rate to set first (None: unchanged).
    restart : str or None
        ``jump_back`` or ``gap``: restart the filters first (None: continue).
    dt_s : float or None
        Time since the previous stamp, s (None for the first message).

    """

    samples: int
    rate_hz: float = None
    restart: str = None
    dt_s: float = None


class StampNotNewer(ValueError):
    """An input stamp equal to the previous one (nothing to sample)."""


class SpacingRefused(ValueError):
    """An input stamp closer to the previous one than 1 / :data:`MAX_RATE_HZ`."""


class InputTimeline:
    """
    Follow the stamps of the input messages; say how to advance the model.

    Parameters
    ----------
    nominal_rate_hz : float
        The model's rate before the first spacing is known, Hz.

    """

    def __init__(self, nominal_rate_hz):
        self.period_s = 1.0 / float(nominal_rate_hz)
        self._spacings = deque(maxlen=WINDOW)
        self.last_ns = None
        self.restarts = 0
        self.replans = 0
        self.filled = 0

    @property
    def mean_period_s(self):
        """Return the mean spacing of the recent stamps per sample, s (None: unknown)."""
        spacings = self._spacings
        return sum(spacings) / len(spacings) if spacings else None

    @property
    def rate_hz(self):
        """Return the mean input rate, Hz (None before two messages)."""
        period = self.mean_period_s
        return None if period is None else 1.0 / period

    def advance(self, stamp_ns):
        """
        Return the :class:`Advance` for a message stamped ``stamp_ns`` (ns).

        Raises :class:`StampNotNewer` for a stamp equal to the previous one and
        :class:`SpacingRefused` for one less than 1 / :data:`MAX_RATE_HZ` after
        it; neither stamp is taken.
        """
        last, stamp_ns = self.last_ns, int(stamp_ns)
        if last is None:
            self.last_ns = stamp_ns
            return Advance(1)
        dt_ns = stamp_ns - last
        if dt_ns == 0:
            raise StampNotNewer(f'imu/ideal: stamp {stamp_ns * 1e-9:.9f} s repeats the '
                                'previous one')
        if 0 < dt_ns < NS_PER_S / MAX_RATE_HZ:
            raise SpacingRefused(
                f'imu/ideal: stamp {stamp_ns * 1e-9:.9f} s is {dt_ns} ns after the previous '
                f'one: allowed at least {NS_PER_S / MAX_RATE_HZ:.0f} ns '
                f'({MAX_RATE_HZ:g} Hz, the highest rate_hz)')
        self.last_ns = stamp_ns
        if dt_ns < 0 or dt_ns > MAX_GAP_S * NS_PER_S:
            self.restarts += 1
            self._spacings.clear()
            return Advance(1, restart='jump_back' if dt_ns < 0 else 'gap', dt_s=dt_ns * 1e-9)
        dt_s = dt_ns * 1e-9
        first = not self._spacings
        count = 1 if first else max(1, int(round(dt_s / self.period_s)))
        self._spacings.append(dt_s / count)
        self.filled += count - 1
        mean = self.mean_period_s
        if (first or len(self._spacings) == WINDOW) and \
                abs(mean / self.period_s - 1.0) > REPLAN_TOLERANCE:
            self.period_s = mean
            self.replans += 1
            return Advance(count, 1.0 / mean, None, dt_s)
        return Advance(count, None, None, dt_s)
