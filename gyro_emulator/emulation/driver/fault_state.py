"""
The node's injected fault: the ``fault.*`` parameters on the node clock (no ROS imports).

Setting any ``fault.*`` parameter (``ros2 param set``, or a scenario's fault
schedule through the parameter service) builds a
:class:`gyro_emulator.sensor.faults.Fault` and starts its clock: ``start_s``
counts from that moment on the node clock (sim time under
``use_sim_time``), so ``fault.kind:=stuck`` alone freezes the output at once.
:class:`FaultState` applies it to each sample
(:class:`gyro_emulator.sensor.faults.Injector`) and follows its state:

``none`` (type none) -> ``pending`` (before start_s) -> ``active`` -> ``ended``
(after duration_s).

Each change of state is reported once (``changed``), for ``~/truth/fault``;
:meth:`situation` gives the diagnostics fields.
"""

from gyro_emulator.sensor import faults
from gyro_emulator.units import NS_PER_S
import numpy as np


class FaultState:
    """
    The fault in force and its state.

    Parameters
    ----------
    range_rad_s : array_like, shape (3,)
        Full-scale range per axis, rad/s (where ``saturate`` pins the output).
    rng : numpy.random.Generator
        Source of the ``noise_burst`` normals.

    """

    def __init__(self, range_rad_s, rng):
        self.range_rad_s = np.asarray(range_rad_s, dtype=float)
        self.rng = rng
        self.fault = faults.Fault()
        self.epoch_ns = 0
        self.state = 'none'
        self.since_ns = 0
        self.changed = True
        self._injector = None

    def end(self, now_ns):
        """End a pending or active fault at ``now_ns`` (it is being replaced)."""
        if self.state in ('pending', 'active'):
            self._move('ended', now_ns)

    def start(self, fault, now_ns, last_rad_s):
        """Put ``fault`` in force from ``now_ns`` (ns); ``last_rad_s`` is the last output."""
        self.fault = fault
        self.epoch_ns = int(now_ns)
        self._injector = None if fault.kind == 'none' else faults.Injector(
            [fault], self.range_rad_s, self.rng, last_rad_s)
        self._move('none' if fault.kind == 'none' else 'pending', now_ns)

    def shift(self, delta_ns):
        """Move the fault's clock with a jump of the time line (a simulation reset)."""
        self.epoch_ns += int(delta_ns)

    def _move(self, state, now_ns):
        if state != self.state:
            self.state = state
            self.since_ns = int(now_ns)
            self.changed = True

    @property
    def level(self):
        """Return the diagnostics level of the fault: 0 unless active, else its severity."""
        return self.fault.severity if self.state == 'active' else 0

    def apply(self, sample_ns, rate_rad_s):
        """
        Apply the fault to one sample's output.

        Parameters
        ----------
        sample_ns : int
            The sample instant on the node clock, ns.
        rate_rad_s : numpy.ndarray, shape (3,)
            The model's output, rad/s.

        Returns
        -------
        tuple of (tuple of float, bool, numpy.ndarray or None)
            The rate to publish, whether to publish (False in a dropout) and
            the axes a ``saturate`` pinned (None when no fault acts).

        """
        injector = self._injector
        if injector is None:
            return tuple(rate_rad_s.tolist()), True, None
        t_s = (int(sample_ns) - self.epoch_ns) / NS_PER_S
        effect = injector.apply(np.array([t_s]), rate_rad_s.reshape(1, 3))
        if effect.active[0]:
            self._move('active', sample_ns)
        elif t_s >= self.fault.end_s:
            self._move('ended', sample_ns)
        return (tuple(effect.gyro_rad_s[0].tolist()), bool(effect.published[0]),
                effect.saturated[0] if effect.active[0] else None)

    def situation(self):
        """Return the diagnostics key/values of the fault."""
        return {'fault.type': self.fault.kind, 'fault.state': self.state,
                'fault': self.fault.describe(), 'fault_level': self.level}
