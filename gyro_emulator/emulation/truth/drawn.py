"""
Drawn test profiles: what a lab did to a part, sample by sample.

The truth generator (:mod:`.generator`) runs a part through one of these
sampled profiles (:class:`gyro_emulator.emulation.profiles.SampledProfile`:
the true rate about the sense axis z, the true (chamber) temperature and the
specific force in the sensor frame). Every random choice comes from the
injected ``numpy.random.Generator``; the deterministic ideas are the shared
profile functions of :mod:`gyro_emulator.emulation.profiles`.

- ``lab`` (:func:`lab_profile`): a rate table in a thermal chamber (soaks
  joined by heating and cooling ramps, rate steps with an acceleration
  limit, swept sines, tilt positions of the table axis);
- ``paper``: the paper's validation experiment (0, 10, 20 and 40 RPM at 25
  to 85 C; :func:`~gyro_emulator.emulation.profiles.paper_rate_steps`);
- ``thermal_ramp``, ``thermal_cycle``: a static part in a chamber that ramps
  the temperature once (temperature and time confounded, like the LSM6DSM
  log) or down and back up
  (:func:`~gyro_emulator.emulation.profiles.temperature_ramp` on drawn knots);
- ``static``: a static part at a steady temperature with a slow wander (an
  Allan run, like the ADIS16405 and MPU-6050 logs;
  :func:`~gyro_emulator.emulation.profiles.static_profile`).
"""

from dataclasses import replace

from gyro_emulator.emulation.profiles import (paper_rate_steps, rate_about_z, sample_times,
                                              SampledProfile, static_profile, temperature_ramp)
from gyro_emulator.emulation.truth import SAMPLED_PROFILES
from gyro_emulator.units import deg_s_to_rad_s, STANDARD_GRAVITY_M_S2
import numpy as np

#: Minutes at each point of the ``paper`` profile (the paper averaged 5 minutes per point).
PAPER_MINUTES_PER_POINT = 5.0


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
    SampledProfile

    """
    plan, end_s = _soak_plan(rng, levels)
    duration = end_s if max_duration_s is None else min(end_s, max_duration_s)
    dt = 1.0 / sample_rate_hz
    t = sample_times(duration, sample_rate_hz)
    temp = _soak_ramp_temperature(t, plan)
    rate, max_rate = _table_rate(rng, t, duration, sample_rate_hz)
    accel = _table_gravity(rng, t, rate, duration, dt)
    return SampledProfile('lab', t, rate_about_z(rate), temp, accel,
                          max_rate_rad_s=float(max_rate))


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


def _thermal_knots(rng, duration_s, cycle):
    """
    Draw a thermal test's chamber program: a soak, a slow ramp (and back), a soak.

    The chamber starts at 25 +- 2 C, ramps to a level 25 to 45 K below or 30
    to 60 K above it, then (``cycle``) back to the start, with soaks of 3 to
    8 % of the run at the ends and at the turn; ``duration_s`` defaults to a
    draw from 6 to 12 h. Returns the (time s, temperature C) knots.
    """
    duration = rng.uniform(6.0, 12.0) * 3600.0 if duration_s is None else float(duration_s)
    start = 25.0 + rng.uniform(-2.0, 2.0)
    far = start - rng.uniform(25.0, 45.0) if rng.random() < 0.5 else \
        start + rng.uniform(30.0, 60.0)
    soaks = rng.uniform(0.03, 0.08, 3) * duration
    if cycle:
        ramp = 0.5 * (duration - soaks.sum())
        return [(0.0, start), (soaks[0], start), (soaks[0] + ramp, far),
                (soaks[0] + ramp + soaks[1], far),
                (soaks[0] + 2 * ramp + soaks[1], start), (duration, start)]
    return [(0.0, start), (soaks[0], start), (duration - soaks[1], far), (duration, far)]


def _static_wander(rng, sample_rate_hz, duration_s):
    """
    Draw a static run: 20 to 30 C with a slow chamber wander of 0.05 K rms (hours).

    The part sits still, gravity along z; ``duration_s`` defaults to a draw
    from 1 to 3 h.
    """
    duration = rng.uniform(1.0, 3.0) * 3600.0 if duration_s is None else float(duration_s)
    part = static_profile(duration, rng.uniform(20.0, 30.0), sample_rate_hz)
    wander = np.interp(part.time_s, np.linspace(0.0, duration, 6), rng.normal(0.0, 0.05, 6))
    return replace(part, temp_c=part.temp_c + wander)


def draw_profile(name, rng, sample_rate_hz, levels=5, duration_s=None):
    """
    Return the sampled profile ``name`` (one of :data:`SAMPLED_PROFILES`).

    ``levels`` is the lab profile's number of temperature levels;
    ``duration_s`` cuts the lab profile, or sets the length of the thermal
    and static ones (default: drawn).

    Returns
    -------
    gyro_emulator.emulation.profiles.SampledProfile

    """
    if name == 'lab':
        return lab_profile(rng, sample_rate_hz=sample_rate_hz, levels=levels,
                           max_duration_s=duration_s)
    if name == 'paper':
        return paper_rate_steps(60.0 * PAPER_MINUTES_PER_POINT, sample_rate_hz=sample_rate_hz)
    if name in ('thermal_ramp', 'thermal_cycle'):
        return temperature_ramp(_thermal_knots(rng, duration_s, name == 'thermal_cycle'),
                                rate_deg_s=0.0, sample_rate_hz=sample_rate_hz, name=name)
    if name == 'static':
        return _static_wander(rng, sample_rate_hz, duration_s)
    raise ValueError(f'truth.profile = {name!r} is not allowed: choose one of '
                     f'{", ".join(SAMPLED_PROFILES)}')
