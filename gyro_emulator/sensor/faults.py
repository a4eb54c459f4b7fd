"""
Injected sensor faults: their types, a schedule, and their effect on the output.

A fault acts on the gyro output (the ``gyro_rad_s`` of the model's samples)
of one axis or all axes, from ``start_s`` for ``duration_s`` (0: until it is
cleared), on the time base of whoever applies it (the node: seconds since the
fault was set; ``simulate`` and a scenario: seconds since the record
started). The types, with the meaning of ``magnitude``:

=============  ======================  ==================================================
type           magnitude               output while active
=============  ======================  ==================================================
``none``       --                      unchanged
``stuck``      --                      the last value before the fault, repeated bit for bit
``bias_step``  rad/s                   + magnitude
``drift``      rad/s per s             + magnitude (t - start_s), a bias ramp
``spike``      rad/s                   + magnitude on the first sample only
``dropout``    --                      no sample is published
``saturate``   sign (>= 0: +, < 0: -)  pinned at +-range_rad_s (flagged saturated)
``noise_burst`` rad/s (sigma)          + magnitude N(0, 1), from an injected Generator
=============  ======================  ==================================================

:data:`SEVERITY` is the level a driver's self-test would report while the
fault is active: ERROR when the output is invalid (stuck, dropout, saturated),
WARN when it is degraded (bias_step, drift, spike, noise_burst).

:func:`apply_block` is the pure effect on a block of samples; :class:`Injector`
carries what a fault needs between blocks (the stuck value, the time of the
previous sample for the spike). A schedule (:func:`parse_schedule`) is a
list of non-overlapping faults, as a scenario or profile YAML gives it::

    faults:
      - {type: bias_step, axis: z, magnitude: 0.01, start_s: 2.0, duration_s: 1.0}
      - {type: dropout, start_s: 4.0, duration_s: 0.2}
"""

from dataclasses import dataclass
import math

from gyro_emulator.resources import read_yaml
from gyro_emulator.units import AXES
from gyro_emulator.validation import quote
import numpy as np

FAULT_TYPES = ('none', 'stuck', 'bias_step', 'drift', 'spike', 'dropout', 'saturate',
               'noise_burst')
#: ``axis`` values: one axis or all three.
FAULT_AXES = AXES + ('all',)
WARN, ERROR = 1, 2
#: Level a driver's self-test would report while the fault is active.
SEVERITY = {'stuck': ERROR, 'dropout': ERROR, 'saturate': ERROR, 'bias_step': WARN,
            'drift': WARN, 'spike': WARN, 'noise_burst': WARN}
#: Unit of ``magnitude`` per type ('' = not used).
MAGNITUDE_UNITS = {'none': '', 'stuck': '', 'bias_step': 'rad/s', 'drift': 'rad/s/s',
                   'spike': 'rad/s', 'dropout': '', 'saturate': 'sign',
                   'noise_burst': 'rad/s'}
#: Largest |magnitude| accepted, in the type's unit.
MAX_ABS_MAGNITUDE = 1000.0
#: Latest start and longest duration accepted, s (about 31 years).
MAX_TIME_S = 1e9


@dataclass(frozen=True)
class Fault:
    """
    One fault (see the module docstring for the types).

    Attributes
    ----------
    kind : str
        One of :data:`FAULT_TYPES` (``type`` in YAML and parameters).
    axis : str
        ``x``, ``y``, ``z`` or ``all``.
    magnitude : float
        Size, in the unit of :data:`MAGNITUDE_UNITS` for the type.
    start_s : float
        Start on the applier's time base, s (>= 0).
    duration_s : float
        Length, s; 0 = until cleared (or the end of the record).

    """

    kind: str = 'none'
    axis: str = 'all'
    magnitude: float = 0.0
    start_s: float = 0.0
    duration_s: float = 0.0

    def __post_init__(self):
        """Check type, axis and the numbers (one-line errors naming the field)."""
        for name, label, choices in (('kind', 'type', FAULT_TYPES),
                                     ('axis', 'axis', FAULT_AXES)):
            value = getattr(self, name)
            if value not in choices:
                raise ValueError(f'fault.{label} = {quote(value)} is not allowed: choose one of '
                                 f'{", ".join(choices)}')
        for name, low, high, unit in (
                ('magnitude', -MAX_ABS_MAGNITUDE, MAX_ABS_MAGNITUDE,
                 MAGNITUDE_UNITS[self.kind]),
                ('start_s', 0.0, MAX_TIME_S, 's'), ('duration_s', 0.0, MAX_TIME_S, 's')):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                    not math.isfinite(value) or not low <= value <= high:
                raise ValueError(f'fault.{name} = {quote(value)} is out of range: allowed '
                                 f'[{low:g}, {high:g}]{" " + unit if unit else ""}')
            object.__setattr__(self, name, float(value))
        if self.kind == 'noise_burst' and self.magnitude < 0.0:
            raise ValueError(f'fault.magnitude = {quote(self.magnitude)} is out of range for '
                             f'noise_burst: allowed [0, {MAX_ABS_MAGNITUDE:g}] rad/s (sigma)')

    @property
    def end_s(self):
        """End of the fault, s (inf: until cleared)."""
        return self.start_s + self.duration_s if self.duration_s > 0.0 else math.inf

    @property
    def axes(self):
        """Return the axis indices the fault acts on."""
        return [0, 1, 2] if self.axis == 'all' else [AXES.index(self.axis)]

    @property
    def severity(self):
        """Self-test level while active: :data:`WARN` or :data:`ERROR` (0 for none)."""
        return SEVERITY.get(self.kind, 0)

    def active(self, t_s):
        """Return where the fault acts at times ``t_s`` (s): start_s <= t < end_s."""
        t = np.asarray(t_s, dtype=float)
        if self.kind == 'none':
            return np.zeros(t.shape, dtype=bool)
        return (t >= self.start_s) & (t < self.end_s)

    def describe(self):
        """Return one line for logs and diagnostics, e.g. ``bias_step 0.01 rad/s on z``."""
        if self.kind == 'none':
            return 'none'
        unit = MAGNITUDE_UNITS[self.kind]
        size = f' {self.magnitude:g} {unit}' if unit and unit != 'sign' else ''
        if self.kind == 'saturate':
            size = ' at -range' if self.magnitude < 0.0 else ' at +range'
        until = f' for {self.duration_s:g} s' if self.duration_s > 0.0 else ''
        return f'{self.kind}{size} on {self.axis}, from {self.start_s:g} s{until}'


@dataclass(frozen=True)
class FaultEffect:
    """What a fault did to a block: output (N, 3), published (N,), saturated (N, 3), active."""

    gyro_rad_s: np.ndarray
    published: np.ndarray
    saturated: np.ndarray
    active: np.ndarray


def apply_block(fault, t_s, gyro_rad_s, range_rad_s, rng=None, held_rad_s=None,
                previous_t_s=None):
    """
    Apply a fault to a block of output samples (pure: the inputs are not changed).

    Parameters
    ----------
    fault : Fault
        The fault.
    t_s : array_like, shape (N,)
        Sample times on the fault's time base, s, increasing.
    gyro_rad_s : array_like, shape (N, 3)
        The sensor output, rad/s.
    range_rad_s : array_like, shape (3,)
        Full-scale range per axis, rad/s (``saturate`` pins the output there).
    rng : numpy.random.Generator, optional
        Source of ``noise_burst`` normals (required for that type).
    held_rad_s : array_like, shape (3,), optional
        For ``stuck`` active from the first sample of the block: the value it
        repeats (the output before the fault); None: the first sample's own.
        A fault that starts inside the block repeats the sample before it.
    previous_t_s : float, optional
        Time of the sample before this block; a ``spike`` falls on the first
        sample at or after ``start_s`` only if that sample is in this block.

    Returns
    -------
    FaultEffect

    """
    t = np.asarray(t_s, dtype=float)
    out = np.array(gyro_rad_s, dtype=float, copy=True).reshape(len(t), 3)
    published = np.ones(len(t), dtype=bool)
    saturated = np.zeros((len(t), 3), dtype=bool)
    active = fault.active(t)
    if not active.any():
        return FaultEffect(out, published, saturated, active)
    axes = fault.axes
    rows = np.flatnonzero(active)
    kind = fault.kind
    if kind == 'stuck':
        first = rows[0]
        if first > 0:
            held = out[first - 1].copy()
        elif held_rad_s is not None:
            held = np.asarray(held_rad_s, dtype=float)
        else:
            held = out[first].copy()
        out[np.ix_(rows, axes)] = held[axes]
    elif kind == 'bias_step':
        out[np.ix_(rows, axes)] += fault.magnitude
    elif kind == 'drift':
        out[np.ix_(rows, axes)] += (fault.magnitude * (t[rows] - fault.start_s))[:, None]
    elif kind == 'spike':
        first = rows[0]
        crossed = previous_t_s is None or previous_t_s < fault.start_s
        if crossed and (first == 0 or t[first - 1] < fault.start_s):
            out[first, axes] += fault.magnitude
    elif kind == 'dropout':
        published[rows] = False
    elif kind == 'saturate':
        sign = -1.0 if fault.magnitude < 0.0 else 1.0
        out[np.ix_(rows, axes)] = sign * np.asarray(range_rad_s, dtype=float)[axes]
        saturated[np.ix_(rows, axes)] = True
    elif kind == 'noise_burst':
        if rng is None:
            raise ValueError('apply_block: a noise_burst fault needs a numpy Generator')
        noise = rng.standard_normal((len(rows), len(axes)))
        out[np.ix_(rows, axes)] += fault.magnitude * noise
    return FaultEffect(out, published, saturated, active)


class Injector:
    """
    Apply one fault, or a schedule of them, block by block (stateful wrapper).

    Block boundaries do not change the result: the stuck value and the time
    of the previous sample carry over, and ``noise_burst`` normals are drawn
    in sample order from ``rng``.

    Parameters
    ----------
    schedule : sequence of Fault
        Non-overlapping faults (:func:`parse_schedule`), or one fault.
    range_rad_s : array_like, shape (3,)
        Full-scale range per axis, rad/s.
    rng : numpy.random.Generator, optional
        Source of ``noise_burst`` normals.
    last_rad_s : array_like, shape (3,), optional
        The output just before the first block (what ``stuck`` repeats if it
        acts from the first sample on).

    """

    def __init__(self, schedule, range_rad_s, rng=None, last_rad_s=None):
        self.schedule = tuple(schedule)
        self.range_rad_s = np.asarray(range_rad_s, dtype=float)
        self.rng = rng
        self._last = None if last_rad_s is None else np.asarray(last_rad_s, dtype=float)
        self._last_t = None
        self._held = {}

    def apply(self, t_s, gyro_rad_s):
        """Return the :class:`FaultEffect` of the schedule on the next block of samples."""
        t = np.asarray(t_s, dtype=float)
        out = np.array(gyro_rad_s, dtype=float, copy=True).reshape(len(t), 3)
        published = np.ones(len(t), dtype=bool)
        saturated = np.zeros((len(t), 3), dtype=bool)
        active = np.zeros(len(t), dtype=bool)
        for index, fault in enumerate(self.schedule):
            if fault.kind == 'none' or not fault.active(t).any():
                continue
            held = self._held.get(index, self._last)
            effect = apply_block(fault, t, out, self.range_rad_s, self.rng, held, self._last_t)
            out, active = effect.gyro_rad_s, active | effect.active
            published &= effect.published
            saturated |= effect.saturated
            if fault.kind == 'stuck':
                first = np.flatnonzero(effect.active)[0]
                self._held[index] = effect.gyro_rad_s[first]
        if len(t):
            self._last = out[-1]
            self._last_t = float(t[-1])
        return FaultEffect(out, published, saturated, active)


def parse_schedule(where, raw):
    """
    Return the faults of a YAML list as a tuple of :class:`Fault`, sorted by start.

    Parameters
    ----------
    where : str
        Name of the list in messages (e.g. ``profile.yaml: faults``).
    raw : list of dict
        Entries with ``type`` and optionally ``axis``, ``magnitude``,
        ``start_s`` and ``duration_s``.

    Raises ValueError naming the entry, the field, the value and the allowed
    range, for unknown keys, and for faults that overlap in time.

    """
    if raw is None:
        return ()
    if not isinstance(raw, list):
        raise ValueError(f'{where} = {quote(raw)} must be a list of faults')
    allowed = ('type', 'axis', 'magnitude', 'start_s', 'duration_s')
    faults = []
    for i, entry in enumerate(raw):
        if not isinstance(entry, dict):
            raise ValueError(f'{where}[{i}] = {quote(entry)} must be a mapping with '
                             f'{", ".join(allowed)}')
        unknown = sorted(set(entry) - set(allowed))
        if unknown:
            raise ValueError(f'{where}[{i}]: unknown key(s) {", ".join(map(str, unknown))}; '
                             f'allowed: {", ".join(allowed)}')
        if 'type' not in entry:
            raise ValueError(f'{where}[{i}].type is missing: choose one of '
                             f'{", ".join(FAULT_TYPES)}')
        fields = dict(entry)
        fields['kind'] = fields.pop('type')
        try:
            faults.append(Fault(**fields))
        except ValueError as exc:
            raise ValueError(f'{where}[{i}]: {exc}') from None
    order = sorted(range(len(faults)), key=lambda k: faults[k].start_s)
    for a, b in zip(order, order[1:]):
        if faults[b].start_s < faults[a].end_s:
            raise ValueError(f'{where}[{b}] starts at {faults[b].start_s:g} s, before '
                             f'{where}[{a}] ends ({faults[a].end_s:g} s): faults may not '
                             'overlap')
    return tuple(faults[k] for k in order)


def load_schedule(path):
    """Return the ``faults:`` list of a YAML file (a scenario, a profile or faults only)."""
    doc = read_yaml(path)
    if not isinstance(doc, dict) or 'faults' not in doc:
        raise ValueError(f'{path}: expected a mapping with a faults: list')
    return parse_schedule(f'{path}: faults', doc['faults'])


def fault_generator(seed_sequence):
    """
    Return the ``noise_burst`` Generator of a run: a SeedSequence child after the model's.

    ``GyroModel`` spawns its streams from the seed's SeedSequence first
    (:mod:`gyro_emulator.sensor.streams`); the fault stream is the next child,
    so a node and ``simulate`` with the same seed draw the same burst.
    """
    return np.random.Generator(np.random.SFC64(seed_sequence.spawn(1)[0]))
