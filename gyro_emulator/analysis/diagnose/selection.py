"""
Choosing the causes: forward selection on held-out evidence.

Starting from the recalibrated baseline, each step (:func:`step`) adds
every remaining cause the record can show to the current model, fits the
joint model per fold (the causes already chosen keep their non-linear
parameters; :mod:`.models`) and scores it on held-out data (:mod:`.cv`). A
candidate is *supported* when, against the current model:

- its held-out RMSE gain is at least ``MIN_GAIN`` (0.5 %; ``MIN_GAIN_RATE``,
  0.1 %, for a cause that acts on the applied rate: :func:`gain_floor`);
- the fold test, after subtracting what the record's own noise would
  give (:func:`.noise_model.null_gain`, for causes that do not multiply the
  rate), gives p < ``alpha`` / m, m the candidates of the step
  (Bonferroni: the chance that a record with no effect gets any cause is
  at most ``alpha``);
- its BIC on the effective number of independent bins is lower by more
  than 10 (:func:`.cv.effective_bic`);

or the likelihood route establishes it (:meth:`Selector.score`). It is
*significant*, and may be chosen, only when moreover it predicts the
held-out data better than the current model, per sample or in the group
means at the verdict's averaging time (a held-out gain > 0: the
likelihood route's evidence is in-sample), and its size stands more than
``SIZE_Z`` (2) sigma clear of zero (:func:`.intervals.clear_of_zero`: one
coefficient, or all of them together on the folds' joint spread). A
supported candidate that fails either is *supported in-sample, not
confirmed on held-out data* (``in_sample_only`` says why): listed, never
chosen.

Among the significant candidates the lowest held-out RMSE leads. Those the
fold test cannot tell from the cause chosen (p >= ``ALPHA_TIE`` that it is
better) are *indistinguishable*: the significant ones, and those that fell
short of the level but predict the held-out data better than it. A
physical cause is named only when it beats every generic competitor it has
(:mod:`.generic`) with p < ``ALPHA_TIE``; among the rest the lowest RMSE is
named, except that between causes of one kind (physical, or generic) the
data cannot separate the one with fewer parameters is preferred. The
chosen cause joins the model and the next step starts (without the
candidates that made the held-out prediction worse with p >= 0.5);
selection stops when no candidate is significant or ``max_causes`` are in.

Parameter uncertainties are delete-a-block jackknife standard deviations
over the per-fold fits.
"""

from dataclasses import dataclass, field, replace
import functools
import math
import zlib

from gyro_emulator.analysis.diagnose import cv as cvmod
from gyro_emulator.analysis.diagnose import intervals, models, noise_model, sandwich, statespace
from gyro_emulator.analysis.diagnose import reference as reference_mod
from gyro_emulator.analysis.diagnose.effects import Effect
import numpy as np

MIN_GAIN = 0.005
#: The floor of a cause that acts on the applied rate (a scale factor, a
#: delay: ``'rate' in needs``). A part's own wander does not follow a rate
#: profile, and on a noisy part a real one hides under 0.5 %: an SF step of
#: 0.1 % under a 50 deg/s sine on ADIS16405 noise (0.35 deg/s per sample)
#: gains 0.13 % at p 2.7e-4. A 0.1 % floor for every cause named a bias step
#: on the raw MPU-6050 z log (its slow drift); for rate causes it named none
#: in 309 independent stretches of the raw logs and 220 synthetic records.
MIN_GAIN_RATE = 0.001
ALPHA = 0.01
ALPHA_TIE = 0.05
DELTA_BIC_MAX = -10.0
MAX_CAUSES = 4
#: A cause whose size is within this many sigma of zero is not chosen.
SIZE_Z = 2.0
#: The share of alpha the likelihood route gets where a cause has both routes
#: (weighted Bonferroni: p = min(p_LR / W_LR, p_fold / (1 - W_LR))).
W_LR = 0.9
MIN_TEMP_SPAN_C = 1.0
MIN_ACCEL_STD_M_S2 = 0.05
MIN_RATE_RMS_RAD_S = 1e-3
#: The columns of a cause the likelihood route tests, where not all: those of a
#: searched cause that do not depend on its searched parameter (the linear
#: drift of bias_time), and the leading term of a temperature polynomial (the
#: tempco dT of bias_temperature: one degree of freedom where a tempco has one;
#: the fold test still scores the whole polynomial).
LR_COLUMNS = {'bias_time': (1,), 'bias_temperature': (0,)}


@dataclass
class Candidate:
    """One cause scored against the current model."""

    effect: object
    evaluated: object
    p_value: float
    gain_step: float
    delta_bic: float
    n_eff: float
    null_share: float
    significant: bool = False
    indistinguishable: list = field(default_factory=list)
    p_fold: float = 1.0
    p_statespace: float = None
    lr: float = None
    gain_binned: float = 0.0
    gain_predictive: float = None
    route: str = 'fold_test'
    #: Why a candidate the tests support was not chosen (None: it was not
    #: supported, or it is significant): no held-out gain, or a size within
    #: SIZE_Z sigma of zero.
    in_sample_only: str = None
    #: Returns what its intervals need (:class:`.sandwich.Wander`), made on
    #: demand: only the causes reported need it.
    wander: object = None


def excitation(prep, data):
    """Which kinds of excitation the record has: a subset of rate, temp, accel."""
    b = prep.binned
    have = set()
    if math.sqrt(float(np.mean(data.rate_cmd_rad_s ** 2))) >= MIN_RATE_RMS_RAD_S:
        have.add('rate')
    if data.has_temp and float(b.temp_c.max() - b.temp_c.min()) >= MIN_TEMP_SPAN_C:
        have.add('temp')
    if data.has_accel and float(np.max(np.std(data.accel_m_s2, axis=0))) >= \
            MIN_ACCEL_STD_M_S2:
        have.add('accel')
    return have


def not_testable_reason(need, data):
    """Return why a cause that needs ``need`` cannot be tested on ``data``."""
    if need == 'rate':
        return ('the applied rate is (nearly) zero, so scale-factor effects are not '
                'observable')
    if need == 'temp':
        return ('the record has no temperature reading' if not data.has_temp else
                f'the temperature spans less than {MIN_TEMP_SPAN_C} K')
    return 'no acceleration columns (or no acceleration change) in the record'


class Selector:
    """
    Forward selection over one prepared record.

    Parameters
    ----------
    cv : gyro_emulator.analysis.diagnose.cv.CrossValidation
        The folds.
    superbins : gyro_emulator.analysis.diagnose.noise_model.SuperBins
        Resolution of the null simulations.
    alpha : float
        Family-wise false-alarm level of each step.
    seed : int
        Seed of the null simulations.
    reference : gyro_emulator.analysis.diagnose.reference.ReferenceNoise, optional
        The noise of a second record of the part, held fixed in every null
        (``--reference``): the simulations and the floor draw it, and the
        likelihood route tests with it known (:class:`.reference.KnownNoise`).

    """

    def __init__(self, cv, superbins, alpha=ALPHA, seed=0, reference=None):
        self.cv, self.superbins = cv, superbins
        self.alpha, self.seed = alpha, seed
        self.reference = reference
        self.ctx = cv.ctx
        self._noise = {}
        self._ss = {}
        self._known = None
        self._group_of_sample = superbins.group[cv.prep.sample_bin]

    def noise_of(self, evaluated):
        """
        Return the noise of a fitted model's residual (:func:`.noise_model.fit_noise`).

        With a reference, its noise with the residual's own short-term spread.
        """
        key = id(evaluated)
        if key not in self._noise:
            fit = self._fit_noise(evaluated)
            if self.reference is not None:
                fit = self.reference.noise_model(fit.white_sigma_rad_s)
            self._noise[key] = (evaluated, fit)
        return self._noise[key][1]

    def _fit_noise(self, evaluated):
        prep = self.cv.prep
        s, b = prep.samples, prep.binned
        resid = s.gyro - models.predict(evaluated.model, self.ctx, s, evaluated.full)
        resid_bins = b.gyro - models.predict(evaluated.model, self.ctx, b, evaluated.full)
        return noise_model.fit_noise(resid, s.time_s, prep.dt_s, prep.duration_s,
                                     resid_bins, b.time_s, prep.bin_s)

    def wander_of(self, evaluated):
        """
        Return what the intervals of a fitted model need (:class:`.sandwich.Wander`).

        The white density of its residual's noise (with a reference, the
        reference's) and the walk fitted per model on the super-bins of this
        record (:func:`.sandwich.wander_law`).
        """
        noise, sb, prep = self.noise_of(evaluated), self.superbins, self.cv.prep
        try:
            groups = statespace.Groups(sb.weight, sb.weight * prep.dt_s, sb.time_s)
        except ValueError:
            return sandwich.Wander(noise, sb)
        s = prep.samples
        resid = s.gyro - models.predict(evaluated.model, self.ctx, s, evaluated.full)
        cap = noise_model.random_walk_cap(resid, s.time_s, prep.dt_s, prep.duration_s,
                                          tau_max_s=math.inf)
        return sandwich.Wander(noise, sb, groups, sb.aggregate(prep.binned.gyro), cap)

    def sims_of(self, noise):
        """Noise records at the super-bins (the same random numbers for every noise model)."""
        return noise_model.draw_noise_records(noise, self.superbins, noise_model.N_SIM,
                                              np.random.default_rng(self.seed))

    def group_columns(self, model, phis):
        """Return the model's columns on the bins, averaged over the super-bins: (groups, p)."""
        b = self.cv.prep.binned
        cols = model.columns(self.ctx, b, phis)
        return np.column_stack([self.superbins.aggregate(c) for c in cols])

    def _candidate_spec(self, current, effect, candidate_eval):
        """
        Return the candidate's added columns on the groups for :func:`.noise_model.null_gain`.

        A step: its multiplier and the group starts. A cause that changes the
        scale-factor column (lag, pressure, mode split, delay): the change of
        that column at its full fit. Otherwise its columns,
        one set per value of its grid, thinned to at most 10 values, that
        the simulations search per fold as its fits do
        (:class:`.noise_model.Searched`). Returned with the ridge of the
        columns of the model extended, the current model's first, as they are
        in it (:meth:`.models.Model.penalty`).
        """
        b = self.cv.prep.binned
        phis = current.full.phis
        basis = current.model.basis(self.ctx, b, phis)
        extended = candidate_eval.model.penalty(self.ctx)
        n_current = current.model.n_columns
        held, own = np.split(extended, [n_current])
        if getattr(effect, 'change_point', False):
            g = self.superbins.aggregate(effect.multiplier(b, basis))
            return ('step', g, self.superbins.start_s), extended
        grids = effect.grids(self.ctx)
        if len(grids) > 1 or effect.n_columns == 0:
            full = candidate_eval.model.columns(self.ctx, b, candidate_eval.full.phis)
            new = [full[1] - basis.sr] + full[n_current:]
            return [np.column_stack([self.superbins.aggregate(c) for c in new])], \
                np.r_[held, 0.0, own]
        sets = {}

        def column_set(v):
            if v not in sets:
                phi = () if v is None else (v,)
                sets[v] = np.column_stack([self.superbins.aggregate(c) for c in
                                           effect.columns(self.ctx, b, phi, basis)])
            return sets[v]

        def unseen_of(train):
            return models.unseen_s(effect, b, train[self.superbins.group])

        # every other grid value at most 10: the simulations search a coarser grid
        values = None if not grids else \
            np.asarray(grids[0])[::max(1, len(grids[0]) // 10)]
        return noise_model.Searched(values, column_set, unseen_of, effect.time_shaped), extended

    def null_reduction(self, current, effect, candidate_eval):
        """
        Return what the record's noise alone gives ``effect``: per fold and in total.

        The mean reduction per fold (for the fold test) comes from the
        noise of the alternative, the residual with ``effect`` in it; the
        simulated totals (for the tail bound) from the wider of that and the
        current model's noise (:meth:`.noise_model.NoiseModel.wider`): a real
        effect raises the current model's wander, a cause that fits the
        wander lowers the alternative's, and the bound must not be lenient
        either way.

        Returns (mean positive reduction per fold, its share of the observed
        reduction, the simulated total reductions, whether the noise model
        saw the wander at the scale of a fold: an Allan deviation measured
        up to at least half a fold; a bursty record's is not).
        """
        cols = self.group_columns(current.model, current.full.phis)
        spec, extended = self._candidate_spec(current, effect, candidate_eval)
        penalty = (current.model.penalty(self.ctx), extended)
        alt = self.noise_of(candidate_eval)
        wide = alt.wider(self.noise_of(current))
        sims = noise_model.null_gain(cols, spec, self.superbins, self.sims_of(alt), penalty,
                                     alt.white_sigma_rad_s)
        sims_wide = noise_model.null_gain(cols, spec, self.superbins, self.sims_of(wide),
                                          penalty, wide.white_sigma_rad_s)
        reduction = np.mean(np.maximum(sims, 0.0), axis=1)
        drop = float(np.sum(current.sse_fold - candidate_eval.sse_fold))
        fold_s = self.cv.prep.duration_s / max(len(self.cv.used_folds), 1)
        return reduction, (float(np.sum(reduction)) / drop if drop > 0.0 else 1.0), \
            np.sum(sims_wide, axis=0), wide.tau_max_s >= 0.5 * fold_s

    def _state_space_null(self, current):
        """
        Return the current model on the super-bins for :mod:`.statespace` (None: too few groups).

        Group means of the output, the current model's columns (the
        nuisance), the walk cap from the current residual's short and
        middle averaging times (:func:`.noise_model.random_walk_cap`), the
        null's fit and, once needed, its bootstrap records.
        """
        key = id(current)
        if key not in self._ss:
            prep, sb = self.cv.prep, self.superbins
            s = prep.samples
            try:
                groups = statespace.Groups(sb.weight, sb.weight * prep.dt_s, sb.time_s)
            except ValueError:
                self._ss[key] = None
                return None
            resid = s.gyro - models.predict(current.model, self.ctx, s, current.full)
            cap = noise_model.random_walk_cap(resid, s.time_s, prep.dt_s, prep.duration_s)
            y = sb.aggregate(prep.binned.gyro)
            x0 = self.group_columns(current.model, current.full.phis)
            self._ss[key] = {'current': current, 'y': y, 'x0': x0, 'groups': groups,
                             'cap': cap, 'boot': None,
                             'null': statespace.fit_level(y, x0, groups, cap)}
        return self._ss[key]

    def _linear_columns(self, current, effect):
        """
        Return the columns a cause adds on the super-bins, when no search sets them.

        None for a cause that changes the scale-factor column or the delay,
        a step, or a searched cause (except the search-free columns of
        :data:`LR_COLUMNS`): their likelihood ratio after a search is not what
        the bootstrap calibrates. Only the columns :data:`LR_COLUMNS` names,
        where it names them.
        """
        pick = LR_COLUMNS.get(effect.effect_id)
        plain = (type(effect).sf_factor is Effect.sf_factor and
                 type(effect).delay_s is Effect.delay_s and
                 not getattr(effect, 'change_point', False) and effect.n_columns > 0)
        grids = effect.grids(self.ctx) if plain else ()
        if not plain or (grids and pick is None):
            return None
        b = self.cv.prep.binned
        phi = tuple(float(np.asarray(g)[0]) for g in grids)
        basis = current.model.basis(self.ctx, b, current.full.phis)
        cols = effect.columns(self.ctx, b, phi, basis)
        cols = [cols[i] for i in pick] if pick is not None else cols
        return np.column_stack([self.superbins.aggregate(c) for c in cols])

    def _step_columns(self, current, effect, candidate_eval):
        """
        Return (column, positions) of a scale-factor step at its fitted time, on the super-bins.

        The step time the least-squares search found on the whole record
        (``candidate_eval.full``) is moved to the nearest super-bin start, so
        the statistic is one of ``positions`` (the super-bins) and a
        Bonferroni factor of ``positions`` bounds its search. Only the
        scale-factor step: its column is the applied rate, which the output's
        wander does not follow; a bias step is one more step of a random
        walk and stays with the fold test.
        """
        if effect.effect_id != 'scale_factor_step':
            return None
        starts = self.superbins.start_s
        t0 = float(candidate_eval.full.phis[-1][0])
        snapped = float(starts[int(np.argmin(np.abs(starts - t0)))])
        b = self.cv.prep.binned
        basis = current.model.basis(self.ctx, b, current.full.phis)
        col = effect.columns(self.ctx, b, (snapped,), basis)[0]
        return self.superbins.aggregate(col)[:, None], len(starts)

    def _searched_columns(self, current, effect, candidate_eval):
        """
        Return (columns, effective tests) of a searched cause at its fitted value, on super-bins.

        For a cause with one searched parameter and columns that add to the
        output (``state_space_search``: a bias following dT/dt through a lag
        tau): its columns at the value the least-squares search found
        (``candidate_eval.full``), with the number of effectively independent
        tests its grid holds, M_eff of Li & Ji (2005) from the eigenvalues of
        the correlation matrix of the differenced columns over the grid
        (1 when they all move together, the grid's size when none does): the
        p of the test is multiplied by it, a Bonferroni bound over the search.
        A fit in the top cell of the grid (a bias that outlasts every gradient
        the cause describes: on a hysteresis record, tau = 300 s) is not
        established this way; the fold test alone decides it.
        """
        if not getattr(effect, 'state_space_search', False):
            return None
        grid = np.asarray(effect.grids(self.ctx)[0], dtype=float)
        if float(candidate_eval.full.phis[-1][0]) >= math.sqrt(grid[-2] * grid[-1]):
            return None
        b = self.cv.prep.binned
        basis = current.model.basis(self.ctx, b, current.full.phis)
        over = np.column_stack([
            self.superbins.aggregate(effect.columns(self.ctx, b, (v,), basis)[0]) for v in grid])
        fitted = tuple(candidate_eval.full.phis[-1])
        cols = np.column_stack([self.superbins.aggregate(c) for c in
                                effect.columns(self.ctx, b, fitted, basis)])
        return cols, effective_tests(np.diff(over, axis=0))

    def state_space_test(self, current, effect, m, candidate_eval=None):
        """
        Likelihood ratio of ``effect``'s columns on the super-bin means (:mod:`.statespace`).

        The noise (white plus a random walk capped by the Allan bound) and
        the effect are estimated jointly, so an effect cannot hide in the
        wander it inflates. The bootstrap runs only where it can move p
        across the decision level alpha / (2 m). A scale-factor step is
        tested at its fitted time with p multiplied by the positions it was
        searched over (:meth:`_step_columns`). Returns a
        :class:`.statespace.LrResult`, or None when the route does not apply.
        """
        cols, positions = self._linear_columns(current, effect), 1
        if cols is None and candidate_eval is not None:
            cols, positions = (self._step_columns(current, effect, candidate_eval)
                               or self._searched_columns(current, effect, candidate_eval)
                               or (None, 1))
        st = None if cols is None else self._state_space_null(current)
        if st is None:
            return None
        if self.reference is not None:
            if self._known is None:
                self._known = reference_mod.KnownNoise(self.reference, st['groups'],
                                                       self.cv.prep.dt_s)
            lr = self._known.lr_test(st['y'], st['x0'], cols)
            return replace(lr, p_value=min(1.0, positions * lr.p_value))

        def boot():
            if st['boot'] is None:
                st['boot'] = statespace.bootstrap_nulls(
                    st['null'], st['x0'], st['groups'], self._record_rng(st['y']),
                    st['cap'])
            return st['boot']

        lr = statespace.lr_test(st['y'], st['x0'], cols, st['groups'], None, st['cap'],
                                decide_at=W_LR * self.alpha / max(m, 1) / positions,
                                null_sims=boot, null=st['null'])
        if positions == 1:
            return lr
        return replace(lr, p_value=min(1.0, positions * lr.p_value))

    def _record_rng(self, values):
        """
        Return the bootstrap's generator: from the seed and the record's own group means.

        Deterministic for a record, and not the same draws for every record:
        a bootstrap's error then averages out over records instead of
        shifting every p-value the same way.
        """
        data = np.ascontiguousarray(values, dtype=float).tobytes()
        return np.random.default_rng([int(self.seed), zlib.crc32(data)])

    def binned_gain(self, ref_resid, new_resid):
        """
        Held-out RMS gain on the super-bin means (the verdict's averaging time).

        ``ref_resid``, ``new_resid``: held-out residuals of every kept sample.
        """
        sb = self.superbins

        def mean_square(r):
            means = np.bincount(self._group_of_sample, weights=r, minlength=len(sb)) / sb.weight
            return float(np.sum(sb.weight * means * means))

        ref = mean_square(ref_resid)
        return 1.0 - math.sqrt(mean_square(new_resid) / ref) if ref > 0.0 else 0.0

    def score(self, current, effect, m):
        """Score ``effect`` added to ``current`` (a :class:`.cv.Evaluated`) as a Candidate."""
        model = current.model.extend(effect)
        fixed = {k: f.phis for k, f in current.fits.items()}
        ev = self.cv.evaluate(model, fixed, current.full.phis, current)
        reduction, share, totals, measured = self.null_reduction(current, effect, ev)
        p_fold = cvmod.fold_test(current.sse_fold, ev.sse_fold, reduction)
        if measured:
            p_sim = cvmod.tail_bound(float(np.sum(current.sse_fold - ev.sse_fold)), totals)
            p_fold = min(1.0, 2.0 * min(p_fold, p_sim))
        lr = self.state_space_test(current, effect, m, ev)
        p, route = p_fold, 'fold_test'
        if lr is not None:
            # either route may establish the cause: a weighted Bonferroni over the
            # two, most of alpha to the likelihood ratio (the efficient test of a
            # slow cause), a tenth to the fold test as a model-free backstop
            p = min(1.0, lr.p_value / W_LR, p_fold / (1.0 - W_LR))
            if lr.p_value / W_LR < p_fold / (1.0 - W_LR):
                route = 'state_space' if self.reference is None else 'reference_noise'

        b = self.cv.prep.binned
        resid_bins = b.gyro - models.predict(model, self.ctx, b, ev.full)
        n_eff = cvmod.effective_bins(resid_bins, b.weight)
        dbic = cvmod.effective_bic(ev.full.sse, current.full.sse, effect.n_params, n_eff)
        gain = 1.0 - ev.rmse / current.rmse
        cand = Candidate(effect, ev, p, gain, dbic, n_eff, share, p_fold=p_fold,
                         p_statespace=None if lr is None else lr.p_value,
                         lr=None if lr is None else lr.lr,
                         gain_binned=self.binned_gain(current.resid, ev.resid), route=route,
                         gain_predictive=None if lr is None else lr.gain_predictive,
                         wander=functools.partial(self.wander_of, ev))
        # the fold test counts the gain per sample and needs the BIC; the
        # likelihood route counts it where the effect lives, in the group means
        # predicted one step ahead (the held-out gain of fixed-level folds is
        # swamped by any slow effect not yet in the model: -14 % for a
        # g-sensitivity at LR 100 beside an unmodelled ramp)
        if route in ('state_space', 'reference_noise'):
            # ... but a cause that predicts the held-out folds significantly
            # worse than the model without it fits some other mismatch
            # (a polynomial in the rate taking up an SF step: -140 %)
            worse = cvmod.fold_test(ev.sse_fold, current.sse_fold) < ALPHA_TIE
            enough = cand.gain_predictive >= gain_floor(effect) and not worse
        else:
            enough = gain >= gain_floor(effect) and dbic < DELTA_BIC_MAX
        supported = bool(enough and p < self.alpha / max(m, 1))
        cand.significant = supported and self._confirmed(cand, current)
        return cand

    def _confirmed(self, cand, current):
        """
        Tell whether a supported candidate holds on held-out data and stands clear of zero.

        Sets ``cand.in_sample_only`` (why not) when it does not.
        """
        ev, effect = cand.evaluated, cand.effect
        if cand.gain_step <= 0.0 and cand.gain_binned <= 0.0:
            cand.in_sample_only = (
                f'held-out gain {100 * cand.gain_step:.3g} % per sample and '
                f'{100 * cand.gain_binned:.3g} % in the group means: it does not predict '
                'the held-out data better')
            return False
        found = intervals.linear_estimates(effect, ev, self.ctx, self.cv.prep.binned)
        if not intervals.clear_of_zero(effect, found, self.ctx, current.full.sse, ev.full.sse,
                                       cand.n_eff, SIZE_Z, ev):
            cand.in_sample_only = f'its estimate is within {SIZE_Z:g} sigma of zero'
            return False
        return True

    def step(self, current, effects):
        """
        Score every effect against ``current``; return (ranked candidates, chosen or None).

        See the module docstring for the rules.
        """
        cands = [self.score(current, e, len(effects)) for e in effects]
        cands.sort(key=lambda c: c.evaluated.rmse)
        sig = [c for c in cands if c.significant]
        if not sig:
            return cands, None
        top = sig[0]
        near = [c for c in sig if c is top or
                cvmod.fold_test(c.evaluated.sse_fold, top.evaluated.sse_fold) >= ALPHA_TIE]
        by_id = {c.effect.effect_id: c for c in cands}
        eligible = [c for c in near if self._beats_competitors(c, by_id)] or \
            [c for c in near if c.effect.kind == 'generic'] or near
        chosen = eligible[0]
        simpler = [c for c in eligible if c.effect.kind == chosen.effect.kind
                   and c.effect.n_params < chosen.effect.n_params]
        if simpler:
            chosen = min(simpler, key=lambda c: (c.effect.n_params, c.evaluated.rmse))
        # a cause that predicts the held-out data better than the one chosen
        # cannot be excluded, even where it fell short of the level itself
        # (on ADIS16405 noise under a rate sine: an SF step at p 0.0016, a
        # pressure drift at p 0.0014, the level 0.0014: both are named)
        chosen.indistinguishable = [
            c.effect.effect_id for c in cands if c is not chosen
            and (c.significant or c.evaluated.rmse < chosen.evaluated.rmse)
            and cvmod.fold_test(c.evaluated.sse_fold, chosen.evaluated.sse_fold) >= ALPHA_TIE]
        return cands, chosen

    @staticmethod
    def _beats_competitors(cand, by_id):
        """Tell whether a cause beats each generic competitor tested (p < ALPHA_TIE)."""
        for comp in cand.effect.competitors:
            other = by_id.get(comp)
            if other is not None and cvmod.fold_test(
                    other.evaluated.sse_fold, cand.evaluated.sse_fold) >= ALPHA_TIE:
                return False
        return True


def effective_tests(columns):
    """
    Effective number of independent tests among correlated columns (Li & Ji 2005).

    M_eff = sum_i [1(lambda_i >= 1) + (lambda_i - floor(lambda_i))] over the
    eigenvalues of the columns' correlation matrix; at least 1.
    """
    x = np.asarray(columns, dtype=float)
    x = x - x.mean(axis=0)
    norm = np.sqrt(np.sum(x * x, axis=0))
    x = x[:, norm > 0.0] / norm[norm > 0.0]
    if x.shape[1] <= 1:
        return 1.0
    lam = np.clip(np.linalg.eigvalsh(x.T @ x), 0.0, None)
    return max(1.0, float(np.sum((lam >= 1.0) + (lam - np.floor(lam)))))


def gain_floor(effect):
    """Return the held-out gain a cause must reach: MIN_GAIN, or MIN_GAIN_RATE on the rate."""
    return MIN_GAIN_RATE if 'rate' in effect.needs else MIN_GAIN


def forward_selection(selector, null, effects, max_causes=MAX_CAUSES):
    """
    Run the steps from the recalibrated baseline ``null``.

    Returns ``(steps, final)``: per step, the ranked candidates and the
    chosen one (None at the last step when nothing was significant), and
    the final :class:`.cv.Evaluated`.
    """
    current, remaining, steps = null, list(effects), []
    while remaining and len(steps) < max_causes:
        cands, chosen = selector.step(current, remaining)
        steps.append((cands, chosen))
        if chosen is None:
            break
        current = chosen.evaluated
        # every other cause is scored again: one that made the prediction
        # worse alone can help once another has joined (a bias tempco beside
        # a scale-factor tempco, a dT/dt bias beside a thermal lag)
        remaining = [e for e in remaining if e is not chosen.effect]
    return steps, current
