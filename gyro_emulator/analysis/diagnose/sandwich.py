"""
The sandwich of an estimate linear in the bin means, under the record's noise law.

What every interval that reads the record's noise law shares (:mod:`.intervals`,
:mod:`.searched`): whether a column varies over the record (:func:`measured`),
the noise law of a model (:class:`Wander`: white noise and the random walk
the local level sees, :func:`wander_law`) and the variance of weights on
the bin means under it (:func:`linear_variance`).
"""

from dataclasses import dataclass, replace
import math

from gyro_emulator.analysis.diagnose import noise_model, statespace
import numpy as np

#: Two-sided level of every parameter interval.
LEVEL = 0.95


def measured(column, weight):
    """Tell whether a column varies over the record (a coefficient the record can measure)."""
    c = np.broadcast_to(np.asarray(column, float), weight.shape)
    mean = float(np.sum(weight * c) / np.sum(weight))
    spread = math.sqrt(float(np.sum(weight * (c - mean) ** 2) / np.sum(weight)))
    return spread > 1e-12 * max(abs(mean), 1e-300) and spread > 0.0


@dataclass(frozen=True)
class Wander:
    """
    What a coefficient's sandwich needs: the noise and the super-bins it acts on.

    ``noise`` (:class:`.noise_model.NoiseModel`) gives the white density;
    with ``groups`` (:class:`.statespace.Groups` of the super-bins) and
    ``y_groups`` (the output's group means) the walk is fitted for each
    model the sandwich is taken of (:func:`wander_law`, at most ``rw_cap``);
    without them (a record of fewer than 8 groups) ``noise`` is the law as
    it is.
    """

    noise: object
    superbins: object
    groups: object = None
    y_groups: object = None
    rw_cap: float = math.inf

    def law(self, model, ctx, frame, phis):
        """Return the noise law under ``model`` with the searched parameters ``phis``."""
        if self.groups is None:
            return self.noise
        sb = self.superbins
        x = np.column_stack([sb.aggregate(c) for c in model.columns(ctx, frame, phis)])
        return wander_law(self.noise, self.y_groups, x, self.groups, self.rw_cap)


def wander_law(noise, y_groups, x_groups, groups, rw_cap=math.inf):
    """
    Return the noise law of a model's intervals: white noise and the walk of the record.

    ``noise`` is the residual's (:func:`.noise_model.fit_noise`); its white
    density is kept. Its flicker and walk come from an Allan fit up to a
    tenth of the record, which misses a wander slower than that (a warm-up
    trend, the walk over the whole record: what biases a step or a tempco)
    and, on white noise, often reports a spurious term. The walk is the
    maximum-likelihood local level's instead (:func:`.statespace.fit_level`)
    of the group means ``y_groups`` on the model's columns ``x_groups``: it
    measures the wander over the whole record, jointly with the model, and
    is 0 where the record shows none. ``rw_cap`` (rad^2/s^3) is the walk
    the model's residual allows at every averaging time up to a quarter of
    its longest segment (:func:`.noise_model.random_walk_cap` with
    ``tau_max_s``): a misfit of the rate within the groups is not a walk.
    """
    try:
        walk = statespace.fit_level(y_groups, x_groups, groups, rw_cap).rw_var_rad2_s3
    except ValueError:
        return noise
    return replace(noise, bias_instability_rad_s=0.0, rrw_rad_s_sqrt_s=math.sqrt(max(walk, 0.0)))


def linear_variance(u, weight, noise, superbins):
    """
    Return the variance of estimates u @ ybar under white noise and the wander of ``noise``.

    ``u`` (k, bins): each estimate's weights on the bin means ybar, whose
    sample counts are ``weight``. White noise of density N gives a bin mean
    of n samples the variance N^2 / (n dt); the wander
    (:func:`.noise_model.wander_covariance`) is taken at the super-bins,
    within which it barely moves: u summed over each super-bin.
    """
    sb = superbins
    if len(u) == 0:
        return np.zeros(0)
    white = noise.arw_rad_s_sqrt_hz ** 2 / sb.dt_s
    inv_w = 1.0 / np.maximum(weight, 1e-300)
    h = np.stack([np.bincount(sb.group, weights=row, minlength=len(sb)) for row in u])
    return white * np.einsum('ij,ij,j->i', u, u, inv_w) + np.einsum(
        'ij,ij->i', h @ noise_model.wander_covariance(noise, sb), h)
