"""
Input profiles: the true rate, ambient temperature and specific force a run sees.

Two kinds, one vocabulary (rad/s, deg C, m/s^2, the level specific force
:data:`LEVEL_ACCEL_M_S2`, the paper's rate steps :data:`PAPER_RATES_RPM`):

* scripted profiles (:class:`Profile`, :func:`make_profile`): segments that
  ``simulate`` samples at its own rate and a scenario plays step by step;
* sampled test profiles (:class:`SampledProfile`, :func:`draw_profile`):
  what a lab did to a part, sample by sample, drawn from an injected
  ``numpy.random.Generator``; the truth generator runs them.

Scripted profiles
-----------------

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

YAML profile (the one segment schema: ``simulate`` profiles and the scenario
files of :mod:`.scenario` share it, :func:`parse_segment`)::

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

Sampled test profiles
---------------------

A :class:`SampledProfile` is the true rate about the sense axis, the true (chamber)
temperature and the specific force in the sensor frame, sample by sample.
Every random choice comes from the injected ``numpy.random.Generator``.

- :func:`lab_profile`: a rate table in a thermal chamber (soaks joined by
  heating and cooling ramps, rate steps with an acceleration limit, swept
  sines, tilt positions of the table axis);
- :func:`paper_profile`: the paper's validation experiment (0, 10, 20 and
  40 RPM at 25 to 85 C);
- :func:`thermal_ramp_profile`: a static part in a chamber that ramps the
  temperature once (``cycle=False``: temperature and time confounded, like
  the LSM6DSM log) or down and back up (``cycle=True``);
- :func:`static_profile`: a static part at a steady temperature (an Allan
  run, like the ADIS16405 and MPU-6050 logs).
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

#: Rate-table rates of the paper's validation test, RPM about z.
PAPER_RATES_RPM = (0.0, 10.0, 20.0, 40.0)
#: Rate-table levels of the ``steps`` profile: the paper's rates and back to 0, RPM.
STEP_LEVELS_RPM = PAPER_RATES_RPM + (0.0,)


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


# --- sampled test profiles (the truth generator) ---------------------------

#: Sampled profile names :func:`draw_profile` accepts.
SAMPLED_PROFILES = ('lab', 'paper', 'thermal_ramp', 'thermal_cycle', 'static')


@dataclass(frozen=True)
class SampledProfile:
    """A sampled test profile: true rate about z, true (chamber) temperature, acceleration."""

    time_s: np.ndarray
    rate_rad_s: np.ndarray
    temp_c: np.ndarray
    accel_m_s2: np.ndarray
    max_rate_rad_s: float
    name: str


def _soak_ramp_temperature(t, plan):
    """Piecewise-linear temperature from (time, temp) knots."""
    knots_t, knots_temp = zip(*plan)
    return np.interp(t, knots_t, knots_temp)


def lab_profile(rng, sample_rate_hz=25.0, levels=5, max_duration_s=None):
    """
    Make a seeded random lab-like profile.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness.
    sample_rate_hz : float
        Output data rate, Hz.
    levels : int
        Temperature soak levels, 25 C included (>= 3).
    max_duration_s : float, optional
        Cut the profile at this duration.

    Returns
    -------
    SampledProfile

    """
    plan, end_s = _soak_plan(rng, levels)
    duration = end_s if max_duration_s is None else min(end_s, max_duration_s)
    dt = 1.0 / sample_rate_hz
    t = np.arange(0.0, duration, dt)
    temp = _soak_ramp_temperature(t, plan)
    rate, max_rate = _table_rate(rng, t, duration, sample_rate_hz)
    accel = _table_gravity(rng, t, rate, duration, dt)
    return SampledProfile(time_s=t, rate_rad_s=rate, temp_c=temp, accel_m_s2=accel,
                          max_rate_rad_s=float(max_rate), name='lab')


def _soak_plan(rng, levels):
    """
    Draw the chamber plan: soaks at ``levels`` temperatures joined by ramps.

    The first soak (600 s) and the last are at 25 C; the others last 6 to
    11 min at levels spread from -10..12 C to 55..85 C in random order, and
    the ramps run at 1 to 3 K/min. Return the (time, temp) knots and the end
    time, s.
    """
    t_lo = rng.uniform(-10.0, 12.0)
    t_hi = rng.uniform(55.0, 85.0)
    temps = list(np.linspace(t_lo, t_hi, levels) + rng.uniform(-3, 3, levels))
    temps[int(np.argmin(np.abs(np.array(temps) - 25.0)))] = 25.0
    others = [v for v in temps if v != 25.0]
    order = [25.0] + list(rng.permutation(others)) + [25.0]
    plan, now = [], 0.0
    for i, level in enumerate(order):
        soak = 600.0 if i == 0 else rng.uniform(360.0, 660.0)
        plan += [(now, level), (now + soak, level)]
        now += soak
        if i + 1 < len(order):
            ramp_k_s = rng.uniform(1.0, 3.0) / 60.0
            now += abs(order[i + 1] - level) / ramp_k_s
    return plan, now


def _table_rate(rng, t, duration, sample_rate_hz):
    """
    Draw the rate-table program: steps under an acceleration limit and chirps.

    Dwells of 20 to 60 s at 0 or +-10, 25, 50, 75 or 100 % of a full scale
    of 150 to 300 deg/s, reached at 100 to 300 deg/s^2; 12 % of the dwells carry a
    swept sine (0.2 Hz up to at most 4 Hz or f_s / 6) with a sin^2 taper.
    Return the rate at ``t``, rad/s, and the full scale, rad/s.
    """
    max_rate = deg_s_to_rad_s(rng.uniform(150.0, 300.0))
    accel_limit = deg_s_to_rad_s(rng.uniform(100.0, 300.0))
    fractions = np.array([0.0, 0.1, 0.25, 0.5, 0.75, 1.0])
    knots_t, knots_r = [0.0], [0.0]
    chirps = []
    now, level = 0.0, 0.0
    while now < duration:
        dwell = rng.uniform(20.0, 60.0)
        if rng.random() < 0.12:
            new = 0.0
            kind = 'chirp'
        else:
            new = 0.0 if rng.random() < 0.25 else float(
                rng.choice(fractions[1:]) * rng.choice([-1.0, 1.0]) * max_rate)
            kind = 'step'
        move = abs(new - level) / accel_limit
        knots_t += [now + move, now + move + dwell]
        knots_r += [new, new]
        if kind == 'chirp':
            f_top = min(4.0, sample_rate_hz / 6.0)
            chirps.append((now + move, dwell, rng.uniform(0.1, 0.4) * max_rate,
                           rng.uniform(0.4 * f_top, f_top)))
        now += move + dwell
        level = new
    rate = np.interp(t, knots_t, knots_r)
    for start, length, amp, f1 in chirps:
        m = (t >= start) & (t < start + length)
        tau = t[m] - start
        f0 = 0.2
        phase = 2 * np.pi * (f0 * tau + 0.5 * (f1 - f0) / length * tau ** 2)
        taper = np.sin(np.pi * tau / length) ** 2
        rate[m] += amp * taper * np.sin(phase)
    return rate, max_rate


def _table_gravity(rng, t, rate, duration, dt):
    """
    Draw the tilts of the table axis; return gravity in the sensor frame, m/s^2.

    The axis dwells 3 to 10 min at a tilt from vertical of 0 to 180 deg;
    gravity's horizontal part turns with the table angle (the integral of
    the rate).
    """
    tilt = np.zeros_like(t)
    now = 0.0
    angles = np.deg2rad([0.0, 30.0, 60.0, 90.0, 120.0, 180.0])
    while now < duration:
        dwell = rng.uniform(180.0, 600.0)
        tilt[(t >= now) & (t < now + dwell)] = rng.choice(angles)
        now += dwell
    table_angle = np.cumsum(rate) * dt
    g = STANDARD_GRAVITY_M_S2
    return np.column_stack([g * np.sin(tilt) * np.cos(table_angle),
                            -g * np.sin(tilt) * np.sin(table_angle),
                            g * np.cos(tilt)])


def paper_profile(sample_rate_hz=10.0, minutes_per_point=5.0,
                  temps_c=(25.0, 40.0, 55.0, 70.0, 85.0),
                  rates_rpm=PAPER_RATES_RPM, ramp_k_min=2.0):
    """
    Make the paper's validation experiment into a profile.

    At each temperature (soak), the table turns at each rate for
    ``minutes_per_point`` minutes (the paper averaged 5 minutes per point);
    the chamber ramps at ``ramp_k_min`` K/min between temperatures with the
    table at rest, axis vertical.

    Parameters
    ----------
    sample_rate_hz : float
        Output data rate, Hz.
    minutes_per_point : float
        Dwell per (temperature, rate) point, min.
    temps_c : sequence of float
        Soak temperatures, deg C.
    rates_rpm : sequence of float
        Table rates, RPM.
    ramp_k_min : float
        Chamber ramp rate, K/min.

    Returns
    -------
    SampledProfile

    """
    dwell = 60.0 * minutes_per_point
    temp_knots, rate_knots = [], []
    now = 0.0
    for i, temp in enumerate(temps_c):
        for rpm in rates_rpm:
            temp_knots += [(now, temp), (now + dwell, temp)]
            rate_knots += [(now + 2.0, rpm_to_rad_s(rpm)),
                           (now + dwell - 2.0, rpm_to_rad_s(rpm))]
            now += dwell
        if i + 1 < len(temps_c):
            rate_knots += [(now, 0.0)]
            now += abs(temps_c[i + 1] - temp) / (ramp_k_min / 60.0)
            rate_knots += [(now, 0.0)]
    dt = 1.0 / sample_rate_hz
    t = np.arange(0.0, now, dt)
    temp = _soak_ramp_temperature(t, temp_knots)
    kt, kr = zip(*([(0.0, 0.0)] + rate_knots))
    rate = np.interp(t, kt, kr)
    accel = np.tile(LEVEL_ACCEL_M_S2, (len(t), 1))
    return SampledProfile(time_s=t, rate_rad_s=rate, temp_c=temp, accel_m_s2=accel,
                          max_rate_rad_s=float(np.max(np.abs(rate))), name='paper')


def thermal_ramp_profile(rng, sample_rate_hz=1.0, duration_s=None, cycle=False):
    """
    Make a static thermal test: a soak, a slow ramp (and back), a soak.

    The part sits still (zero applied rate, gravity along z). The chamber
    starts at 25 +- 2 C, ramps to a level 25 to 45 K below or 30 to 60 K
    above it, then (``cycle=True``) back to the start, with soaks of 3 to
    8 % of the run at the ends and at the turn. A single ramp makes
    temperature and time nearly collinear, as in a real cool-down log; the
    cycle separates them.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness.
    sample_rate_hz : float
        Output data rate, Hz.
    duration_s : float, optional
        Length of the run, s (default: drawn from 6 to 12 h).
    cycle : bool
        Ramp back to the start temperature.

    Returns
    -------
    SampledProfile

    """
    duration = rng.uniform(6.0, 12.0) * 3600.0 if duration_s is None else float(duration_s)
    start = 25.0 + rng.uniform(-2.0, 2.0)
    far = start - rng.uniform(25.0, 45.0) if rng.random() < 0.5 else \
        start + rng.uniform(30.0, 60.0)
    soaks = rng.uniform(0.03, 0.08, 3) * duration
    if cycle:
        ramp = 0.5 * (duration - soaks.sum())
        knots = [(0.0, start), (soaks[0], start), (soaks[0] + ramp, far),
                 (soaks[0] + ramp + soaks[1], far),
                 (soaks[0] + 2 * ramp + soaks[1], start), (duration, start)]
    else:
        knots = [(0.0, start), (soaks[0], start),
                 (duration - soaks[1], far), (duration, far)]
    t = np.arange(0.0, duration, 1.0 / sample_rate_hz)
    temp = _soak_ramp_temperature(t, knots)
    accel = np.tile(LEVEL_ACCEL_M_S2, (len(t), 1))
    return SampledProfile(time_s=t, rate_rad_s=np.zeros(len(t)), temp_c=temp,
                          accel_m_s2=accel, max_rate_rad_s=0.0,
                          name='thermal_cycle' if cycle else 'thermal_ramp')


def static_profile(rng, sample_rate_hz=100.0, duration_s=None):
    """
    Make a static run at a steady temperature (an Allan-deviation run).

    The chamber holds 20 to 30 C with a slow wander of 0.05 K rms (hours);
    the part sits still, gravity along z. ``duration_s`` defaults to a draw
    from 1 to 3 h.
    """
    duration = rng.uniform(1.0, 3.0) * 3600.0 if duration_s is None else float(duration_s)
    t = np.arange(0.0, duration, 1.0 / sample_rate_hz)
    knots_t = np.linspace(0.0, duration, 6)
    temp = rng.uniform(20.0, 30.0) + np.interp(t, knots_t, rng.normal(0.0, 0.05, 6))
    accel = np.tile(LEVEL_ACCEL_M_S2, (len(t), 1))
    return SampledProfile(time_s=t, rate_rad_s=np.zeros(len(t)), temp_c=temp,
                          accel_m_s2=accel, max_rate_rad_s=0.0, name='static')


def draw_profile(name, rng, sample_rate_hz, levels=5, duration_s=None):
    """
    Return the sampled profile ``name`` (one of :data:`SAMPLED_PROFILES`).

    ``levels`` is the lab profile's number of temperature levels;
    ``duration_s`` cuts the lab profile, or sets the length of the thermal
    and static ones (default: drawn).
    """
    if name == 'lab':
        return lab_profile(rng, sample_rate_hz=sample_rate_hz, levels=levels,
                           max_duration_s=duration_s)
    if name == 'paper':
        return paper_profile(sample_rate_hz=sample_rate_hz)
    if name in ('thermal_ramp', 'thermal_cycle'):
        return thermal_ramp_profile(rng, sample_rate_hz, duration_s,
                                    cycle=name == 'thermal_cycle')
    if name == 'static':
        return static_profile(rng, sample_rate_hz, duration_s)
    raise ValueError(f'truth.profile = {name!r} is not allowed: choose one of '
                     f'{", ".join(SAMPLED_PROFILES)}')
