"""
The catalogue of candidate causes: each a mechanism with its model.

Every model keeps the baseline's form and adds to it::

    gyro = b0 + s0 s(T, t) Omega_s + (the causes' columns)

with ``s = R(T)`` times the scale-factor factor of each cause
(:meth:`Effect.sf_factor`), ``Omega_s`` the applied rate (delayed by a delay
cause) and the columns each cause adds (:meth:`Effect.columns`). Causes
compose, so a model is a list of causes (:mod:`.models`). ``b0`` and ``s0``
are refitted with the causes' parameters, so a cause is judged against the
baseline refitted on the same data (the *recalibrated baseline*,
:data:`NULL`), never against a worse calibration.

Each cause is *physical* (a mechanism of the paper's device with a model
from the physics: viscosity, thermal lag, pressure, mode split, delay, a
bias following dT/dt) or *generic* (a description of what changes, with the
mechanisms that could produce it: a polynomial bias or scale factor in
temperature or time, a step, a rate polynomial, a g-sensitivity;
:mod:`.generic`). A physical cause lists its generic competitors: it is
named only when it beats them on held-out data (:mod:`.selection`).
"""

from dataclasses import dataclass

from gyro_emulator.units import SECONDS_PER_HOUR
import numpy as np


@dataclass(frozen=True)
class Context:
    """What the models need besides the data: physics and reference points."""

    phys: object
    ref_temp_c: float
    time_span_s: tuple
    duration_s: float
    #: Noise variance that weighs the ridge holding each cause to its physical
    #: range (:meth:`Effect.column_scales`), (rad/s)^2 per sample: white
    #: noise inflated for the bins' correlation (``pipeline.prior_noise_variance``).
    noise_var_rad2_s2: float = 0.0

    @property
    def mid_time_s(self):
        """Middle of the record, s (the origin of time polynomials)."""
        return 0.5 * (self.time_span_s[0] + self.time_span_s[1])


@dataclass(frozen=True)
class Param:
    """A reported parameter: name (with unit suffix), unit and meaning."""

    name: str
    unit: str
    meaning: str


@dataclass(frozen=True)
class Basis:
    """The scale-factor part of a model at one resolution: s(T, t) and s Omega_s."""

    s: np.ndarray
    sr: np.ndarray


def slow_temp(frame):
    """Return the bin-mean temperature reading (slow quantities are computed on bins)."""
    return frame.bins.binned.temp_c


#: Entries a frame's cache holds before it is emptied.
CACHE_SIZE = 2048


def cached(frame, key, compute):
    """
    Return ``compute()`` for ``key``, remembered on the bins of ``frame``.

    Slow quantities live on the bins, which do not change during a
    diagnosis; a search evaluates the same ones at the same parameter
    values for every fold.
    """
    store = frame.bins.__dict__.setdefault('_effect_cache', {})
    value = store.get(key)
    if value is None:
        if len(store) >= CACHE_SIZE:
            store.clear()
        value = compute()
        store[key] = value
    return value


class Effect:
    """
    One candidate cause.

    Subclasses set ``effect_id``, ``cause`` (a sentence), ``kind``
    ('physical' or 'generic'), ``needs`` (subset of 'rate', 'temp',
    'accel'), ``params`` (reported parameters: the non-linear ones first,
    one per grid, then the linear ones), ``grid`` (one array per non-linear
    parameter, empty when linear), ``competitors`` (generic causes a
    physical one must beat), ``mechanisms`` (what could produce a generic
    one) and ``scales`` (the physical range of each column's coefficient,
    :meth:`column_scales`). A cause changes the scale-factor ratio
    (:meth:`sf_factor`), delays the sensed rate (:meth:`delay_s`) or adds
    columns (:meth:`columns`). Every cause has a parameter value that gives
    the model without it (a zero coefficient, a zero delay or lag, ...).
    """

    effect_id = ''
    cause = ''
    kind = 'physical'
    needs = ()
    params = ()
    grid = ()
    competitors = ()
    mechanisms = ()
    scales = ()

    def grids(self, ctx):
        """Grids of the non-linear parameters for this record."""
        return self.grid

    def search_form(self):
        """
        Return the cause whose fit chooses the non-linear parameters: itself.

        A cause with a share of a law (:class:`ViscosityTemperature`) chooses
        the law's constant with the law itself, then fits the share.
        """
        return self

    #: The cause's shape starts with the record (a warm-up, :class:`.generic.BiasTime`):
    #: a fold whose training rows start later takes the slowest shape its rows
    #: allow (:func:`.models.extrapolates_back`).
    starts_with_record = False
    #: The cause is a shape in time (a drift, a warm-up): the first and last
    #: held-out folds see it carried past the training rows, which
    #: :meth:`.cv.CrossValidation.evaluate` allows only where it predicts.
    time_shaped = False

    def sf_factor(self, ctx, frame, phi):
        """Return the factor on R(T) on the bins, or None (no change)."""
        return None

    def delay_s(self, phi):
        """Return the delay of the sensed rate, s (0: none)."""
        return 0.0

    def columns(self, ctx, frame, phi, basis):
        """Return the regressors this cause adds, at ``frame``'s rows."""
        return []

    def report(self, coef, phi, s0):
        """Return the physical parameter values: the non-linear ones, then ``coef``."""
        values = list(phi) + list(coef[:len(self.params) - len(phi)])
        return {p.name: float(v) for p, v in zip(self.params, values)}

    def column_scales(self):
        """
        Physical range of each column's coefficient (the ridge of :meth:`.models.Model.penalty`).

        Several times the largest the mechanism reaches in a part (and in
        the truth generator): the prior decides only what the training rows
        leave undetermined.
        """
        scales = tuple(self.scales)[:self.n_columns]
        return scales + (np.inf,) * (self.n_columns - len(scales))

    @property
    def n_params(self):
        """Free parameters of the cause alone."""
        return len(self.params)

    @property
    def n_columns(self):
        """Columns the cause adds (its linear parameters)."""
        return len(self.params) - len(self.grid)


class Recalibrated(Effect):
    """The baseline with b0, s0 refitted on the same data (the reference): [1, R(T) Omega]."""

    effect_id = 'recalibrated_baseline'
    cause = 'The paper model with its bias and scale factor refitted.'


class SutherlandLaw(Effect):
    """Sutherland viscosity inside the physics at share 1: the form that chooses S."""

    effect_id = 'viscosity_temperature'
    needs = ('rate', 'temp')
    grid = (np.geomspace(20.0, 1000.0, 36),)

    def sf_factor(self, ctx, frame, phi):
        """R_S(T) / R(T) from the physics at Sutherland constant S."""
        return 1.0 + sutherland_change(ctx, frame, phi[0])


def sutherland_change(ctx, frame, sutherland_k):
    """R_S(T) / R(T) - 1 on the bins: the Sutherland law's relative SF change at S."""
    def compute():
        temp = slow_temp(frame)
        return ctx.phys.sutherland_ratio(temp, sutherland_k) / ctx.phys.ratio(temp) - 1.0

    return cached(frame, ('sutherland', float(sutherland_k)), compute)


class ViscosityTemperature(Effect):
    """
    Sutherland viscosity inside the physics: a share a of its scale-factor change, S fitted.

    SF = s0 [R(T) + a (R_S(T) - R(T))], R_S the physics' ratio with the gas
    viscosity following Sutherland's law at constant S (Eq 9-11). a = 1 is
    the law itself, a = 0 the baseline's constant viscosity: no Sutherland
    constant gives a constant viscosity, so the share is what lets the law
    represent "no change", and its prior (:attr:`scales`) holds it where
    the training rows do not determine it. S is the law's constant: it is
    chosen, and its profile interval drawn, with the law itself (share 1,
    :class:`SutherlandLaw`); the share is then fitted at that S.
    """

    effect_id = 'viscosity_temperature'
    cause = ("The gas viscosity rises with temperature (Sutherland's law), "
             'raising the drive and sense damping (Eq 9-11), so the scale '
             'factor falls with temperature instead of following the '
             'constant-viscosity model.')
    needs = ('rate', 'temp')
    params = (Param('sutherland_constant_k', 'K',
                    'Sutherland constant S of mu = mu_ref (T/T_ref)^1.5 '
                    '(T_ref + S)/(T + S) (air: 110.4 K)'),
              Param('sutherland_share', '',
                    'share a of the Sutherland scale-factor change, SF = s0 [R(T) + '
                    'a (R_S(T) - R(T))] (1: the law; 0: constant viscosity)'))
    grid = SutherlandLaw.grid
    #: a share of 2: twice the law itself (the truth generator plants 1)
    scales = (2.0,)
    competitors = ('scale_factor_temperature',)

    def search_form(self):
        """Return the law at share 1 (:class:`SutherlandLaw`): it chooses S."""
        return SutherlandLaw()

    def columns(self, ctx, frame, phi, basis):
        """[s Omega_s (R_S(T)/R(T) - 1)]: the law's change at share 1."""
        return [basis.sr * frame.slow(sutherland_change(ctx, frame, phi[0]))]

    def report(self, coef, phi, s0):
        """S and a = c/s0."""
        s0 = s0 if s0 != 0.0 else np.nan
        return {'sutherland_constant_k': float(phi[0]), 'sutherland_share': float(coef[0] / s0)}


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
    grid = (None,)
    competitors = ('scale_factor_temperature',)

    def grids(self, ctx):
        """
        No lag, then time constants from 5 s to the record's length.

        tau = 0 is the baseline (the structure at the reading), so that the
        law can represent "no change" and is not forced to a 5 s lag.
        """
        return (np.r_[0.0, np.geomspace(5.0, max(50.0, min(2e4, ctx.duration_s)), 40)],)

    def sf_factor(self, ctx, frame, phi):
        """R(T_lag) / R(T), T_lag the reading through a first-order lag tau (None at tau 0)."""
        if phi[0] <= 0.0:
            return None

        def compute():
            lagged = frame.bins.lagged_temp_on_bins(phi[0])
            return ctx.phys.ratio(lagged) / ctx.phys.ratio(slow_temp(frame))

        return cached(frame, ('lag', float(phi[0])), compute)


class TimeDelay(Effect):
    """The output lags the applied rate by a fixed delay."""

    effect_id = 'time_delay'
    cause = ('The output lags the applied rate by a fixed delay (digital '
             'filtering and sampling latency, or, against a baseline without rate '
             "dynamics, the sense mode's own response: its group delay).")
    needs = ('rate',)
    params = (Param('delay_s', 's', 'output delay behind the applied rate'),)
    grid = (np.linspace(-0.05, 0.3, 71),)

    def delay_s(self, phi):
        """Return d: the model uses Omega(t - d)."""
        return phi[0]


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
    grid = (None,)
    competitors = ('scale_factor_time',)

    def grids(self, ctx):
        """Pressure rates keeping P(t) >= 0.1 P_ref over the record."""
        hours = max(1e-6, (ctx.time_span_s[1] - ctx.time_span_s[0]) / SECONDS_PER_HOUR)
        return (np.linspace(max(-0.9 / hours, -3.0), 3.0, 61),)

    def sf_factor(self, ctx, frame, phi):
        """Y(T, P(t)) / Y(T, P_ref)."""
        b = frame.bins.binned
        pressure = 1.0 + phi[0] * (b.time_s - ctx.time_span_s[0]) / SECONDS_PER_HOUR
        where = cached(frame, 'temp_index', lambda: ctx.phys.temp_index(b.temp_c))
        return ctx.phys.pressure_factor(where, np.maximum(pressure, 0.05))


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
    competitors = ('scale_factor_temperature',)

    def sf_factor(self, ctx, frame, phi):
        """m(T) = 1/sqrt(1 + (2 Q (df0 + df1 dT)/f)^2)."""
        temp = slow_temp(frame)
        split = phi[0] + phi[1] * (temp - ctx.ref_temp_c)
        qf = cached(frame, 'q_and_freq', lambda: ctx.phys.q_and_freq(temp))
        return ctx.phys.mode_split_factor(qf, split)

    def report(self, coef, phi, s0):
        """df0, df1 (sign chosen so df1 >= 0: the model is even in df)."""
        df0, df1 = phi
        if df1 < 0:
            df0, df1 = -df0, -df1
        return {'mode_split_at_ref_hz': float(df0), 'mode_split_temp_coeff_hz_k': float(df1)}


class TemperatureRateBias(Effect):
    """Bias proportional to the rate of change of temperature inside the part."""

    effect_id = 'temperature_rate_bias'
    cause = ('The bias follows the rate of change of temperature: during '
             'ramps a thermal gradient across the die stresses the '
             'suspension (heating and cooling give opposite offsets).')
    needs = ('temp',)
    params = (Param('gradient_time_constant_s', 's',
                    'time constant of the body the gradient builds up in'),
              Param('bias_per_temp_rate_rad_s_per_k_s', 'rad/s per K/s',
                    'bias per unit dT/dt'))
    # a gradient across a die or package settles within minutes
    grid = (np.geomspace(2.0, 300.0, 20),)
    #: 0.3 rad/s per K/s is 0.3 deg/s per K/min (the truth generator's largest: 0.09)
    scales = (0.3,)
    #: The likelihood route tests it at its fitted tau, over its grid's effective tests.
    state_space_search = True
    competitors = ('bias_temperature', 'bias_time', 'bias_hysteresis')

    def columns(self, ctx, frame, phi, basis):
        """
        [dT_b/dt], T_b the reading through a first-order lag tau.

        A gradient across a body that follows the reading with time constant
        tau is proportional to T - T_b = tau dT_b/dt (exact for the lag): the
        reading's slope smoothed the way the body smooths it, without
        differencing the reading's noise.
        """
        def compute():
            lagged = frame.bins.lagged_temp_on_bins(phi[0])
            return (slow_temp(frame) - lagged) / phi[0]

        return [frame.slow(cached(frame, ('gradient', float(phi[0])), compute))]


#: The reference every cause is judged against.
NULL = Recalibrated()


def physical_causes():
    """Return the physical causes, in the order reports list them."""
    return (ViscosityTemperature(), ThermalLag(), TimeDelay(), PressureDrift(),
            ModeSplitDrift(), TemperatureRateBias())
