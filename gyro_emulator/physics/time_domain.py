"""
Eq 3-4 in time, discretised exactly, with synchronous demodulation.

:func:`simulate_time_domain` runs Omega(t), T(t), an open-loop or
amplitude-regulated (AGC) drive and the demodulator; the augmented 6-state
system advances one drive cycle per matrix step, exactly. Also the settling
time and the swept frequency response. The tests and the benchmark check
the transient against scipy's DOP853 (test/dynamics_reference.py).
"""

from dataclasses import dataclass
import math

from gyro_emulator.physics import first_order
from gyro_emulator.physics.exact import exact_steady_state, sense_frequency_hz
from gyro_emulator.validation import check_choice, check_range, check_temperature_c
import numpy as np
from scipy import linalg

#: Drive modes of :func:`simulate_time_domain`.
DRIVE_MODES = ('open_loop', 'agc')


#: Initial states of :func:`simulate_time_domain`.
INITIAL_STATES = ('steady', 'rest')


@dataclass(frozen=True)
class AgcSettings:
    """
    Drive amplitude regulation (AGC), as gyro ASICs do.

    A PI loop on the demodulated drive amplitude sets the drive force. The
    gains place the zero on the nominal drive pole (sigma_d = C_d / 2M) so the
    loop gain is ``2 pi bandwidth_hz / s``: kp = 2 M w (2 pi bandwidth_hz),
    ki = kp sigma_d. ``amplitude_m`` None holds the first-order X_drive at the
    device's calibration temperature (Eq 15). The loop updates every
    ``update_cycles`` drive cycles (a digital AGC); the force is limited to
    ``max_force_ratio`` times Eq 12's F_d, with conditional integration.
    """

    amplitude_m: float = None
    bandwidth_hz: float = 50.0
    update_cycles: int = 4
    max_force_ratio: float = 10.0

    def __post_init__(self):
        """Validate every field; see the class docstring for units."""
        if self.amplitude_m is not None:
            check_range('AgcSettings', 'amplitude_m', self.amplitude_m, 0.0,
                        1e-3, 'm')
        check_range('AgcSettings', 'bandwidth_hz', self.bandwidth_hz, 0.0, 2000.0,
                    'Hz')
        check_range('AgcSettings', 'update_cycles', self.update_cycles, 1, 1000,
                    '', False)
        if int(self.update_cycles) != self.update_cycles:
            raise ValueError(f'AgcSettings.update_cycles = {self.update_cycles!r} '
                             'is not an integer')
        check_range('AgcSettings', 'max_force_ratio', self.max_force_ratio, 1.0,
                    1e3, '', False)


@dataclass(frozen=True)
class TimeDomainResult:
    """
    Demodulated outputs of :func:`simulate_time_domain`, one row per drive cycle.

    ``time_s`` is the centre of each cycle (the demodulation window), where
    the rate and temperature were sampled. Sense and drive displacements are
    demodulated against cos(phi) (in-phase, the rate channel) and sin(phi)
    (quadrature) of the drive force F sin(phi). ``state_m`` holds (x, x', y,
    y') at the start of each cycle (m, m/s).
    """

    time_s: np.ndarray
    period_s: np.ndarray
    rate_rad_s: np.ndarray
    temp_c: np.ndarray
    drive_freq_hz: np.ndarray
    drive_force_n: np.ndarray
    in_phase_m: np.ndarray
    quadrature_m: np.ndarray
    drive_in_phase_m: np.ndarray
    drive_quadrature_m: np.ndarray
    state_m: np.ndarray

    @property
    def sense_amplitude_m(self):
        """|demodulated sense| signed by the in-phase part, m."""
        return np.copysign(np.hypot(self.in_phase_m, self.quadrature_m),
                           self.in_phase_m)

    @property
    def drive_amplitude_m(self):
        """Demodulated drive amplitude, m."""
        return np.hypot(self.drive_in_phase_m, self.drive_quadrature_m)


@dataclass(frozen=True)
class _Mechanics:
    mass: float
    k_x: float
    k_y: float
    c_d: float
    c_s: float
    force: float
    drive_freq_hz: float


def _mechanics(device, temp_c, split_hz, drive_freq_hz):
    p = first_order.lumped_parameters(device, temp_c)
    if np.ndim(p.mass_kg):
        raise ValueError('simulate_time_domain: device fields must be scalars, '
                         'not arrays')
    _, f_y = sense_frequency_hz('simulate_time_domain', p, split_hz)
    m = float(p.mass_kg)
    return _Mechanics(m, float(p.stiffness_x_n_m),
                      m * (2.0 * np.pi * float(f_y)) ** 2,
                      float(p.damping_drive_n_s_m), float(p.damping_sense_n_s_m),
                      float(p.drive_force_n),
                      float(p.freq_x_hz) if drive_freq_hz is None
                      else float(drive_freq_hz))


def _series_order(max_rate_h):
    """
    Series order for the per-cycle maps of ``_cycle_maps``.

    The k-th Dyson term is k nested integrals of the Coriolis coupling
    (size 2 |Omega|) over one cycle h of a nearly norm-preserving propagator,
    so it is about (2 |Omega| h)^k / k!; return one order more than the K
    that brings that below 1e-17 (checked against a direct matrix
    exponential in test/test_dynamics.py).
    """
    a = 2.0 * max_rate_h
    term = 1.0
    for k in range(1, 41):
        term *= a / k
        if term < 1e-17:
            return k  # one order of margin over the bound
    raise ValueError(f'simulate_time_domain.rate_rad_s: |rate| x drive period = '
                     f'{max_rate_h!r} is too large: allowed < 3')


def _cycle_maps(mech, w0, order, samples):
    """
    Exact one-cycle maps of Eq 3-4 as power series in Omega.

    The state (x, x'/w0, y, y'/w0, c, s) is augmented with the drive
    oscillator (c, s) = F (cos phi, sin phi), so the sinusoidal force is part
    of an LTI system and one matrix exponential covers a whole cycle exactly.
    A(Omega) = A0 + Omega A1 is linear in the rate; the block-bidiagonal
    matrix [[A0, A1/h, 0..], [0, A0, A1/h, ..], ..] has the Dyson-series
    coefficients Phi_k of e^{A(Omega) h} = sum_k (Omega h)^k Phi_k in its
    first block row (Van Loan 1978), so the per-cycle map for any rate is a
    cheap polynomial. ``order`` terms keep the truncation below 1e-17.

    Returns ``(phi, g, r_out, f_out)``: per k, the 4x4 state map, the force
    column (per N), and the demodulated outputs (I_x, Q_x, I_y, Q_y) over
    ``samples`` mid-points as linear maps of the cycle-start state and force.
    """
    w = 2.0 * np.pi * mech.drive_freq_hz
    h = 1.0 / mech.drive_freq_hz
    m = mech.mass
    a0 = np.zeros((6, 6))
    a0[0, 1] = w0
    a0[1, 0] = -mech.k_x / (m * w0)
    a0[1, 1] = -mech.c_d / m
    a0[1, 5] = 1.0 / (m * w0)
    a0[2, 3] = w0
    a0[3, 2] = -mech.k_y / (m * w0)
    a0[3, 3] = -mech.c_s / m
    a0[4, 5] = -w
    a0[5, 4] = w
    a1 = np.zeros((6, 6))
    a1[1, 3] = 2.0 / h
    a1[3, 1] = -2.0 / h
    n_blk = order + 1
    big = np.kron(np.eye(n_blk), a0) + np.kron(np.eye(n_blk, k=1), a1)
    half = linalg.expm(big * (h / (2.0 * samples)))
    step = half @ half
    phases = 2.0 * np.pi * (np.arange(samples) + 0.5) / samples
    ref = np.stack([np.cos(phases), np.sin(phases)]) * (2.0 / samples)
    rows = np.zeros((samples, 2, 6 * n_blk))
    cur = half
    for j in range(samples):
        rows[j] = cur[[0, 2], :]
        if j + 1 < samples:
            cur = step @ cur
    full = (half @ cur)[:6].reshape(6, n_blk, 6).transpose(1, 0, 2)
    # demodulated outputs: (I_x, Q_x, I_y, Q_y) = sum_j ref_j * sample_j
    dem = np.einsum('rj,jqc->qrc', ref, rows).reshape(4, n_blk, 6)
    dem = dem.transpose(1, 0, 2)
    return (full[:, :4, :4].copy(), full[:, :4, 4].copy(),
            dem[:, :, :4].copy(), dem[:, :, 4].copy())


def _as_function(owner, name, value):
    """Return ``(function_of_time, constant_or_None)`` for a scalar or callable."""
    if callable(value):
        return value, None
    if np.ndim(value):
        raise ValueError(f'{owner}.{name} must be a scalar or a callable of time '
                         f'(s), got an array of shape {np.shape(value)}')
    v = float(check_range(owner, name, value, None, None))
    return (lambda t: v), v


def _eval_rate(fn, const, t):
    if const is not None:
        return np.full(t.shape, const)
    out = np.broadcast_to(np.asarray(fn(t), dtype=float), t.shape).copy()
    check_range('simulate_time_domain', 'rate_rad_s', out, None, None, 'rad/s')
    return out


def _steady_state_vector(mech, w0, rate, force):
    """(x, x'/w0, y, y'/w0) at phase 0 of the harmonic solution of Eq 3-4."""
    w = 2.0 * np.pi * mech.drive_freq_hz
    m = mech.mass
    z_x = mech.k_x - m * w * w + 1j * w * mech.c_d
    z_y = mech.k_y - m * w * w + 1j * w * mech.c_s
    cor = 2j * m * rate * w
    x = -1j * force * z_y / (z_x * z_y + cor ** 2)
    y = -cor * x / z_y
    return np.array([x.real, (1j * w * x).real / w0, y.real, (1j * w * y).real / w0])


def simulate_time_domain(device, duration_s, rate_rad_s=0.0, temp_c=25.0,
                         split_hz=0.0, drive='open_loop', agc=None,
                         drive_freq_hz=None, samples_per_cycle=8,
                         temp_update_s=0.02, initial='steady'):
    """
    Simulate Eq 3-4 in time with Omega(t), T(t) and synchronous demodulation.

    Method (and why): between rate and temperature updates Eq 3-4 are linear
    and time-invariant, and the drive force F sin(phi) is the output of a
    2-state oscillator, so the augmented 6-state system advances one whole
    drive cycle exactly with one matrix exponential (see ``_cycle_maps``). The
    rate enters linearly, so the exact map for any Omega is a short power
    series precomputed once per temperature. This is exact (no integration
    error at any step size), needs one 4x4 step per drive cycle instead of
    40+ RK4 stages, and the recursion is evaluated in vectorised chunks; only
    the AGC needs a Python loop, one small matrix product per AGC update.
    ``bench/bench_dynamics.py`` measures it against fixed-step RK4 and
    checks it against DOP853.

    Inputs are held per drive cycle: Omega is sampled at each cycle's centre
    and T at the start of each ``temp_update_s`` segment (T sets the lumped
    parameters, Eq 5-12 and 22, and, by default, the drive frequency).
    The drive frequency follows f_x(T) (an ideal PLL) unless
    ``drive_freq_hz`` fixes it; each cycle starts at phase 0, so the phase
    stays continuous. The demodulator samples x and y at ``samples_per_cycle``
    mid-points of each cycle and averages against cos/sin of the drive
    phase, which nulls 2f exactly (``samples_per_cycle`` >= 3).

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device (scalar fields).
    duration_s : float
        Simulated time, s (rounded up to whole drive cycles), at most 600 s
        (about 8 M cycles; use the envelope model for long runs).
    rate_rad_s : float or callable
        True rate Omega, rad/s, or a vectorised function of time (s).
    temp_c : float or callable
        Die temperature, deg C, or a function of time (s).
    split_hz : float
        Drive-sense split f_y - f_x, Hz.
    drive : str
        ``'open_loop'`` (force amplitude F_d of Eq 12) or ``'agc'``.
    agc : AgcSettings, optional
        AGC settings for ``drive='agc'``; default ``AgcSettings()``.
    drive_freq_hz : float, optional
        Fixed drive frequency, Hz; default f_x(T).
    samples_per_cycle : int
        Demodulator samples per drive cycle, 3..64.
    temp_update_s : float
        Hold time of the temperature when ``temp_c`` is a function, s.
    initial : str
        ``'steady'`` (harmonic steady state for the rate and temperature at
        t = 0) or ``'rest'`` (all displacements and velocities zero).

    Returns
    -------
    TimeDomainResult

    """
    owner = 'simulate_time_domain'
    duration, samples, agc = _checked_run(owner, duration_s, drive, initial, samples_per_cycle,
                                          temp_update_s, split_hz, drive_freq_hz, agc)
    rate_fn, rate_const = _as_function(owner, 'rate_rad_s', rate_rad_s)
    temp_fn, temp_const = _as_function(owner, 'temp_c', temp_c)
    seg_temp, seg_cycles, mechs = _temperature_segments(
        device, duration, temp_fn, temp_const, temp_update_s, split_hz, drive_freq_hz)
    seg_of_cycle = np.repeat(np.arange(len(seg_temp)), seg_cycles)
    period = np.array([1.0 / mechs[T].drive_freq_hz for T in seg_temp])[seg_of_cycle]
    start = np.concatenate(([0.0], np.cumsum(period)[:-1]))
    centre = start + 0.5 * period
    rate = _eval_rate(rate_fn, rate_const, centre)
    mech0 = mechs[seg_temp[0]]
    w0 = 2.0 * np.pi * mech0.drive_freq_hz
    order = _series_order(float(np.max(np.abs(rate) * period)))
    maps = {temp: _cycle_maps(mechs[temp], w0, order, samples) for temp in set(seg_temp)}
    rate0 = float(_eval_rate(rate_fn, rate_const, np.zeros(1))[0])
    loop = _DriveLoop.start(device, drive, agc, mech0, w0, rate0)
    z = (np.zeros(4) if initial == 'rest'
         else _steady_state_vector(mech0, w0, rate0, loop.force))
    run = _Run(maps=maps, seg_temp=seg_temp, seg_of_cycle=seg_of_cycle, period=period,
               powers=(rate * period)[:, None] ** np.arange(order + 1), loop=loop)
    outputs, states, forces = _propagate(run, z)
    states = states * np.array([1.0, w0, 1.0, w0])
    temps = np.array(seg_temp)[seg_of_cycle]
    return TimeDomainResult(
        time_s=centre, period_s=period, rate_rad_s=rate, temp_c=temps,
        drive_freq_hz=1.0 / period, drive_force_n=forces,
        in_phase_m=outputs[:, 2], quadrature_m=outputs[:, 3],
        drive_in_phase_m=outputs[:, 0], drive_quadrature_m=outputs[:, 1],
        state_m=states)


def _checked_run(owner, duration_s, drive, initial, samples_per_cycle, temp_update_s,
                 split_hz, drive_freq_hz, agc):
    """Validate the run settings; return ``(duration_s, samples_per_cycle, agc)``."""
    duration = check_range(owner, 'duration_s', duration_s, 0.0, 600.0, 's')
    check_choice(owner, 'drive', drive, DRIVE_MODES)
    check_choice(owner, 'initial', initial, INITIAL_STATES)
    check_range(owner, 'samples_per_cycle', samples_per_cycle, 3, 64, '', False)
    samples = int(samples_per_cycle)
    if samples != samples_per_cycle:
        raise ValueError(f'{owner}.samples_per_cycle = {samples_per_cycle!r} '
                         'is not an integer')
    check_range(owner, 'temp_update_s', temp_update_s, 0.0, 1e3, 's')
    if np.ndim(split_hz):
        raise ValueError(f'{owner}.split_hz = {split_hz!r} must be a scalar')
    if drive_freq_hz is not None:
        check_range(owner, 'drive_freq_hz', drive_freq_hz, 0.0, None, 'Hz')
    if agc is None:
        agc = AgcSettings()
    elif not isinstance(agc, AgcSettings):
        raise ValueError(f'{owner}.agc = {agc!r} is not an AgcSettings')
    return duration, samples, agc


def _temperature_segments(device, duration, temp_fn, temp_const, temp_update_s, split_hz,
                          drive_freq_hz):
    """
    Split the run into segments of constant temperature, whole drive cycles each.

    Returns ``(temperatures, cycles per segment, {temperature: _Mechanics})``.
    """
    mechs = {}
    seg_temp, seg_cycles = [], []
    t = 0.0
    while True:
        temp = temp_fn(t) if temp_const is None else temp_const
        temp = float(check_temperature_c(temp, 'simulate_time_domain', 'temp_c'))
        if temp not in mechs:
            mechs[temp] = _mechanics(device, temp, split_hz, drive_freq_hz)
        f = mechs[temp].drive_freq_hz
        left = max(1, int(math.ceil((duration - t) * f - 1e-9)))
        n = left if temp_const is not None else min(
            left, max(1, int(round(temp_update_s * f))))
        seg_temp.append(temp)
        seg_cycles.append(n)
        t += n / f
        if n == left:
            return seg_temp, np.array(seg_cycles), mechs


@dataclass
class _DriveLoop:
    """The drive: a fixed force (open loop) or the AGC's PI state and gains."""

    agc: bool
    force: float
    chunk: int
    target: float = 0.0
    kp: float = 0.0
    ki: float = 0.0
    f_max: float = 0.0
    integ: float = 0.0

    @classmethod
    def start(cls, device, drive, settings, mech0, w0, rate0):
        """Set up the drive of :func:`simulate_time_domain` at t = 0."""
        if drive != 'agc':
            return cls(agc=False, force=mech0.force, chunk=32)
        target = settings.amplitude_m
        if target is None:
            target = float(first_order.first_order_response(
                device, 0.0, device.calibration_temp_c).drive_amplitude_m)
        unit = _steady_state_vector(mech0, w0, rate0, 1.0)
        force0 = target / float(np.hypot(unit[0], unit[1] * w0 / (
            2.0 * np.pi * mech0.drive_freq_hz)))
        w_d = 2.0 * np.pi * mech0.drive_freq_hz
        kp = 2.0 * mech0.mass * w_d * 2.0 * np.pi * settings.bandwidth_hz
        return cls(agc=True, force=force0, chunk=int(settings.update_cycles), target=target,
                   kp=kp, ki=kp * mech0.c_d / (2.0 * mech0.mass),
                   f_max=settings.max_force_ratio * mech0.force, integ=force0)

    def update(self, amplitude_m, dt_s):
        """PI step on the demodulated drive amplitude, conditional integration."""
        err = self.target - amplitude_m
        trial = self.integ + self.ki * err * dt_s
        if 0.0 <= trial + self.kp * err <= self.f_max:
            self.integ = trial
        self.force = min(max(self.integ + self.kp * err, 0.0), self.f_max)


@dataclass
class _Run:
    """What :func:`_propagate` needs: per-temperature maps and per-cycle inputs."""

    maps: dict
    seg_temp: list
    seg_of_cycle: np.ndarray
    period: np.ndarray
    powers: np.ndarray
    loop: _DriveLoop


def _propagate(run, z):
    """
    Run the per-cycle maps over every cycle, in blocks of whole AGC chunks.

    Returns the demodulated outputs (I_x, Q_x, I_y, Q_y), the cycle-start
    states (x, x'/w0, y, y'/w0) and the drive force of every cycle. Stacks
    of 4x4 products (@ and einsum) stay below BLAS threading.
    """
    n_cyc = len(run.period)
    chunk = run.loop.chunk
    block = chunk * max(1, 16384 // chunk)
    outputs = np.empty((n_cyc, 4))
    states = np.empty((n_cyc, 4))
    forces = np.empty(n_cyc)
    for b0 in range(0, n_cyc, block):
        b1 = min(n_cyc, b0 + block)
        cum, cum_g = _chunk_products(run, b0, b1)
        if run.loop.agc:
            z, z_start, f_chunk = _agc_chunks(run, b0, b1, cum, cum_g, z)
        else:
            z, z_start, f_chunk = _open_loop_chunks(run, cum, cum_g, z)
        n = b1 - b0
        z_all = (np.einsum('clij,cj->cli', cum[:, :chunk], z_start)
                 + f_chunk[:, None, None] * cum_g[:, :chunk]).reshape(-1, 4)[:n]
        f_all = np.repeat(f_chunk, chunk)[:n]
        outputs[b0:b1] = _demodulated(run, b0, b1, z_all, f_all)
        states[b0:b1] = z_all
        forces[b0:b1] = f_all
    return outputs, states, forces


def _segment_slices(segs):
    """Yield ``(segment, slice)`` for each run of equal segment indices."""
    for s_idx in np.unique(segs):
        yield s_idx, slice(*np.flatnonzero(segs == s_idx)[[0, -1]] + [0, 1])


def _chunk_products(run, b0, b1):
    """
    Cumulative maps within each chunk of cycles ``b0:b1``.

    ``cum[c, j]`` and ``cum_g[c, j]`` map the state and the force at the start
    of chunk c to the state at its j-th cycle (j = 0 .. chunk).
    """
    chunk = run.loop.chunk
    n = b1 - b0
    n_pad = -(-n // chunk) * chunk
    n_ch = n_pad // chunk
    eye = np.eye(4)
    phi = np.broadcast_to(eye, (n_pad, 4, 4)).copy()
    g = np.zeros((n_pad, 4))
    pw = run.powers[b0:b1]
    for s_idx, sel in _segment_slices(run.seg_of_cycle[b0:b1]):
        p_k, g_k, _, _ = run.maps[run.seg_temp[s_idx]]
        phi[sel] = np.einsum('nk,kij->nij', pw[sel], p_k)
        g[sel] = np.einsum('nk,ki->ni', pw[sel], g_k)
    phi = phi.reshape(n_ch, chunk, 4, 4)
    g = g.reshape(n_ch, chunk, 4)
    cum = np.empty((n_ch, chunk + 1, 4, 4))
    cum_g = np.empty((n_ch, chunk + 1, 4))
    cum[:, 0] = eye
    cum_g[:, 0] = 0.0
    for j in range(chunk):
        cum[:, j + 1] = phi[:, j] @ cum[:, j]
        cum_g[:, j + 1] = np.einsum('cij,cj->ci', phi[:, j], cum_g[:, j]) + g[:, j]
    return cum, cum_g


def _open_loop_chunks(run, cum, cum_g, z):
    """Chain the chunks at a fixed force; return (end state, chunk starts, forces)."""
    chunk = run.loop.chunk
    tot, tot_g = cum[:, chunk], cum_g[:, chunk]
    force = run.loop.force
    z_start = np.empty((len(tot), 4))
    for c in range(len(tot)):
        z_start[c] = z
        z = tot[c].dot(z) + force * tot_g[c]
    return z, z_start, np.full(len(tot), force)


def _agc_chunks(run, b0, b1, cum, cum_g, z):
    """
    Chain the chunks with one AGC update per chunk.

    One affine map per chunk gives the next chunk's start state and the
    demodulated drive (I_x, Q_x) of the chunk's last cycle, whose amplitude
    the PI loop regulates.
    """
    loop, chunk = run.loop, run.loop.chunk
    n_ch = cum.shape[0]
    last = np.minimum(b0 + np.arange(1, n_ch + 1) * chunk - 1, b1 - 1)
    lp = run.powers[last]
    l_seg = run.seg_of_cycle[last]
    r_last = np.empty((n_ch, 2, 4))
    f_last = np.empty((n_ch, 2))
    for s_idx in np.unique(l_seg):
        sel = l_seg == s_idx
        _, _, r_k, f_k = run.maps[run.seg_temp[s_idx]]
        r_last[sel] = np.einsum('nk,kij->nij', lp[sel], r_k[:, :2])
        f_last[sel] = np.einsum('nk,ki->ni', lp[sel], f_k[:, :2])
    in_chunk = (last - b0) % chunk
    pick = np.arange(n_ch)
    aff = np.concatenate([cum[:, chunk], np.einsum(
        'cij,cjk->cik', r_last, cum[pick, in_chunk])], axis=1)
    aff_f = np.concatenate([cum_g[:, chunk], np.einsum(
        'cij,cj->ci', r_last, cum_g[pick, in_chunk]) + f_last], axis=1)
    dt_upd = run.period[b0:b0 + n_ch * chunk:chunk] * chunk
    z_start = np.empty((n_ch, 4))
    f_chunk = np.empty(n_ch)
    for c in range(n_ch):
        z_start[c] = z
        f_chunk[c] = loop.force
        v = aff[c].dot(z) + loop.force * aff_f[c]
        z = v[:4]
        loop.update(math.hypot(v[4], v[5]), dt_upd[c])
    return z, z_start, f_chunk


def _demodulated(run, b0, b1, z_all, f_all):
    """Demodulated (I_x, Q_x, I_y, Q_y) of cycles ``b0:b1`` from their start states."""
    out = np.empty((b1 - b0, 4))
    pw = run.powers[b0:b1]
    for s_idx, sel in _segment_slices(run.seg_of_cycle[b0:b1]):
        _, _, r_k, f_k = run.maps[run.seg_temp[s_idx]]
        per_k = np.einsum('kij,nj->nki', r_k, z_all[sel]) + f_all[sel, None, None] * f_k
        out[sel] = np.einsum('nk,nki->ni', pw[sel], per_k)
    return out


def settle_time_s(device, temp_c=25.0, decades=12.0):
    """
    Time for drive and sense transients to decay by 10^-``decades``, s.

    Both modes decay as e^{-sigma t}, sigma = C / (2 M) (Eq 3-4).

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device (scalar fields).
    temp_c : float
        Its die temperature, deg C.
    decades : float
        Decades of decay wanted.

    Returns
    -------
    float

    """
    p = first_order.lumped_parameters(device, temp_c)
    sigma = min(float(p.damping_drive_n_s_m), float(p.damping_sense_n_s_m)) / (
        2.0 * float(p.mass_kg))
    return decades * math.log(10.0) / sigma


def time_domain_frequency_response(device, freq_hz, temp_c=25.0, split_hz=0.0,
                                   rate_amplitude_rad_s=1.0, samples_per_cycle=8):
    """
    Measure the rate channel's frequency response with the time-domain model.

    Drives Omega(t) = Omega_1 sin(2 pi f t) from the drive's steady state,
    waits :func:`settle_time_s`, fits a sin + b cos + c to the in-phase output
    over whole periods of f and returns (a + j b) / (Omega_1 g_DC), g_DC being
    the exact in-phase scale factor (:func:`exact_steady_state`). Comparable
    with :func:`rate_channel_frequency_response`.

    Parameters
    ----------
    device : gyro_emulator.physics.params.Device
        The device (scalar fields).
    freq_hz : float
        Rate-input frequency, Hz (at most f_x / 20).
    temp_c : float
        Die temperature, deg C.
    split_hz : float
        Drive-sense split f_y - f_x, Hz.
    rate_amplitude_rad_s : float
        Omega_1, rad/s.
    samples_per_cycle : int
        Demodulator samples per drive cycle.

    Returns
    -------
    complex

    """
    owner = 'time_domain_frequency_response'
    ref = exact_steady_state(device, rate_amplitude_rad_s, temp_c, split_hz)
    fx = float(ref.params.freq_x_hz)
    f_r = float(check_range(owner, 'freq_hz', freq_hz, 0.0, fx / 20.0, 'Hz'))
    settle = settle_time_s(device, temp_c, 6.0)
    periods = max(3, int(math.ceil(0.01 * f_r)))
    duration = settle + periods / f_r
    omega = 2.0 * np.pi * f_r
    res = simulate_time_domain(
        device, duration, lambda t: rate_amplitude_rad_s * np.sin(omega * t),
        temp_c, split_hz, samples_per_cycle=samples_per_cycle)
    sel = res.time_s >= duration - periods / f_r
    t = res.time_s[sel]
    basis = np.stack([np.sin(omega * t), np.cos(omega * t), np.ones_like(t)], 1)
    coef, *_ = np.linalg.lstsq(basis, res.in_phase_m[sel], rcond=None)
    gain = float(ref.sense_in_phase_m)
    return complex(coef[0], coef[1]) / gain
