"""
Drawing the parts of a fleet: one seeded generator per block of devices.

Devices are numbered 0, 1, ... and grouped in blocks of :data:`BLOCK_DEVICES`.
Block k draws from ``numpy.random.SeedSequence(seed).spawn(...)[k]`` (built
directly as ``SeedSequence(seed, spawn_key=(k,))``, the same sequence), so
device i is the same part whatever the scheduler, the number of workers or
how blocks are grouped into tasks. Within a block the tolerances draw in
name order, then the factors: n standard normals (``normal``) or uniforms on
[-1, 1) (``uniform``) each, scaled.

A drawn part outside the physics' valid range (a field range of
:mod:`gyro_emulator.physics.params`, holes larger than the plate, a beam
made thinner than zero by the sense mismatch) is never passed on: with
``invalid: reject`` it is marked invalid (counted, its metrics NaN, it fails
every spec) and evaluated at the nominal; with ``invalid: clip`` each field
is clipped into its range (counted as clipped) and only parts that still
break a cross-field rule are rejected.
"""

from dataclasses import dataclass, replace
from types import SimpleNamespace

from gyro_emulator import validation
from gyro_emulator.analysis.fleet.config import DEVICE_GROUPS, MISMATCH
from gyro_emulator.physics import params
import numpy as np

#: Devices per block: the unit of seeding (part of the seeded-output contract).
BLOCK_DEVICES = 1 << 16


def block_count(n_devices):
    """Return the number of blocks of ``n_devices`` devices."""
    return -(-int(n_devices) // BLOCK_DEVICES)


def block_size(n_devices, block):
    """Return the number of devices of ``block``."""
    return min(BLOCK_DEVICES, int(n_devices) - block * BLOCK_DEVICES)


def block_seed(seed, block):
    """Return block ``block``'s SeedSequence: ``SeedSequence(seed).spawn(...)[block]``."""
    return np.random.SeedSequence(seed, spawn_key=(int(block),))


@dataclass
class Draw:
    """
    The sampled parameters of one block.

    ``nominal`` maps every varied parameter to its nominal value;
    ``contributions[source][parameter]`` is what a source (a tolerance, or
    ``factor.<name>``) adds to it, arrays of n.
    """

    n: int
    nominal: dict
    contributions: dict

    def values(self, without=None):
        """Parameter arrays: nominal plus every contribution but ``without``'s, in order."""
        out = {name: np.full(self.n, value) for name, value in self.nominal.items()}
        for source, parts in self.contributions.items():
            if source == without:
                continue
            for name, part in parts.items():
                out[name] = out[name] + part
        return out


def draw_block(config, seed, block, n):
    """
    Draw the ``n`` parts of ``block`` (see the module docstring).

    Returns
    -------
    Draw

    """
    rng = np.random.Generator(np.random.SFC64(block_seed(seed, block)))
    nominal = {name: config.parameters[name].nominal for name in config.varied}
    contributions = {}
    for tol in config.tolerances:
        z = _unit(rng, tol.dist, n)
        contributions[tol.name] = {tol.name: tol.offset + tol.scale * z}
    for factor in config.factors:
        value = factor.scale * _unit(rng, factor.dist, n)
        parts = {}
        for name, coefficient in factor.moves:
            scale = coefficient * (abs(nominal[name]) if factor.relative else 1.0)
            parts[name] = scale * value
        contributions['factor.' + factor.name] = parts
    return Draw(n, nominal, contributions)


def _unit(rng, dist, n):
    if dist == 'normal':
        return rng.standard_normal(n)
    return rng.uniform(-1.0, 1.0, n)


def _outside(param, values):
    """Mask of values outside the parameter's range (NaN counts as outside)."""
    return validation.outside(values, param.low, param.high, param.low_open)


def _clip(param, values):
    low = -np.inf if param.low is None else (
        np.nextafter(param.low, np.inf) if param.low_open else param.low)
    high = np.inf if param.high is None else param.high
    return np.clip(values, low, high)


def checked(config, values, n):
    """
    Validate n parts' drawn parameter arrays; return (values, invalid, clipped masks).

    Invalid parts get the nominal values (so the physics runs on valid
    numbers) and are reported by the mask; see the module docstring.
    """
    invalid = np.zeros(n, dtype=bool)
    clipped = np.zeros(n, dtype=bool)
    out = dict(values)
    for name, arr in values.items():
        bad = _outside(config.parameters[name], arr)
        if not bad.any():
            continue
        if config.invalid == 'clip':
            out[name] = _clip(config.parameters[name], arr)
            clipped |= bad
        else:
            invalid |= bad
    invalid |= _cross_field(config, out, n)
    if invalid.any():
        for name in out:
            out[name] = np.where(invalid, config.parameters[name].nominal, out[name])
    return out, invalid, clipped & ~invalid


def _cross_field(config, values, n):
    """
    Return the parts that break a rule between fields.

    Holes larger than the plate, beams <= 0, a Young's modulus that falls
    below its floor at a model temperature.
    """
    g = config.device.geometry
    side = _param_or(values, 'geometry.plate_side_m', g.plate_side_m)
    hole = _param_or(values, 'geometry.hole_side_m', g.hole_side_m)
    bad = np.asarray(g.hole_count * hole ** 2 >= side ** 2)
    m = config.device.material
    drawn = {name: _param_or(values, 'material.' + name, getattr(m, name)) for name in (
        'youngs_modulus_pa', 'youngs_ref_temp_c', 'youngs_temp_coeff_pa_k')}
    bad = bad | (params.lowest_youngs_modulus_pa(SimpleNamespace(
        youngs_modulus_law=m.youngs_modulus_law, **drawn)) < params.MIN_YOUNGS_MODULUS_PA)
    delta = _param_or(values, MISMATCH, config.parameters[MISMATCH].nominal)
    for width in ('beam1_width_m', 'beam2_width_m'):
        bad = bad | (_param_or(values, 'geometry.' + width, getattr(g, width)) + delta <= 0.0)
    return np.broadcast_to(bad, (n,)).copy()


def _param_or(values, name, default):
    return values[name] if name in values else default


def device_of(config, values):
    """
    Return the fleet's Device with the drawn fields as arrays of n.

    The fields broadcast against a temperature grid of shape (T, 1): every
    first-order quantity comes out (T, n) in one call, one row per
    temperature (row reductions are then element-wise over devices).
    """
    device = config.device
    changes = {}
    for group in DEVICE_GROUPS:
        prefix = group + '.'
        fields = {name[len(prefix):]: arr for name, arr in values.items()
                  if name.startswith(prefix)}
        if fields:
            changes[group] = replace(getattr(device, group), **fields)
    return replace(device, **changes) if changes else device


def sense_geometry(config, geometry, values):
    """Return the geometry the sense mode bends: beam widths plus the x/y mismatch."""
    delta = _param_or(values, MISMATCH, config.parameters[MISMATCH].nominal)
    return replace(geometry, beam1_width_m=geometry.beam1_width_m + delta,
                   beam2_width_m=geometry.beam2_width_m + delta)
