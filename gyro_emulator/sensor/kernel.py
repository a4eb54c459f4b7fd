"""
The compiled per-sample kernel of :class:`gyro_emulator.sensor.model.GyroModel`.

One pass per sample through every term (see :mod:`gyro_emulator.sensor.model`
for the equations), on three parameter structs (numba-supported namedtuples
of arrays):

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

from gyro_emulator.sensor.streams import FLICKER, JITTER, RRW, WHITE
import numba
import numpy as np

#: Switches (int64, 0 or 1).
(F_THERMAL, F_SF, F_MIS, F_NONLIN, F_DYN, F_BIAS_T, F_GSENS, F_FLICKER,
 F_RRW, F_WHITE, F_MECH, F_LPF, F_SAT, F_QUANT, F_JITTER, F_DRIFT) = range(16)
FLAG_COUNT = 16
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

Outputs = namedtuple('Outputs', ['gyro', 'true', 'die', 'bias', 'gain', 'sat', 'delay'])
Outputs.__doc__ = 'Output arrays of a call, in SensorBatch field order.'


def consumed_streams(flags):
    """Return the streams the kernel reads one normal from per sample, for ``flags``."""
    streams = [JITTER] if flags[F_JITTER] else []
    for on, first in ((F_WHITE, WHITE), (F_FLICKER, FLICKER), (F_RRW, RRW)):
        if flags[on]:
            streams += [first, first + 1, first + 2]
    return np.array(sorted(streams), dtype=np.int64)


@numba.njit(cache=True, error_model='numpy')
def advance(rate, amb, accel, coef, state, normals, pos, out, start, stop):
    """
    Advance the model over samples ``start:stop`` of a record.

    ``rate`` (n, 3), ``amb`` (n,) and ``accel`` ((n, 3), (1, 3) held, or
    (0, 3) for none) are the whole record; ``stop - start`` must not exceed
    the unread normals of any used stream. The call with ``start == 0`` first
    computes and checks the die temperature of the WHOLE record: it returns
    1 + the index of the first one outside the model range, having written
    only ``out.die`` (state and streams intact). Otherwise returns 0.
    """
    if start == 0:
        bad = _die_temperatures(amb, coef, state, out.die)
        if bad:
            return bad
    _samples(rate, accel, coef, state, normals, pos, out, start, stop)
    n = stop - start
    for k in coef.streams:
        pos[k] += n
    state.ints[I_INDEX] += n
    return 0


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


@numba.njit(cache=True, error_model='numpy', inline='always')
def _switches(flags):
    """Return the switches as a tuple of booleans (registers, not memory, in the loop)."""
    return (flags[0] != 0, flags[1] != 0, flags[2] != 0, flags[3] != 0, flags[4] != 0,
            flags[5] != 0, flags[6] != 0, flags[7] != 0, flags[8] != 0, flags[9] != 0,
            flags[10] != 0, flags[11] != 0, flags[12] != 0, flags[13] != 0,
            flags[14] != 0, flags[15] != 0)


@numba.njit(cache=True, error_model='numpy', inline='always')
def _offsets(pos, start):
    """Return ``pos - start`` per stream as a tuple (constant during a call)."""
    return (pos[0] - start, pos[1] - start, pos[2] - start, pos[3] - start,
            pos[4] - start, pos[5] - start, pos[6] - start, pos[7] - start,
            pos[8] - start, pos[9] - start, pos[10] - start)


@numba.njit(cache=True, error_model='numpy')
def _samples(rate, accel, coef, state, normals, pos, out, start, stop):
    """
    Every term of samples ``start:stop``, whose die temperatures are in ``out.die``.

    The arrays are taken out of the structs once, before the loop: a struct
    field read inside the loop would cost a reference-count update per sample.
    """
    on, at = _switches(coef.flags), _offsets(pos, start)
    sc, ax, ints = coef.scalars, coef.axis, state.ints
    sf_tab, sf_index = coef.sf_tab, coef.sf_index
    mech_tab, mech_index = coef.mech_tab, coef.mech_index
    dyn_b, dyn_a, dyn_zi, dyn_z = coef.dyn_b, coef.dyn_a, coef.dyn_zi, state.dyn_z
    lpf_b, lpf_a, lpf_zi, lpf_z = coef.lpf_b, coef.lpf_a, coef.lpf_zi, state.lpf_z
    mis, g, fl_phi, fl_gains = (coef.misalignment, coef.g_sensitivity, coef.flicker_phi,
                                coef.flicker_gains)
    fl, rrw, die = state.flicker, state.rrw, out.die
    true, gain, bias, gyro, sat, delay = (out.true, out.gain, out.bias, out.gyro, out.sat,
                                          out.delay)
    use_table = on[F_SF] or on[F_MECH]
    low_c, steps, sqrt_fs = sc[S_LOW_C], sc[S_STEPS], sc[S_SQRT_FS]
    last_cell = sf_tab.shape[2] - 2 if on[F_SF] else mech_tab.shape[2] - 2
    use_g = on[F_GSENS] and accel.shape[0] > 0
    held = accel.shape[0] == 1
    index = ints[I_INDEX] - start
    x = np.empty(3)
    sigma = ax[A_WHITE_SIGMA].copy()
    u, cell = 0.0, 0
    for j in range(start, stop):
        d = die[j]
        if use_table:               # one grid cell for every temperature curve
            u = (d - low_c) * steps
            cell = min(max(int(u), 0), last_cell)
            u -= cell
        _sensed(rate, j, on, ax, mis, sf_tab, sf_index, cell, u, x, true, gain)
        if on[F_DYN]:
            _filter(dyn_b, dyn_a, dyn_zi, dyn_z, ints, I_DYN_READY, x)
        if on[F_MECH]:              # white-noise sigma at this die temperature: N(T) sqrt(fs)
            _white_sigma(mech_tab, mech_index, cell, u, ax, sqrt_fs, sigma)
        ja = 0 if held else j
        _bias(d, accel, ja, use_g, on, ax, g, normals, at, j, fl_phi, fl_gains, fl, rrw, x,
              bias)
        if on[F_WHITE]:
            for i in range(3):
                x[i] += normals[WHITE + i, at[WHITE + i] + j] * sigma[i]
        if on[F_LPF]:
            _filter(lpf_b, lpf_a, lpf_zi, lpf_z, ints, I_LPF_READY, x)
        _output_stage(x, j, on, ax, gyro, sat)
        delay[j] = _delay(normals, at, j, index + j, sc, on)


@numba.njit(cache=True, error_model='numpy', inline='always')
def _tdf2(b, a, z, i, x):
    """One sample of transposed direct form II (scipy.signal.lfilter), row i of b, a, z."""
    m = b.shape[1]
    y = z[i, 0] + b[i, 0] * x
    for k in range(m - 2):
        z[i, k] = z[i, k + 1] + b[i, k + 1] * x - a[i, k + 1] * y
    z[i, m - 2] = b[i, m - 1] * x - a[i, m - 1] * y
    return y


@numba.njit(cache=True, error_model='numpy', inline='always')
def _filter(b, a, zi0, z, ints, ready, x):
    """Filter axis i of x by b[i], a[i] (TDF-II state z), started in steady state zi0 x."""
    if ints[ready] == 0:
        for i in range(3):
            for k in range(z.shape[1]):
                z[i, k] = zi0[i, k] * x[i]
        ints[ready] = 1
    for i in range(3):
        x[i] = _tdf2(b, a, z, i, x[i])


@numba.njit(cache=True, error_model='numpy', inline='always')
def _sensed(rate, j, on, ax, mis, sf_tab, sf_index, cell, u, x, true, gain):
    """Sensed signal x: misalignment, nonlinearity, total gain (Eq 18 with errors)."""
    r0, r1, r2 = rate[j, 0], rate[j, 1], rate[j, 2]
    true[j, 0], true[j, 1], true[j, 2] = r0, r1, r2
    for i in range(3):
        xi = rate[j, i]
        if on[F_MIS]:
            xi = xi + (r0 * mis[i, 0] + r1 * mis[i, 1] + r2 * mis[i, 2])
        if on[F_NONLIN]:
            xi = xi + ax[A_NONLIN, i] * xi * xi
        gi = ax[A_SF1, i]
        if on[F_SF]:
            t = sf_index[i]
            gi = (sf_tab[t, 0, cell] + u * sf_tab[t, 1, cell]) * gi
        gain[j, i] = gi
        x[i] = xi * gi


@numba.njit(cache=True, error_model='numpy', inline='always')
def _white_sigma(mech_tab, mech_index, cell, u, ax, sqrt_fs, sigma):
    """Per-sample white sigma sqrt(N_mech(T)^2 + N_elec^2) sqrt(fs) of each axis."""
    for i in range(3):
        t = mech_index[i]
        sigma[i] = math.sqrt(mech_tab[t, 0, cell] + u * mech_tab[t, 1, cell]
                             + ax[A_ELEC_SQ, i]) * sqrt_fs


@numba.njit(cache=True, error_model='numpy', inline='always')
def _bias(d, accel, ja, use_g, on, ax, g, normals, at, j, phi, gains, fl, rrw, x, bias):
    """Add the bias (turn-on, temperature, g, flicker, random walk) to x and record it."""
    for i in range(3):
        b = ax[A_TURN_ON, i]
        if on[F_BIAS_T]:
            dtemp = d - ax[A_CAL, i]
            b += (ax[A_C1, i] + ax[A_C2, i] * dtemp) * dtemp
        if use_g:
            b += (accel[ja, 0] * g[i, 0] + accel[ja, 1] * g[i, 1] + accel[ja, 2] * g[i, 2])
        if on[F_FLICKER]:
            w = normals[FLICKER + i, at[FLICKER + i] + j] * ax[A_FLICKER_B, i]
            for k in range(phi.shape[0]):
                xk = phi[k] * fl[i, k] + gains[k] * w
                fl[i, k] = xk
                b += xk
        if on[F_RRW]:
            rrw[i] += normals[RRW + i, at[RRW + i] + j] * ax[A_RRW_STEP, i]
            b += rrw[i]
        bias[j, i] = b
        x[i] += b


@numba.njit(cache=True, error_model='numpy', inline='always')
def _output_stage(x, j, on, ax, gyro, sat):
    """Range flag, LSB rounding and clip to whole LSBs."""
    use_sat, use_q = on[F_SAT], on[F_QUANT]
    for i in range(3):
        y = x[i]
        sat[j, i] = use_sat and abs(y) > ax[A_RANGE, i]
        lsb = ax[A_LSB, i]
        if use_q and lsb > 0.0:
            y = np.rint(y / lsb) * lsb
        if use_sat:
            limit = ax[A_SAT_LIMIT, i]
            y = max(min(y, limit), -limit)
        gyro[j, i] = y


@numba.njit(cache=True, error_model='numpy', inline='always')
def _delay(normals, at, j, index, sc, on):
    """Latency + timestamp jitter (clipped at 0) + clock drift of sample ``index``, s."""
    dl = sc[S_LATENCY]
    if on[F_JITTER]:
        dl = max(dl + sc[S_JITTER] * normals[JITTER, at[JITTER] + j], 0.0)
    if on[F_DRIFT]:
        dl += index * sc[S_DT] * sc[S_DRIFT]
    return dl
