"""
Generic causes: what changes, without saying which mechanism changes it.

A generic cause is a flexible description of one observable: the bias or
the scale factor as a polynomial in temperature or time, a step at an
unknown time, a polynomial in the rate, a bias linear in acceleration, a
bias with hysteresis in temperature. It
comes with the mechanisms that could produce it (``mechanisms``). A
physical cause (:mod:`.effects`) that describes the same observable must
beat its generic competitor on held-out data before it is named
(:mod:`.selection`); when the generic one wins, the report lists these
mechanisms instead of guessing one.

:data:`CATALOGUE` holds every candidate, physical and generic.
"""

import copy

from gyro_emulator.analysis.calibrate import thermal
from gyro_emulator.analysis.diagnose.effects import (cached, Effect, NULL, Param,
                                                     physical_causes, slow_temp)
from gyro_emulator.emulation.truth.effects import CATALOGUE_TRUTHS
from gyro_emulator.units import AXES, SECONDS_PER_HOUR
import numpy as np


class TemperaturePolynomial(Effect):
    """
    A cause polynomial in dT = T - T_ref: its order follows the span (:func:`polynomial_order`).

    ``params`` lists the coefficients in ascending order; :meth:`at_order`
    keeps the first ``order`` of them, so a term the span cannot carry is
    neither fitted nor reported.
    """

    order = 2

    def at_order(self, order):
        """Return this cause with its polynomial cut to ``order`` (1 or 2)."""
        out = copy.copy(self)
        out.order = int(order)
        out.params = type(self).params[:out.order]
        return out

    def powers(self, ctx, frame):
        """[dT, dT^2, ...] up to the order, on the bins (slow)."""
        dt = frame.slow(slow_temp(frame) - ctx.ref_temp_c)
        return [dt ** k for k in range(1, self.order + 1)]


def polynomial_order(span_k, temps_c, requested=TemperaturePolynomial.order):
    """
    Order of the temperature polynomials a record carries: the rule of ``calibrate``.

    :func:`gyro_emulator.analysis.calibrate.thermal.allowed_order`: order k
    needs a span of 5, 15 or 25 K and k + 3 distinct temperatures
    (:data:`~gyro_emulator.analysis.calibrate.thermal.DISTINCT_K` apart).
    ``diagnose`` tests a linear term from its own smaller span (a held-out
    test, not an export), so below the rule's order 1 it keeps order 1.

    Returns
    -------
    (int, str or None)
        The order, and a sentence when a term was dropped.

    """
    distinct = thermal.distinct_temperatures(temps_c)
    try:
        order = thermal.allowed_order(span_k, distinct, requested)
    except ValueError:
        order = 1
    if order >= requested:
        return order, None
    k = order + 1
    return order, (f'temperature polynomials cut to order {order}: the record spans '
                   f'{span_k:.1f} K with {distinct} distinct temperatures, and order {k} '
                   f'needs {thermal.MIN_SPAN_K[k]:g} K and {k + 3} distinct temperatures '
                   '(the rule of calibrate)')


def with_polynomial_order(catalogue, order):
    """Return ``catalogue`` with every temperature polynomial cut to ``order`` (None: as is)."""
    if order is None:
        return tuple(catalogue)
    return tuple(e.at_order(min(order, e.order)) if isinstance(e, TemperaturePolynomial)
                 else e for e in catalogue)


class BiasTemperature(TemperaturePolynomial):
    """Zero-rate bias linear + quadratic in temperature."""

    effect_id = 'bias_temperature'
    kind = 'generic'
    cause = ('The zero-rate bias drifts with temperature (thermal stress and '
             'electronics offsets), a term the paper model lacks entirely.')
    needs = ('temp',)
    params = (Param('bias_temp_coeff_rad_s_k', 'rad/s/K',
                    'bias change per kelvin at T_ref'),
              Param('bias_temp_coeff2_rad_s_k2', 'rad/s/K^2',
                    'quadratic bias coefficient'))
    #: 1 deg/s/K and 0.06 deg/s/K^2
    scales = (0.02, 1e-3)
    mechanisms = ('thermal stress of the package and die',
                  'electronics offsets that follow temperature',
                  'on a one-way ramp: a thermal gradient (temperature_rate_bias) '
                  'or a drift in time (bias_time)')

    def columns(self, ctx, frame, phi, basis):
        """[dT, dT^2] up to the order, dT = T - T_ref."""
        return self.powers(ctx, frame)


class ScaleFactorNonlinearity(Effect):
    """Output not linear in rate: quadratic and cubic terms."""

    effect_id = 'scale_factor_nonlinearity'
    kind = 'generic'
    cause = ('The output is not linear in rate (sense-mode and electrostatic '
             'nonlinearity): quadratic and cubic terms in the applied rate.')
    needs = ('rate',)
    params = (Param('nonlinearity_quadratic_s_rad', 's/rad',
                    'a2 in Omega (1 + a2 Omega + a3 Omega^2)'),
              Param('nonlinearity_cubic_s2_rad2', 's^2/rad^2',
                    'a3 in Omega (1 + a2 Omega + a3 Omega^2)'))
    #: 10 % at 1 rad/s (the coefficients are s0 a2, s0 a3)
    scales = (0.1, 0.1)
    mechanisms = ('sense-mode (Duffing) and electrostatic nonlinearity',
                  'saturation of the electronics near full scale')

    def columns(self, ctx, frame, phi, basis):
        """[s Omega^2, s Omega^3]."""
        return [basis.s * frame.rate2, basis.s * frame.rate3]

    def report(self, coef, phi, s0):
        """a2 = c2/s0, a3 = c3/s0."""
        s0 = s0 if s0 != 0.0 else np.nan
        return {'nonlinearity_quadratic_s_rad': float(coef[0] / s0),
                'nonlinearity_cubic_s2_rad2': float(coef[1] / s0)}


class GSensitivity(Effect):
    """Bias proportional to linear acceleration."""

    effect_id = 'g_sensitivity'
    kind = 'generic'
    cause = ('The bias is proportional to linear acceleration (g-sensitivity: '
             'the proof mass is pulled off its nominal position by gravity and '
             'vibration).')
    needs = ('accel',)
    params = tuple(Param(f'g_sensitivity_{a}_rad_s_per_m_s2', 'rad/s per m/s^2',
                         f'bias per unit acceleration along {a}')
                   for a in AXES)
    #: 1.1 deg/s/g (a consumer part: about 0.1)
    scales = (2e-3, 2e-3, 2e-3)
    mechanisms = ('proof-mass offset under gravity and vibration',
                  'a mounting that flexes under load')

    def columns(self, ctx, frame, phi, basis):
        """[a_x, a_y, a_z]."""
        return [frame.accel[:, k] for k in range(3)]


class ScaleFactorTemperature(TemperaturePolynomial):
    """Scale factor a polynomial in temperature: SF(T) = s0 R(T) (1 + c1 dT + c2 dT^2)."""

    effect_id = 'scale_factor_temperature'
    kind = 'generic'
    cause = ('The scale factor changes with temperature in a way the paper model does '
             'not predict: SF(T) = s0 R(T) (1 + c1 dT + c2 dT^2).')
    needs = ('rate', 'temp')
    params = (Param('sf_temp_coeff_per_k', '1/K',
                    'relative scale-factor change per kelvin at T_ref (1e-6 = 1 ppm/K)'),
              Param('sf_temp_coeff2_per_k2', '1/K^2',
                    'quadratic relative scale-factor coefficient'))
    #: 1 %/K and 0.1 %/K^2
    scales = (0.01, 1e-3)
    mechanisms = ('an electronics gain temperature coefficient',
                  'factory temperature compensation (the part does not follow the physics)',
                  'gas viscosity rising with temperature (viscosity_temperature)',
                  'a drive-sense mode split drifting with temperature (mode_split_drift)',
                  'a thermal lag of the structure (thermal_lag) on slow ramps')

    def columns(self, ctx, frame, phi, basis):
        """[s Omega dT, s Omega dT^2] up to the order."""
        return [basis.sr * p for p in self.powers(ctx, frame)]

    def report(self, coef, phi, s0):
        """c1 = k1/s0, c2 = k2/s0 (those fitted)."""
        s0 = s0 if s0 != 0.0 else np.nan
        return {p.name: float(c / s0) for p, c in zip(self.params, coef)}


def _hours_from_mid(ctx, frame):
    """(t - t_mid) in hours at ``frame``'s rows (slow: from the bins)."""
    return frame.slow((frame.bins.binned.time_s - ctx.mid_time_s) / SECONDS_PER_HOUR)


class ScaleFactorTime(Effect):
    """Scale factor drifting in time: SF = s0 R(T) (1 + k1 t_h + k2 t_h^2)."""

    effect_id = 'scale_factor_time'
    kind = 'generic'
    cause = 'The scale factor drifts in time during the run.'
    needs = ('rate',)
    params = (Param('sf_drift_per_h', '1/h',
                    'relative scale-factor change per hour at mid-record'),
              Param('sf_drift2_per_h2', '1/h^2', 'quadratic relative drift coefficient'))
    #: 10 %/h and 10 %/h^2
    scales = (0.1, 0.1)
    #: carried into a held-out end fold only where it predicts its neighbour (:mod:`.cv`)
    time_shaped = True
    mechanisms = ('a cavity pressure drift (pressure_drift)',
                  'ageing of the electronics gain',
                  'a temperature change confounded with time')

    def columns(self, ctx, frame, phi, basis):
        """[s Omega t_h, s Omega t_h^2], t_h in hours from mid-record."""
        th = _hours_from_mid(ctx, frame)
        return [basis.sr * th, basis.sr * th * th]

    def report(self, coef, phi, s0):
        """k1 = c1/s0, k2 = c2/s0."""
        s0 = s0 if s0 != 0.0 else np.nan
        return {'sf_drift_per_h': float(coef[0] / s0), 'sf_drift2_per_h2': float(coef[1] / s0)}


class BiasTime(Effect):
    """Bias drifting in time: a warm-up A exp(-(t - t0)/tau) plus a linear ageing."""

    effect_id = 'bias_time'
    kind = 'generic'
    cause = ('The bias drifts in time: a warm-up A exp(-(t - t_start)/tau) plus a '
             'linear ageing.')
    needs = ()
    params = (Param('warmup_time_constant_s', 's', 'warm-up time constant tau'),
              Param('warmup_rad_s', 'rad/s', 'warm-up bias A at the start of the record'),
              Param('bias_drift_rad_s_per_h', 'rad/s/h', 'linear bias drift per hour'))
    grid = (None,)
    #: 5.7 deg/s of warm-up, 5.7 deg/s/h of drift
    scales = (0.1, 0.1)
    #: carried into a held-out end fold only where it predicts its neighbour (:mod:`.cv`)
    time_shaped = True
    mechanisms = ('warm-up after power-on', 'ageing',
                  'a temperature change confounded with time (bias_temperature)',
                  'bias wander slower than the record can show as noise')

    def grids(self, ctx):
        """Time constants from 1 % to 50 % of the record."""
        return (np.geomspace(0.01, 0.5, 20) * ctx.duration_s,)

    #: A warm-up that has decayed before the first training row is seen by
    #: those rows only in its tail, where it cannot be told from the part's
    #: wander: extrapolated back to the record's start at the time constant
    #: of least SSE it multiplied a tail of noise by up to e^(t_1/tau) (a fold
    #: of 1300 s and tau 290 s: 87; 8.3x the RMSE of the model without it on
    #: the held-out first fold). Such a fold takes the slowest time constant
    #: its rows cannot tell from the best (:func:`.models.slowest_within`);
    #: where they resolve the decay (a 900 s warm-up seen from 1800 s on under
    #: white noise) that is the best one.
    starts_with_record = True

    def columns(self, ctx, frame, phi, basis):
        """[exp(-(t - t_start)/tau), t_h]."""
        t = frame.bins.binned.time_s - ctx.time_span_s[0]
        return [frame.slow(np.exp(-t / phi[0])), _hours_from_mid(ctx, frame)]


def play(temp_c, width_k):
    """
    Play (backlash) operator of half width w: p follows T only when |T - p| > w.

    p[0] = T[0]; p[n] = min(T[n] + w, max(T[n] - w, p[n-1])) (Krasnosel'skii &
    Pokrovskii; the elementary hysteresis operator of the Preisach model).
    """
    p = np.empty(len(temp_c))
    state = float(temp_c[0])
    for i, value in enumerate(np.asarray(temp_c, dtype=float)):
        state = min(value + width_k, max(value - width_k, state))
        p[i] = state
    return p


class BiasHysteresis(Effect):
    """Bias that depends on the direction of the last temperature change (a play operator)."""

    effect_id = 'bias_hysteresis'
    kind = 'generic'
    cause = ('The bias depends on the thermal history: after heating and after cooling '
             'it sits on different branches, and keeps them through a soak.')
    needs = ('temp',)
    params = (Param('hysteresis_width_k', 'K',
                    'half width w of the play: the temperature change that moves the '
                    'bias from one branch to the other'),
              Param('bias_hysteresis_rad_s', 'rad/s',
                    'half the bias difference between the cooling and heating branches'))
    grid = (np.geomspace(0.3, 10.0, 20),)
    #: 1.1 deg/s (a part: about 0.1)
    scales = (0.02,)
    refine = False
    mechanisms = ('stress relaxation of the package, die attach or adhesive (hysteresis)',
                  'a thermal gradient that settles slower than the soaks '
                  '(temperature_rate_bias with a long time constant)',
                  'a bias that follows the direction of the last temperature change')

    def columns(self, ctx, frame, phi, basis):
        """[(p - T) / w], p the play of the bin temperatures: -1 heating, +1 cooling."""
        def compute():
            temp = slow_temp(frame)
            return (play(temp, phi[0]) - temp) / phi[0]

        return [frame.slow(cached(frame, ('play', float(phi[0])), compute))]


class _Step(Effect):
    """A step at an unknown time (found by an exact change-point search, :mod:`.models`)."""

    change_point = True
    grid = (None,)

    def grids(self, ctx):
        """No grid: the step time is searched over every bin start."""
        return (None,)

    @staticmethod
    def step(frame, t0):
        """H(t - t0) at ``frame``'s rows (bins: their first sample's time)."""
        if frame.level == 'bins':
            return (frame.bins.bin_start_s >= t0).astype(float)
        return (frame.time_s >= t0).astype(float)

    def multiplier(self, frame, basis):
        """Return the column the step multiplies: 1 (bias) or s Omega (scale factor)."""
        raise NotImplementedError

    def columns(self, ctx, frame, phi, basis):
        """[g H(t - t0)]."""
        return [self.multiplier(frame, basis) * self.step(frame, phi[0])]


class BiasStep(_Step):
    """A one-time bias change at time t0."""

    effect_id = 'bias_step'
    kind = 'generic'
    cause = 'The bias changes once, abruptly, during the run.'
    needs = ()
    params = (Param('step_time_s', 's', 'time of the step (first sample after it)'),
              Param('bias_step_rad_s', 'rad/s', 'bias change at the step'))
    #: 5.7 deg/s
    scales = (0.1,)
    mechanisms = ('a mechanical shock', 'a remount or a disturbed fixture',
                  'a power cycle or restart of the part')

    def multiplier(self, frame, basis):
        """Return 1: a bias step multiplies the constant."""
        return np.ones(len(basis.sr))


class ScaleFactorStep(_Step):
    """A one-time relative scale-factor change at time t0."""

    effect_id = 'scale_factor_step'
    kind = 'generic'
    cause = 'The scale factor changes once, abruptly, during the run.'
    needs = ('rate',)
    params = (Param('step_time_s', 's', 'time of the step (first sample after it)'),
              Param('sf_step', '', 'relative scale-factor change at the step'))
    #: 20 %
    scales = (0.2,)
    mechanisms = ('a mechanical shock or overload', 'a range or gain switch',
                  'a remount or restart of the part')

    def multiplier(self, frame, basis):
        """Return s Omega: a scale-factor step multiplies the rate term."""
        return basis.sr

    def report(self, coef, phi, s0):
        """t0 and the relative step c/s0."""
        s0 = s0 if s0 != 0.0 else np.nan
        return {'step_time_s': float(phi[0]), 'sf_step': float(coef[0] / s0)}


def generic_causes():
    """Return the generic causes, in the order reports list them."""
    return (BiasTemperature(), ScaleFactorNonlinearity(), GSensitivity(),
            ScaleFactorTemperature(), ScaleFactorTime(), ScaleFactorStep(),
            BiasTime(), BiasStep(), BiasHysteresis())


def _catalogue():
    """
    Return the nine causes of the first catalogue in their order, then the new ones.

    The nine are the causes the truth generator plants
    (:data:`gyro_emulator.emulation.truth.effects.CATALOGUE_TRUTHS`), one list.
    """
    by_id = {e.effect_id: e for e in physical_causes() + generic_causes()}
    first = CATALOGUE_TRUTHS
    rest = tuple(k for k in by_id if k not in first)
    return tuple(by_id[k] for k in first + rest)


#: Every candidate cause, in the order reports list them.
CATALOGUE = _catalogue()
#: The nine causes of the first catalogue (those the truth generator plants).
EFFECT_IDS = tuple(e.effect_id for e in CATALOGUE[:9])
#: Every candidate's id.
CANDIDATE_IDS = tuple(e.effect_id for e in CATALOGUE)

__all__ = ['CANDIDATE_IDS', 'CATALOGUE', 'effect', 'EFFECT_IDS', 'NULL']


def effect(effect_id):
    """Return the catalogue entry ``effect_id``."""
    for e in CATALOGUE:
        if e.effect_id == effect_id:
            return e
    raise ValueError(f'effect {effect_id!r} is unknown: choose one of '
                     f'{", ".join(CANDIDATE_IDS)}')
