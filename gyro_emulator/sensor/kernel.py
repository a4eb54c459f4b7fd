"""
The compiled kernel of :class:`gyro_emulator.sensor.model.GyroModel`.

Every term (see :mod:`gyro_emulator.sensor.model` for the equations), term
by term over a block of samples, with each sample's arithmetic in the order
of a per-sample pass (so the result does not depend on the block size), on
three parameter structs (numba-supported namedtuples of arrays):

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

    Term by term over the block (each loop is simple enough for the compiler
    to vectorise, and the recursions run their three axes side by side),
    with the arithmetic of each sample in the same order as a per-sample
    pass, so the result does not depend on the block size. ``out.gyro``
    holds the signal as it goes through the chain; ``out.bias`` the bias.
    """
    on, at = _switches(coef.flags), _offsets(pos, start)
    ax, ints = coef.axis, state.ints
    x, bias = out.gyro, out.bias
    cell, u = _table_cells(out.die, start, stop, on[F_SF] or on[F_MECH], coef)
    _sensed(rate, start, stop, on, ax, coef.misalignment, coef.sf_tab, coef.sf_index,
            cell, u, x, out.true, out.gain)
    if on[F_DYN]:
        _filter(coef.dyn_b, coef.dyn_a, coef.dyn_zi, state.dyn_z, ints, I_DYN_READY, x,
                start, stop)
    _static_bias(out.die, accel, start, stop, on, ax, coef.g_sensitivity, bias)
    if on[F_FLICKER]:
        _flicker(normals, at, start, stop, ax, coef.flicker_phi,
                 coef.flicker_gains, state.flicker, bias)
    if on[F_RRW]:
        _walk(normals, at, start, stop, ax, state.rrw, bias)
    _add_bias_and_noise(normals, at, start, stop, on, ax, coef,
                        cell, u, bias, x)
    if on[F_LPF]:
        _filter(coef.lpf_b, coef.lpf_a, coef.lpf_zi, state.lpf_z, ints, I_LPF_READY, x,
                start, stop)
    _output_stage(x, start, stop, on, ax, out.sat)
    _delays(normals, at, start, stop, ints[I_INDEX], coef.scalars, on, out.delay)


@numba.njit(cache=True, error_model='numpy')
def _table_cells(die, start, stop, used, coef):
    """Grid cell and fraction of each die temperature in the temperature tables."""
    n = stop - start
    cell = np.zeros(n, dtype=np.int64)
    u = np.zeros(n)
    if not used:
        return cell, u
    sc = coef.scalars
    low_c, steps = sc[S_LOW_C], sc[S_STEPS]
    last_cell = (coef.sf_tab.shape[2] if coef.flags[F_SF] else coef.mech_tab.shape[2]) - 2
    for m in range(n):
        v = (die[start + m] - low_c) * steps
        c = min(max(int(v), 0), last_cell)
        cell[m] = c
        u[m] = v - c
    return cell, u


@numba.njit(cache=True, error_model='numpy')
def _sensed(rate, start, stop, on, ax, mis, sf_tab, sf_index, cell, u, x, true, gain):
    """Sensed signal x: misalignment, nonlinearity, total gain (Eq 18 with errors)."""
    for j in range(start, stop):
        for i in range(3):
            true[j, i] = rate[j, i]
    for i in range(3):
        sf1, nl, t = ax[A_SF1, i], ax[A_NONLIN, i], sf_index[i]
        m0, m1, m2 = mis[i, 0], mis[i, 1], mis[i, 2]
        for j in range(start, stop):
            xi = rate[j, i]
            if on[F_MIS]:
                xi = xi + (rate[j, 0] * m0 + rate[j, 1] * m1 + rate[j, 2] * m2)
            if on[F_NONLIN]:
                xi = xi + nl * xi * xi
            gi = sf1
            if on[F_SF]:
                c = cell[j - start]
                gi = (sf_tab[t, 0, c] + u[j - start] * sf_tab[t, 1, c]) * gi
            gain[j, i] = gi
            x[j, i] = xi * gi


@numba.njit(cache=True, error_model='numpy')
def _filter(b, a, zi0, z, ints, ready, x, start, stop):
    """
    Filter each axis of x[start:stop] by b[i], a[i] (transposed direct form II).

    The scipy.signal.lfilter recursion on state z; a filter not yet started
    starts in steady state for its first input, z = zi0 x.
    """
    order = b.shape[1] - 1
    if ints[ready] == 0:
        for i in range(3):
            for k in range(order):
                z[i, k] = zi0[i, k] * x[start, i]
        ints[ready] = 1
    for j in range(start, stop):
        for i in range(3):
            xi = x[j, i]
            y = z[i, 0] + b[i, 0] * xi
            for k in range(order - 1):
                z[i, k] = z[i, k + 1] + b[i, k + 1] * xi - a[i, k + 1] * y
            z[i, order - 1] = b[i, order] * xi - a[i, order] * y
            x[j, i] = y


@numba.njit(cache=True, error_model='numpy')
def _static_bias(die, accel, start, stop, on, ax, g, bias):
    """Bias b = turn-on + temperature polynomial + g-sensitivity, per sample and axis."""
    use_g = on[F_GSENS] and accel.shape[0] > 0
    held = accel.shape[0] == 1
    for i in range(3):
        b0, cal, c1, c2 = ax[A_TURN_ON, i], ax[A_CAL, i], ax[A_C1, i], ax[A_C2, i]
        g0, g1, g2 = g[i, 0], g[i, 1], g[i, 2]
        for j in range(start, stop):
            b = b0
            if on[F_BIAS_T]:
                dtemp = die[j] - cal
                b += (c1 + c2 * dtemp) * dtemp
            if use_g:
                ja = 0 if held else j
                b += (accel[ja, 0] * g0 + accel[ja, 1] * g1 + accel[ja, 2] * g2)
            bias[j, i] = b


@numba.njit(cache=True, error_model='numpy')
def _flicker(normals, at, start, stop, ax, phi, gains, fl, bias):
    """Add the bias instability: sections x_k = phi_k x_k + c_k B w, summed in k order."""
    sections = phi.shape[0]
    for j in range(start, stop):
        for i in range(3):
            w = normals[FLICKER + i, at[FLICKER + i] + j] * ax[A_FLICKER_B, i]
            b = bias[j, i]
            for k in range(sections):
                xk = phi[k] * fl[i, k] + gains[k] * w
                fl[i, k] = xk
                b += xk
            bias[j, i] = b


@numba.njit(cache=True, error_model='numpy')
def _walk(normals, at, start, stop, ax, rrw, bias):
    """Add the rate random walk r[n] = r[n-1] + K sqrt(dt) w[n]."""
    for i in range(3):
        r, step = rrw[i], ax[A_RRW_STEP, i]
        for j in range(start, stop):
            r += normals[RRW + i, at[RRW + i] + j] * step
            bias[j, i] += r
        rrw[i] = r


@numba.njit(cache=True, error_model='numpy')
def _add_bias_and_noise(normals, at, start, stop, on, ax, coef, cell, u, bias, x):
    """Add the bias and the white noise of sigma N(T_die) sqrt(fs) to x."""
    mech_tab, mech_index = coef.mech_tab, coef.mech_index
    sqrt_fs = coef.scalars[S_SQRT_FS]
    for i in range(3):
        sigma, elec_sq, t = ax[A_WHITE_SIGMA, i], ax[A_ELEC_SQ, i], mech_index[i]
        for j in range(start, stop):
            y = x[j, i] + bias[j, i]
            if on[F_WHITE]:
                if on[F_MECH]:
                    c = cell[j - start]
                    sigma = math.sqrt(mech_tab[t, 0, c] + u[j - start] * mech_tab[t, 1, c]
                                      + elec_sq) * sqrt_fs
                y += normals[WHITE + i, at[WHITE + i] + j] * sigma
            x[j, i] = y


@numba.njit(cache=True, error_model='numpy')
def _output_stage(x, start, stop, on, ax, sat):
    """Range flag, LSB rounding and clip to whole LSBs, in place on x."""
    use_sat, use_q = on[F_SAT], on[F_QUANT]
    for i in range(3):
        lsb, full, limit = ax[A_LSB, i], ax[A_RANGE, i], ax[A_SAT_LIMIT, i]
        quantise = use_q and lsb > 0.0
        for j in range(start, stop):
            y = x[j, i]
            sat[j, i] = use_sat and abs(y) > full
            if quantise:
                y = np.rint(y / lsb) * lsb
            if use_sat:
                y = max(min(y, limit), -limit)
            x[j, i] = y


@numba.njit(cache=True, error_model='numpy')
def _delays(normals, at, start, stop, index, sc, on, delay):
    """Latency + timestamp jitter (clipped at 0) of each sample, s (drift: sample period)."""
    latency, jitter = sc[S_LATENCY], sc[S_JITTER]
    for j in range(start, stop):
        dl = latency
        if on[F_JITTER]:
            dl = max(dl + jitter * normals[JITTER, at[JITTER] + j], 0.0)
        delay[j] = dl
