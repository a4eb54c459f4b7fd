"""
Truth generator: simulated measured records with one hidden effect.

A record is the output of the one sensor simulator,
:class:`gyro_emulator.sensor.model.GyroModel`, configured as a part with the
baseline physics (the paper's first-order model of a preset: SF(T) from
:func:`gyro_emulator.physics.first_order.scale_factor_ratio`), a random bias
and scale-factor error, plus ONE effect of the catalogue (or none) with a
random magnitude, driven by a seeded random lab-like profile, plus noise:

- white rate noise of density N (angle random walk), sigma = N / sqrt(dt);
- a bias random walk of density K (rate random walk), increments K sqrt(dt)
  (IEEE Std 952 terms; exact discretisation, GyroModel's streams);
- a temperature reading with 0.02 C white noise.

Effects the error model has (bias temperature coefficients, die thermal lag,
g-sensitivity, quadratic nonlinearity) are its terms; the others are physics
or lab effects it cannot express: they act on the rate the part senses
(delay, the cubic nonlinearity term, a drifting mode split, a leaking cavity)
or, for the temperature-rate bias, add to its output.

The profile (:func:`lab_profile`) resembles real lab work: temperature soaks
(the first one at 25 C for calibration) joined by heating and cooling ramps,
rate-table steps with an acceleration limit throughout, swept-sine rate
segments, and tilt positions of the table axis (gravity in the sensor frame
rotates with the table). :func:`paper_profile` is the paper's validation
experiment: 0, 10, 20 and 40 RPM at each of 25, 40, 55, 70 and 85 C.

Everything random comes from one ``numpy.random.Generator``. The hidden
effect and its parameters are returned beside the record, never inside it:
the CSV holds only the diagnose contract columns.
"""

from dataclasses import dataclass

from gyro_emulator.analysis.diagnose.data import MeasuredData
from gyro_emulator.analysis.diagnose.effects import EFFECT_IDS, HOUR_S
from gyro_emulator.physics import first_order
from gyro_emulator.physics.presets import physics_preset
from gyro_emulator.sensor.config import ErrorTerms, SensorConfig
from gyro_emulator.sensor.model import GyroModel
from gyro_emulator.units import (deg_s_to_rad_s, rpm_to_rad_s,
                                 STANDARD_GRAVITY_M_S2)
from gyro_emulator.validation import check_range
import numpy as np

#: Effects the generator can hide: the catalogue and 'none' (clean data).
TRUTH_EFFECTS = EFFECT_IDS + ('none',)
PROFILES = ('lab', 'paper')
#: Sutherland constant of air, K (White, Viscous Fluid Flow).
AIR_SUTHERLAND_K = 110.4
TEMP_READING_NOISE_C = 0.02
ACCEL_NOISE_M_S2 = 0.02


@dataclass(frozen=True)
class Profile:
    """A test profile: true rate, true (chamber) temperature, acceleration."""

    time_s: np.ndarray
    rate_rad_s: np.ndarray
    temp_c: np.ndarray
    accel_m_s2: np.ndarray
    max_rate_rad_s: float
    name: str


def _soak_ramp_temperature(t, plan):
    """Piecewise-linear temperature from (time, temp) knots."""
    knots_t, knots_temp = zip(*plan)
    return np.interp(t, knots_t, knots_temp)


def lab_profile(rng, sample_rate_hz=25.0, levels=5, max_duration_s=None):
    """
    Make a seeded random lab-like profile.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness.
    sample_rate_hz : float
        Output data rate, Hz.
    levels : int
        Temperature soak levels, 25 C included (>= 3).
    max_duration_s : float, optional
        Cut the profile at this duration.

    Returns
    -------
    Profile

    """
    plan, end_s = _soak_plan(rng, levels)
    duration = end_s if max_duration_s is None else min(end_s, max_duration_s)
    dt = 1.0 / sample_rate_hz
    t = np.arange(0.0, duration, dt)
    temp = _soak_ramp_temperature(t, plan)
    rate, max_rate = _table_rate(rng, t, duration, sample_rate_hz)
    accel = _table_gravity(rng, t, rate, duration, dt)
    return Profile(time_s=t, rate_rad_s=rate, temp_c=temp, accel_m_s2=accel,
                   max_rate_rad_s=float(max_rate), name='lab')


def _soak_plan(rng, levels):
    """
    Draw the chamber plan: soaks at ``levels`` temperatures joined by ramps.

    The first soak (600 s) and the last are at 25 C; the others last 6 to
    11 min at levels spread from -10..12 C to 55..85 C in random order, and
    the ramps run at 1 to 3 K/min. Return the (time, temp) knots and the end
    time, s.
    """
    t_lo = rng.uniform(-10.0, 12.0)
    t_hi = rng.uniform(55.0, 85.0)
    temps = list(np.linspace(t_lo, t_hi, levels) + rng.uniform(-3, 3, levels))
    temps[int(np.argmin(np.abs(np.array(temps) - 25.0)))] = 25.0
    others = [v for v in temps if v != 25.0]
    order = [25.0] + list(rng.permutation(others)) + [25.0]
    plan, now = [], 0.0
    for i, level in enumerate(order):
        soak = 600.0 if i == 0 else rng.uniform(360.0, 660.0)
        plan += [(now, level), (now + soak, level)]
        now += soak
        if i + 1 < len(order):
            ramp_k_s = rng.uniform(1.0, 3.0) / 60.0
            now += abs(order[i + 1] - level) / ramp_k_s
    return plan, now


def _table_rate(rng, t, duration, sample_rate_hz):
    """
    Draw the rate-table program: steps under an acceleration limit and chirps.

    Dwells of 20 to 60 s at 0 or +-10, 25, 50, 75 or 100 % of a full scale
    of 150 to 300 deg/s, reached at 100 to 300 deg/s^2; 12 % of the dwells carry a
    swept sine (0.2 Hz up to at most 4 Hz or f_s / 6) with a sin^2 taper.
    Return the rate at ``t``, rad/s, and the full scale, rad/s.
    """
    max_rate = deg_s_to_rad_s(rng.uniform(150.0, 300.0))
    accel_limit = deg_s_to_rad_s(rng.uniform(100.0, 300.0))
    fractions = np.array([0.0, 0.1, 0.25, 0.5, 0.75, 1.0])
    knots_t, knots_r = [0.0], [0.0]
    chirps = []
    now, level = 0.0, 0.0
    while now < duration:
        dwell = rng.uniform(20.0, 60.0)
        if rng.random() < 0.12:
            new = 0.0
            kind = 'chirp'
        else:
            new = 0.0 if rng.random() < 0.25 else float(
                rng.choice(fractions[1:]) * rng.choice([-1.0, 1.0]) * max_rate)
            kind = 'step'
        move = abs(new - level) / accel_limit
        knots_t += [now + move, now + move + dwell]
        knots_r += [new, new]
        if kind == 'chirp':
            f_top = min(4.0, sample_rate_hz / 6.0)
            chirps.append((now + move, dwell, rng.uniform(0.1, 0.4) * max_rate,
                           rng.uniform(0.4 * f_top, f_top)))
        now += move + dwell
        level = new
    rate = np.interp(t, knots_t, knots_r)
    for start, length, amp, f1 in chirps:
        m = (t >= start) & (t < start + length)
        tau = t[m] - start
        f0 = 0.2
        phase = 2 * np.pi * (f0 * tau + 0.5 * (f1 - f0) / length * tau ** 2)
        taper = np.sin(np.pi * tau / length) ** 2
        rate[m] += amp * taper * np.sin(phase)
    return rate, max_rate


def _table_gravity(rng, t, rate, duration, dt):
    """
    Draw the tilts of the table axis; return gravity in the sensor frame, m/s^2.

    The axis dwells 3 to 10 min at a tilt from vertical of 0 to 180 deg;
    gravity's horizontal part turns with the table angle (the integral of
    the rate).
    """
    tilt = np.zeros_like(t)
    now = 0.0
    angles = np.deg2rad([0.0, 30.0, 60.0, 90.0, 120.0, 180.0])
    while now < duration:
        dwell = rng.uniform(180.0, 600.0)
        tilt[(t >= now) & (t < now + dwell)] = rng.choice(angles)
        now += dwell
    table_angle = np.cumsum(rate) * dt
    g = STANDARD_GRAVITY_M_S2
    return np.column_stack([g * np.sin(tilt) * np.cos(table_angle),
                            -g * np.sin(tilt) * np.sin(table_angle),
                            g * np.cos(tilt)])


def paper_profile(sample_rate_hz=10.0, minutes_per_point=5.0,
                  temps_c=(25.0, 40.0, 55.0, 70.0, 85.0),
                  rates_rpm=(0.0, 10.0, 20.0, 40.0), ramp_k_min=2.0):
    """
    Make the paper's validation experiment into a profile.

    At each temperature (soak), the table turns at each rate for
    ``minutes_per_point`` minutes (the paper averaged 5 minutes per point);
    the chamber ramps at ``ramp_k_min`` K/min between temperatures with the
    table at rest, axis vertical.

    Parameters
    ----------
    sample_rate_hz : float
        Output data rate, Hz.
    minutes_per_point : float
        Dwell per (temperature, rate) point, min.
    temps_c : sequence of float
        Soak temperatures, deg C.
    rates_rpm : sequence of float
        Table rates, RPM.
    ramp_k_min : float
        Chamber ramp rate, K/min.

    Returns
    -------
    Profile

    """
    dwell = 60.0 * minutes_per_point
    temp_knots, rate_knots = [], []
    now = 0.0
    for i, temp in enumerate(temps_c):
        for rpm in rates_rpm:
            temp_knots += [(now, temp), (now + dwell, temp)]
            rate_knots += [(now + 2.0, rpm_to_rad_s(rpm)),
                           (now + dwell - 2.0, rpm_to_rad_s(rpm))]
            now += dwell
        if i + 1 < len(temps_c):
            rate_knots += [(now, 0.0)]
            now += abs(temps_c[i + 1] - temp) / (ramp_k_min / 60.0)
            rate_knots += [(now, 0.0)]
    dt = 1.0 / sample_rate_hz
    t = np.arange(0.0, now, dt)
    temp = _soak_ramp_temperature(t, temp_knots)
    kt, kr = zip(*([(0.0, 0.0)] + rate_knots))
    rate = np.interp(t, kt, kr)
    accel = np.tile([0.0, 0.0, STANDARD_GRAVITY_M_S2], (len(t), 1))
    return Profile(time_s=t, rate_rad_s=rate, temp_c=temp, accel_m_s2=accel,
                   max_rate_rad_s=float(np.max(np.abs(rate))), name='paper')


def draw_effect_parameters(effect, rng, profile):
    """
    Random magnitude of a hidden effect, realistic and detectable.

    Parameters
    ----------
    effect : str
        One of :data:`TRUTH_EFFECTS`.
    rng : numpy.random.Generator
        Source of randomness.
    profile : Profile
        The profile (its temperature span and rates set the scales).

    Returns
    -------
    dict
        Parameter name -> value (SI; names as in the diagnose report).

    """
    sign = float(rng.choice([-1.0, 1.0]))
    span = max(abs(profile.temp_c.max() - 25.0), abs(profile.temp_c.min() - 25.0),
               1.0)
    r_max = profile.max_rate_rad_s
    if effect == 'none':
        return {}
    if effect == 'viscosity_temperature':
        return {'sutherland_constant_k': rng.uniform(80.0, 250.0)}
    if effect == 'bias_temperature':
        b1 = sign * deg_s_to_rad_s(rng.uniform(0.05, 0.5)) / span
        return {'bias_temp_coeff_rad_s_k': b1,
                'bias_temp_coeff2_rad_s_k2': rng.uniform(-0.5, 0.5) * abs(b1)
                / span}
    if effect == 'thermal_lag':
        return {'thermal_time_constant_s': rng.uniform(120.0, 600.0)}
    if effect == 'scale_factor_nonlinearity':
        return {'nonlinearity_quadratic_s_rad':
                rng.uniform(-0.003, 0.003) / r_max,
                'nonlinearity_cubic_s2_rad2':
                sign * rng.uniform(0.002, 0.01) / r_max ** 2}
    if effect == 'g_sensitivity':
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        mag = deg_s_to_rad_s(rng.uniform(0.03, 0.15)) / STANDARD_GRAVITY_M_S2
        return {f'g_sensitivity_{a}_rad_s_per_m_s2': float(mag * direction[k])
                for k, a in enumerate('xyz')}
    if effect == 'time_delay':
        return {'delay_s': rng.uniform(0.002, 0.02)}
    if effect == 'pressure_drift':
        hours = profile.time_s[-1] / HOUR_S
        return {'pressure_rate_per_h': sign * rng.uniform(0.1, 0.4) / hours}
    if effect == 'mode_split_drift':
        return {'mode_split_at_ref_hz': rng.uniform(-5.0, 5.0),
                'mode_split_temp_coeff_hz_k': sign * rng.uniform(0.4, 1.5)}
    if effect == 'temperature_rate_bias':
        return {'bias_per_temp_rate_rad_s_per_k_s':
                sign * deg_s_to_rad_s(rng.uniform(1.0, 5.0))}
    raise ValueError(f'truth.effect = {effect!r} is not allowed: choose one '
                     f'of {", ".join(TRUTH_EFFECTS)}')


def _sensor_config(device, effect, params, drawn):
    """
    Return the error model of the simulated part, for :class:`GyroModel`.

    The part's own terms: turn-on bias, scale-factor error, SF(T) from the
    physics of ``device``, white rate noise N and rate random walk K, and the
    hidden effect where the error model has it (bias temperature
    coefficients, die thermal lag, g-sensitivity, quadratic nonlinearity).
    Everything else is off.
    """
    on = {'scale_factor_temperature', 'turn_on_bias', 'scale_factor_error',
          'electronics_noise', 'rate_random_walk'}
    extra = {}
    if effect == 'bias_temperature':
        on.add('bias_temperature')
        extra = {'bias_temp_coeff_rad_s_k': (0.0, 0.0, params['bias_temp_coeff_rad_s_k']),
                 'bias_temp_coeff2_rad_s_k2':
                 (0.0, 0.0, params['bias_temp_coeff2_rad_s_k2'])}
    elif effect == 'thermal_lag':
        on.add('thermal_lag')
        extra = {'thermal_time_constant_s': params['thermal_time_constant_s']}
    elif effect == 'g_sensitivity':
        on.add('g_sensitivity')
        row = tuple(params[f'g_sensitivity_{a}_rad_s_per_m_s2'] for a in 'xyz')
        extra = {'g_sensitivity_rad_s_m_s2': ((0.0,) * 3, (0.0,) * 3, row)}
    elif effect == 'scale_factor_nonlinearity':
        on.add('nonlinearity')
        extra = {'nonlinearity_s_rad': (0.0, 0.0, params['nonlinearity_quadratic_s_rad'])}
    terms = ErrorTerms(**{name: name in on for name in ErrorTerms.names()})
    return SensorConfig(
        device=device, terms=terms, range_rad_s=(1000.0,) * 3,
        turn_on_bias_rad_s=(0.0, 0.0, float(deg_s_to_rad_s(drawn['bias_deg_s']))),
        scale_factor_error=(0.0, 0.0, drawn['scale_factor'] - 1.0),
        electronics_noise_rad_s_sqrt_hz=(
            0.0, 0.0, float(deg_s_to_rad_s(drawn['arw_deg_sqrt_s']))),
        rate_random_walk_rad_s_sqrt_s=(
            0.0, 0.0, float(deg_s_to_rad_s(drawn['rrw_deg_s_sqrt_s']))), **extra)


def _rate_into_the_part(profile, effect, params, device):
    """
    Return the rate the error model sees: the true rate with the effects it lacks.

    Delay (the part's latency term only stamps its samples, it does not
    shift them), the cubic term of the nonlinearity (x = Omega (1 + a3 Omega^2);
    the part adds its quadratic term, x + a2 x^2, so the output is
    Omega (1 + a2 Omega + a3 Omega^2) to within 2 a3 Omega^2 <= 2 % of the
    quadratic term), and the scale-factor changes of a drifting mode split
    (Eq 4 off resonance) or a leaking cavity pressure (Eq 5-12 at the new
    pressure) act on the sensed rate before the part's own gain.
    """
    t, rate, temp = profile.time_s, profile.rate_rad_s, profile.temp_c
    tref = device.calibration_temp_c
    rate_in = rate
    if effect == 'time_delay':
        rate_in = np.interp(t - params['delay_s'], t, rate, left=rate[0])
    if effect == 'scale_factor_nonlinearity':
        rate_in = rate_in * (1.0 + params['nonlinearity_cubic_s2_rad2'] * rate_in ** 2)
    if effect == 'mode_split_drift':
        p = first_order.lumped_parameters(device, temp)
        split = params['mode_split_at_ref_hz'] + params[
            'mode_split_temp_coeff_hz_k'] * (temp - tref)
        rate_in = rate_in / np.sqrt(1.0 + (2.0 * p.q_sense * split / p.freq_y_hz) ** 2)
    if effect == 'pressure_drift':
        coarse = np.arange(0, len(t), max(1, int(round(1.0 / float(t[1] - t[0])))))
        pr = 1.0 + params['pressure_rate_per_h'] * t[coarse] / HOUR_S
        sf_p = first_order.sense_scale_factor_m_per_rad_s(
            device.with_gas(pressure_pa=device.gas.pressure_pa * pr),
            temp[coarse]) / first_order.sense_scale_factor_m_per_rad_s(
            device, temp[coarse])
        rate_in = rate_in * np.interp(t, t[coarse], sf_p)
    return rate_in


def _draw_part_errors(rng, noise=None):
    """Draw the part's noise densities, turn-on bias and scale factor; ``noise`` overrides."""
    drawn = {
        # white noise density, deg/s/sqrt(Hz) (= deg/sqrt(s))
        'arw_deg_sqrt_s': rng.uniform(0.006, 0.015),
        # rate random walk, deg/h/sqrt(h) -> deg/s/sqrt(s)
        'rrw_deg_s_sqrt_s': rng.uniform(5.0, 40.0) / 3600.0 / 60.0,
        'bias_deg_s': rng.uniform(-0.5, 0.5),
        'scale_factor': rng.uniform(0.98, 1.02),
    }
    drawn.update(noise or {})
    return drawn


def simulate(profile, effect, params, rng, preset='paper', noise=None):
    """
    Simulate the measured output for a profile with one hidden effect.

    The sensor is :class:`gyro_emulator.sensor.model.GyroModel` (the one
    simulator) on the z axis, configured by :func:`_sensor_config`, driven
    by the true rate with the effects it lacks applied
    (:func:`_rate_into_the_part`); a temperature-rate bias is added to its
    output. The viscosity effect changes the physics of the device itself
    (a Sutherland gas law).

    Parameters
    ----------
    profile : Profile
        True rate, temperature and acceleration.
    effect : str
        Hidden effect id or 'none'.
    params : dict
        Its parameters (see :func:`draw_effect_parameters`).
    rng : numpy.random.Generator
        Source of randomness (noise, calibration errors); the sensor's noise
        streams are spawned from it.
    preset : str
        Physics preset of the simulated device.
    noise : dict, optional
        Override ``arw_deg_sqrt_s``, ``rrw_deg_s_sqrt_s``, ``bias_deg_s``,
        ``scale_factor``.

    Returns
    -------
    (MeasuredData, dict)
        The record and the truth (effect, parameters, noise).

    """
    device = physics_preset(preset)
    t, rate, temp = profile.time_s, profile.rate_rad_s, profile.temp_c
    n = len(t)
    dt = float(t[1] - t[0])
    drawn = _draw_part_errors(rng, noise)
    part = device
    if effect == 'viscosity_temperature':
        part = device.with_gas(viscosity_law='sutherland',
                               sutherland_constant_k=params['sutherland_constant_k'])
    model = GyroModel(_sensor_config(part, effect, params, drawn), 1.0 / dt, rng)
    rate_in = np.zeros((n, 3))
    rate_in[:, 2] = _rate_into_the_part(profile, effect, params, device)
    accel = profile.accel_m_s2
    out = model.run(rate_in, temp, accel).gyro_rad_s[:, 2]
    if effect == 'temperature_rate_bias':
        out = out + params['bias_per_temp_rate_rad_s_per_k_s'] * np.gradient(temp, t)
    data = MeasuredData(
        time_s=t, rate_cmd_rad_s=rate,
        temp_c=temp + rng.normal(0.0, TEMP_READING_NOISE_C, n),
        gyro_rad_s=out,
        accel_m_s2=accel + rng.normal(0.0, ACCEL_NOISE_M_S2, accel.shape),
        source=f'truth:{profile.name}')
    truth = {'effect': effect, 'parameters': dict(params), 'preset': preset,
             'noise': drawn, 'profile': profile.name,
             'duration_s': float(t[-1] + dt), 'sample_rate_hz': 1.0 / dt}
    return data, truth


def make_truth(effect, seed, profile='lab', sample_rate_hz=25.0, levels=5,
               params=None, preset='paper', noise=None, max_duration_s=None):
    """
    One simulated measured record with a hidden effect.

    Parameters
    ----------
    effect : str
        One of :data:`TRUTH_EFFECTS`, or 'random' to draw it from the seed.
    seed : int
        Seed of the one ``numpy.random.Generator`` used.
    profile : str
        'lab' (:func:`lab_profile`) or 'paper' (:func:`paper_profile`).
    sample_rate_hz : float
        Output data rate, Hz.
    levels : int
        Temperature levels of the lab profile.
    params : dict, optional
        Fix some effect parameters instead of drawing them.
    preset : str
        Physics preset of the simulated device.
    noise : dict, optional
        Override noise and calibration-error terms (see :func:`simulate`).
    max_duration_s : float, optional
        Cut the lab profile at this duration, s.

    Returns
    -------
    (MeasuredData, dict)
        The record and the hidden truth.

    """
    check_range('truth', 'sample_rate_hz', sample_rate_hz, 1.0, 2000.0, 'Hz',
                low_open=False)
    check_range('truth', 'levels', levels, 3, 12, '', low_open=False)
    rng = np.random.default_rng(seed)
    if effect == 'random':
        effect = str(rng.choice(TRUTH_EFFECTS))
    if effect not in TRUTH_EFFECTS:
        raise ValueError(f'truth.effect = {effect!r} is not allowed: choose '
                         f'one of random, {", ".join(TRUTH_EFFECTS)}')
    if profile == 'lab':
        prof = lab_profile(rng, sample_rate_hz=sample_rate_hz, levels=levels,
                           max_duration_s=max_duration_s)
    elif profile == 'paper':
        prof = paper_profile(sample_rate_hz=sample_rate_hz)
    else:
        raise ValueError(f'truth.profile = {profile!r} is not allowed: choose '
                         f'one of {", ".join(PROFILES)}')
    drawn = draw_effect_parameters(effect, rng, prof)
    unknown = sorted(set(params or {}) - set(drawn))
    if unknown:
        raise ValueError(
            f'truth.params: {", ".join(unknown)} is not a parameter of '
            f'{effect}; allowed: {", ".join(sorted(drawn)) or "(none)"}')
    drawn.update({k: float(v) for k, v in (params or {}).items()})
    return simulate(prof, effect, drawn, rng, preset=preset, noise=noise)
