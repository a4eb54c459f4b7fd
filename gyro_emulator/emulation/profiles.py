"""
Input profiles: the true rate, ambient temperature and specific force a run sees.

One protocol, :class:`Profile`: a profile has a ``name``, a ``duration_s``
and gives its 3-axis samples on the times asked, ``samples(time_s)`` ->
:class:`ProfileSamples` (rate rad/s (N, 3), temperature deg C (N,),
specific force m/s^2 (N, 3)). Its kinds:

* scripted (:class:`ScriptedProfile`): segments from YAML or the built-in
  ideas, evaluated at any time; ``simulate`` samples them at its own rate;
* sampled (:class:`SampledProfile`): values at sample times, linear between
  them; the drawn lab/paper/thermal/static profiles of the truth generator
  (:mod:`.truth.drawn`);
* recorded (:class:`.recorded_profile.RecordedProfile`): a measured CSV or
  bag as a sampled profile (``simulate --profile LOG``);
* scenario (:class:`.scenario.Scenario`): constant steps played onto the
  node, a scripted profile with labels.

:func:`gyro_emulator.emulation.run_profile.run_over_profile` is the one
loop that runs the sensor model over any of them.

One function per profile idea, each giving the scripted kind, or the
sampled kind on a grid with ``sample_rate_hz`` (linear between the idea's
knots, as a lab program is), so that ``simulate`` and the truth generator
share it:

* :func:`static_profile`: a part at rest, level, at a constant temperature;
* :func:`temperature_ramp`: a chamber program (linear between (time,
  temperature) knots) at a constant rate about z: the paper's Fig 6, or a
  thermal test's soak, ramp (and back), soak;
* :func:`paper_rate_steps`: the paper's rate-table steps about z at one or
  more temperatures, the chamber ramping between them.

Vocabulary: rad/s, deg C, m/s^2, the level specific force
:data:`LEVEL_ACCEL_M_S2`, the paper's rates :data:`PAPER_RATES_RPM`.

Specific force. A profile either gives its specific force (``accel_m_s2``:
the truth generator's drawn profiles, a record's acceleration channel, a
YAML profile that writes ``accel_m_s2``) or leaves it to the motion: then
its samples carry ``accel_m_s2`` None and the applied linear acceleration
in the body frame (``linear_accel_m_s2``, zero unless given), and the one
chunk loop (:func:`gyro_emulator.emulation.run_profile.run_over_profile`)
integrates the attitude from the profile's ``initial_attitude_wxyz``
(level by default) with the profile's rate and takes
f = a_body - R(q)^T (0, 0, -g) (:mod:`gyro_emulator.physics.kinematics`),
g = the profile's ``gravity_m_s2``. The gyro's g-sensitivity and the
accelerometer see that same f. Rotations about z only (the built-in
profiles) leave gravity exactly on z: (0, 0, g).

Scripted profiles
-----------------

A :class:`ScriptedProfile` is a sequence of segments; within a segment the
body rate and the ambient temperature move linearly from a start to an end
value (equal values hold them constant) and the specific force is constant.
Built-in profiles (:data:`PROFILE_NAMES`) stretch to the requested duration;
a YAML profile keeps its own segment durations and holds its last values if
the simulation runs longer.

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
    initial_attitude_wxyz: [1, 0, 0, 0]  # optional (level); body to world, REP 103
    gravity_m_s2: 9.80665                # optional
    linear_accel_m_s2: [0.0, 0.0, 0.0]   # optional default applied acceleration, body
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
        linear_accel_m_s2: [0.5, 0, 0]   # applied acceleration, body frame

A profile may instead give its specific force itself, ``accel_m_s2``
(a profile default and per segment; a segment without it takes the
default, else level): then the attitude is not integrated, and
``linear_accel_m_s2``, ``initial_attitude_wxyz`` and ``gravity_m_s2`` are
refused.

``temperature_c`` is the old spelling of ``temp_c``: still read, with a
deprecation warning.
"""

from dataclasses import dataclass
import os
from typing import Protocol, runtime_checkable

from gyro_emulator.emulation.segments import (DEFAULT_AXIS, LEVEL_ACCEL_M_S2, parse_segment,
                                              Segment, unit_axis)
from gyro_emulator.physics.kinematics import check_attitude, check_gravity, LEVEL_WXYZ
from gyro_emulator.resources import read_yaml
from gyro_emulator.units import deg_s_to_rad_s, rpm_to_rad_s, STANDARD_GRAVITY_M_S2
from gyro_emulator.validation import quote
import numpy as np

PROFILE_NAMES = ('static', 'steps', 'temp-ramp')

#: Rate-table rates of the paper's validation test, RPM about z.
PAPER_RATES_RPM = (0.0, 10.0, 20.0, 40.0)
#: Chamber temperatures of the paper's validation test, deg C.
PAPER_TEMPS_C = (25.0, 40.0, 55.0, 70.0, 85.0)
#: Rate-table levels of the ``steps`` profile: the paper's rates and back to 0, RPM.
STEP_LEVELS_RPM = PAPER_RATES_RPM + (0.0,)


@dataclass(frozen=True)
class ProfileSamples:
    """
    Profile values at the sample times: (N, 3) rates and forces, (N,) temperatures.

    ``accel_m_s2`` is the specific force, or None where the profile leaves
    it to the motion (module docstring); then ``linear_accel_m_s2`` is the
    applied linear acceleration in the body frame (None: zero).
    """

    rate_rad_s: np.ndarray
    temp_c: np.ndarray
    accel_m_s2: np.ndarray
    linear_accel_m_s2: np.ndarray = None

    @staticmethod
    def concatenate(parts):
        """Join samples in time order."""
        def joined(name):
            values = [getattr(p, name) for p in parts]
            return None if any(v is None for v in values) else np.concatenate(values)
        return ProfileSamples(*(joined(name) for name in (
            'rate_rad_s', 'temp_c', 'accel_m_s2', 'linear_accel_m_s2')))


@runtime_checkable
class Profile(Protocol):
    """
    The one profile protocol: 3-axis samples on the times asked.

    Attributes
    ----------
    name : str
        What the profile is called (a built-in name, a file, a drawn kind).
    duration_s : float
        Its length, s.
    initial_attitude_wxyz : tuple
        Attitude at time 0 (w, x, y, z), body to world (REP 103; level
        :data:`~gyro_emulator.physics.kinematics.LEVEL_WXYZ`), for a
        profile that leaves its specific force to the motion.
    gravity_m_s2 : float
        Magnitude of gravity for that specific force, m/s^2.

    """

    name: str
    initial_attitude_wxyz: tuple
    gravity_m_s2: float

    @property
    def duration_s(self):
        """Length, s."""

    def samples(self, time_s):
        """
        Return the rate (rad/s, (N, 3)), temperature (deg C, (N,)) and specific force.

        Parameters
        ----------
        time_s : array_like
            Times, s, shape (N,).

        Returns
        -------
        ProfileSamples

        """


@dataclass(frozen=True)
class ScriptedProfile:
    """
    A named sequence of :class:`Segment` (module docstring): the scripted kind.

    Its segments either all give their specific force or all leave it to
    the motion, from ``initial_attitude_wxyz`` under ``gravity_m_s2``.
    """

    name: str
    segments: tuple
    initial_attitude_wxyz: tuple = LEVEL_WXYZ
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2

    def __post_init__(self):
        """Require at least one segment, one kind of specific force, a unit attitude, a gravity."""
        if not self.segments:
            raise ValueError(f'Profile {quote(self.name)} has no segments')
        object.__setattr__(self, 'segments', tuple(self.segments))
        given = {s.accel_m_s2 is not None for s in self.segments}
        if len(given) > 1:
            raise ValueError(f'Profile {quote(self.name)}: some segments give accel_m_s2 and some '
                             'do not: give the specific force in every segment or in none')
        owner = f'Profile {quote(self.name)}'
        object.__setattr__(self, 'initial_attitude_wxyz', tuple(
            check_attitude(self.initial_attitude_wxyz, owner).tolist()))
        object.__setattr__(self, 'gravity_m_s2', check_gravity(self.gravity_m_s2, owner))

    @property
    def duration_s(self):
        """Total duration, s."""
        return float(sum(s.duration_s for s in self.segments))

    def samples(self, time_s):
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
        dur = np.array([s.duration_s for s in self.segments])
        frac = np.clip((t - starts[idx]) / dur[idx], 0.0, 1.0)
        rate = r0[idx] + (r1[idx] - r0[idx]) * frac[:, np.newaxis]
        temp = t0[idx] + (t1[idx] - t0[idx]) * frac
        if self.segments[0].accel_m_s2 is not None:
            acc = np.array([s.accel_m_s2 for s in self.segments])
            return ProfileSamples(rate_rad_s=rate, temp_c=temp, accel_m_s2=acc[idx])
        linear = np.array([s.linear_accel_m_s2 for s in self.segments])
        return ProfileSamples(rate_rad_s=rate, temp_c=temp, accel_m_s2=None,
                              linear_accel_m_s2=linear[idx])


@dataclass(frozen=True)
class SampledProfile:
    """
    Values at sample times, linear between them (:func:`numpy.interp`): the sampled kind.

    Attributes
    ----------
    name : str
        What the profile is (``lab``, ``paper``, a record's path, ...).
    time_s : numpy.ndarray
        Sample times, s, shape (N,), non-decreasing.
    rate_rad_s, accel_m_s2 : numpy.ndarray
        True rate (rad/s) and specific force (m/s^2), shape (N, 3); a
        specific force of None is left to the motion (module docstring).
    temp_c : numpy.ndarray
        True (chamber) temperature, deg C, shape (N,).
    max_rate_rad_s : float, optional
        Largest rate the profile commands, rad/s (a lab's table full scale;
        default: the largest magnitude of ``rate_rad_s``).
    linear_accel_m_s2 : numpy.ndarray, optional
        Applied linear acceleration in the body frame, (N, 3), m/s^2, with a
        specific force of None (None: zero).
    initial_attitude_wxyz, gravity_m_s2
        As :class:`Profile`.
    rate_knots : tuple, optional
        (times s (K,), rates rad/s (K, 3)) of a rate linear between knots:
        the rate at any time, exactly, between the samples too
        (:meth:`rate_at`; a delayed rate needs it).

    """

    name: str
    time_s: np.ndarray
    rate_rad_s: np.ndarray
    temp_c: np.ndarray
    accel_m_s2: np.ndarray
    max_rate_rad_s: float = None
    linear_accel_m_s2: np.ndarray = None
    initial_attitude_wxyz: tuple = LEVEL_WXYZ
    gravity_m_s2: float = STANDARD_GRAVITY_M_S2
    rate_knots: tuple = None

    def __post_init__(self):
        """Check the shapes: (N,) times and temperatures, (N, 3) rates and forces."""
        n = len(self.time_s)
        for name, shape in (('time_s', (n,)), ('rate_rad_s', (n, 3)), ('temp_c', (n,)),
                            ('accel_m_s2', (n, 3)), ('linear_accel_m_s2', (n, 3))):
            if name in ('accel_m_s2', 'linear_accel_m_s2') and getattr(self, name) is None:
                continue
            arr = np.asarray(getattr(self, name), dtype=float)
            if arr.shape != shape:
                raise ValueError(f'SampledProfile.{name} has shape {arr.shape}: expected '
                                 f'{shape}')
            object.__setattr__(self, name, arr)
        if self.max_rate_rad_s is None:
            object.__setattr__(self, 'max_rate_rad_s',
                               float(np.max(np.abs(self.rate_rad_s))) if n else 0.0)
        owner = f'Profile {quote(self.name)}'
        object.__setattr__(self, 'initial_attitude_wxyz', tuple(
            check_attitude(self.initial_attitude_wxyz, owner).tolist()))
        object.__setattr__(self, 'gravity_m_s2', check_gravity(self.gravity_m_s2, owner))

    @property
    def sample_period_s(self):
        """Return the median positive sample interval, s."""
        dt = np.diff(self.time_s)
        return float(np.median(dt[dt > 0.0]))

    @property
    def rate_hz(self):
        """Return the nominal sample rate, Hz."""
        return 1.0 / self.sample_period_s

    @property
    def duration_s(self):
        """First to last sample plus one interval, s."""
        return float(self.time_s[-1] - self.time_s[0]) + self.sample_period_s

    def samples(self, time_s):
        """Return the samples at ``time_s``: linear between the profile's samples, held outside."""
        t = np.asarray(time_s, dtype=float)

        def at(values):
            if values is None:
                return None
            return np.column_stack([np.interp(t, self.time_s, values[:, k]) for k in range(3)])

        return ProfileSamples(at(self.rate_rad_s), np.interp(t, self.time_s, self.temp_c),
                              at(self.accel_m_s2), at(self.linear_accel_m_s2))

    def rate_at(self, time_s):
        """
        Return the rate at ``time_s``, rad/s (N, 3).

        From the knots when the profile has them (zero before the first and
        after the last: the table at rest), else from the samples as
        :meth:`samples` gives it.
        """
        t = np.asarray(time_s, dtype=float)
        if self.rate_knots is None:
            return self.samples(t).rate_rad_s
        kt, kr = self.rate_knots
        return np.column_stack([np.interp(t, kt, kr[:, k], left=0.0, right=0.0)
                                for k in range(3)])

    def own_samples(self, start, stop):
        """Return the profile's own samples ``start`` .. ``stop - 1``, as they are."""
        def rows(values):
            return None if values is None else values[start:stop]
        return ProfileSamples(self.rate_rad_s[start:stop], self.temp_c[start:stop],
                              rows(self.accel_m_s2), rows(self.linear_accel_m_s2))


def rate_about_z(rate_rad_s):
    """Return rates about z, (N,), as (N, 3) body rates (x and y zero), rad/s."""
    rate = np.zeros((len(rate_rad_s), 3))
    rate[:, 2] = rate_rad_s
    return rate


def level_accel(count):
    """Return ``count`` level specific forces (:data:`LEVEL_ACCEL_M_S2`), (N, 3) m/s^2."""
    return np.tile(LEVEL_ACCEL_M_S2, (count, 1))


def sample_times(duration_s, sample_rate_hz):
    """Return a sampled profile's grid: 0, 1 / sample_rate_hz, ... before ``duration_s``."""
    return np.arange(0.0, duration_s, 1.0 / sample_rate_hz)


# --- one function per profile idea -----------------------------------------

def static_profile(duration_s, temp_c=25.0, sample_rate_hz=None):
    """
    Return a part at rest, level (z up), at a constant ambient temperature (an Allan run).

    ``simulate --profile static``, the fleet's sensor runs, and the truth
    generator's ``static`` (sampled, plus a drawn chamber wander).

    Parameters
    ----------
    duration_s : float
        Length, s.
    temp_c : float
        Ambient temperature, deg C.
    sample_rate_hz : float, optional
        Give the sampled kind on :func:`sample_times` (default: scripted).

    Returns
    -------
    ScriptedProfile or SampledProfile

    """
    if sample_rate_hz is None:
        zero = (0.0, 0.0, 0.0)
        return ScriptedProfile('static', (Segment(duration_s, zero, zero, temp_c, temp_c),))
    t = sample_times(duration_s, sample_rate_hz)
    return SampledProfile('static', t, np.zeros((len(t), 3)), np.full(len(t), float(temp_c)),
                          level_accel(len(t)), max_rate_rad_s=0.0)


def temperature_ramp(knots, rate_deg_s=60.0, sample_rate_hz=None, name='temp-ramp'):
    """
    Return a chamber program, linear between (time, temperature) knots, rate held about z.

    The paper's Fig 6 (``simulate --profile temp-ramp``: 25 to 85 C over the
    run at 60 deg/s) and the truth generator's thermal tests (a static part:
    soak, ramp, and back for a cycle, soak).

    Parameters
    ----------
    knots : sequence of (float, float)
        (time s, temperature deg C), time non-decreasing from 0; the last
        time is the length.
    rate_deg_s : float
        Rate about z, deg/s.
    sample_rate_hz : float, optional
        Give the sampled kind on :func:`sample_times`, the temperature by
        :func:`numpy.interp` between the knots (default: scripted, one
        segment per pair of knots at different times).
    name : str
        The profile's name.

    Returns
    -------
    ScriptedProfile or SampledProfile

    """
    rate = (0.0, 0.0, float(deg_s_to_rad_s(rate_deg_s)))
    if sample_rate_hz is None:
        return ScriptedProfile(name, tuple(
            Segment(t1 - t0, rate, rate, c0, c1)
            for (t0, c0), (t1, c1) in zip(knots[:-1], knots[1:]) if t1 != t0))
    knots_t, knots_c = zip(*knots)
    t = sample_times(knots_t[-1], sample_rate_hz)
    return SampledProfile(name, t, rate_about_z(np.full(len(t), rate[2])),
                          np.interp(t, knots_t, knots_c), level_accel(len(t)))


def paper_rate_steps(dwell_s, temps_c=PAPER_TEMPS_C, rates_rpm=PAPER_RATES_RPM, ramp_k_min=2.0,
                     transition_s=2.0, sample_rate_hz=None, name='paper'):
    """
    Return the paper's validation: at each temperature the table turns at each rate about z.

    The chamber ramps at ``ramp_k_min`` between temperatures with the table
    at rest, axis vertical. ``simulate --profile steps`` is one temperature
    and the rates and back to 0 (:data:`STEP_LEVELS_RPM`); the truth
    generator's ``paper`` is the paper's grid, 5 minutes a point (the paper
    averaged 5 minutes per point).

    Parameters
    ----------
    dwell_s : float
        Time at each (temperature, rate) point, s.
    temps_c : sequence of float
        Soak temperatures, deg C.
    rates_rpm : sequence of float
        Table rates, RPM.
    ramp_k_min : float
        Chamber ramp rate, K/min.
    transition_s : float
        Sampled kind: the table moves linearly between rates from
        ``transition_s`` before a change to ``transition_s`` after it (the
        scripted kind steps at once).
    sample_rate_hz : float, optional
        Give the sampled kind on :func:`sample_times` (default: scripted).
    name : str
        The profile's name.

    Returns
    -------
    ScriptedProfile or SampledProfile

    """
    if sample_rate_hz is None:
        return ScriptedProfile(name, tuple(_step_segments(dwell_s, temps_c, rates_rpm,
                                                          ramp_k_min)))
    temp_knots, rate_knots = [], []
    now = 0.0
    for i, temp in enumerate(temps_c):
        for rpm in rates_rpm:
            temp_knots += [(now, temp), (now + dwell_s, temp)]
            rate_knots += [(now + transition_s, rpm_to_rad_s(rpm)),
                           (now + dwell_s - transition_s, rpm_to_rad_s(rpm))]
            now += dwell_s
        if i + 1 < len(temps_c):
            rate_knots += [(now, 0.0)]
            now += abs(temps_c[i + 1] - temp) / (ramp_k_min / 60.0)
            rate_knots += [(now, 0.0)]
    t = sample_times(now, sample_rate_hz)
    knots_t, knots_c = zip(*temp_knots)
    knots_rt, knots_r = zip(*([(0.0, 0.0)] + rate_knots))
    return SampledProfile(name, t, rate_about_z(np.interp(t, knots_rt, knots_r)),
                          np.interp(t, knots_t, knots_c), level_accel(len(t)))


def _step_segments(dwell_s, temps_c, rates_rpm, ramp_k_min):
    """Yield the scripted segments of :func:`paper_rate_steps`: the dwells and the ramps."""
    zero = (0.0, 0.0, 0.0)
    for i, temp in enumerate(temps_c):
        for rpm in rates_rpm:
            rate = (0.0, 0.0, float(rpm_to_rad_s(rpm)))
            yield Segment(dwell_s, rate, rate, temp, temp)
        if i + 1 < len(temps_c) and temps_c[i + 1] != temp:
            yield Segment(abs(temps_c[i + 1] - temp) / (ramp_k_min / 60.0), zero, zero, temp,
                          temps_c[i + 1])


#: Profile keys of a specific force left to the motion.
_MOTION_KEYS = ('linear_accel_m_s2', 'initial_attitude_wxyz', 'gravity_m_s2')


def profile_from_mapping(mapping, source='profile'):
    """
    Build a :class:`ScriptedProfile` from a parsed YAML mapping (module docstring).

    Unknown keys and bad values raise ``ValueError`` naming the segment and key.
    """
    if not isinstance(mapping, dict):
        raise ValueError(f'{source}: expected a mapping with "segments", got {quote(mapping)}')
    allowed = ('name', 'segments', 'accel_m_s2', 'axis') + _MOTION_KEYS
    unknown = sorted(set(mapping) - set(allowed))
    if unknown:
        raise ValueError(f'{source}: unknown key(s) {", ".join(map(str, unknown))}; '
                         f'allowed: {", ".join(allowed)}')
    axis = unit_axis(source, mapping.get('axis', DEFAULT_AXIS))
    raw = mapping.get('segments')
    if not isinstance(raw, list) or not raw:
        raise ValueError(f'{source}: segments must be a non-empty list')
    given = 'accel_m_s2' in mapping or any(isinstance(seg, dict) and 'accel_m_s2' in seg
                                           for seg in raw)
    motion = [k for k in _MOTION_KEYS if k in mapping]
    if given and motion:
        raise ValueError(f'{source}: {", ".join(motion)} is for a specific force left to the '
                         'motion: give it or accel_m_s2 (the specific force itself), not both')
    default_acc = mapping.get('accel_m_s2', LEVEL_ACCEL_M_S2) if given else None
    default_linear = mapping.get('linear_accel_m_s2', (0.0, 0.0, 0.0))
    segments = []
    last_temp = 25.0
    for i, seg in enumerate(raw):
        segment = parse_segment(f'{source}: segment {i + 1}', seg, axis, last_temp,
                                default_acc, default_linear)
        last_temp = segment.temp_end_c
        segments.append(segment)
    try:
        return ScriptedProfile(str(mapping.get('name', source)), tuple(segments),
                               mapping.get('initial_attitude_wxyz', LEVEL_WXYZ),
                               mapping.get('gravity_m_s2', STANDARD_GRAVITY_M_S2))
    except ValueError as exc:
        raise ValueError(f'{source}: {exc}') from None


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
    ScriptedProfile

    """
    if name_or_path == 'static':
        return static_profile(duration_s, temp_c)
    if name_or_path == 'steps':
        return paper_rate_steps(float(duration_s) / len(STEP_LEVELS_RPM), (temp_c,),
                                STEP_LEVELS_RPM, name='steps')
    if name_or_path == 'temp-ramp':
        return temperature_ramp(((0.0, 25.0), (duration_s, 85.0)))
    if not os.path.isfile(str(name_or_path)):
        raise ValueError(f'profile {quote(name_or_path)} is neither a built-in profile '
                         f'({", ".join(PROFILE_NAMES)}) nor a readable YAML file')
    return load_profile(name_or_path)
