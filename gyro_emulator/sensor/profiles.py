"""
Scripted rate and temperature profiles for offline simulation.

A :class:`Profile` is a sequence of segments; within a segment the body rate
and the ambient temperature move linearly from a start to an end value (equal
values hold them constant) and the specific force is constant. Built-in
profiles (:data:`PROFILE_NAMES`) stretch to the requested duration; a YAML
profile keeps its own segment durations and holds its last values if the
simulation runs longer.

Built-in profiles:

* ``static``: zero rate, constant ambient temperature.
* ``steps``: a rate table about z at 0, 10, 20 and 40 RPM and back to 0, equal
  dwells (the rates of the paper's validation).
* ``temp-ramp``: a constant 60 deg/s about z while the ambient temperature
  ramps linearly from 25 to 85 C (the conditions of the paper's Fig 6).

YAML profile (the one segment schema: ``simulate`` profiles and the ROS
``scenario`` share it, :func:`parse_segment`)::

    name: my-profile                     # optional
    axis: [0, 0, 1]                      # optional: direction of scalar rates
    accel_m_s2: [0.0, 0.0, 9.80665]      # optional default specific force
    segments:
      - duration_s: 10
        rate_deg_s: [0, 0, 0]            # or rate_rad_s / rate_rpm
        temp_c: 25
      - duration_s: 60
        rate_deg_s: [[0, 0, 0], [0, 0, 90]]   # [start, end]: a ramp
        temp_c: [25, 40]                      # [start, end]: a ramp
      - duration_s: 5
        rate_rpm: 40                     # a number: constant, along ``axis``
        settle_s: 1                      # left out of a summary (scenario)

``temperature_c`` is the old spelling of ``temp_c``: still read, with a
deprecation warning.
"""

from dataclasses import dataclass
import os
from types import MappingProxyType
import warnings

from gyro_emulator.resources import read_yaml
from gyro_emulator.units import (deg_s_to_rad_s, rpm_to_rad_s,
                                 STANDARD_GRAVITY_M_S2)
from gyro_emulator.validation import MODEL_TEMP_RANGE_C
import numpy as np

PROFILE_NAMES = ('static', 'steps', 'temp-ramp')

#: Specific force of a gyro at rest, z up (REP 103), m/s^2.
LEVEL_ACCEL_M_S2 = (0.0, 0.0, STANDARD_GRAVITY_M_S2)

#: Rate-table levels of the ``steps`` profile, RPM about z (paper validation).
STEP_LEVELS_RPM = (0.0, 10.0, 20.0, 40.0, 0.0)


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
    accel_m_s2 : tuple
        Specific force (x, y, z), m/s^2.
    settle_s : float
        Start of the segment a summary leaves out (transients), s.

    """

    duration_s: float
    rate_start_rad_s: tuple
    rate_end_rad_s: tuple
    temp_start_c: float
    temp_end_c: float
    accel_m_s2: tuple = LEVEL_ACCEL_M_S2
    settle_s: float = 0.0

    def __post_init__(self):
        """Validate the duration, temperatures and vectors."""
        if not (np.isfinite(self.duration_s) and self.duration_s > 0.0):
            raise ValueError(f'Segment.duration_s = {self.duration_s!r} is out of range: '
                             'allowed > 0 s')
        lo, hi = MODEL_TEMP_RANGE_C
        for name in ('temp_start_c', 'temp_end_c'):
            value = getattr(self, name)
            if not (np.isfinite(value) and lo <= value <= hi):
                raise ValueError(f'Segment.{name} = {value!r} is out of range: allowed '
                                 f'[{lo}, {hi}] C')
        for name in ('rate_start_rad_s', 'rate_end_rad_s', 'accel_m_s2'):
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.shape != (3,) or not np.all(np.isfinite(arr)):
                raise ValueError(f'Segment.{name} = {getattr(self, name)!r} is not '
                                 'allowed: expected 3 finite numbers (x, y, z)')
            object.__setattr__(self, name, tuple(float(v) for v in arr))
        if not (np.isfinite(self.settle_s) and 0.0 <= self.settle_s <= self.duration_s):
            raise ValueError(f'Segment.settle_s = {self.settle_s!r} is out of range: allowed '
                             f'[0, {self.duration_s:g}] s (the duration)')


@dataclass(frozen=True)
class ProfileSamples:
    """Profile values at the sample times: (N, 3) rates and forces, (N,) temperatures."""

    rate_rad_s: np.ndarray
    temp_c: np.ndarray
    accel_m_s2: np.ndarray


@dataclass(frozen=True)
class Profile:
    """A named sequence of :class:`Segment`; see the module docstring."""

    name: str
    segments: tuple

    def __post_init__(self):
        """Require at least one segment."""
        if not self.segments:
            raise ValueError(f'Profile {self.name!r} has no segments')
        object.__setattr__(self, 'segments', tuple(self.segments))

    @property
    def duration_s(self):
        """Total duration, s."""
        return float(sum(s.duration_s for s in self.segments))

    def sample(self, time_s):
        """
        Evaluate the profile at ``time_s`` (s, any order; after the end: hold).

        Returns
        -------
        ProfileSamples

        """
        t = np.asarray(time_s, dtype=float)
        starts = np.concatenate(([0.0], np.cumsum([s.duration_s for s in self.segments])))
        idx = np.clip(np.searchsorted(starts, t, side='right') - 1, 0,
                      len(self.segments) - 1)
        r0 = np.array([s.rate_start_rad_s for s in self.segments])
        r1 = np.array([s.rate_end_rad_s for s in self.segments])
        t0 = np.array([s.temp_start_c for s in self.segments])
        t1 = np.array([s.temp_end_c for s in self.segments])
        acc = np.array([s.accel_m_s2 for s in self.segments])
        dur = np.array([s.duration_s for s in self.segments])
        frac = np.clip((t - starts[idx]) / dur[idx], 0.0, 1.0)
        rate = r0[idx] + (r1[idx] - r0[idx]) * frac[:, np.newaxis]
        temp = t0[idx] + (t1[idx] - t0[idx]) * frac
        return ProfileSamples(rate_rad_s=rate, temp_c=temp, accel_m_s2=acc[idx])


def static(duration_s, temp_c=25.0):
    """Zero rate at a constant ambient temperature."""
    zero = (0.0, 0.0, 0.0)
    return Profile('static', (Segment(duration_s, zero, zero, temp_c, temp_c),))


def rate_table_steps(duration_s, temp_c=25.0, levels_rpm=STEP_LEVELS_RPM):
    """Rate-table steps about z at ``levels_rpm`` (equal dwells), constant temperature."""
    dwell = float(duration_s) / len(levels_rpm)
    segments = []
    for level in levels_rpm:
        rate = (0.0, 0.0, float(rpm_to_rad_s(level)))
        segments.append(Segment(dwell, rate, rate, temp_c, temp_c))
    return Profile('steps', tuple(segments))


def temperature_ramp(duration_s, start_c=25.0, end_c=85.0, rate_deg_s=60.0):
    """Hold a constant rate about z while the ambient temperature ramps (paper Fig 6)."""
    rate = (0.0, 0.0, float(deg_s_to_rad_s(rate_deg_s)))
    return Profile('temp-ramp', (Segment(duration_s, rate, rate, start_c, end_c),))


_SEGMENT_KEYS = ('duration_s', 'rate_rad_s', 'rate_deg_s', 'rate_rpm', 'temp_c',
                 'accel_m_s2', 'settle_s')
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
    raise ValueError(f'{where}: {key} = {value!r} is not allowed: give {want} or '
                     f'[start, end] of {want}')


def _rate_start_end(where, key, value, axis):
    """Rates of a segment: a number along ``axis``, a 3-vector, or [start, end] 3-vectors."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
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
                  default_accel_m_s2=LEVEL_ACCEL_M_S2):
    """
    Build one :class:`Segment` from its mapping (the keys of the module docstring).

    A rate given as a number (or [start, end] of numbers) is along ``axis``;
    a missing ``temp_c`` holds ``last_temp_c``. Unknown keys and bad values
    raise ``ValueError`` naming ``where`` and the key.
    """
    if not isinstance(seg, dict):
        raise ValueError(f'{where} must be a mapping, got {seg!r}')
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
    acc, _ = _start_end(where, 'accel_m_s2', seg.get('accel_m_s2', default_accel_m_s2), (3,))
    try:
        return Segment(float(seg['duration_s']), tuple(r0), tuple(r1), float(t0), float(t1),
                       tuple(acc), float(seg.get('settle_s', 0.0)))
    except (TypeError, ValueError) as exc:
        raise ValueError(f'{where}: {exc}') from None


def profile_from_mapping(mapping, source='profile'):
    """
    Build a :class:`Profile` from a parsed YAML mapping (module docstring).

    Unknown keys and bad values raise ``ValueError`` naming the segment and key.
    """
    if not isinstance(mapping, dict):
        raise ValueError(f'{source}: expected a mapping with "segments", got {mapping!r}')
    unknown = sorted(set(mapping) - {'name', 'segments', 'accel_m_s2', 'axis'})
    if unknown:
        raise ValueError(f'{source}: unknown key(s) {", ".join(map(str, unknown))}; '
                         'allowed: name, segments, accel_m_s2, axis')
    default_acc = mapping.get('accel_m_s2', LEVEL_ACCEL_M_S2)
    axis = unit_axis(source, mapping.get('axis', DEFAULT_AXIS))
    raw = mapping.get('segments')
    if not isinstance(raw, list) or not raw:
        raise ValueError(f'{source}: segments must be a non-empty list')
    segments = []
    last_temp = 25.0
    for i, seg in enumerate(raw):
        segment = parse_segment(f'{source}: segment {i + 1}', seg, axis, last_temp,
                                default_acc)
        last_temp = segment.temp_end_c
        segments.append(segment)
    return Profile(str(mapping.get('name', source)), tuple(segments))


def unit_axis(source, axis):
    """Return ``axis`` (3 numbers, not all zero) scaled to unit length."""
    arr = np.asarray(axis, dtype=float) if isinstance(axis, (list, tuple)) else None
    if arr is None or arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f'{source}.axis = {axis!r} must be a list of 3 numbers')
    norm = float(np.linalg.norm(arr))
    if norm == 0.0:
        raise ValueError(f'{source}.axis = {axis!r} is the zero vector')
    return tuple(float(v) / norm for v in arr)


def load_profile(path):
    """Load a YAML profile file (see the module docstring)."""
    return profile_from_mapping(read_yaml(path), source=str(path))


def make_profile(name_or_path, duration_s, temp_c=25.0):
    """
    Return a built-in profile stretched to ``duration_s``, or a YAML profile.

    Parameters
    ----------
    name_or_path : str
        One of :data:`PROFILE_NAMES` or a YAML file.
    duration_s : float
        Simulation length, s (built-in profiles span it).
    temp_c : float
        Ambient temperature of ``static`` and ``steps``, deg C.

    Returns
    -------
    Profile

    """
    if name_or_path == 'static':
        return static(duration_s, temp_c)
    if name_or_path == 'steps':
        return rate_table_steps(duration_s, temp_c)
    if name_or_path == 'temp-ramp':
        return temperature_ramp(duration_s)
    if not os.path.isfile(str(name_or_path)):
        raise ValueError(f'profile {name_or_path!r} is neither a built-in profile '
                         f'({", ".join(PROFILE_NAMES)}) nor a readable YAML file')
    return load_profile(name_or_path)
