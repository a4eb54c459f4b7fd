"""
The one segment schema: a profile segment and its YAML form.

A :class:`Segment` is a stretch of a scripted profile
(:class:`~gyro_emulator.emulation.profiles.ScriptedProfile`): the body
rate and the ambient temperature move linearly from a start to an end value
and the specific force is constant (or left to the motion, with a constant
applied linear acceleration). :func:`parse_segment` reads its YAML mapping
(the keys of :mod:`gyro_emulator.emulation.profiles`); ``simulate``
profiles and the scenario files (:mod:`gyro_emulator.emulation.scenario`)
share it.
"""

from dataclasses import dataclass
from types import MappingProxyType
import warnings

from gyro_emulator.sensor.imu import MAX_APPLIED_ACCEL_M_S2, MAX_SPECIFIC_FORCE_M_S2
from gyro_emulator.units import deg_s_to_rad_s, rpm_to_rad_s, STANDARD_GRAVITY_M_S2
from gyro_emulator.validation import MODEL_TEMP_RANGE_C, quote, RECORD_LIMITS
import numpy as np

#: Specific force of a gyro at rest, z up (REP 103), m/s^2.
LEVEL_ACCEL_M_S2 = (0.0, 0.0, STANDARD_GRAVITY_M_S2)


#: Largest |component| of each vector of a segment, its unit and why: a rate the
#: record rule takes (``validation.RECORD_LIMITS``, so that a simulated bag reads back),
#: a specific force the model takes, an applied acceleration whose specific force it takes.
_VECTOR_LIMITS = MappingProxyType({
    'rate_start_rad_s': (RECORD_LIMITS['rate'][1], 'rad/s', RECORD_LIMITS['rate'][3]),
    'rate_end_rad_s': (RECORD_LIMITS['rate'][1], 'rad/s', RECORD_LIMITS['rate'][3]),
    'accel_m_s2': (MAX_SPECIFIC_FORCE_M_S2, 'm/s^2', 'the model range'),
    'linear_accel_m_s2': (MAX_APPLIED_ACCEL_M_S2, 'm/s^2',
                          'its specific force within the model range at any gravity')})


@dataclass(frozen=True)
class Segment:
    """
    One profile segment: linear rate and temperature, constant specific force.

    Attributes
    ----------
    duration_s : float
        Length, s (> 0).
    rate_start_rad_s, rate_end_rad_s : tuple
        Body rate (x, y, z) at the start and the end, rad/s.
    temp_start_c, temp_end_c : float
        Ambient temperature at the start and the end, deg C.
    accel_m_s2 : tuple or None
        Specific force (x, y, z), m/s^2; None: left to the motion (module
        docstring).
    settle_s : float
        Start of the segment a summary leaves out (transients), s.
    label : str
        The rate as the profile wrote it (a scenario step's ``10 RPM``), or ''.
    linear_accel_m_s2 : tuple
        Applied linear acceleration in the body frame (x, y, z), m/s^2, when
        the specific force is left to the motion.

    """

    duration_s: float
    rate_start_rad_s: tuple
    rate_end_rad_s: tuple
    temp_start_c: float
    temp_end_c: float
    accel_m_s2: tuple = None
    settle_s: float = 0.0
    label: str = ''
    linear_accel_m_s2: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        """Validate the duration, temperatures and vectors."""
        if not (np.isfinite(self.duration_s) and self.duration_s > 0.0):
            raise ValueError(f'Segment.duration_s = {quote(self.duration_s)} is out of range: '
                             'allowed > 0 s')
        lo, hi = MODEL_TEMP_RANGE_C
        for name in ('temp_start_c', 'temp_end_c'):
            value = getattr(self, name)
            if not (np.isfinite(value) and lo <= value <= hi):
                raise ValueError(f'Segment.{name} = {quote(value)} is out of range: allowed '
                                 f'[{lo}, {hi}] C')
        for name, (top, unit, why) in _VECTOR_LIMITS.items():
            if name == 'accel_m_s2' and self.accel_m_s2 is None:
                continue
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.shape != (3,) or not np.all(np.isfinite(arr)):
                raise ValueError(f'Segment.{name} = {quote(getattr(self, name))} is not '
                                 'allowed: expected 3 finite numbers (x, y, z)')
            if not np.all(np.abs(arr) <= top):
                raise ValueError(f'Segment.{name} = {quote(getattr(self, name))} is out of '
                                 f'range: allowed 3 numbers in [{-top:g}, {top:g}] {unit} ({why})')
            object.__setattr__(self, name, tuple(float(v) for v in arr))
        if not (np.isfinite(self.settle_s) and 0.0 <= self.settle_s <= self.duration_s):
            raise ValueError(f'Segment.settle_s = {quote(self.settle_s)} is out of range: allowed '
                             f'[0, {self.duration_s:g}] s (the duration)')


_SEGMENT_KEYS = ('duration_s', 'rate_rad_s', 'rate_deg_s', 'rate_rpm', 'temp_c',
                 'accel_m_s2', 'linear_accel_m_s2', 'settle_s')
#: Rate keys of a segment and their conversion to rad/s.
RATE_UNITS = MappingProxyType({'rate_rad_s': lambda v: v, 'rate_deg_s': deg_s_to_rad_s,
                               'rate_rpm': rpm_to_rad_s})
#: Old spellings still read, with a one-line deprecation warning.
_ALIASES = {'temperature_c': 'temp_c'}
#: Rate direction of scalar rates when a profile gives no ``axis``: z (REP 103).
DEFAULT_AXIS = (0.0, 0.0, 1.0)


def _start_end(where, key, value, shape):
    arr = np.asarray(value, dtype=float) if not isinstance(value, (str, bool)) else None
    if arr is not None and arr.shape == shape:
        return arr, arr
    if arr is not None and arr.shape == (2,) + shape:
        return arr[0], arr[1]
    want = 'a number' if shape == () else '3 numbers'
    raise ValueError(f'{where}: {key} = {quote(value)} is not allowed: give {want} or '
                     f'[start, end] of {want}')


def _floats(values):
    """Return ``values`` as a tuple of Python floats (an error shows them as numbers)."""
    return tuple(float(v) for v in values)


def _rate_start_end(where, key, value, axis):
    """Rates of a segment: a number along ``axis``, a 3-vector, or [start, end] 3-vectors."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if not np.isfinite(value):      # inf x 0 would be NaN on the other axes
            raise ValueError(f'{where}: {key} = {quote(value)} is not allowed: give a finite '
                             'number')
        along = np.asarray(axis) * float(value)
        return along, along
    return _start_end(where, key, value, (3,))


def canonical_segment(where, seg):
    """Return the segment mapping with old spellings renamed (warned once each)."""
    out = dict(seg)
    for old, new in _ALIASES.items():
        if old in out:
            if new in out:
                raise ValueError(f'{where}: give {new} only ({old} is its old spelling)')
            warnings.warn(f'{where}: {old} is deprecated, write {new}', DeprecationWarning,
                          stacklevel=3)
            out[new] = out.pop(old)
    return out


def parse_segment(where, seg, axis=DEFAULT_AXIS, last_temp_c=25.0,
                  default_accel_m_s2=LEVEL_ACCEL_M_S2, default_linear_m_s2=(0.0, 0.0, 0.0)):
    """
    Build one :class:`Segment` from its mapping (the keys of the module docstring).

    A rate given as a number (or [start, end] of numbers) is along ``axis``;
    a missing ``temp_c`` holds ``last_temp_c``; a missing ``accel_m_s2``
    is ``default_accel_m_s2`` (None: the specific force is left to the
    motion, with ``linear_accel_m_s2`` or ``default_linear_m_s2``). Unknown
    keys and bad values raise ``ValueError`` naming ``where`` and the key.
    """
    if not isinstance(seg, dict):
        raise ValueError(f'{where} must be a mapping, got {quote(seg)}')
    seg = canonical_segment(where, seg)
    unknown = sorted(set(seg) - set(_SEGMENT_KEYS))
    if unknown:
        raise ValueError(f'{where}: unknown key(s) {", ".join(map(str, unknown))}; '
                         f'allowed: {", ".join(_SEGMENT_KEYS)}')
    if 'duration_s' not in seg:
        raise ValueError(f'{where}: duration_s is required')
    rate_keys = [k for k in RATE_UNITS if k in seg]
    if len(rate_keys) > 1:
        raise ValueError(f'{where}: give only one of {", ".join(rate_keys)}')
    r0 = r1 = np.zeros(3)
    if rate_keys:
        key = rate_keys[0]
        r0, r1 = _rate_start_end(where, key, seg[key], axis)
        r0, r1 = RATE_UNITS[key](r0), RATE_UNITS[key](r1)
    t0, t1 = _start_end(where, 'temp_c', seg.get('temp_c', last_temp_c), ())
    acc = seg.get('accel_m_s2', default_accel_m_s2)
    if acc is not None and 'linear_accel_m_s2' in seg:
        raise ValueError(f'{where}: linear_accel_m_s2 is for a specific force left to the '
                         'motion: give it or accel_m_s2 (the specific force itself), not both')
    if acc is not None:
        acc = _floats(_start_end(where, 'accel_m_s2', acc, (3,))[0])
    linear, _ = _start_end(where, 'linear_accel_m_s2',
                           seg.get('linear_accel_m_s2', default_linear_m_s2), (3,))
    try:
        return Segment(float(seg['duration_s']), _floats(r0), _floats(r1), float(t0),
                       float(t1), acc, float(seg.get('settle_s', 0.0)),
                       linear_accel_m_s2=_floats(linear))
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{where}: {exc}') from None


def unit_axis(source, axis):
    """Return ``axis`` (3 numbers, not all zero) scaled to unit length."""
    arr = np.asarray(axis, dtype=float) if isinstance(axis, (list, tuple)) else None
    if arr is None or arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f'{source}.axis = {quote(axis)} must be a list of 3 numbers')
    norm = float(np.linalg.norm(arr))
    if norm == 0.0:
        raise ValueError(f'{source}.axis = {quote(axis)} is the zero vector')
    return tuple(float(v) / norm for v in arr)
