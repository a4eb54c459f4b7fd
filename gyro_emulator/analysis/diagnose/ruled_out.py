"""
What the data rule out: a 95 % upper bound on every cause that was tested and not found.

A cause the record could test but that was not chosen is not thereby
absent: it may be smaller than the record can show. Its fit beside the
final model (the last selection step scored every remaining cause against
it) gives the size's 95 % interval (:mod:`.intervals`); the bound is the
end farther from zero, the largest size the data allow, in the unit a
datasheet gives it:

| cause | quantity | unit |
|---|---|---|
| ``bias_temperature`` | bias tempco, dT at T_ref | deg/s/K |
| ``scale_factor_temperature`` | SF tempco beyond the baseline's, at T_ref | ppm/K |
| ``g_sensitivity`` | g-sensitivity (the norm over the measured axes) | deg/s/g |
| ``scale_factor_nonlinearity`` | deviation at the largest rate (1) | % of that rate |
| ``scale_factor_time`` | SF drift at mid-record | ppm/h |
| ``scale_factor_step`` | SF step (at its best-fitting time) | ppm |
| ``bias_time`` | bias drift; warm-up amplitude | deg/s/h; deg/s |
| ``bias_step`` | bias step (at its best-fitting time) | deg/s |
| ``bias_hysteresis`` | half the gap between the heating and cooling branches | deg/s |
| ``temperature_rate_bias`` | bias per unit dT/dt | deg/s per K/min |
| ``time_delay`` | output delay | ms |
| ``pressure_drift`` | cavity pressure drift | %/h |
| ``thermal_lag`` | lag time constant (its upper end) | s |
| ``mode_split_drift`` | mode-split drift | Hz/K |
| ``viscosity_temperature`` | share of the Sutherland law's SF change (at its best S) | % |

(1) None on a record of one rate magnitude, where it is a scale factor
(:func:`nonlinearity_measured`).
"""

import math

from gyro_emulator.analysis.diagnose import intervals
from gyro_emulator.units import rad_s_per_m_s2_to_deg_s_per_g, rad_s_to_deg_s, ratio_to_ppm
import numpy as np

_PER_MIN = 60.0


def _far(e):
    """
    Return the end of an interval farther from zero (None: not measured).

    An end the profile likelihood left open (still admissible at the end of
    the searched range: a delay on a record whose rate never changes) is
    where the search stopped, not a bound of the data: None as well.
    """
    if e.interval is None:
        return None
    lo, hi = abs(e.interval[0]), abs(e.interval[1])
    if (e.open_low and lo >= hi) or (e.open_high and hi >= lo):
        return None
    return max(lo, hi)


def _scaled(name, factor):
    def bound(found, info):
        far = _far(found[name])
        return None if far is None else far * factor
    return bound


def _g_norm(found, info):
    fars = [_far(e) for e in found.values()]
    fars = [f for f in fars if f is not None]
    return None if not fars else float(rad_s_per_m_s2_to_deg_s_per_g(math.sqrt(sum(
        f * f for f in fars))))


#: Least share of the variance of rate^2 and rate^3 that a bias and a scale factor
#: leave, for a nonlinearity to be measured beside them.
MIN_SHAPE_SHARE = 1e-6


def nonlinearity_measured(rate_rad_s):
    """
    Tell whether a record's applied rates can measure a nonlinearity beside a calibration.

    The baseline calibrates a bias and a scale factor, so the part of
    rate^2 and rate^3 that is a line in the rate is theirs. On a record
    with one rate magnitude (0 and 0.5 rad/s: rate^2 = 0.5 rate; +-0.5
    rad/s: rate^3 = 0.25 rate) a deviation at the largest rate is a scale
    factor: no bound on it holds. Both powers must keep more than
    :data:`MIN_SHAPE_SHARE` of their variance about the best line.
    """
    rate = np.asarray(rate_rad_s, float)
    top = float(np.max(np.abs(rate))) if len(rate) else 0.0
    if not top > 0.0:
        return False
    x = rate / top
    line = np.column_stack([np.ones_like(x), x])
    for power in (2, 3):
        y = x ** power
        spread = float(np.var(y))
        resid = y - line @ np.linalg.lstsq(line, y, rcond=None)[0]
        if not spread > 0.0 or float(np.var(resid)) <= MIN_SHAPE_SHARE * spread:
            return False
    return True


def _nonlinearity(found, info):
    a2 = _far(found['nonlinearity_quadratic_s_rad'])
    a3 = _far(found['nonlinearity_cubic_s2_rad2'])
    if a2 is None or a3 is None or not info.get('nonlinearity_measured', True):
        return None
    rate = info['max_rate_rad_s']
    return 100.0 * (a2 * rate + a3 * rate * rate)


def _lag(found, info):
    e = found['thermal_time_constant_s']
    return None if e.interval is None or e.open_high else e.interval[1]


_DEG = float(rad_s_to_deg_s(1.0))
_PPM = float(ratio_to_ppm(1.0))

#: Per cause: (quantity, unit, bound of the found estimates and the record's facts).
BOUNDS = {
    'bias_temperature': [('bias tempco', 'deg/s/K', _scaled('bias_temp_coeff_rad_s_k', _DEG))],
    'scale_factor_temperature': [('SF tempco', 'ppm/K', _scaled('sf_temp_coeff_per_k', _PPM))],
    'g_sensitivity': [('g-sensitivity', 'deg/s/g', _g_norm)],
    'scale_factor_nonlinearity': [('SF nonlinearity at the largest rate', '% of that rate',
                                   _nonlinearity)],
    'scale_factor_time': [('SF drift', 'ppm/h', _scaled('sf_drift_per_h', _PPM))],
    'scale_factor_step': [('SF step', 'ppm', _scaled('sf_step', _PPM))],
    'bias_time': [('bias drift', 'deg/s/h', _scaled('bias_drift_rad_s_per_h', _DEG)),
                  ('warm-up', 'deg/s', _scaled('warmup_rad_s', _DEG))],
    'bias_step': [('bias step', 'deg/s', _scaled('bias_step_rad_s', _DEG))],
    'bias_hysteresis': [('bias hysteresis', 'deg/s', _scaled('bias_hysteresis_rad_s', _DEG))],
    'temperature_rate_bias': [('bias per dT/dt', 'deg/s per K/min',
                               _scaled('bias_per_temp_rate_rad_s_per_k_s', _DEG / _PER_MIN))],
    'time_delay': [('delay', 'ms', _scaled('delay_s', 1e3))],
    'pressure_drift': [('pressure drift', '%/h', _scaled('pressure_rate_per_h', 100.0))],
    'thermal_lag': [('thermal lag', 's', _lag)],
    'mode_split_drift': [('mode-split drift', 'Hz/K',
                          _scaled('mode_split_temp_coeff_hz_k', 1.0))],
    'viscosity_temperature': [('share of the Sutherland law', '%',
                               _scaled('sutherland_share', 100.0))],
}

__all__ = ['BOUNDS', 'bounds_of', 'estimates_of', 'nonlinearity_measured', 'text']


def bounds_of(effect_id, found, info):
    """
    Return the bounds of one cause: [(quantity, upper bound, unit)], measurable ones only.

    ``found`` are its :class:`.intervals.Estimate` s, ``info`` the record's
    facts (``max_rate_rad_s``; ``nonlinearity_measured``,
    :func:`nonlinearity_measured`).
    """
    out = []
    for quantity, unit, bound in BOUNDS.get(effect_id, ()):
        value = bound(found, info)
        if value is not None and math.isfinite(value):
            out.append((quantity, float(value), unit))
    return out


def text(bounds):
    """Return "bias tempco above 0.0006 deg/s/K; SF tempco above 40 ppm/K" of a list of Bound."""
    return '; '.join(f'{b.quantity} above {b.upper:.2g} {b.unit}' for b in bounds)


def estimates_of(cand, ctx, frame):
    """Return the :class:`.intervals.Estimate` s of a scored candidate (its last cause)."""
    return intervals.estimates(cand.effect, cand.evaluated, ctx, frame, cand.n_eff,
                               None if cand.wander is None else cand.wander())
