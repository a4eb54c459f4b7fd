"""
A continuous searched parameter's interval, widened as a coefficient's.

A searched parameter's profile interval (:mod:`.intervals`) scales the SSE
by the residual's effective bins, which a wander as slow as the cause does
not reach. :func:`widen` makes it the union of the profile's and phi +-
t_{K-1} sigma, sigma the larger of the jackknife over the folds
(:func:`fold_sigma`) and the sandwich under the record's noise law,
linearised in phi (:func:`searched_sigma`), as a coefficient's interval is.
"""

from dataclasses import replace
import math

from gyro_emulator.analysis.diagnose import models
from gyro_emulator.analysis.diagnose.sandwich import LEVEL, linear_variance, measured
import numpy as np
from scipy.special import stdtrit

#: Said of a searched parameter's interval that was widened (:func:`widen`).
NOTE = ('; widened to the larger of the jackknife over the folds and the '
        "linearised sandwich under the record's noise law")
#: Relative step of the derivative of a prediction in a searched parameter.
JACOBIAN_STEP = 1e-3


def searched_sigma(evaluated, ctx, frame, wander, span):
    """
    Return the sandwich 1-sigma of the last cause's one searched parameter, linearised.

    Near the fit the prediction is linear in (beta, phi) (Gauss-Newton;
    Seber & Wild 1989, ch. 5): phi's column is the derivative of the
    prediction, J = d pred / d phi (central difference, relative step
    :data:`JACOBIAN_STEP`, the coefficients held; one-sided where phi is
    within a step of an end of the searched range ``span`` = (first, last),
    whose parameters may not exist beyond it), and phi's weights on the
    bin means are the last row of the regularised normal matrix's inverse of
    [X, J] times [X, J]' W (the causes' ridge on X, none on J). Its variance
    under the record's noise law (white noise and the walk the local level
    sees, :meth:`.sandwich.Wander.law`) is then that of a coefficient
    (:func:`.sandwich.linear_variance`). 0 where the prediction does not depend on phi.
    """
    model, full = evaluated.model, evaluated.full
    phi = float(full.phis[-1][0])
    step = JACOBIAN_STEP * abs(phi) if phi else JACOBIAN_STEP
    head = tuple(full.phis[:-1])

    def predict_at(value):
        return models.predict(model, ctx, frame, replace(full, phis=head + ((value,),)))

    low, high = max(phi - step, span[0]), min(phi + step, span[1])
    if high <= low:
        return 0.0
    inside = (low, high) == (phi - step, phi + step)
    jac = (predict_at(high) - predict_at(low)) / (2.0 * step if inside else high - low)
    n, w = len(frame), frame.weight
    if not measured(jac, w):
        return 0.0
    x = np.column_stack([np.broadcast_to(c, (n,)) for c in model.columns(ctx, frame, full.phis)]
                        + [jac])
    rows = models.coefficient_map(x, w, np.r_[model.penalty(ctx), 0.0])[-1:]
    u = rows @ (x * w[:, None]).T
    var = linear_variance(u, w, wander.law(model, ctx, frame, full.phis), wander.superbins)
    return math.sqrt(max(float(var[0]), 0.0))


def fold_sigma(evaluated):
    """Return the delete-a-fold jackknife sigma of the last cause's one searched parameter."""
    theta = np.array([float(fit.phis[-1][0]) for fit in evaluated.fits.values()])
    k = len(theta)
    return math.sqrt((k - 1) / k * float(np.sum((theta - theta.mean()) ** 2)))


def widen(effect, evaluated, ctx, frame, wander, ends):
    """
    Widen a continuous searched parameter's profile interval as a coefficient's, t_{K-1}.

    The profile's threshold scales the SSE by the residual's effective bins,
    which a wander as slow as the cause itself does not reach: a warm-up's
    time constant trades with the record's random walk. On seeded 1200 s
    records with a warm-up (tau 300 s, 2e-2 rad/s) beside a walk of 2e-5
    and 5e-5 rad/s/sqrt(s) the profile interval held the truth on 44 and
    25 of 60. The interval is the union of the profile's and phi +- t_{K-1}
    sigma, sigma the larger of the jackknife over the folds
    (:func:`fold_sigma`) and the linearised sandwich under the record's
    noise law (:func:`searched_sigma`), as a coefficient's
    (:func:`.intervals.linear_estimates`): 59 and 55 of 60. The law's walk is often 0
    on such a record (the warm-up and drift columns take up what the local
    level would see), and the sandwich alone held 50 and 38; with the true
    walk in the law it held 59 and 56. The interval is kept inside the
    searched range (an end there is open). Returns (ends, widened).
    """
    lo, hi, olo, ohi = ends
    grid = np.asarray(effect.grids(ctx)[0], dtype=float)
    first, last = float(grid.min()), float(grid.max())
    sigma = max(searched_sigma(evaluated, ctx, frame, wander, (first, last)),
                fold_sigma(evaluated))
    phi = float(evaluated.full.phis[-1][0])
    half = float(stdtrit(len(evaluated.fits) - 1, 0.5 + LEVEL / 2.0)) * sigma
    new_lo, new_hi = max(min(lo, phi - half), first), min(max(hi, phi + half), last)
    widened = (new_lo, new_hi) != (lo, hi)
    return (new_lo, new_hi, olo or (widened and new_lo <= first),
            ohi or (widened and new_hi >= last)), widened
