"""
Effects hidden in real noise: a measured static log plus an applied profile and an effect.

``diagnose`` is proved on synthetic noise (:mod:`.generator`); a real part
adds its own. This module builds a record as a lab would see it if the
part behind a real static log had been driven through a test profile::

    gyro = noise + rate(t - delay) (1 + sf_error) + sum of effects(inputs)

``noise`` is a stretch of a real log at rest (its bias, wander, flicker,
quantisation and glitches kept as measured), ``rate`` the applied rate of
the profile, and each effect a function of the profile's inputs
(:data:`EFFECTS`). The profile is a sampled profile of the one profile
protocol (:class:`gyro_emulator.emulation.profiles.SampledProfile`: the
rate about the sense axis z, the temperature, the specific force), with the
rate's knots (``rate_knots``) when the table moves; a one-way ramp is the
shared chamber-program idea
(:func:`gyro_emulator.emulation.profiles.temperature_ramp`). Everything is a
function of arrays; the result is a
:class:`gyro_emulator.recording.record.Record` (:func:`inject`) that
``diagnose`` takes as it takes a CSV. Effects are exact: the delay of a
piecewise-linear rate is the rate at ``t - delay`` from its knots.
"""

from gyro_emulator.emulation import profiles
from gyro_emulator.recording.record import load_record, Record
from gyro_emulator.units import deg_s_to_rad_s, STANDARD_GRAVITY_M_S2
from gyro_emulator.validation import check_range
import numpy as np
from scipy.signal import lfilter

#: Temperature the tempco effects are zero at, deg C.
REF_TEMP_C = 25.0
#: Full scale of the rate-step profile and of the nonlinearity, rad/s.
FULL_SCALE_RAD_S = float(deg_s_to_rad_s(240.0))
_DEG = float(deg_s_to_rad_s(1.0))

#: Datasheet-size effects, SI (the ADIS16405's typical figures, used for every
#: part so that the logs compare): bias tempco 0.01 deg/s/K; scale-factor
#: tempco 40 ppm/K; g-sensitivity 0.05 deg/s/g; a 12 ms delay (one output
#: filter group delay); cubic scale-factor nonlinearity 0.1 % of full scale at
#: full scale; a 0.1 % scale-factor step at mid-record.
DATASHEET = {
    'bias_tempco': 0.01 * _DEG,
    'sf_tempco': 40e-6,
    'g_sensitivity': 0.05 * _DEG / STANDARD_GRAVITY_M_S2,
    'delay': 0.012,
    'sf_nonlinearity': 1e-3,
    'sf_step': 1e-3,
}
#: Units of :data:`DATASHEET`, for messages.
UNITS = {'bias_tempco': 'rad/s/K', 'sf_tempco': '1/K', 'g_sensitivity': 'rad/s per m/s^2',
         'delay': 's', 'sf_nonlinearity': 'of full scale', 'sf_step': '(relative)'}


#: The axis the applied rate turns about and the record senses (the sampled
#: profiles' convention, :func:`gyro_emulator.emulation.profiles.rate_about_z`).
SENSE = 2


def sensed_rate(prof, time_s=None):
    """
    Return the applied rate about the sense axis, rad/s: at the samples, or at ``time_s``.

    At other times it comes from the rate's knots (zero before the first and
    after the last), exactly; zero for a profile without motion.
    """
    if time_s is None:
        return prof.rate_rad_s[:, SENSE]
    if prof.rate_knots is None:
        return np.zeros(len(time_s))
    return prof.rate_at(time_s)[:, SENSE]


def load_real(path, axis=None):
    """
    Read one gyro axis of a real log: (time_s from 0, gyro rad/s, temp_c or None).

    ``axis`` picks ``gyro_<axis>_rad_s`` of a 3-axis CSV; None takes the
    single ``gyro_rad_s`` column.
    """
    rec = load_record(path)
    gyro = rec.gyro['x' if axis is None else axis]
    temp = None if rec.temp is None else rec.temp.values
    return rec.time_s - rec.time_s[0], gyro, temp


def stretch(time_s, values, duration_s, rng, flip=True):
    """
    Return (time_s from 0, values) of a random stretch of ``duration_s`` of a log.

    The start is uniform; with ``flip``, the stretch is time-reversed and
    sign-flipped each with probability 1/2 (both keep the statistics of
    stationary noise and make overlapping stretches less alike).
    """
    time_s = np.asarray(time_s, dtype=float)
    n = min(len(time_s), int(np.searchsorted(time_s, time_s[0] + duration_s)))
    start = int(rng.integers(0, len(time_s) - n + 1))
    t = time_s[start:start + n] - time_s[start]
    v = np.array(values[start:start + n], dtype=float)
    if flip and rng.random() < 0.5:
        v = v[::-1]
    if flip and rng.random() < 0.5:
        v = -v
    return t, v


def first_order_lag(time_s, target, tau_s):
    """
    Die temperature behind a chamber set point: a first-order lag of ``target``, deg C.

    Exact for a target held over each sample interval, on the record's median
    interval: y[i] = a y[i-1] + (1 - a) u[i], a = exp(-dt / tau).
    """
    dt = float(np.median(np.diff(time_s))) if len(time_s) > 1 else 1.0
    a = float(np.exp(-dt / tau_s))
    target = np.asarray(target, dtype=float)
    out, _ = lfilter([1.0 - a], [1.0, -a], target, zi=[a * target[0]])
    return out


def one_way_ramp(time_s, low_c=15.0, high_c=55.0):
    """
    One-way linear ramp from ``low_c`` to ``high_c`` over the record, deg C.

    The chamber-program idea :func:`gyro_emulator.emulation.profiles.temperature_ramp`
    with two knots, the part at rest.
    """
    span = max(float(time_s[-1] - time_s[0]), 1e-12)
    program = profiles.temperature_ramp([(0.0, low_c), (span, high_c)], rate_deg_s=0.0)
    return program.samples(np.asarray(time_s, dtype=float) - time_s[0]).temp_c


def temperature_cycles(time_s, cycles=2, low_c=15.0, high_c=55.0, phase=0.0):
    """
    Chamber cycles: hold low, ramp up, hold high, ramp down; the die lags by 1/60 of the record.

    Each cycle spends 30 % of its time at each end and 20 % on each ramp;
    ``phase`` (a share of a cycle) is where in the cycle the record starts.
    """
    span = max(time_s[-1] - time_s[0], 1e-12)
    phase = ((time_s - time_s[0]) / span * cycles + phase) % 1.0
    shape = np.interp(phase, [0, 0.15, 0.35, 0.65, 0.85, 1.0], [0, 0, 1, 1, 0, 0])
    return first_order_lag(time_s, low_c + (high_c - low_c) * shape, span / 60.0)


def temperature_soaks(time_s, levels_c=(15.0, 25.0, 35.0, 45.0, 55.0)):
    """Soaks: the chamber steps through ``levels_c``; the die lags by 1/40 of the record."""
    span = max(time_s[-1] - time_s[0], 1e-12)
    k = np.minimum(((time_s - time_s[0]) / span * len(levels_c)).astype(int),
                   len(levels_c) - 1)
    return first_order_lag(time_s, np.asarray(levels_c, dtype=float)[k], span / 40.0)


def tilt_steps(time_s, rng, steps=16):
    """
    Gravity on a part tilted in steps about y: (n, 3) m/s^2, g (sin th, 0, cos th).

    ``steps`` equal dwells at angles drawn from -90..90 deg (both signs of
    the x component, so a g-sensitivity is not a bias).
    """
    angles = rng.permutation(np.linspace(-np.pi / 2, np.pi / 2, steps))
    span = max(time_s[-1] - time_s[0], 1e-12)
    k = np.minimum(((time_s - time_s[0]) / span * steps).astype(int), steps - 1)
    th = angles[k]
    return STANDARD_GRAVITY_M_S2 * np.column_stack([np.sin(th), np.zeros(len(th)), np.cos(th)])


def rate_step_knots(duration_s, levels_deg_s=(30, 60, 120, 240), hold_s=4.0, gap_s=4.0,
                    accel_deg_s2=2e4):
    """
    Knots (times s, rates rad/s) of rate-table steps: 0 -> +r -> 0 -> -r for each level.

    Ramps at ``accel_deg_s2`` (the default steps to 240 deg/s within 12 ms,
    about a sample at 100 Hz); the pattern repeats to cover ``duration_s``.
    """
    kt, kr, tk = [0.0], [0.0], 0.0
    pattern = [s * r for r in levels_deg_s for s in (1, -1)]
    while tk < duration_s + 1.0:
        for r in pattern:
            ramp = abs(r) / accel_deg_s2
            kt += [tk + gap_s, tk + gap_s + ramp, tk + gap_s + ramp + hold_s,
                   tk + gap_s + 2 * ramp + hold_s]
            kr += [0.0, r, r, 0.0]
            tk = kt[-1]
    return np.asarray(kt), np.asarray(kr) * _DEG


def rate_sine_knots(time_s, rng, amplitude_deg_s=(50.0, 300.0), frequency_hz=(0.2, 2.0)):
    """
    Knots (times s, rates rad/s) of a rate-table sine between 5 % and 95 % of the record.

    Amplitude and frequency are drawn uniformly from their ranges; the
    knots are 20 per period (a linear interpolation of them is within
    1.3 % of the sine's amplitude, and exact at the knots).
    """
    amp = float(rng.uniform(*amplitude_deg_s)) * _DEG
    freq = float(rng.uniform(*frequency_hz))
    start = time_s[0] + 0.05 * (time_s[-1] - time_s[0])
    stop = time_s[-1] - 0.05 * (time_s[-1] - time_s[0])
    kt = np.arange(start, stop, 1.0 / (20.0 * freq))
    return kt, amp * np.sin(2.0 * np.pi * freq * (kt - start))


#: Parts of a profile :func:`profile` builds: temperature, then motion.
TEMPERATURES = ('ramp', 'cycles', 'soaks', 'chamber')
MOTIONS = ('tilt', 'rate_steps', 'rate_sine')


def profile(name, time_s, rng, temp_c=None):
    """
    Return a profile on ``time_s``: a :class:`~gyro_emulator.emulation.profiles.SampledProfile`.

    ``name`` is ``static`` or parts joined by ``+``: at most one of
    :data:`TEMPERATURES` (``ramp``, ``cycles``, ``soaks``: 15..55 C;
    ``chamber``: the log's own temperature ``temp_c``; default 25 C) and
    any of :data:`MOTIONS` (``tilt``: gravity in steps; ``rate_steps``: a
    rate table to 240 deg/s; ``rate_sine``: a rate-table sine, not with
    ``rate_steps``), e.g. ``'cycles+tilt'``. The rate turns about z (the
    sense axis, :data:`SENSE`); with motion on the table the profile carries
    the rate's knots.
    """
    parts = [] if name == 'static' else name.split('+')
    unknown = [p for p in parts if p not in TEMPERATURES + MOTIONS]
    if unknown or sum(p in TEMPERATURES for p in parts) > 1:
        raise ValueError(f'profile {name!r}: expected static or one of {", ".join(TEMPERATURES)} '
                         f'and any of {", ".join(MOTIONS)} joined by +')
    t = np.asarray(time_s, dtype=float)
    temp = np.full(len(t), REF_TEMP_C)
    accel = np.tile([0.0, 0.0, STANDARD_GRAVITY_M_S2], (len(t), 1))
    if 'ramp' in parts:
        temp = one_way_ramp(t)
    elif 'cycles' in parts:
        temp = temperature_cycles(t)
    elif 'soaks' in parts:
        temp = temperature_soaks(t)
    elif 'chamber' in parts:
        if temp_c is None:
            raise ValueError('profile chamber: the log has no temperature')
        temp = np.asarray(temp_c, dtype=float)
    if 'tilt' in parts:
        accel = tilt_steps(t, rng)
    if 'rate_steps' in parts and 'rate_sine' in parts:
        raise ValueError(f'profile {name!r}: rate_steps and rate_sine cannot be joined')
    if 'rate_steps' in parts:
        kt, kr = rate_step_knots(float(t[-1] - t[0]))
        knots = (kt + t[0], kr)
    elif 'rate_sine' in parts:
        knots = rate_sine_knots(t, rng)
    else:
        return profiles.SampledProfile(name, t, np.zeros((len(t), 3)), temp, accel)
    return profiles.SampledProfile(
        name, t, profiles.rate_about_z(np.interp(t, *knots, left=0.0, right=0.0)), temp, accel,
        rate_knots=(np.asarray(knots[0], dtype=float), profiles.rate_about_z(knots[1])))


def block_means(time_s, values, factor):
    """
    Return (times, values) averaged over consecutive blocks of ``factor`` samples.

    A real log at a lower output rate (as through a moving-average output
    filter): the same part's noise, fewer samples.
    """
    n = len(values) // factor * factor
    return (np.asarray(time_s[:n:factor], dtype=float),
            np.asarray(values[:n], dtype=float).reshape(-1, factor).mean(axis=1))


def effect_signal(prof, effect, size, rate_rad_s=None):
    """
    Output error of one effect, rad/s per sample (``size`` in the units of :data:`UNITS`).

    bias_tempco: size (T - 25); sf_tempco: size (T - 25) rate; g_sensitivity:
    size a_x; delay: rate(t - size) - rate(t); sf_nonlinearity: size FS
    (rate/FS)^3; sf_step: size rate after mid-record. ``prof`` is the
    profile (:func:`profile`); ``rate_rad_s`` the rate the part senses
    (default the applied one; a delayed one when a delay acts too).
    """
    rate = sensed_rate(prof) if rate_rad_s is None else rate_rad_s
    dtemp = prof.temp_c - REF_TEMP_C
    t = prof.time_s
    if effect == 'bias_tempco':
        return size * dtemp
    if effect == 'sf_tempco':
        return size * dtemp * rate
    if effect == 'g_sensitivity':
        return size * prof.accel_m_s2[:, 0]
    if effect == 'delay':
        return sensed_rate(prof, t - size) - rate
    if effect == 'sf_nonlinearity':
        return size * FULL_SCALE_RAD_S * (rate / FULL_SCALE_RAD_S) ** 3
    if effect == 'sf_step':
        return size * rate * (t > 0.5 * (t[0] + t[-1]))
    raise ValueError(f'effect {effect!r} is unknown: choose one of {", ".join(DATASHEET)}')


def inject(noise_rad_s, prof, effects=None, sf_error=0.0, path='injected'):
    """
    Return the Record of real noise, the applied rate and the effects.

    Parameters
    ----------
    noise_rad_s : numpy.ndarray
        A stretch of a real log at rest on ``prof.time_s``, rad/s.
    prof : gyro_emulator.emulation.profiles.SampledProfile
        The profile (:func:`profile`).
    effects : dict, optional
        Effect name (:data:`DATASHEET`) -> size in its unit (:data:`UNITS`).
    sf_error : float
        Constant relative scale-factor error of the part, [-0.1, 0.1].
    path : str
        A name for reports.

    Returns
    -------
    gyro_emulator.recording.record.Record
        Time, gyro, rate, temperature and acceleration (the diagnose contract).

    """
    check_range('inject', 'sf_error', sf_error, -0.1, 0.1, '', low_open=False,
                high_open=False)
    noise = np.asarray(noise_rad_s, dtype=float)
    if noise.shape != prof.time_s.shape:
        raise ValueError(f'inject: noise has {noise.shape} samples, the profile '
                         f'{prof.time_s.shape}')
    effects = dict(effects or {})
    applied = sensed_rate(prof)
    sensed = applied
    if 'delay' in effects:
        sensed = sensed_rate(prof, prof.time_s - float(effects.pop('delay')))
    gyro = noise + sensed * (1.0 + sf_error)
    for name, size in effects.items():
        gyro = gyro + effect_signal(prof, name, float(size), sensed)
    return Record.from_arrays(prof.time_s, gyro, applied, prof.temp_c, prof.accel_m_s2,
                              path=path)
