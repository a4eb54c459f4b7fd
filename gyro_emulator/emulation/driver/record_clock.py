"""
The record time of the extended terms on a node's clock (no ROS imports).

The extended terms (:mod:`gyro_emulator.sensor.extensions`) read a record
time t = ``extended.start_time_s`` + the time since the model's first
sample. A node places that first sample on its clock: by default it is
record time ``start_time_s`` (power-on at the first sample); with an
origin (``record_start_clock_s`` >= 0, the node-clock time, s, of record
time ``start_time_s``) a sample at clock time c has record time
``start_time_s + c - origin``, whenever the node starts. After a jump of the
clock the next sample's record time follows the clock again; a jump back
to before the origin makes that instant the origin. A record time the
model cannot hold (more than ``sensor.extensions.TIME_LIMIT_S`` from the
origin: a ``/clock`` that jumps from 10 s to epoch seconds, 1.7e9 s, as a
bag replay after a simulator does) re-anchors it: the configured origin
(``record_start_clock_s``) when the new clock time is within reach of it,
else that instant. Re-anchorings are counted.
"""

from gyro_emulator.units import NS_PER_S


class RecordClock:
    """
    Keep a model's record time on a clock (see the module docstring).

    Parameters
    ----------
    origin_s : float
        Clock time of record time ``start_time_s``, s; negative: the first
        sample's.
    report : callable
        Called with one line when the origin cannot be used (a first sample
        more than the model's time limit away from it: the first sample is
        then the origin).

    Attributes
    ----------
    zero_ns : int or None
        Clock time of record time ``start_time_s``, ns (None before the first sample).
    reanchors : int
        Jumps after which the record time could not follow the clock.

    """

    def __init__(self, origin_s, report):
        self.zero_ns = None
        self.reanchors = 0
        self._origin_ns = None if origin_s < 0.0 else int(round(origin_s * NS_PER_S))
        self._report = report

    def first(self, model, sample_ns):
        """Place the model's first sample, at clock ``sample_ns``, before it is run."""
        if self.zero_ns is not None:
            return
        self.zero_ns = int(sample_ns)
        if self._origin_ns is None:
            return
        try:
            model.set_elapsed_s((sample_ns - self._origin_ns) / NS_PER_S)
        except ValueError as exc:
            self._report(f'record_start_clock_s = {self._origin_ns / NS_PER_S:g} s is '
                         f'not used: the first sample is at {sample_ns / NS_PER_S:g} s on '
                         f'the node clock ({exc}); record time start_time_s is that sample')
            return
        self.zero_ns = self._origin_ns

    def jumped(self, model, next_ns):
        """
        After a clock jump, put the next sample (at clock ``next_ns``) back on the clock.

        Returns
        -------
        str or None
            One line when the record time was re-anchored (it could not follow
            the clock), else None.

        """
        if self.zero_ns is None or next_ns is None:
            return None
        next_ns = int(next_ns)
        zero_ns = min(self.zero_ns, next_ns)
        if _held(model, next_ns - zero_ns):
            self.zero_ns = zero_ns
            return None
        origin = self._origin_ns
        if origin is not None and next_ns >= origin and _held(model, next_ns - origin):
            self.zero_ns, where = origin, 'record_start_clock_s'
        else:
            _held(model, 0)
            self.zero_ns, where = next_ns, 'this sample'
        self.reanchors += 1
        return (f'record time re-anchored at {where} (the clock at '
                f'{next_ns / NS_PER_S:.9g} s is out of reach of the previous origin)')


def _held(model, elapsed_ns):
    """Put the model's next sample ``elapsed_ns`` after its origin; False if out of its range."""
    try:
        model.set_elapsed_s(elapsed_ns / NS_PER_S)
    except ValueError:
        return False
    return True
