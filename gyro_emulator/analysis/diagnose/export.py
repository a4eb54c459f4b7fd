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
"""

import os
import tempfile

from gyro_emulator.analysis.calibrate.yaml_text import dump, Figure, Flow
from gyro_emulator.sensor.config import (config_from_mapping, PRESET_NAMES, preset_path,
                                         YAML_ALIASES)
from gyro_emulator.units import AXES
import yaml

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
    with open(path, encoding='utf-8') as f:
        mapping = yaml.safe_load(f) or {}
    if not isinstance(mapping, dict):
        raise ValueError(f'{path}: a sensor config must be a mapping')
    return mapping, path


def _axis_value(axis, value):
    return Flow([Figure(value if a == axis else 0.0, '') for a in AXES])


def _values(entry):
    return {name: p['value'] for name, p in entry['parameters'].items()}


def _term(cause, values, axis, doc):
    """Return the ``extended`` sub-block of ``cause`` with diagnose's values."""
    out = {}
    for name, kind in TERMS[cause].items():
        if name in values:      # a polynomial cut to order 1 has no quadratic term
            out[name] = (_axis_value(axis, values[name]) if kind == 'axis'
                         else Figure(values[name], ''))
    if cause in MID_ORIGIN:
        out['time_origin_s'] = Figure(sum(doc['input']['time_span_s']) / 2, '')
    if cause == 'scale_factor_temperature':
        out['ref_temp_c'] = Figure(doc['calibration']['ref_temp_c'], '')
    out['enabled'] = True
    return out


def _canonical(mapping, target, config):
    """Remove ``target`` and its aliases from ``mapping``; return its value in ``config``."""
    for key in [k for k, (t, _) in YAML_ALIASES.items() if t == target] + [target]:
        mapping.pop(key, None)
    return getattr(config, target)


def _add_bias_temperature(mapping, config, values, axis, doc):
    """Add diagnose's bias polynomial, re-centred on the device's calibration temperature."""
    i = AXES.index(axis)
    c1 = values.get('bias_temp_coeff_rad_s_k', 0.0)
    c2 = values.get('bias_temp_coeff2_rad_s_k2', 0.0)
    shift = config.device[i].calibration_temp_c - doc['calibration']['ref_temp_c']
    for target, add in (('bias_temp_coeff_rad_s_k', c1 + 2.0 * c2 * shift),
                        ('bias_temp_coeff2_rad_s_k2', c2)):
        old = list(_canonical(mapping, target, config))
        old[i] += add
        mapping[target] = Flow([Figure(v, '') for v in old])
    _switch_on(mapping, 'bias_temperature')


def _add_g_sensitivity(mapping, config, values, axis):
    """Add diagnose's g-sensitivity to the diagnosed axis's row of the matrix."""
    i = AXES.index(axis)
    rows = [list(r) for r in _canonical(mapping, 'g_sensitivity_rad_s_m_s2', config)]
    for j, a in enumerate(AXES):
        rows[i][j] += values[f'g_sensitivity_{a}_rad_s_per_m_s2']
    mapping['g_sensitivity_rad_s_m_s2'] = [Flow([Figure(v, '') for v in r]) for r in rows]
    _switch_on(mapping, 'g_sensitivity')


def _switch_on(mapping, term):
    """Switch ``term`` on where the starting config switched it off (a twin has it off)."""
    terms = mapping.get('terms')
    if isinstance(terms, dict) and terms.get(term) is False:
        mapping['terms'] = dict(terms, **{term: True})


def _add_noise(mapping, config, noise, axis):
    """
    Write the record's noise terms (:mod:`.record_noise`) into ``mapping``.

    The diagnosed axis gets N, B, K, the turn-on bias and the LSB; the other
    two keep the starting configuration's values. The flicker band and the
    switches are shared by the axes: the band is the record's; the terms
    the record measures are switched on and mechanical_noise off (the
    measured N carries the whole white noise), as ``calibrate noise --format
    preset`` does. An axis whose record shows no LSB gets 0.
    """
    i = AXES.index(axis)
    values = dict(noise.fields.per_axis[axis])
    lsb = noise.fields.shared.get('lsb_deg_s', 0.0)
    for key, value in list(values.items()) + [('lsb_deg_s', lsb)]:
        target, convert = YAML_ALIASES[key]
        old = list(_canonical(mapping, target, config))
        old[i] = convert(value)
        mapping[target] = Flow([Figure(v, '') for v in old])
    for key in ('bias_instability_band_s', 'bias_instability_per_decade'):
        value = noise.fields.shared[key]
        mapping[key] = (Flow([Figure(v, '') for v in value]) if isinstance(value, tuple)
                        else Figure(value, ''))
    terms = dict(mapping.get('terms') or {})
    terms.update(dict.fromkeys(sorted(noise.fields.terms_on), True))
    terms['mechanical_noise'] = False       # the measured N is the whole white noise
    mapping['terms'] = terms


def _flow_text(values):
    return '{' + ', '.join(f'{k}: {v:.6g}' for k, v in values.items()) + '}'


def extended_model(doc, config, axis='z', config_name='paper', device=None, noise=None):
    """
    Return the text of the extended sensor YAML and the causes written commented out.

    Parameters
    ----------
    doc : dict
        A diagnosis (:attr:`.pipeline.Diagnosis.doc`).
    config : str
        Starting configuration: a preset name or a sensor YAML file.
    axis : str
        The diagnosed axis, 'x', 'y' or 'z': it gets the per-axis amplitudes.
    config_name : str
        How the header names the starting configuration.
    device : str, optional
        Physics preset that replaces the configuration's ``device`` (the
        device diagnose's baseline used).
    noise : gyro_emulator.analysis.diagnose.record_noise.RecordNoise, optional
        The record's noise terms (``--noise``): written to the diagnosed
        axis, with their intervals in the provenance comment. Without it the
        noise fields of the starting configuration stay as they are.

    Returns
    -------
    (str, list of (cause id, reason))

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
    ext = dict(mapping.pop('extended', None) or {})
    commented, active = [], []
    for entry in doc['selected']:
        cause, values = entry['effect'], _values(entry)
        if cause in NO_TERM:
            commented.append((cause, _flow_text(values), NO_TERM[cause]))
            continue
        if cause in TERMS:
            if start.extended.get(cause) is not None:
                raise ValueError(f'{path}: extended.{cause} is already on and diagnose found '
                                 f'{cause} again: one term per cause; edit the term instead')
            ext[cause] = _term(cause, values, axis, doc)
        elif cause == 'bias_temperature':
            _add_bias_temperature(mapping, start, values, axis, doc)
        elif cause == 'g_sensitivity':
            _add_g_sensitivity(mapping, start, values, axis)
        else:
            raise ValueError(f'diagnose found {cause!r}, which no emulator term models')
        active.append(cause)
    hint = doc['residual'].get('suggestive')
    if hint is not None:
        found = [f for f in doc['findings'] if f['effect'] == hint['effect']]
        values = _flow_text(_values(found[0])) if found and not doc['selected'] else '{}'
        commented.append((hint['effect'], values,
                          f"suggestive, not established (gain {100 * hint['gain']:.0f} %, "
                          f"p = {hint['p_value']:.2g} before the correction for the candidates)"))
    if any(k != 'start_time_s' for k in ext):
        start_s = ext.pop('start_time_s', Figure(doc['input']['time_span_s'][0], ''))
        ext = {'start_time_s': start_s, **ext}
    mapping['extended'] = ext or None
    header = _header(doc, config_name, axis, active)
    if noise is not None:
        _add_noise(mapping, start, noise, axis)
        header += ''.join(f'# {line}\n' for line in noise.comment_lines())
    text = header + dump(mapping, _comments(axis))
    if commented:
        text += ''.join(f'  # {c}: {v}   # not active: {why}\n' for c, v, why in commented)
    config_from_mapping(yaml.safe_load(text), source='the written config')   # it loads
    return text, [(c, why) for c, _, why in commented]


def _comments(axis):
    others = ', '.join(a for a in AXES if a != axis)
    per_axis = f'diagnosed axis {axis}; {others} 0: not measured'
    out = {name: per_axis for kinds in TERMS.values() for name, kind in kinds.items()
           if kind == 'axis'}
    out.update({'bias_temp_coeff_rad_s_k': per_axis, 'bias_temp_coeff2_rad_s_k2': per_axis,
                'g_sensitivity_rad_s_m_s2': f'row {axis}: diagnosed axis',
                'start_time_s': 'record time of the first sample, s',
                'time_origin_s': "mid-record: the origin of diagnose's time polynomials, s",
                'ref_temp_c': "diagnose's reference temperature, C",
                'pressure_rate_per_h': 'the cavity of every axis'})
    return out


def _header(doc, config_name, axis, active):
    """Return the provenance comment block."""
    inp = doc['input']
    t0, t1 = inp['time_span_s']
    lines = [
        'Extended sensor model written by gyro-emulator diagnose --write-config.',
        f'Starting configuration: {config_name}; added: {", ".join(active) or "nothing"}.',
        f"Source log: {inp['source']} ({inp['rows']} samples, record time {t0:.6g} .. "
        f'{t1:.6g} s); diagnosed axis {axis}; reference temperature '
        f"{doc['calibration']['ref_temp_c']:.6g} C.",
        f"Verdict: {doc['verdict']}; baseline held-out RMSE "
        f"{doc['baseline']['rmse_rad_s']:.4g} rad/s.",
        'Parameters below: the value of the step that selected the cause, '
        '+- 1 sigma (delete-a-block jackknife).']
    for i, e in enumerate(doc['selected'], 1):
        lines.append(
            f"Cause {i}: {e['effect']} ({e['kind']}): gain over the baseline "
            f"{100 * e['gain']:.2f} %, this step {100 * e['gain_step']:.2f} % per sample and "
            f"{100 * e['gain_binned']:.2f} % on super-bin means (gain_binned); "
            f"p = {e['p_value']:.2g}.")
        for name, p in e['parameters'].items():
            lines.append(f"  {name} = {p['value']:.6g} +- {p['sigma']:.2g} {p['unit']}")
        if e['indistinguishable_from']:
            lines.append(f"  cannot be told from: {', '.join(e['indistinguishable_from'])}")
    for c in doc['confounded']:
        lines.append(f"Confounded in this record: {c['a']} and {c['b']} "
                     f"(r = {c['correlation']:+.4f}).")
    pair = doc.get('confounded_pair')
    if pair:
        lines.append(f"Not separated: {pair['text']}; to tell them apart, "
                     f"{pair['experiment']}.")
    return ''.join(f'# {line}\n' for line in lines)


def write_text(path, text, overwrite=False):
    """Write ``text`` to ``path`` atomically (a temporary file, then ``os.replace``)."""
    check_target(path, overwrite)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix='.' + os.path.basename(path) + '.',
                               suffix='.tmp')
    try:
        with os.fdopen(fd, 'w', encoding='utf-8') as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def check_target(path, overwrite):
    """Raise ValueError for an existing ``path`` unless ``overwrite``."""
    if os.path.exists(path) and not overwrite:
        raise ValueError(f'{path} exists: give --overwrite to replace it')
    if os.path.isdir(path):
        raise ValueError(f'{path} is a directory: give a file name')
