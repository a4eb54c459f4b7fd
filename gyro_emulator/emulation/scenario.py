"""
Scenario files: a profile of constant-input steps and how to play it.

A scenario is a YAML file of constant-input steps, written in the one
segment schema of :mod:`gyro_emulator.emulation.profiles` (a number as a rate
is along ``axis``), plus what the player needs: how often to re-send the
commands, a grid of every rate at every temperature, the node's parameters
and a fault schedule. A :class:`Scenario` is a profile of the one protocol
(:class:`~gyro_emulator.emulation.profiles.Profile`): its steps are
constant segments with labels (:class:`~.segments.Segment`), its samples
those of the scripted profile they make. :func:`summarize` averages the
output the player collected over each step; a step that got no sample in
its measurement window is not a number but an error :func:`unmeasured`
names (the table says "no samples", the JSON null). The ROS edge that
plays it is :mod:`gyro_emulator.ros.scenario`.

Scenario keys (SI unless the name says otherwise)::

    name: paper_validation
    axis: [0.0, 0.0, 1.0]        # rate direction in the sensor frame
    publish_rate_hz: 50.0
    grid:                        # every rate at every temperature ...
      temps_c: [25.0, 45.0, 65.0, 85.0]
      rates_rpm: [0.0, 10.0, 20.0, 40.0]   # or rates_deg_s / rates_rad_s
      hold_s: 2.0                # duration of each step
      settle_s: 0.8              # start of each step left out of the summary
    segments:                    # ... and/or explicit steps, played after
      - {duration_s: 2.0, rate_deg_s: 60.0, temp_c: 25.0, settle_s: 0.5}
    node_parameters: {}          # parameters a runner should give the node
    faults:                      # injected while playing (sensor.faults schema)
      - {type: bias_step, axis: z, magnitude: 0.01, start_s: 3.0, duration_s: 1.0}

``node_parameters`` is what makes a compressed profile meaningful (e.g. a
short die thermal time constant); ``gyro_emulator.cli.main_job`` passes it on.
``faults`` is a fault schedule, times from the start of the profile (the
player sends each to the node ahead of its start).
"""

from dataclasses import dataclass, replace
import math
import os
import warnings

from gyro_emulator.emulation import profiles
from gyro_emulator.emulation import segments as schema
from gyro_emulator.resources import config_file, read_yaml
from gyro_emulator.sensor import faults
from gyro_emulator.validation import quote
import numpy as np

DEFAULT_PROFILE = 'scenario_paper_validation.yaml'
#: How a step's label writes the unit of each rate key of the segment schema.
RATE_LABELS = {'rate_rad_s': 'rad/s', 'rate_deg_s': 'deg/s', 'rate_rpm': 'RPM'}


def _constant_step(where, segment, label):
    """Return ``segment`` as a scenario step: it holds its rate and temperature; labelled."""
    if segment.rate_start_rad_s != segment.rate_end_rad_s or \
            segment.temp_start_c != segment.temp_end_c:
        raise ValueError(f'{where}: a scenario step holds its rate and temp_c: give '
                         'numbers, not [start, end] ramps')
    return replace(segment, label=label)


@dataclass(frozen=True)
class Scenario:
    """
    A parsed scenario: a profile of constant steps, and how to play it.

    Attributes
    ----------
    name : str
        The scenario's name.
    axis : tuple
        Unit rate direction in the sensor frame.
    publish_rate_hz : float
        How often the player re-sends the commands, Hz.
    steps : tuple of gyro_emulator.emulation.segments.Segment
        Constant segments, each with the label of its rate (e.g. ``10 RPM``).
    node_parameters : dict
        Parameters a runner should give the node.
    faults : tuple
        The fault schedule, times from the start of the profile.

    """

    name: str
    axis: tuple
    publish_rate_hz: float
    steps: tuple
    node_parameters: dict
    faults: tuple = ()

    @property
    def duration_s(self):
        """Total length of the profile, s."""
        return sum(step.duration_s for step in self.steps)

    @property
    def profile(self):
        """Return the steps as a :class:`~.profiles.ScriptedProfile`."""
        return profiles.ScriptedProfile(self.name, self.steps)

    @property
    def initial_attitude_wxyz(self):
        """Attitude at time 0 (level): the specific force follows the motion, as on the node."""
        return self.profile.initial_attitude_wxyz

    @property
    def gravity_m_s2(self):
        """Magnitude of gravity, m/s^2 (standard)."""
        return self.profile.gravity_m_s2

    def samples(self, time_s):
        """Return the profile's samples at ``time_s`` (:class:`~.profiles.ProfileSamples`)."""
        return self.profile.samples(time_s)

    def rate_along_axis_rad_s(self, step):
        """Return a step's rate along :attr:`axis`, rad/s (what the player commands)."""
        return sum(a * r for a, r in zip(self.axis, step.rate_start_rad_s))


def _number(where, key, value, low=None, high=None, low_open=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value):
        raise ValueError(f'{where}.{key} = {quote(value)} is not a finite number')
    if (low is not None and (value <= low if low_open else value < low)) or (
            high is not None and value > high):
        lo = '-inf' if low is None else f'{low:g}'
        hi = 'inf' if high is None else f'{high:g}'
        raise ValueError(f'{where}.{key} = {quote(value)} is out of range: allowed '
                         f'{"(" if low_open else "["}{lo}, {hi}]')
    return float(value)


def _rate(where, mapping, plural=False):
    names = {('rates_' + k[5:] if plural else k): k for k in schema.RATE_UNITS}
    found = [n for n in names if n in mapping]
    if len(found) != 1:
        raise ValueError(f'{where}: give exactly one of {", ".join(names)}')
    return found[0], names[found[0]]


def _step(where, raw, axis):
    """Parse one step with the shared segment schema (:func:`.segments.parse_segment`)."""
    if not isinstance(raw, dict):
        raise ValueError(f'{where} = {quote(raw)} must be a mapping')
    raw = schema.canonical_segment(where, raw)
    key = _rate(where, raw)[0]
    value = _number(where, key, raw[key])
    if 'temp_c' not in raw:
        raise ValueError(f'{where}.temp_c = None is not a finite number')
    if 'duration_s' in raw:
        _number(where, 'duration_s', raw['duration_s'], 0.0, 86400.0, True)
    for given in ('accel_m_s2', 'linear_accel_m_s2'):
        if given in raw:
            raise ValueError(f'{where}: {given} is not played: the player commands the rate '
                             'and temp_c only, and the node turns gravity with the rate '
                             '(publish cmd/linear_acceleration, the applied acceleration, '
                             'yourself)')
    segment = schema.parse_segment(where, raw, axis, default_accel_m_s2=None)
    return _constant_step(where, segment, f'{value:g} {RATE_LABELS[key]}')


def _grid(where, raw, axis):
    if not isinstance(raw, dict):
        raise ValueError(f'{where} = {quote(raw)} must be a mapping')
    plural, key = _rate(where, raw, plural=True)
    raw = dict(raw)
    if 'temperatures_c' in raw and 'temps_c' not in raw:
        warnings.warn(f'{where}: temperatures_c is deprecated, write temps_c',
                      DeprecationWarning, stacklevel=3)
        raw['temps_c'] = raw.pop('temperatures_c')
    allowed = {'temps_c', 'hold_s', 'settle_s', plural}
    unknown = sorted(set(raw) - allowed)
    if unknown:
        raise ValueError(f'{where}: unknown key(s) {", ".join(unknown)}; allowed: '
                         f'{", ".join(sorted(allowed))}')
    temps, rates = raw.get('temps_c'), raw[plural]
    for name, values in (('temps_c', temps), (plural, rates)):
        if not isinstance(values, list) or not values:
            raise ValueError(f'{where}.{name} = {quote(values)} must be a non-empty list')
    hold = raw.get('hold_s')
    steps = []
    for temp in temps:
        for rate in rates:
            steps.append(_step(f'{where}[T={temp}, {plural}={rate}]', {
                'duration_s': hold, key: rate, 'temp_c': temp,
                'settle_s': raw.get('settle_s', 0.0)}, axis))
    return steps


def parse_scenario(doc, source='profile'):
    """
    Build a :class:`Scenario` from a parsed YAML mapping.

    Raises ValueError naming the key, the value and the allowed range.
    """
    if not isinstance(doc, dict):
        raise ValueError(f'{source}: expected a mapping, got {quote(doc)}')
    allowed = {'name', 'description', 'axis', 'publish_rate_hz', 'grid', 'segments',
               'node_parameters', 'faults'}
    unknown = sorted(set(doc) - allowed)
    if unknown:
        raise ValueError(f'{source}: unknown key(s) {", ".join(unknown)}; allowed: '
                         f'{", ".join(sorted(allowed))}')
    axis = schema.unit_axis(source, doc.get('axis', list(schema.DEFAULT_AXIS)))
    rate_hz = _number(source, 'publish_rate_hz', doc.get('publish_rate_hz', 50.0),
                      0.0, 1000.0, True)
    steps = []
    if 'grid' in doc:
        steps += _grid(f'{source}.grid', doc['grid'], axis)
    segments = doc.get('segments', [])
    if not isinstance(segments, list):
        raise ValueError(f'{source}.segments = {quote(segments)} must be a list')
    steps += [_step(f'{source}.segments[{i}]', s, axis) for i, s in enumerate(segments)]
    if not steps:
        raise ValueError(f'{source}: no steps (give grid and/or segments)')
    node_parameters = doc.get('node_parameters') or {}
    if not isinstance(node_parameters, dict):
        raise ValueError(f'{source}.node_parameters = {quote(node_parameters)} must be a mapping')
    schedule = faults.parse_schedule(f'{source}.faults', doc.get('faults'))
    return Scenario(str(doc.get('name', os.path.basename(str(source)))),
                    axis, rate_hz, tuple(steps),
                    dict(node_parameters), schedule)


def default_profile_path():
    """Return the shipped paper-validation profile (see ``resources.config_dir``)."""
    return config_file(DEFAULT_PROFILE)


def load_scenario(path=None):
    """Read and parse a scenario YAML (default: the paper validation scenario)."""
    path = default_profile_path() if path is None else path
    return parse_scenario(read_yaml(path), path)


# --- the summary -----------------------------------------------------------

@dataclass(frozen=True)
class StepResult:
    """Commanded vs measured for one step (rates along the axis, deg/s; the step a Segment)."""

    step: schema.Segment
    commanded_deg_s: float
    measured_deg_s: float
    std_deg_s: float
    die_temp_c: float
    samples: int

    @property
    def error_deg_s(self):
        """Measured minus commanded rate, deg/s."""
        return self.measured_deg_s - self.commanded_deg_s


def summarize(profile, start_ns, imu, temps):
    """
    Average the output over each step's measurement window.

    Parameters
    ----------
    profile : Scenario
        The scenario that was played.
    start_ns : int
        Clock time at which the first step began, ns.
    imu : list of (int, tuple)
        (stamp ns, angular velocity (x, y, z) rad/s) of every Imu received.
    temps : list of (int, float)
        (stamp ns, die temperature deg C) of every Temperature received.

    Returns
    -------
    list of StepResult

    """
    stamps = np.array([s for s, _ in imu], dtype=np.int64)
    along = np.array([sum(a * w for a, w in zip(profile.axis, v)) for _, v in imu])
    t_stamps = np.array([s for s, _ in temps], dtype=np.int64)
    t_values = np.array([v for _, v in temps])
    results = []
    begin = start_ns
    for step in profile.steps:
        lo = begin + int(step.settle_s * 1e9)
        hi = begin + int(step.duration_s * 1e9)
        begin = hi
        sel = along[(stamps >= lo) & (stamps < hi)] if len(stamps) else along
        tsel = t_values[(t_stamps >= lo) & (t_stamps < hi)] if len(t_stamps) else t_values
        measured = float(np.degrees(sel.mean())) if len(sel) else float('nan')
        std = float(np.degrees(sel.std())) if len(sel) > 1 else float('nan')
        results.append(StepResult(
            step, math.degrees(profile.rate_along_axis_rad_s(step)), measured, std,
            float(tsel.mean()) if len(tsel) else float('nan'), int(len(sel))))
    return results


def _cell(value, width, spec):
    """Format a number for the table; '-' where there is none (NaN)."""
    return f'{value:>{width}{spec}}' if math.isfinite(value) else f'{"-":>{width}}'


def format_summary(results):
    """Return the summary table as text (one row per step; "no samples" where none came)."""
    head = (f'{"step":>4} {"T_amb C":>8} {"T_die C":>8} {"rate":>10} {"cmd deg/s":>10} '
            f'{"meas deg/s":>11} {"err deg/s":>10} {"std deg/s":>10} {"n":>6}')
    lines = [head, '-' * len(head)]
    for i, r in enumerate(results):
        row = (f'{i:>4} {r.step.temp_start_c:>8.1f} {_cell(r.die_temp_c, 8, ".2f")} '
               f'{r.step.label:>10} {r.commanded_deg_s:>10.3f} ')
        if r.samples:
            row += (f'{r.measured_deg_s:>11.3f} {r.error_deg_s:>+10.3f} '
                    f'{_cell(r.std_deg_s, 10, ".3f")} {r.samples:>6d}')
        else:
            row += f'{"no samples":>33} {0:>6d}'
        lines.append(row)
    return '\n'.join(lines)


def describe_step(index, step):
    """Name a step for a message: ``step 3 (10 RPM at 25 C)`` (numbered from 1)."""
    return f'step {index + 1} ({step.label} at {step.temp_start_c:g} C)'


def unmeasured(results):
    """
    Name the steps that got no output sample in their measurement window.

    Returns
    -------
    str or None
        E.g. "step 1 (0 RPM at 25 C) and step 2 (10 RPM at 25 C) got no Imu
        sample after their settle time"; None when every step has samples.

    """
    empty = [describe_step(i, r.step) for i, r in enumerate(results) if not r.samples]
    if not empty:
        return None
    names = empty[0] if len(empty) == 1 else ', '.join(empty[:-1]) + ' and ' + empty[-1]
    return f'{names} got no Imu sample after {"its" if len(empty) == 1 else "their"} settle time'


def interruption_note(profile, start_ns, stop_ns):
    """
    Say where a stopped profile stopped, and which steps it did not finish.

    Parameters
    ----------
    profile : Scenario
        The profile that was played.
    start_ns, stop_ns : int or None
        Clock times (ns) at which the first step began and the player
        stopped; ``start_ns`` None when it stopped before the first step.

    Returns
    -------
    str
        One line, e.g. "interrupted at 12.3 s of 32 s, in step 3 of 8: steps
        3-8 were not finished (NaN where no sample was taken)".

    """
    count = len(profile.steps)
    if start_ns is None or stop_ns is None:
        return f'interrupted before the first step: none of the {count} steps was played'
    elapsed = (stop_ns - start_ns) / 1e9
    end = 0.0
    for index, step in enumerate(profile.steps):
        end += step.duration_s
        if elapsed < end:
            break
    else:
        return f'interrupted after the last step ({elapsed:.1f} s of {profile.duration_s:g} s)'
    steps = f'step {index + 1}' if index + 1 == count else f'steps {index + 1}-{count}'
    return (f'interrupted at {elapsed:.1f} s of {profile.duration_s:g} s, in step '
            f'{index + 1} of {count}: {steps} {"was" if index + 1 == count else "were"} not '
            'finished (no samples where none was taken)')


def number_or_none(value):
    """Return ``value``, or None (JSON null) where it is not a number (no samples)."""
    return value if math.isfinite(value) else None


def results_json(profile, results, interrupted=None):
    """
    Return the summary as a JSON-ready dict (``interrupted``: the note, when it was).

    A figure with no samples behind it is null; ``unmeasured`` names those steps.
    """
    doc = {'profile': profile.name, 'axis': list(profile.axis)}
    if interrupted:
        doc['interrupted'] = interrupted
    missing = unmeasured(results)
    if missing:
        doc['unmeasured'] = missing
    doc['steps'] = [
        {'temperature_c': r.step.temp_start_c, 'rate': r.step.label,
         'commanded_deg_s': r.commanded_deg_s,
         'measured_deg_s': number_or_none(r.measured_deg_s),
         'error_deg_s': number_or_none(r.error_deg_s),
         'std_deg_s': number_or_none(r.std_deg_s),
         'die_temp_c': number_or_none(r.die_temp_c), 'samples': r.samples} for r in results]
    return doc
