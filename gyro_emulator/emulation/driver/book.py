"""
The driver's counters and the diagnostics status they give (no ROS imports).

:class:`DiagnosticsBook` counts samples, saturation, rejected and clamped
inputs and model errors; :meth:`DiagnosticsBook.report` turns the counts
since the previous report and the node's current situation into one status:

* ERROR: the model raised on a sample in the period, or gave a non-finite
  one (nothing published for either), an injected fault that invalidates
  the output is acting (stuck, dropout, saturate), or the self-recording
  (``record_dir``) stopped on a write error (a full disk); the node keeps
  publishing.
* WARN: an injected fault that degrades the output is acting (bias_step,
  drift, spike, noise_burst), stale rate command, inputs rejected or temperatures clamped in the
  period, samples dropped by the overrun policy in the period, saturation in
  the period, or (wall clock only) an achieved rate below 90 % of ``rate_hz``,
  or (sim time, or behind a simulator) no sample yet, waiting for what the
  time line comes from (``/clock``, ``imu/ideal``).
* OK otherwise.

Events (:meth:`DiagnosticsBook.event`: a clock jump, the end of the start-up
bias calibration) are said once, in the next report, at their own level.
Counters in the key/values are cumulative since start; the message names
what happened in the last period.
"""

from dataclasses import dataclass

from gyro_emulator.emulation.driver.commands import CLAMP_REASONS, REJECT_REASONS
from gyro_emulator.units import AXES

#: Levels of a report (``diagnostic_msgs/DiagnosticStatus`` OK, WARN, ERROR).
OK, WARN, ERROR = 0, 1, 2
#: Achieved/target rate below which a wall-clock run warns.
RATE_WARN_FRACTION = 0.9


@dataclass(frozen=True)
class Report:
    """One diagnostics status: level (OK/WARN/ERROR), message and key/values."""

    level: int
    message: str
    values: tuple


class DiagnosticsBook:
    """Counters of the node, with a mark at each report for per-period deltas."""

    def __init__(self):
        self.rejected = dict.fromkeys(REJECT_REASONS, 0)
        self.clamped = dict.fromkeys(CLAMP_REASONS, 0)
        self.samples = 0
        self.saturated = [0, 0, 0]
        self.model_errors = 0
        self.last_model_error = ''
        self.nonfinite = 0
        self.last_nonfinite = ''
        self.dropped = 0
        self.clock_jumps = 0
        self._events = []
        self._mark = self._snapshot()

    def _snapshot(self):
        return (dict(self.rejected), dict(self.clamped), self.samples,
                list(self.saturated), self.model_errors, self.dropped, self.nonfinite)

    def drop(self, count):
        """Count samples the overrun policy dropped (due, never published)."""
        self.dropped += int(count)

    def reject(self, reason):
        """Count one rejected input."""
        self.rejected[reason] = self.rejected.get(reason, 0) + 1

    def clamp(self, reason):
        """Count one clamped input."""
        self.clamped[reason] = self.clamped.get(reason, 0) + 1

    def sample(self, saturated):
        """Count one published sample; ``saturated`` is per axis (x, y, z)."""
        self.samples += 1
        for axis in range(3):
            if saturated[axis]:
                self.saturated[axis] += 1

    def model_error(self, text):
        """Count one sample the model refused."""
        self.model_errors += 1
        self.last_model_error = text

    def non_finite(self, text):
        """Count one sample withheld because the model gave a NaN or an infinity."""
        self.nonfinite += 1
        self.last_nonfinite = text

    def clock_jump(self, text):
        """Count one jump of the clock (the samples' time line) and say it once."""
        self.clock_jumps += 1
        self.event(WARN, text)

    def event(self, level, text):
        """Say ``text`` once, in the next report, at ``level`` (OK, WARN or ERROR) at least."""
        self._events.append((level, text))

    def report(self, elapsed_s, rate_hz, situation, check_rate=True, waiting_for=None):
        """
        Close the period and return a :class:`Report`.

        Parameters
        ----------
        elapsed_s : float
            Length of the period, s (steady clock).
        rate_hz : float
            Target output rate, Hz.
        situation : dict
            Current state: ``stale`` (bool), ``rate_age_s`` (float or None),
            ``stale_policy`` (str), ``fault_level`` (0, WARN or ERROR) with
            ``fault`` (its description), and any further key/values to show.
        check_rate : bool
            Warn on a low achieved rate (False under use_sim_time).
        waiting_for : str or None
            Where the samples' time comes from when it is not the wall clock
            (``/clock``, ``imu/ideal``): warn while no sample has come yet.

        """
        rejected0, clamped0, samples0, saturated0, errors0, dropped0, nonfinite0 = self._mark
        self._mark = self._snapshot()
        events, self._events = self._events, []
        achieved = (self.samples - samples0) / elapsed_s if elapsed_s > 0 else 0.0
        level, notes = OK, []
        errors = self.model_errors - errors0
        if errors:
            level = ERROR
            notes.append(f'model refused {errors} sample(s): {self.last_model_error}')
        nonfinite = self.nonfinite - nonfinite0
        if nonfinite:
            level = ERROR
            notes.append(f'{nonfinite} non-finite sample(s) withheld: {self.last_nonfinite}')
        for event_level, text in events:
            level = max(level, event_level)
            notes.append(text)
        if situation.get('recording_error'):
            level = ERROR
            notes.append(f'recording stopped: {situation["recording_error"]}')
        fault_level = situation.get('fault_level', 0)
        if fault_level:
            level = max(level, ERROR if fault_level >= ERROR else WARN)
            notes.append(f'fault injected: {situation.get("fault", "")}')
        if situation.get('stale'):
            level = max(level, WARN)
            age = situation.get('rate_age_s')
            policy = situation.get('stale_policy', 'zero')
            held = 'rate held at zero' if policy == 'zero' else 'last rate held'
            notes.append(f'stale rate command ({age:.2f} s old): {held}')
        dropped = self.dropped - dropped0
        if dropped:
            level = max(level, WARN)
            notes.append(f'{dropped} sample(s) dropped by the overrun policy '
                         f'({situation.get("overrun_policy", "fifo")}): the timer fell behind')
        new_rejects = {r: n - rejected0.get(r, 0) for r, n in self.rejected.items()
                       if n - rejected0.get(r, 0)}
        if new_rejects:
            level = max(level, WARN)
            notes.append(f'{sum(new_rejects.values())} input(s) rejected ('
                         + ', '.join(f'{r} {n}' for r, n in new_rejects.items()) + ')')
        new_clamps = sum(n - clamped0.get(r, 0) for r, n in self.clamped.items())
        if new_clamps:
            level = max(level, WARN)
            notes.append(f'{new_clamps} temperature(s) outside the model range clamped')
        sat_axes = [a for a, n, n0 in zip(AXES, self.saturated, saturated0) if n > n0]
        if sat_axes:
            level = max(level, WARN)
            notes.append('saturated on ' + ', '.join(sat_axes))
        if waiting_for and not self.samples:
            level = max(level, WARN)
            notes.append(f'no sample yet: waiting for {waiting_for}')
        if check_rate and elapsed_s > 0 and achieved < RATE_WARN_FRACTION * rate_hz:
            level = max(level, WARN)
            notes.append(f'output rate {achieved:.1f} Hz below target {rate_hz:g} Hz')
        values = [('rate_hz', rate_hz), ('achieved_rate_hz', round(achieved, 2)),
                  ('samples', self.samples)]
        values += [(k, v) for k, v in situation.items()
                   if k not in ('stale_policy', 'fault_level')]
        values += [('saturated_samples.' + a, n) for a, n in zip(AXES, self.saturated)]
        values += [('rejected.' + r, n) for r, n in self.rejected.items()]
        values += [('clamped.' + r, n) for r, n in self.clamped.items()]
        values.append(('rejected_total', sum(self.rejected.values())))
        values.append(('model_errors', self.model_errors))
        values.append(('nonfinite_samples', self.nonfinite))
        values.append(('clock_jumps', self.clock_jumps))
        message = '; '.join(notes) if notes else 'OK'
        return Report(level, message, tuple(values))
