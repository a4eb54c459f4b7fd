"""
The compiled kernel of :class:`gyro_emulator.sensor.model.GyroModel`.

Every term (see :mod:`gyro_emulator.sensor.model` for the equations) in one
pass over a block of samples, the three axes side by side as the lanes of one
SIMD vector (:mod:`gyro_emulator.sensor.simd`), each lane's arithmetic that
of a scalar per-sample pass in the same order (so the result does not depend
on the block size and is bit for bit the scalar kernel's), on three parameter
structs (numba-supported namedtuples of arrays):

* :class:`Coefficients` -- read-only, precomputed by
  :class:`gyro_emulator.sensor.plan.Plan`: switches (``flags``), scalars and
  per-axis rows packed in arrays indexed by the ``F_*``, ``S_*`` and ``A_*``
  constants below (compile-time constants in numba), temperature tables,
  filter coefficients and the flicker sections;
* :class:`State` -- the mutable state carried between calls;
* :class:`Outputs` -- the output arrays, in :class:`SensorBatch` field order.

The standard normals come pre-drawn from the public numpy ``Generator`` API
(:mod:`gyro_emulator.sensor.streams`): the m-th sample of a call reads
``normals[k, pos[k] + m]`` of each stream ``k`` its terms use, then ``pos``
advances. Every used stream consumes exactly one normal per sample, so the
samples do not depend on how a record is split into calls.

Exact discretisation throughout: first-order lags and Gauss-Markov sections
phi = exp(-dt/T); white sigma N sqrt(fs); walk steps K sqrt(dt).
"""

from collections import namedtuple
import math

from gyro_emulator.sensor.simd import (vabs, vget, vlane, vload4, vmax, vmin, vpack, vput,
                                       vrint, vrow, vsplat, vsqrt, vstore4, vstore_greater,
                                       vwhere)
from gyro_emulator.sensor.streams import FLICKER, JITTER, RRW, WHITE
import numba
import numpy as np

#: Switches (int64, 0 or 1).
(F_THERMAL, F_SF, F_MIS, F_NONLIN, F_DYN, F_BIAS_T, F_GSENS, F_FLICKER,
 F_RRW, F_WHITE, F_MECH, F_LPF, F_SAT, F_QUANT, F_JITTER, F_DRIFT) = range(16)
FLAG_COUNT = 16
#: Largest timestamp jitter, in sample periods (stamps stay strictly increasing).
JITTER_BOUND = 0.45
#: Scalars (float64).
(S_PHI, S_GAIN, S_HEAT, S_INIT_DIE, S_LOW_C, S_STEPS, S_SQRT_FS, S_LATENCY,
 S_JITTER, S_DT, S_DRIFT, S_TEMP_LO, S_TEMP_HI) = range(13)
SCALAR_COUNT = 13
#: Per-axis rows (float64, (rows, 3)).
(A_SF1, A_NONLIN, A_CAL, A_C1, A_C2, A_TURN_ON, A_FLICKER_B, A_RRW_STEP,
 A_ELEC_SQ, A_WHITE_SIGMA, A_RANGE, A_SAT_LIMIT, A_LSB) = range(13)
AXIS_ROWS = 13
#: Integer state: sample index, ready flags of the die temperature and filters.
I_INDEX, I_DIE_READY, I_DYN_READY, I_LPF_READY = range(4)

Coefficients = namedtuple('Coefficients', [
    'flags', 'scalars', 'axis', 'misalignment', 'g_sensitivity', 'sf_tab', 'sf_index',
    'mech_tab', 'mech_index', 'dyn_b', 'dyn_a', 'dyn_zi', 'lpf_b', 'lpf_a', 'lpf_zi',
    'flicker_phi', 'flicker_gains', 'streams'])
Coefficients.__doc__ = 'Read-only coefficients of the kernel (built by sensor.plan.Plan).'

State = namedtuple('State', ['ints', 'die_c', 'dyn_z', 'lpf_z', 'flicker', 'rrw'])
State.__doc__ = 'Mutable kernel state: I_* integers, die temperature, filter and noise states.'

Outputs = namedtuple('Outputs', ['gyro', 'die', 'bias', 'gain', 'sat', 'delay'])
Outputs.__doc__ = 'Output arrays of a call, SensorBatch order (the true rate is the input).'


def consumed_streams(flags):
    """Return the streams the kernel reads one normal from per sample, for ``flags``."""
    streams = [JITTER] if flags[F_JITTER] else []
    for on, first in ((F_WHITE, WHITE), (F_FLICKER, FLICKER), (F_RRW, RRW)):
        if flags[on]:
            streams += [first, first + 1, first + 2]
    return np.array(sorted(streams), dtype=np.int64)


@numba.njit(cache=True, error_model='numpy')
def advance(rate, amb, accel, xbias, xgain, coef, state, normals, pos, out, start, stop):
    """
    Advance the model over samples ``start:stop`` of a record.

    ``rate`` (n, 3), ``amb`` (n,) and ``accel`` ((n, 3), (1, 3) held, or
    (0, 3) for none) are the whole record; ``xbias`` and ``xgain`` (rows 0 to
    ``stop - start - 1`` for samples ``start:stop`` and at least one row
    more, read four doubles at a time; or (0, 3) for none) are the extended
    terms' additive bias and gain multiplier of the block
    (:mod:`gyro_emulator.sensor.extensions`); ``stop - start`` must not exceed
    the unread normals of any used stream. The call with ``start == 0`` first
    computes and checks the die temperature of the WHOLE record: it returns
    1 + the index of the first one outside the model range, having written
    only ``out.die`` (state and streams intact). Otherwise returns 0.
    """
    if start == 0:
        bad = _die_temperatures(amb, coef, state, out.die)
        if bad:
            return bad
    _samples(rate, accel, xbias, xgain, coef, state, normals, pos, out, start, stop)
    n = stop - start
    for k in coef.streams:
        pos[k] += n
    state.ints[I_INDEX] += n
    return 0


def die_temperatures(amb, coef, state, die):
    """
    Write the die temperatures of ambients ``amb`` (N,) into ``die`` (N,), from ``state``.

    The lag of :func:`advance` alone (the same compiled loop): ``state``'s
    die temperature advances. Returns 0, or 1 + the index of the first die
    temperature out of the model range.
    """
    return _die_temperatures(amb, coef, state, die)


@numba.njit(cache=True, error_model='numpy')
def _die_temperatures(amb, coef, state, die):
    """Exact first-order lag T[n] = phi T[n-1] + (1 - phi) T_target[n]; 0 or 1 + bad index."""
    sc, ints = coef.scalars, state.ints
    heat, phi, gain = sc[S_HEAT], sc[S_PHI], sc[S_GAIN]
    thermal = coef.flags[F_THERMAL] != 0
    if ints[I_DIE_READY]:
        last = state.die_c[0]
    elif thermal and not math.isnan(sc[S_INIT_DIE]):
        last = sc[S_INIT_DIE]
    else:
        last = amb[0] + heat
    lo, hi = sc[S_TEMP_LO], sc[S_TEMP_HI]
    for j in range(amb.shape[0]):
        target = amb[j] + heat
        last = phi * last + gain * target if thermal else target
        die[j] = last
        if not lo <= last <= hi:
            return j + 1
    state.die_c[0] = last
    ints[I_DIE_READY] = 1
    return 0


@numba.njit(cache=True, error_model='numpy')
def _switches(flags):
    """Return the switches as a tuple of booleans (registers, not memory, in the loop)."""
    return (flags[0] != 0, flags[1] != 0, flags[2] != 0, flags[3] != 0, flags[4] != 0,
            flags[5] != 0, flags[6] != 0, flags[7] != 0, flags[8] != 0, flags[9] != 0,
            flags[10] != 0, flags[11] != 0, flags[12] != 0, flags[13] != 0,
            flags[14] != 0, flags[15] != 0)


@numba.njit(cache=True, error_model='numpy')
def _samples(rate, accel, xbias, xgain, coef, state, normals, pos, out, start, stop):
    """
    Every term of samples ``start:stop``, whose die temperatures are in ``out.die``.

    One pass, sample by sample (:func:`_loop`), the three axes side by side
    as the lanes of one vector (:mod:`gyro_emulator.sensor.simd`: each
    operation on the three axes is one instruction, each lane's arithmetic
    that of a scalar pass in the same order, so the result does not depend on
    the block size). Filter and walk states and up to 8 flicker sections live
    in registers; more sections and an output low-pass of order 3 or 4 keep
    theirs in small arrays of lane rows.
    """
    on = _switches(coef.flags)
    ax, sc = coef.axis, coef.scalars
    quantise = vpack(1.0 if on[F_QUANT] and ax[A_LSB, 0] > 0.0 else 0.0,
                     1.0 if on[F_QUANT] and ax[A_LSB, 1] > 0.0 else 0.0,
                     1.0 if on[F_QUANT] and ax[A_LSB, 2] > 0.0 else 0.0)
    limit, gs = vrow(ax, A_SAT_LIMIT), _lanes(coef.g_sensitivity)
    g_held = vsplat(0.0)
    if accel.shape[0] == 1:
        g_held = (vsplat(accel[0, 0]) * vload4(gs, 0) + vsplat(accel[0, 1]) * vload4(gs, 1)
                  + vsplat(accel[0, 2]) * vload4(gs, 2))
    const = (vrow(ax, A_SF1), vrow(ax, A_NONLIN), vrow(ax, A_CAL), vrow(ax, A_C1),
             vrow(ax, A_C2), vrow(ax, A_TURN_ON), vrow(ax, A_FLICKER_B),
             vrow(ax, A_RRW_STEP), vrow(ax, A_ELEC_SQ), vrow(ax, A_WHITE_SIGMA),
             vwhere(quantise, vrow(ax, A_LSB), vsplat(1.0)), quantise, vrow(ax, A_RANGE),
             limit, vsplat(0.0) - limit, vsplat(sc[S_SQRT_FS]), g_held)
    mis, db, da = _lanes(coef.misalignment), _lanes(coef.dyn_b), _lanes(coef.dyn_a)
    lb, la = _lanes(coef.lpf_b), _lanes(coef.lpf_a)
    top = lb.shape[0] - 1
    rows = (vload4(mis, 0), vload4(mis, 1), vload4(mis, 2), vload4(gs, 0), vload4(gs, 1),
            vload4(gs, 2), vload4(db, 0), vload4(db, 1), vload4(db, 2), vload4(da, 1),
            vload4(da, 2), vload4(lb, 0), vload4(lb, min(1, top)), vload4(lb, min(2, top)),
            vload4(la, min(1, top)), vload4(la, min(2, top)))
    fl, dz, lz = _lanes(state.flicker), _lanes(state.dyn_z), _lanes(state.lpf_z)
    # Rows below ``wide`` are read and written four doubles at a time (the
    # spare lane touches the next row's first element, written later).
    wide = stop - start if stop < rate.shape[0] else stop - start - 1
    walk = _loop(rate[start:stop], accel if accel.shape[0] <= 1 else accel[start:stop],
                 xbias, xgain, coef, state.ints, normals, pos, out, start, stop, wide, on,
                 const, rows,
                 lb, la, fl, dz, lz, vpack(state.rrw[0], state.rrw[1], state.rrw[2]))
    _lanes_out(fl, state.flicker)
    _lanes_out(dz, state.dyn_z)
    _lanes_out(lz, state.lpf_z)
    state.rrw[0], state.rrw[1], state.rrw[2] = vlane(walk, 0), vlane(walk, 1), vlane(walk, 2)
    if not on[F_SAT]:
        out.sat[start:stop] = False
    _delays(normals[JITTER, pos[JITTER]:], sc, on, out.delay[start:stop])


@numba.njit(cache=True, error_model='numpy')
def _loop(rate, accel, xbias, xgain, coef, ints, normals, pos, out, start, stop, wide, on,
          const, rows, lb, la, fl, dz, lz, walk):
    """Run the per-sample pass of :func:`_samples` (equations: sensor.model)."""
    (sf1, nl, cal, c1, c2, turn_on, fb, walk_step, elec, sigma, lsb, quantise, full, limit,
     neg_limit, sqrt_fs, g_held) = const
    m0, m1, m2, g0, g1, g2, b0, b1, b2, a1, a2, lb0, lb1, lb2, la1, la2 = rows
    die, gain, bias, gyro, sat = (out.die[start:stop], out.gain[start:stop],
                                  out.bias[start:stop], out.gyro[start:stop],
                                  out.sat[start:stop])
    sf, mech, tx, ty, tz, mx, my, mz = (coef.sf_tab, coef.mech_tab, coef.sf_index[0],
                                        coef.sf_index[1], coef.sf_index[2], coef.mech_index[0],
                                        coef.mech_index[1], coef.mech_index[2])
    low_c, steps, last_cell = (coef.scalars[S_LOW_C], coef.scalars[S_STEPS],
                               (sf.shape[2] if on[F_SF] else mech.shape[2]) - 2)
    use_g, held = on[F_GSENS] and accel.shape[0] > 0, accel.shape[0] == 1
    use_xb, use_xg = xbias.shape[0] > 0, xgain.shape[0] > 0
    phi, gains, sections = coef.flicker_phi, coef.flicker_gains, fl.shape[0]
    ps, qs, xs = _section_lanes(phi, gains, fl)
    lpf = lb.shape[0] - 1 if on[F_LPF] else 0
    zd0, zd1, zl0, zl1 = vload4(dz, 0), vload4(dz, 1), vload4(lz, 0), vload4(lz, lz.shape[0] - 1)
    sf_shared, mech_shared = tx == ty and ty == tz, mx == my and my == mz
    # Each stream's unread normals from its read position on (indices from 0:
    # no wrap-around arithmetic per access).
    f0, f1, f2, r0, r1, r2, w0, w1, w2 = _unread(normals, pos)
    dyn_fresh, lpf_fresh = on[F_DYN] and ints[I_DYN_READY] == 0, lpf and ints[I_LPF_READY] == 0
    c, u = 0, vsplat(0.0)
    for j in range(stop - start):
        d = die[j]
        if on[F_SF] or on[F_MECH]:      # one grid cell for every temperature curve
            v = (d - low_c) * steps
            c = min(max(int(v), 0), last_cell)
            u = vsplat(v - c)
        x = _sensed(vget(rate, j, wide), rate[j, 0], rate[j, 1], rate[j, 2], m0, m1, m2, nl, on)
        g = sf1
        if on[F_SF] and sf_shared:
            g = (vsplat(sf[tx, 0, c]) + u * vsplat(sf[tx, 1, c])) * g
        elif on[F_SF]:
            g = (vpack(sf[tx, 0, c], sf[ty, 0, c], sf[tz, 0, c])
                 + u * vpack(sf[tx, 1, c], sf[ty, 1, c], sf[tz, 1, c])) * g
        if use_xg:                      # extended terms' gain multiplier (padded rows)
            g = g * vget(xgain, j, stop)
        vput(gain, j, g, wide)
        s = x * g
        if on[F_DYN]:
            if dyn_fresh:               # a filter starts in steady state for its first input
                _steady(dz, coef.dyn_zi, s)
                zd0, zd1, dyn_fresh, ints[I_DYN_READY] = vload4(dz, 0), vload4(dz, 1), False, 1
            s, zd0, zd1 = _tdf2(s, zd0, zd1, b0, b1, b2, a1, a2)
        e = _static_bias(d, turn_on, cal, c1, c2, on)
        if use_xb:                      # extended terms' bias (padded rows)
            e = e + vget(xbias, j, stop)
        if use_g:
            e = e + (g_held if held else vsplat(accel[j, 0]) * g0 + vsplat(accel[j, 1]) * g1
                     + vsplat(accel[j, 2]) * g2)
        if on[F_FLICKER]:               # sections x_k = phi_k x_k + c_k B w, summed in k order
            w = vpack(f0[j], f1[j], f2[j]) * fb
            if sections <= SECTIONS_IN_REGISTERS:
                e, xs = _sections(e, w, xs, ps, qs, sections)
            else:
                for k in range(sections):
                    xk = vsplat(phi[k]) * vload4(fl, k) + vsplat(gains[k]) * w
                    vstore4(fl, k, xk)
                    e = e + xk
        if on[F_RRW]:
            walk = walk + vpack(r0[j], r1[j], r2[j]) * walk_step
            e = e + walk
        vput(bias, j, e, wide)
        y = s + e
        if on[F_WHITE]:
            if on[F_MECH] and mech_shared:
                sigma = vsqrt(vsplat(mech[mx, 0, c]) + u * vsplat(mech[mx, 1, c]) + elec) * sqrt_fs
            elif on[F_MECH]:
                sigma = vsqrt(vpack(mech[mx, 0, c], mech[my, 0, c], mech[mz, 0, c])
                              + u * vpack(mech[mx, 1, c], mech[my, 1, c], mech[mz, 1, c])
                              + elec) * sqrt_fs
            y = y + vpack(w0[j], w1[j], w2[j]) * sigma
        if lpf:
            if lpf_fresh:               # a filter starts in steady state for its first input
                _steady(lz, coef.lpf_zi, y)
                zl0, zl1 = vload4(lz, 0), vload4(lz, lz.shape[0] - 1)
                lpf_fresh, ints[I_LPF_READY] = False, 1
            if lpf == 1:
                y, zl0 = _tdf1(y, zl0, lb0, lb1, la1)
            elif lpf == 2:
                y, zl0, zl1 = _tdf2(y, zl0, zl1, lb0, lb1, lb2, la1, la2)
            else:
                y = _tdf2_rows(lb, la, lz, y)
        if on[F_SAT]:
            vstore_greater(sat, j, vabs(y), full)
        vput(gyro, j, _output(y, on, quantise, lsb, limit, neg_limit), wide)
    _store_states(dz, zd0, zd1, fl, xs, sections, lz, zl0, zl1, lpf)
    return walk


@numba.njit(cache=True, error_model='numpy')
def _unread(normals, pos):
    """Return the unread normals of the flicker, walk and white streams (x, y, z each)."""
    return (normals[FLICKER, pos[FLICKER]:], normals[FLICKER + 1, pos[FLICKER + 1]:],
            normals[FLICKER + 2, pos[FLICKER + 2]:], normals[RRW, pos[RRW]:],
            normals[RRW + 1, pos[RRW + 1]:], normals[RRW + 2, pos[RRW + 2]:],
            normals[WHITE, pos[WHITE]:], normals[WHITE + 1, pos[WHITE + 1]:],
            normals[WHITE + 2, pos[WHITE + 2]:])


@numba.njit(cache=True, error_model='numpy')
def _sensed(x, r0, r1, r2, m0, m1, m2, nl, on):
    """Misaligned, nonlinear rate x + M x, then x + nl x^2 (lanes; Eq 18 with errors)."""
    if on[F_MIS]:
        x = x + (vsplat(r0) * m0 + vsplat(r1) * m1 + vsplat(r2) * m2)
    if on[F_NONLIN]:
        x = x + nl * x * x
    return x


@numba.njit(cache=True, error_model='numpy')
def _static_bias(d, turn_on, cal, c1, c2, on):
    """Turn-on bias + (c1 + c2 dT) dT, dT = T_die - T_cal (lanes)."""
    if on[F_BIAS_T]:
        dtemp = vsplat(d) - cal
        return turn_on + (c1 + c2 * dtemp) * dtemp
    return turn_on


@numba.njit(cache=True, error_model='numpy')
def _tdf1(x, z0, b0, b1, a1):
    """One sample of a first-order transposed direct form II (scipy.signal.lfilter)."""
    y = z0 + b0 * x
    return y, b1 * x - a1 * y


@numba.njit(cache=True, error_model='numpy')
def _tdf2(x, z0, z1, b0, b1, b2, a1, a2):
    """One sample of a second-order transposed direct form II (scipy.signal.lfilter)."""
    y = z0 + b0 * x
    return y, z1 + b1 * x - a1 * y, b2 * x - a2 * y


@numba.njit(cache=True, error_model='numpy')
def _output(y, on, quantise, lsb, limit, neg_limit):
    """LSB rounding (lanes with quantise != 0) and clip to whole LSBs within the range."""
    if on[F_QUANT]:
        y = vwhere(quantise, vrint(y / lsb) * lsb, y)
    if on[F_SAT]:
        y = vmax(vmin(y, limit), neg_limit)
    return y


@numba.njit(cache=True, error_model='numpy')
def _store_states(dz, zd0, zd1, fl, xs, sections, lz, zl0, zl1, lpf):
    """Write the register states of :func:`_loop` back into their lane rows."""
    vstore4(dz, 0, zd0)
    vstore4(dz, 1, zd1)
    if sections <= SECTIONS_IN_REGISTERS:
        for k in range(sections):
            vstore4(fl, k, xs[k])
    if lpf == 1 or lpf == 2:
        vstore4(lz, lz.shape[0] - 1, zl1)
        vstore4(lz, 0, zl0)


#: Flicker sections whose states the per-sample pass keeps in registers.
SECTIONS_IN_REGISTERS = 8


@numba.njit(cache=True, error_model='numpy')
def _section_lanes(phi, gains, fl):
    """Return the first 8 flicker sections as vectors: phi_k, c_k and states x_k (0 past K)."""
    count = min(fl.shape[0], SECTIONS_IN_REGISTERS)
    return (_splat8(phi, count), _splat8(gains, count),
            (_state(fl, 0, count), _state(fl, 1, count), _state(fl, 2, count),
             _state(fl, 3, count), _state(fl, 4, count), _state(fl, 5, count),
             _state(fl, 6, count), _state(fl, 7, count)))


@numba.njit(cache=True, error_model='numpy')
def _state(rows, k, count):
    """Return lane row k of ``rows`` as a vector, or zeros for k >= count."""
    return vload4(rows, k) if k < count else vsplat(0.0)


@numba.njit(cache=True, error_model='numpy')
def _splat8(values, count):
    """Return values[0..7] splatted into 8 vectors (zeros from index ``count`` on)."""
    v = np.zeros(8)
    for k in range(count):
        v[k] = values[k]
    return (vsplat(v[0]), vsplat(v[1]), vsplat(v[2]), vsplat(v[3]), vsplat(v[4]),
            vsplat(v[5]), vsplat(v[6]), vsplat(v[7]))


@numba.njit(cache=True, error_model='numpy')
def _sections(e, w, xs, ps, qs, count):
    """Flicker sections x_k = phi_k x_k + c_k w (k < count <= 8) added to e in k order."""
    x0, x1, x2, x3, x4, x5, x6, x7 = xs
    if count > 0:
        x0 = ps[0] * x0 + qs[0] * w
        e = e + x0
    if count > 1:
        x1 = ps[1] * x1 + qs[1] * w
        e = e + x1
    if count > 2:
        x2 = ps[2] * x2 + qs[2] * w
        e = e + x2
    if count > 3:
        x3 = ps[3] * x3 + qs[3] * w
        e = e + x3
    if count > 4:
        x4 = ps[4] * x4 + qs[4] * w
        e = e + x4
    if count > 5:
        x5 = ps[5] * x5 + qs[5] * w
        e = e + x5
    if count > 6:
        x6 = ps[6] * x6 + qs[6] * w
        e = e + x6
    if count > 7:
        x7 = ps[7] * x7 + qs[7] * w
        e = e + x7
    return e, (x0, x1, x2, x3, x4, x5, x6, x7)


@numba.njit(cache=True, error_model='numpy')
def _lanes(arr):
    """
    Return a per-axis array (3, k) as (max(k, 1), 4) lane rows (row i = column i).

    Coefficients and states in this form load and store as whole vectors.
    """
    rows = np.zeros((max(arr.shape[1], 1), 4))
    for i in range(3):
        for k in range(arr.shape[1]):
            rows[k, i] = arr[i, k]
    return rows


@numba.njit(cache=True, error_model='numpy')
def _lanes_out(rows, z):
    """Write the lane rows of :func:`_lanes` back into the per-axis state (3, k)."""
    for i in range(3):
        for k in range(z.shape[1]):
            z[i, k] = rows[k, i]


@numba.njit(cache=True, error_model='numpy')
def _steady(rows, zi, y):
    """Set a filter state to steady state for input ``y``: row k = zi[:, k] y (lanes)."""
    zi_rows = _lanes(zi)
    for k in range(zi.shape[1]):
        vstore4(rows, k, vload4(zi_rows, k) * y)


@numba.njit(cache=True, error_model='numpy')
def _tdf2_rows(b, a, z, x):
    """One sample of transposed direct form II (scipy.signal.lfilter), lane-row state z."""
    order = z.shape[0]
    y = vload4(z, 0) + vload4(b, 0) * x
    for k in range(order - 1):
        vstore4(z, k, vload4(z, k + 1) + vload4(b, k + 1) * x - vload4(a, k + 1) * y)
    vstore4(z, order - 1, vload4(b, order) * x - vload4(a, order) * y)
    return y


@numba.njit(cache=True, error_model='numpy')
def _delays(jitter_normals, sc, on, delay):
    """
    Latency + timestamp jitter of each sample of the block, s.

    The jitter is clipped to +-JITTER_BOUND dt and the delay at 0: two
    stamps then differ by more than (1 - 2 JITTER_BOUND) dt > 0, so the
    stamps increase strictly even for a sigma of many periods (a driver's
    stamp jitter cannot reorder its samples).
    """
    latency, jitter = sc[S_LATENCY], sc[S_JITTER]
    if not on[F_JITTER]:
        delay[:] = latency
        return
    bound = JITTER_BOUND * sc[S_DT]
    for j in range(delay.shape[0]):
        shift = min(max(jitter * jitter_normals[j], -bound), bound)
        delay[j] = max(latency + shift, 0.0)
