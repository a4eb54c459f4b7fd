"""
The catalogue of candidate causes: each a physical mechanism with its model.

Every model keeps the baseline's form and changes one physical ingredient::

    gyro = b0 + s0 R(T) Omega + (the cause's term)

``b0`` and ``s0`` are refitted with the cause's parameters, so a cause is
judged against the baseline refitted on the same data (the *recalibrated
baseline*, :data:`NULL`), never against a worse calibration. Parameters that
enter linearly are solved by weighted least squares; the others (a time
constant, a delay, a gas constant, a mode split) by variable projection: a
grid search over them, each point solving the linear part, then a bounded
refinement.
"""

from dataclasses import dataclass

import numpy as np

HOUR_S = 3600.0


@dataclass(frozen=True)
class Context:
    """What the models need besides the data: physics and reference points."""

    phys: object
    ref_temp_c: float
    time_span_s: tuple
    duration_s: float


@dataclass(frozen=True)
class Param:
    """A reported parameter: name (with unit suffix), unit and meaning."""

    name: str
    unit: str
    meaning: str


def _slow_temp(frame):
    return frame.bins.binned.temp_c


class Effect:
    """
    One candidate cause.

    Subclasses set ``effect_id``, ``cause`` (a sentence), ``needs`` (subset of
    'rate', 'temp', 'accel'), ``params`` (reported parameters: the non-linear
    ones first, one per grid, then the linear ones) and ``grid`` (one array
    per non-linear parameter, empty when the model is linear). The model is
    ``[1, s(T) Omega_s, extra...]``: subclasses change the scale-factor ratio
    s (:meth:`ratio`), the sensed rate Omega_s (:meth:`sensed_rate`) or add
    bias regressors (:meth:`extra_columns`).
    """

    effect_id = ''
    cause = ''
    needs = ()
    params = ()
    grid = ()

    def grids(self, ctx):
        """Grids of the non-linear parameters for this record."""
        return self.grid

    def ratio(self, ctx, frame, phi):
        """Return the scale-factor ratio on the bins: the baseline R(T)."""
        return ctx.phys.ratio(_slow_temp(frame))

    def sensed_rate(self, frame, phi):
        """Return the rate the scale factor multiplies: the applied rate."""
        return frame.rate

    def extra_columns(self, ctx, frame, phi):
        """Return the regressors beyond bias and scale factor (none)."""
        return []

    def columns(self, ctx, frame, phi):
        """Regressor columns [1, scale-factor term, ...] at ``frame``'s rows."""
        return [np.ones(len(frame)),
                frame.slow(self.ratio(ctx, frame, phi)) * self.sensed_rate(frame, phi)
                ] + self.extra_columns(ctx, frame, phi)

    def report(self, beta, phi):
        """Return the physical parameter values: the non-linear ones, then beta[2:]."""
        values = list(phi) + list(beta[2:2 + len(self.params) - len(phi)])
        return {p.name: v for p, v in zip(self.params, values)}

    @property
    def n_params(self):
        """Free parameters, b0 and s0 included."""
        return 2 + len(self.params)


class Recalibrated(Effect):
    """The baseline with b0, s0 refitted on the same data (the reference): [1, R(T) Omega]."""

    effect_id = 'recalibrated_baseline'
    cause = 'The paper model with its bias and scale factor refitted.'


class ViscosityTemperature(Effect):
    """Sutherland viscosity inside the physics: fitted Sutherland constant."""

    effect_id = 'viscosity_temperature'
    cause = ("The gas viscosity rises with temperature (Sutherland's law), "
             'raising the drive and sense damping (Eq 9-11), so the scale '
             'factor falls with temperature instead of following the '
             'constant-viscosity model.')
    needs = ('rate', 'temp')
    params = (Param('sutherland_constant_k', 'K',
                    'Sutherland constant S of mu = mu_ref (T/T_ref)^1.5 '
                    '(T_ref + S)/(T + S) (air: 110.4 K)'),)
    grid = (np.geomspace(20.0, 1000.0, 36),)

    def ratio(self, ctx, frame, phi):
        """R_S(T) from the physics at Sutherland constant S."""
        return ctx.phys.sutherland_ratio(_slow_temp(frame), phi[0])


class BiasTemperature(Effect):
    """Zero-rate bias linear + quadratic in temperature."""

    effect_id = 'bias_temperature'
    cause = ('The zero-rate bias drifts with temperature (thermal stress and '
             'electronics offsets), a term the paper model lacks entirely.')
    needs = ('temp',)
    params = (Param('bias_temp_coeff_rad_s_k', 'rad/s/K',
                    'bias change per kelvin at T_ref'),
              Param('bias_temp_coeff2_rad_s_k2', 'rad/s/K^2',
                    'quadratic bias coefficient'))

    def extra_columns(self, ctx, frame, phi):
        """[dT, dT^2], dT = T - T_ref."""
        dt = frame.slow(_slow_temp(frame) - ctx.ref_temp_c)
        return [dt, dt * dt]


class ThermalLag(Effect):
    """The structure's temperature lags the reading by a first-order lag."""

    effect_id = 'thermal_lag'
    cause = ("The structure's temperature lags the temperature reading "
             '(first-order thermal time constant), so the temperature-'
             'dependent scale factor follows a delayed temperature during '
             'ramps.')
    needs = ('rate', 'temp')
    params = (Param('thermal_time_constant_s', 's',
                    'first-order lag between the reading and the structure'),)

    def grids(self, ctx):
        """Time constants from 5 s to the record's length."""
        return (np.geomspace(5.0, max(50.0, min(2e4, ctx.duration_s)), 40),)

    def ratio(self, ctx, frame, phi):
        """R(T_lag), T_lag the reading through a first-order lag tau."""
        return ctx.phys.ratio(frame.bins.lagged_temp_on_bins(phi[0]))


class ScaleFactorNonlinearity(Effect):
    """Output not linear in rate: quadratic and cubic terms."""

    effect_id = 'scale_factor_nonlinearity'
    cause = ('The output is not linear in rate (sense-mode and electrostatic '
             'nonlinearity): quadratic and cubic terms in the applied rate.')
    needs = ('rate',)
    params = (Param('nonlinearity_quadratic_s_rad', 's/rad',
                    'a2 in Omega (1 + a2 Omega + a3 Omega^2)'),
              Param('nonlinearity_cubic_s2_rad2', 's^2/rad^2',
                    'a3 in Omega (1 + a2 Omega + a3 Omega^2)'))

    def columns(self, ctx, frame, phi):
        """[1, R Omega, R Omega^2, R Omega^3]."""
        ratio = frame.slow(self.ratio(ctx, frame, phi))
        return [np.ones(len(frame)), ratio * frame.rate, ratio * frame.rate2,
                ratio * frame.rate3]

    def report(self, beta, phi):
        """a2 = c2/s0, a3 = c3/s0."""
        s0 = beta[1] if beta[1] != 0.0 else np.nan
        return {'nonlinearity_quadratic_s_rad': beta[2] / s0,
                'nonlinearity_cubic_s2_rad2': beta[3] / s0}


class GSensitivity(Effect):
    """Bias proportional to linear acceleration."""

    effect_id = 'g_sensitivity'
    cause = ('The bias is proportional to linear acceleration (g-sensitivity: '
             'the proof mass is pulled off its nominal position by gravity and '
             'vibration).')
    needs = ('accel',)
    params = tuple(Param(f'g_sensitivity_{a}_rad_s_per_m_s2', 'rad/s per m/s^2',
                         f'bias per unit acceleration along {a}')
                   for a in 'xyz')

    def extra_columns(self, ctx, frame, phi):
        """[a_x, a_y, a_z]."""
        return [frame.accel[:, k] for k in range(3)]


class TimeDelay(Effect):
    """The output lags the applied rate by a fixed delay."""

    effect_id = 'time_delay'
    cause = ('The output lags the applied rate by a fixed delay (digital '
             'filtering and sampling latency).')
    needs = ('rate',)
    params = (Param('delay_s', 's', 'output delay behind the applied rate'),)
    grid = (np.linspace(-0.05, 0.3, 71),)

    def sensed_rate(self, frame, phi):
        """Omega(t - d)."""
        return frame.delayed_rate(phi[0])


class PressureDrift(Effect):
    """Cavity pressure drifting linearly in time, through Eq 8-11."""

    effect_id = 'pressure_drift'
    cause = ('The package pressure changes over the run (leak or '
             'outgassing): through the Knudsen number the damping and so the '
             'scale factor drift with time at fixed temperature.')
    # The cavity holds the preset's pressure at the start of the record and
    # drifts linearly from there (the part was sealed at that pressure).
    needs = ('rate',)
    params = (Param('pressure_rate_per_h', '1/h',
                    'relative cavity pressure change per hour, '
                    'P(t) = P_ref (1 + k (t - t_start))'),)

    def grids(self, ctx):
        """Pressure rates keeping P(t) >= 0.1 P_ref over the record."""
        hours = max(1e-6, (ctx.time_span_s[1] - ctx.time_span_s[0]) / HOUR_S)
        return (np.linspace(max(-0.9 / hours, -3.0), 3.0, 61),)

    def ratio(self, ctx, frame, phi):
        """R(T) Y(T, P(t)) / Y(T, P_ref)."""
        b = frame.bins.binned
        pressure = 1.0 + phi[0] * (b.time_s - ctx.time_span_s[0]) / HOUR_S
        factor = ctx.phys.pressure_factor(b.temp_c, np.maximum(pressure, 0.05))
        return ctx.phys.ratio(b.temp_c) * factor


class ModeSplitDrift(Effect):
    """Drive-sense frequency split linear in temperature."""

    effect_id = 'mode_split_drift'
    cause = ('The drive-sense frequency split changes with temperature (the '
             "two suspensions' stiffnesses drift differently), so the sense "
             'amplitude leaves the matched-mode first-order value as '
             '1/sqrt(1 + (2 Q df/f)^2).')
    needs = ('rate', 'temp')
    params = (Param('mode_split_at_ref_hz', 'Hz', 'split df at T_ref'),
              Param('mode_split_temp_coeff_hz_k', 'Hz/K',
                    'split change per kelvin'))
    _df0 = np.array([0.0, 2.0, 5.0, 10.0, 20.0, 40.0, 70.0, 110.0, 160.0])
    grid = (np.r_[-_df0[:0:-1], _df0],
            np.array([0.0, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0]))

    def ratio(self, ctx, frame, phi):
        """R(T) m(T), m = 1/sqrt(1 + (2 Q (df0 + df1 dT)/f)^2)."""
        temp = _slow_temp(frame)
        split = phi[0] + phi[1] * (temp - ctx.ref_temp_c)
        return ctx.phys.ratio(temp) * ctx.phys.mode_split_factor(temp, split)

    def report(self, beta, phi):
        """df0, df1 (sign chosen so df1 >= 0: the model is even in df)."""
        df0, df1 = phi
        if df1 < 0:
            df0, df1 = -df0, -df1
        return {'mode_split_at_ref_hz': df0, 'mode_split_temp_coeff_hz_k': df1}


class TemperatureRateBias(Effect):
    """Bias proportional to the rate of change of temperature."""

    effect_id = 'temperature_rate_bias'
    cause = ('The bias follows the rate of change of temperature: during '
             'ramps a thermal gradient across the die stresses the '
             'suspension (heating and cooling give opposite offsets).')
    needs = ('temp',)
    params = (Param('bias_per_temp_rate_rad_s_per_k_s', 'rad/s per K/s',
                    'bias per unit dT/dt'),)

    def extra_columns(self, ctx, frame, phi):
        """[dT/dt]."""
        return [frame.temp_rate_c_s()]


#: The reference every cause is judged against.
NULL = Recalibrated()

#: The catalogue, in the order reports list it.
CATALOGUE = (ViscosityTemperature(), BiasTemperature(), ThermalLag(),
             ScaleFactorNonlinearity(), GSensitivity(), TimeDelay(),
             PressureDrift(), ModeSplitDrift(), TemperatureRateBias())

#: Effect ids, plus 'none' for "no cause found".
EFFECT_IDS = tuple(e.effect_id for e in CATALOGUE)


def effect(effect_id):
    """Return the catalogue entry ``effect_id``."""
    for e in CATALOGUE:
        if e.effect_id == effect_id:
            return e
    raise ValueError(f'effect {effect_id!r} is unknown: choose one of '
                     f'{", ".join(EFFECT_IDS)}')
