"""
The extended model ``diagnose --write-config`` writes: a sensor YAML the emulator loads.

The file is the starting configuration (a preset's YAML or the user's) plus
every cause diagnose *selected*, written as the emulator term of the same
name with diagnose's fitted values (``selected[i].parameters[name].value``
of the JSON), so that :func:`gyro_emulator.sensor.config.load_sensor_config`
reads it. Where a cause goes:

* the eight causes of :data:`gyro_emulator.sensor.extensions.TERM_TYPES`:
  ``extended.<cause id>`` with diagnose's parameter names and units;
  ``start_time_s`` is the record time of the first sample (the origin of the
  warm-up and of the pressure drift) and ``time_origin_s`` mid-record (the
  origin of diagnose's time polynomials, :attr:`.effects.Context.mid_time_s`);
  ``scale_factor_temperature`` gets diagnose's reference temperature;
* ``bias_temperature``: added to ``bias_temp_coeff_rad_s_k`` and
  ``bias_temp_coeff2_rad_s_k2`` (about the device's calibration
  temperature: re-centred when diagnose's reference differs);
* ``g_sensitivity``: added to the diagnosed axis's row of
  ``g_sensitivity_rad_s_m_s2``.

Per-axis amplitudes go to the diagnosed axis; the two others get 0 (the
record does not measure them) and the file says so. A cause with no exact
emulator term (:data:`NO_TERM`) and a cause diagnose calls only suggestive
are written commented out, with the reason: never active. Above the data a
comment block gives the provenance: the source log, each cause's gains,
p-value and 1-sigma intervals, and what could not be told apart.

:func:`extended_model` builds the :class:`ExtendedModel` once: the
:class:`~gyro_emulator.sensor.config.SensorConfig` with every cause added,
and the keys it is written with (the starting file's keys keep their order
and spelling; a field diagnose changes is written under its own name after
them). ``--noise`` adds the record's noise terms to that configuration
(:meth:`ExtendedModel.with_noise`), and
:func:`gyro_emulator.sensor.config.config_yaml` writes it: no text is read
back.
"""

from dataclasses import dataclass, replace
import os

from gyro_emulator import atomic, outputs
from gyro_emulator.analysis.diagnose import emulated
from gyro_emulator.resources import read_yaml
from gyro_emulator.sensor.accel import YAML_ALIASES as ACCEL_ALIASES
from gyro_emulator.sensor.config import (config_from_mapping, config_yaml, PRESET_NAMES,
                                         preset_path, SensorConfig, YAML_ALIASES, YamlKey)
from gyro_emulator.sensor.extensions import TERM_TYPES
from gyro_emulator.units import AXES, rad_s_to_deg_s
import numpy as np

#: Diagnose parameters of each extended term: 'axis' (per-axis amplitude) or 'scalar'.
TERMS = {
    'bias_hysteresis': {'hysteresis_width_k': 'scalar', 'bias_hysteresis_rad_s': 'axis'},
    'bias_time': {'warmup_time_constant_s': 'scalar', 'warmup_rad_s': 'axis',
                  'bias_drift_rad_s_per_h': 'axis'},
    'bias_step': {'step_time_s': 'scalar', 'bias_step_rad_s': 'axis'},
    'temperature_rate_bias': {'gradient_time_constant_s': 'scalar',
                              'bias_per_temp_rate_rad_s_per_k_s': 'axis'},
    'pressure_drift': {'pressure_rate_per_h': 'scalar'},
    'scale_factor_temperature': {'sf_temp_coeff_per_k': 'axis', 'sf_temp_coeff2_per_k2': 'axis'},
    'scale_factor_time': {'sf_drift_per_h': 'axis', 'sf_drift2_per_h2': 'axis'},
    'scale_factor_step': {'step_time_s': 'scalar', 'sf_step': 'axis'},
}
#: Terms whose time polynomial diagnose fits about mid-record.
MID_ORIGIN = ('bias_time', 'scale_factor_time')
#: Causes the emulator has no exact term for: the reason.
NO_TERM = {
    'scale_factor_nonlinearity': 'the emulator has the quadratic nonlinearity_s_rad but no '
                                 'cubic term in the rate',
    'mode_split_drift': 'the emulator has no mode split that drifts with temperature',
    'time_delay': 'the emulator has no delay of the output behind the applied rate',
    'thermal_lag': 'the emulator has no lag of the structure temperature behind the reading',
    'viscosity_temperature': 'the Sutherland law is a field of the device; this writer does '
                             'not change the device',
}


def start_mapping(config):
    """Return (parsed YAML mapping, path) of a preset name or a sensor YAML file."""
    path = preset_path(config) if config in PRESET_NAMES else config
    if not os.path.isfile(path):
        raise ValueError(f'sensor config {config!r} is neither a preset '
                         f'({", ".join(PRESET_NAMES)}) nor a readable file')
    mapping = read_yaml(path) or {}
    if not isinstance(mapping, dict):
        raise ValueError(f'{path}: a sensor config must be a mapping')
    return mapping, path


@dataclass(frozen=True)
class ExtendedModel:
    """
    The extended sensor model before it is text: the configuration and how it is written.

    ``config`` is the :class:`~gyro_emulator.sensor.config.SensorConfig`,
    ``layout`` its keys in order (:class:`~gyro_emulator.sensor.config.YamlKey`),
    ``header`` the provenance comment block, ``axis`` the diagnosed axis and
    ``commented`` the causes written commented out: (cause id, values, reason);
    ``noise`` whether the record's noise terms were added (:meth:`with_noise`).
    """

    config: SensorConfig
    layout: tuple
    header: str
    axis: str
    commented: tuple
    noise: bool = False

    @property
    def warnings(self):
        """Return (cause id, reason) of every cause written commented out."""
        return [(cause, why) for cause, _, why in self.commented]

    def text(self):
        """Return the sensor YAML (:func:`gyro_emulator.sensor.config.config_yaml`)."""
        footer = ''.join(f'  # {c}: {v}   # not active: {why}\n' for c, v, why in self.commented)
        return config_yaml(self.config, self.layout, self.header,
                           _comments(self.axis, self.config, self.noise), footer)

    def with_measured_range(self, data):
        """
        Return this model with the diagnosed axis's full scale covering what the record measured.

        Where the record's output on the diagnosed axis lies beyond the
        configuration's ``range_rad_s`` and the applied rate drives the
        model's noise-free output beyond it too, the part measured more than
        the configuration's full scale: the emulator would clip there, and
        ``simulate --config OUT --profile RECORD`` would miss the record by
        the clipped share, which diagnose's claim does not hold. The axis's
        range becomes the larger of the model's unclipped noise-free output
        over the record and the record's output at those samples; the header
        says so. A record that stays within the range (or is pinned at it),
        or a configuration without saturation, changes nothing.
        """
        i = AXES.index(self.axis)
        old = self.config.range_rad_s[i]
        measured = np.abs(np.asarray(data.gyro_rad_s, dtype=float))
        if not self.config.terms.saturation or not np.any(measured > old):
            return self
        free = replace(self.config, terms=replace(self.config.terms, saturation=False))
        unclipped = np.abs(emulated.emulated_output(free, data, self.axis))
        driven = unclipped > old
        if not np.any(driven & (measured > old)):
            return self
        new = float(max(np.max(unclipped), np.max(measured[driven])))
        ranges = list(self.config.range_rad_s)
        ranges[i] = new
        config = _checked(replace, self.config, range_rad_s=tuple(ranges))
        layout = {key.name: key for key in self.layout}
        _rewrite(layout, 'range_rad_s')
        header = self.header + (
            f'# Full scale of axis {self.axis} widened from {old:.6g} to {new:.6g} rad/s '
            f'({float(rad_s_to_deg_s(new)):.6g} deg/s): the record measured up to '
            f'{float(np.max(measured[driven])):.6g} rad/s where the applied rate drives '
            'the model beyond the starting range, which would clip it.\n')
        return replace(self, config=config, layout=tuple(layout.values()), header=header)

    def with_noise(self, noise):
        """
        Return this model with the record's noise terms (:mod:`.record_noise`).

        The diagnosed axis gets N, B, K, the turn-on bias and the LSB; the
        other two keep the starting configuration's values. The flicker band
        and the switches are shared by the axes: the band is the record's;
        the terms the record measures are switched on and mechanical_noise
        off (the measured N carries the whole white noise), as ``calibrate
        noise --format preset`` does. An axis whose record shows no LSB gets 0.
        The output low-pass the record's PSD shows (cut-off and order) is
        written with its switch on; without one the starting configuration's
        filter stays as it is.
        """
        i = AXES.index(self.axis)
        layout = {key.name: key for key in self.layout}
        changes = {}
        values = dict(noise.fields.per_axis[self.axis])
        lsb = noise.fields.shared.get('lsb_deg_s', 0.0)
        for key, value in list(values.items()) + [('lsb_deg_s', lsb)]:
            target, convert = YAML_ALIASES[key]
            old = list(getattr(self.config, target))
            old[i] = convert(value)
            changes[target] = tuple(old)
            _rewrite(layout, target)
        for key in ('bias_instability_band_s', 'bias_instability_per_decade',
                    'output_filter_hz', 'output_filter_order'):
            if key in noise.fields.shared:      # the filter: when the record shows one
                changes[key] = noise.fields.shared[key]
                layout[key] = YamlKey(key)
        names = _switch_names(layout) + [t for t in sorted(noise.fields.terms_on)
                                         if t not in _switch_names(layout)]
        switches = dict.fromkeys(noise.fields.terms_on, True)
        switches['mechanical_noise'] = False       # the measured N is the whole white noise
        layout['terms'] = YamlKey('terms', parts=tuple(YamlKey(n) for n in dict.fromkeys(
            names + ['mechanical_noise'])))
        config = _checked(replace, self.config, terms=replace(self.config.terms, **switches),
                          **changes)
        header = self.header + ''.join(f'# {line}\n' for line in noise.comment_lines())
        return replace(self, config=config, layout=tuple(layout.values()), header=header,
                       noise=True)

    def with_accel_noise(self, accel):
        """
        Return this model with the record's accelerometer noise (``record_noise.identify_accel``).

        ``accel`` None (the record has no accelerometer) changes nothing. The
        accelerometer's N, B, K, turn-on bias, flicker band and LSB replace the
        starting configuration's, with the same switches as ``calibrate noise
        --format preset`` (mechanical_noise off); its other settings (range,
        temperature terms) stay. Not identified, the header says why.
        """
        if accel is None:
            return self
        header = self.header + ''.join(f'# {line}\n' for line in accel.comment_lines())
        if accel.fields is None:
            return replace(self, header=header)
        start = self.config.accelerometer
        changes = {name: tuple(v[name] for v in _per_axis(accel.fields.per_axis))
                   for name in next(iter(accel.fields.per_axis.values()))}
        changes.update(accel.fields.shared)
        changes['terms'] = replace(start.terms, mechanical_noise=False, **dict.fromkeys(
            accel.fields.terms_on, True))
        accelerometer = _checked(replace, start, **changes)
        config = _checked(replace, self.config, accelerometer=accelerometer)
        layout = {key.name: key for key in self.layout}
        layout['accelerometer'] = _accel_key(layout.get('accelerometer'), changes)
        return replace(self, config=config, layout=tuple(layout.values()), header=header)


def _per_axis(per_axis):
    """Return the three axes' fields of a calibration: an axis it lacks copies the first."""
    return [per_axis.get(a) or next(iter(per_axis.values())) for a in AXES]


def _accel_key(start, changes):
    """
    Return the ``accelerometer`` key: the starting one's settings, then ``changes`` (SI names).

    A starting setting ``changes`` replaces, directly or through a datasheet
    alias, is dropped; the switches are written whole.
    """
    given = {} if start is None or start.given is None else dict(start.given)
    replaced = set(changes)
    parts = [YamlKey(k, given=v) for k, v in given.items() if k != 'terms' and
             (ACCEL_ALIASES[k][0] if k in ACCEL_ALIASES else k) not in replaced]
    return YamlKey('accelerometer', parts=(YamlKey('terms'), *parts,
                                           *(YamlKey(n) for n in changes if n != 'terms')))


def _checked(make, *args, **kwargs):
    """Return ``make(*args, **kwargs)``; a value out of the emulator's range names the file."""
    try:
        return make(*args, **kwargs)
    except ValueError as exc:
        raise ValueError(f'the written config: {exc}') from None


def _switch_names(layout):
    """Return the switches the ``terms`` key of ``layout`` writes (none when it has none)."""
    key = layout.get('terms')
    return [] if key is None else [p.name for p in key.parts]


def _rewrite(layout, target):
    """Drop ``target`` and its aliases from ``layout``; write it under its own name, last."""
    for key in [k for k, (t, _) in YAML_ALIASES.items() if t == target] + [target]:
        layout.pop(key, None)
    layout[target] = YamlKey(target)


def _axis_value(axis, value):
    return tuple(value if a == axis else 0.0 for a in AXES)


def _values(cause):
    return {name: p.value for name, p in cause.parameters.items()}


def _term(cause, values, axis, diagnosis):
    """Return (the ``extended`` term of ``cause`` with diagnose's values, its key)."""
    fields = {}
    for name, kind in TERMS[cause].items():
        if name in values:      # a polynomial cut to order 1 has no quadratic term
            fields[name] = _axis_value(axis, values[name]) if kind == 'axis' else values[name]
    if cause in MID_ORIGIN:
        fields['time_origin_s'] = sum(diagnosis.record.time_span_s) / 2
    if cause == 'scale_factor_temperature':
        fields['ref_temp_c'] = diagnosis.calibration.ref_temp_c
    fields['enabled'] = True
    term = _checked(TERM_TYPES[cause], **fields)
    return term, YamlKey(cause, parts=tuple(YamlKey(n) for n in fields))


def _bias_temperature(start, values, axis, diagnosis):
    """Return diagnose's bias polynomial added, about the device's calibration temperature."""
    i = AXES.index(axis)
    c1 = values.get('bias_temp_coeff_rad_s_k', 0.0)
    c2 = values.get('bias_temp_coeff2_rad_s_k2', 0.0)
    shift = start.device[i].calibration_temp_c - diagnosis.calibration.ref_temp_c
    out = {}
    for target, add in (('bias_temp_coeff_rad_s_k', c1 + 2.0 * c2 * shift),
                        ('bias_temp_coeff2_rad_s_k2', c2)):
        old = list(getattr(start, target))
        old[i] += add
        out[target] = tuple(old)
    return out


def _g_sensitivity(start, values, axis):
    """Return diagnose's g-sensitivity added to the diagnosed axis's row of the matrix."""
    i = AXES.index(axis)
    rows = [list(r) for r in start.g_sensitivity_rad_s_m_s2]
    for j, a in enumerate(AXES):
        rows[i][j] += values[f'g_sensitivity_{a}_rad_s_per_m_s2']
    return {'g_sensitivity_rad_s_m_s2': tuple(tuple(r) for r in rows)}


def _flow_text(values):
    return '{' + ', '.join(f'{k}: {v:.6g}' for k, v in values.items()) + '}'


def _suggestive(diagnosis):
    """Return the suggestive candidate as a commented-out cause, or None."""
    hint = diagnosis.residual.suggestive
    if hint is None:
        return None
    found = [f for f in diagnosis.findings if f.effect == hint.effect]
    values = _flow_text(_values(found[0])) if found and not diagnosis.selected else '{}'
    return (hint.effect, values,
            f'suggestive, not established (gain {100 * hint.gain:.0f} %, '
            f'p = {hint.p_value:.2g} before the correction for the candidates)')


def _causes(diagnosis, start, axis, path):
    """
    Return what the selected causes add: (fields, switches, terms and their keys, commented).

    Raises ValueError for a cause whose term the starting configuration has on already.
    """
    fields, switches, terms, commented = {}, {}, {}, []
    for cause in diagnosis.selected:
        name, values = cause.effect, _values(cause)
        if name in NO_TERM:
            commented.append((name, _flow_text(values), NO_TERM[name]))
            continue
        if name in TERMS:
            if start.extended.get(name) is not None:
                raise ValueError(f'{path}: extended.{name} is already on and diagnose found '
                                 f'{name} again: one term per cause; edit the term instead')
            terms[name] = _term(name, values, axis, diagnosis)
        elif name == 'bias_temperature':
            fields.update(_bias_temperature(start, values, axis, diagnosis))
            switches[name] = True
        elif name == 'g_sensitivity':
            fields.update(_g_sensitivity(start, values, axis))
            switches[name] = True
        else:
            raise ValueError(f'diagnose found {name!r}, which no emulator term models')
    return fields, switches, terms, commented


def _extended(start, given, terms, diagnosis):
    """Return (the extended terms, the ``extended`` key): the start's terms, then the new ones."""
    parts = {name: YamlKey(name, given=value) for name, value in given.items()}
    parts.update({name: key for name, (_, key) in terms.items()})
    ext = start.extended
    if any(name != 'start_time_s' for name in parts):
        start_s = (ext.start_time_s if 'start_time_s' in given
                   else diagnosis.record.time_span_s[0])
        first = parts.pop('start_time_s', YamlKey('start_time_s'))
        parts = {'start_time_s': first, **parts}
        ext = replace(ext, start_time_s=start_s, **{n: t for n, (t, _) in terms.items()})
    return ext, YamlKey('extended', parts=tuple(parts.values()))


def extended_model(diagnosis, config, axis='z', config_name='paper', device=None):
    """
    Return the extended sensor model of a diagnosis (:class:`ExtendedModel`).

    Parameters
    ----------
    diagnosis : gyro_emulator.analysis.diagnose.diagnosis.Diagnosis
        What diagnose found.
    config : str
        Starting configuration: a preset name or a sensor YAML file.
    axis : str
        The diagnosed axis, 'x', 'y' or 'z': it gets the per-axis amplitudes.
    config_name : str
        How the header names the starting configuration.
    device : str, optional
        Physics preset that replaces the configuration's ``device`` (the
        device diagnose's baseline used).

    Raises
    ------
    ValueError
        The starting configuration already has an active term of a cause
        diagnose found again, or a value is out of the emulator's range.

    """
    if axis not in AXES:
        raise ValueError(f'diagnose.axis = {axis!r} is not allowed: choose x, y or z')
    mapping, path = start_mapping(config)
    if device is not None:
        mapping['device'] = device
    start = config_from_mapping(dict(mapping), source=path)
    given = dict(mapping.pop('extended', None) or {})
    layout = {key: YamlKey(key, given=value) for key, value in mapping.items()}
    if 'terms' in layout:
        layout['terms'] = YamlKey('terms', parts=tuple(YamlKey(n) for n in mapping['terms']))
    fields, switches, terms, commented = _causes(diagnosis, start, axis, path)
    for target in fields:
        _rewrite(layout, target)
    hint = _suggestive(diagnosis)
    if hint is not None:
        commented.append(hint)
    ext, layout['extended'] = _extended(start, given, terms, diagnosis)
    built = _checked(replace, start, terms=replace(start.terms, **switches), extended=ext,
                     **fields)
    active = [e.effect for e in diagnosis.selected if e.effect not in NO_TERM]
    return ExtendedModel(built, tuple(layout.values()),
                         _header(diagnosis, config_name, axis, active), axis, tuple(commented))


#: Per-axis fields ``with_noise`` writes for the diagnosed axis.
NOISE_FIELDS = ('electronics_noise_rad_s_sqrt_hz', 'bias_instability_rad_s',
                'rate_random_walk_rad_s_sqrt_s', 'turn_on_bias_rad_s', 'lsb_rad_s')


def _per_axis_comment(config, name, axis):
    """Say what the diagnosed axis's value is and, truly, where the other axes' come from."""
    others = [a for a in AXES if a != axis]
    values = [getattr(config, name)] if hasattr(config, name) else []
    values += [getattr(t, name) for t in (getattr(config.extended, n) for n in TERM_TYPES)
               if t is not None and hasattr(t, name)]
    if all(v[AXES.index(a)] == 0.0 for v in values for a in others):
        return f'diagnosed axis {axis}; {", ".join(others)} 0: not measured'
    return (f"diagnosed axis {axis}; {', '.join(others)}: the starting configuration's, not "
            'measured here')


def _comments(axis, config, noise=False):
    names = [name for kinds in TERMS.values() for name, kind in kinds.items() if kind == 'axis']
    names += ['bias_temp_coeff_rad_s_k', 'bias_temp_coeff2_rad_s_k2']
    names += list(NOISE_FIELDS) if noise else []
    out = {name: _per_axis_comment(config, name, axis) for name in names}
    out.update({'g_sensitivity_rad_s_m_s2': f'row {axis}: diagnosed axis',
                'start_time_s': 'record time of the first sample, s',
                'time_origin_s': "mid-record: the origin of diagnose's time polynomials, s",
                'ref_temp_c': "diagnose's reference temperature, C",
                'pressure_rate_per_h': 'the cavity of every axis'})
    return out


def _header(diagnosis, config_name, axis, active):
    """Return the provenance comment block."""
    inp = diagnosis.record
    t0, t1 = inp.time_span_s
    lines = [
        'Extended sensor model written by gyro-emulator diagnose --write-config.',
        f'Starting configuration: {config_name}; added: {", ".join(active) or "nothing"}.',
        f'Source log: {inp.source} ({inp.rows} samples, record time {t0:.6g} .. '
        f'{t1:.6g} s); diagnosed axis {axis}; reference temperature '
        f'{diagnosis.calibration.ref_temp_c:.6g} C.',
        f'Verdict: {diagnosis.verdict}; baseline held-out RMSE '
        f'{diagnosis.baseline.rmse_rad_s:.4g} rad/s.',
        'Parameters below: the value of the step that selected the cause, '
        '+- 1 sigma (the larger of the delete-a-block jackknife and the sandwich '
        "under the record's noise law)."]
    for i, e in enumerate(diagnosis.selected, 1):
        lines.append(
            f'Cause {i}: {e.effect} ({e.kind}): gain over the baseline '
            f'{100 * e.gain:.2f} %, this step {100 * e.gain_step:.2f} % per sample and '
            f'{100 * e.gain_binned:.2f} % on super-bin means (gain_binned); '
            f'p = {e.p_value:.2g}.')
        for name, p in e.parameters.items():
            lines.append(f'  {name} = {p.value:.6g} +- {p.sigma:.2g} {p.unit}')
        if e.indistinguishable_from:
            lines.append(f"  cannot be told from: {', '.join(e.indistinguishable_from)}")
    for c in diagnosis.confounded:
        lines.append(f'Confounded in this record: {c.a} and {c.b} '
                     f'(r = {c.correlation:+.4f}).')
    pair = diagnosis.confounded_pair
    if pair:
        lines.append(f'Not separated: {pair.text}; to tell them apart, {pair.experiment}.')
    return ''.join(f'# {line}\n' for line in lines)


def write_text(path, text, overwrite=False):
    """Write ``text`` to ``path`` atomically (:func:`gyro_emulator.atomic.write_text`)."""
    check_target(path, overwrite)
    atomic.write_text(path, text)


def check_target(path, overwrite):
    """Raise ValueError for an existing ``path`` unless ``overwrite`` (one check: outputs)."""
    outputs.check([outputs.file('--write-config', path)], overwrite=overwrite)
