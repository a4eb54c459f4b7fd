"""
Truth generator: simulated measured records with hidden effects.

A record is the output of the one sensor simulator,
:class:`gyro_emulator.sensor.model.GyroModel`, configured as a part with the
baseline physics (the paper's first-order model of a preset: SF(T) from
:func:`gyro_emulator.physics.first_order.scale_factor_ratio`), a random bias
and scale-factor error, the hidden effects (:mod:`.effects`: none,
one, or several joined by ``+``), driven by a seeded profile
(:class:`gyro_emulator.emulation.profiles.SampledProfile`, drawn by
:func:`gyro_emulator.emulation.truth.drawn.draw_profile`), plus noise:

- white rate noise of density N (angle random walk), sigma = N / sqrt(dt);
- bias instability B (flicker: a sum of exactly discretised Gauss-Markov
  terms across 1 s to 3e4 s) and a rate random walk K (IEEE Std 952 terms,
  GyroModel's own streams);
- a temperature reading with 0.02 C white noise;
- optionally, outliers as a lab makes them: handling motion (the part is
  turned by hand for 5 to 60 s: a real rotation the part senses and the
  rate column does not show) and spikes (single corrupt samples of 0.5 to
  20 deg/s from the logger, after the part).

Everything random comes from one ``numpy.random.Generator``. The hidden
effects and their parameters are returned beside the record, never inside
it: the CSV holds only the diagnose contract columns. The part runs in the
one chunk loop, :func:`gyro_emulator.emulation.run_profile.run_over_profile`.
"""

from dataclasses import replace

from gyro_emulator.emulation.profiles import rate_about_z
from gyro_emulator.emulation.run_profile import OwnSamples, run_over_profile
from gyro_emulator.emulation.truth import effects as te
from gyro_emulator.emulation.truth.drawn import draw_profile
from gyro_emulator.physics.presets import physics_preset
from gyro_emulator.recording.record import Record
from gyro_emulator.sensor.config import ErrorTerms, SensorConfig
from gyro_emulator.sensor.model import GyroModel
from gyro_emulator.units import (deg_h_to_rad_s, deg_s_to_rad_s,
                                 rrw_deg_h_sqrt_h_to_rad_s_sqrt_s)
from gyro_emulator.validation import check_range, check_seed
import numpy as np
from scipy.signal import butter, lfilter

TRUTH_EFFECTS = te.TRUTH_EFFECTS
#: Sutherland constant of air, K (White, Viscous Fluid Flow).
AIR_SUTHERLAND_K = 110.4
TEMP_READING_NOISE_C = 0.02
ACCEL_NOISE_M_S2 = 0.02
#: Correlation-time band of the simulated bias instability, s.
FLICKER_BAND_S = (1.0, 3e4)
#: Outlier kinds :func:`make_truth` accepts (joined by + for both).
OUTLIER_KINDS = ('spikes', 'motion')

__all__ = ['make_record', 'make_truth', 'TRUTH_EFFECTS']


def _sensor_config(device, effects, params, drawn):
    """
    Return the error model of the simulated part, for :class:`GyroModel`.

    The part's own terms: turn-on bias, scale-factor error, SF(T) from the
    physics of ``device``, white rate noise N, bias instability B, rate
    random walk K, and the hidden effects the error model has
    (:func:`.effects.part_config`). Everything else is off.
    """
    on = {'scale_factor_temperature', 'turn_on_bias', 'scale_factor_error',
          'electronics_noise', 'rate_random_walk', 'bias_instability'}
    more, fields, off = te.part_config(effects, params)
    on = (on | more) - off
    if drawn['lsb_deg_s'] > 0.0:
        on.add('quantization')
        fields['lsb_rad_s'] = (0.0, 0.0, float(deg_s_to_rad_s(drawn['lsb_deg_s'])))
    terms = ErrorTerms(**{name: name in on for name in ErrorTerms.names()})
    return SensorConfig(
        device=device, terms=terms, range_rad_s=(1000.0,) * 3,
        turn_on_bias_rad_s=(0.0, 0.0, float(deg_s_to_rad_s(drawn['bias_deg_s']))),
        scale_factor_error=(0.0, 0.0, drawn['scale_factor'] - 1.0),
        electronics_noise_rad_s_sqrt_hz=(
            0.0, 0.0, float(deg_s_to_rad_s(drawn['arw_deg_sqrt_s']))),
        bias_instability_rad_s=(
            0.0, 0.0, float(deg_h_to_rad_s(drawn['bias_instability_deg_h']))),
        bias_instability_band_s=FLICKER_BAND_S,
        rate_random_walk_rad_s_sqrt_s=(
            0.0, 0.0, float(rrw_deg_h_sqrt_h_to_rad_s_sqrt_s(drawn['rrw_deg_h_sqrt_h']))),
        **fields)


def _draw_part_errors(rng, noise=None):
    """
    Draw the part's noise and calibration errors; ``noise`` overrides any of them.

    White noise 0.004-0.015 deg/s/sqrt(Hz), bias instability 2-30 deg/h and
    rate random walk 1-30 deg/h/sqrt(h) (both log-uniform), turn-on bias
    +-0.5 deg/s, scale factor 1 +- 2 %, no quantisation (``lsb_deg_s``).
    """
    drawn = {
        'arw_deg_sqrt_s': rng.uniform(0.004, 0.015),
        'bias_instability_deg_h': float(np.exp(rng.uniform(np.log(2.0), np.log(30.0)))),
        'rrw_deg_h_sqrt_h': float(np.exp(rng.uniform(np.log(1.0), np.log(30.0)))),
        'bias_deg_s': rng.uniform(-0.5, 0.5),
        'scale_factor': rng.uniform(0.98, 1.02),
        'lsb_deg_s': 0.0,
    }
    unknown = sorted(set(noise or {}) - set(drawn))
    if unknown:
        raise ValueError(f'truth.noise: {", ".join(unknown)} is not a noise term; '
                         f'allowed: {", ".join(sorted(drawn))}')
    drawn.update({k: float(v) for k, v in (noise or {}).items()})
    return drawn


def config_schedule(config, bias, sf):
    """
    Return the part's configuration schedule: sample index -> SensorConfig.

    The record is cut where the bias (or scale-factor) schedule moves by more
    than 1 % of its range (:func:`.effects.change_points`); each piece runs
    with the schedule's mean over it added to the part's turn-on bias
    (scale-factor error), applied with ``GyroModel.update_config`` so the
    states (noise, die temperature) carry over. Empty without a schedule.
    """
    if bias is None and sf is None:
        return {}
    n = len(bias if bias is not None else sf)
    starts = {0}
    for values in (bias, sf):
        if values is not None:
            tol = max(0.01 * float(np.ptp(values)), 1e-15)
            starts.update(te.change_points(values, tol).tolist())
    edges = sorted(starts) + [n]
    b0 = config.turn_on_bias_rad_s[2]
    s0 = config.scale_factor_error[2]
    schedule = {}
    for lo, hi in zip(edges[:-1], edges[1:]):
        fields = {}
        if bias is not None:
            fields['turn_on_bias_rad_s'] = (0.0, 0.0, b0 + float(np.mean(bias[lo:hi])))
        if sf is not None:
            fields['scale_factor_error'] = (0.0, 0.0, s0 + float(np.mean(sf[lo:hi])))
        schedule[lo] = replace(config, **fields)
    return schedule


def _parse_outliers(outliers):
    """Return the set of outlier kinds in ``'spikes+motion'`` (None -> empty)."""
    if not outliers:
        return set()
    kinds = {k.strip() for k in str(outliers).split('+') if k.strip()}
    bad = sorted(kinds - set(OUTLIER_KINDS))
    if bad or not kinds:
        raise ValueError(f'truth.outliers = {outliers!r} is not allowed: choose '
                         f'{", ".join(OUTLIER_KINDS)} or both joined by +')
    return kinds


def handling_motion(rng, t):
    """
    Draw 1 to 3 segments of handling motion; return the rate, rad/s, and the segments.

    Each lasts 5 to 60 s: low-pass filtered random rotation (second-order,
    1 Hz) of 3 to 30 deg/s rms with sin^2 tapers, placed at random in the
    record. Returns ``(rate_rad_s, [(start_s, end_s), ...])``.
    """
    dt = float(t[1] - t[0])
    rate = np.zeros(len(t))
    spans = []
    for _ in range(int(rng.integers(1, 4))):
        length = rng.uniform(5.0, 60.0)
        start = t[0] + rng.uniform(0.05, 0.95) * (t[-1] - t[0] - length)
        m = (t >= start) & (t < start + length)
        k = int(m.sum())
        if k < 3:
            continue
        b, a = butter(2, min(0.9, 2.0 * dt * 1.0))
        motion = lfilter(b, a, rng.standard_normal(k + 200))[200:]
        motion *= deg_s_to_rad_s(rng.uniform(3.0, 30.0)) / max(float(np.std(motion)), 1e-12)
        rate[m] += motion * np.sin(np.pi * np.arange(k) / k) ** 2
        spans.append((float(start), float(start + length)))
    return rate, spans


def logger_spikes(rng, n):
    """
    Draw single-sample spikes: 0.02 to 0.1 % of the samples, 0.5 to 20 deg/s.

    Returns ``(indices, values_rad_s)``; magnitudes log-uniform, random sign.
    """
    count = max(1, int(round(rng.uniform(2e-4, 1e-3) * n)))
    idx = np.sort(rng.choice(n, size=min(count, n), replace=False))
    mags = np.exp(rng.uniform(np.log(0.5), np.log(20.0), len(idx)))
    return idx, deg_s_to_rad_s(mags * rng.choice([-1.0, 1.0], len(idx)))


def make_record(profile, effects, params, rng, preset='paper', noise=None, outliers=None,
                record_temperature=True):
    """
    Make the measured record of a part with hidden effects run through a profile.

    The sensor is :class:`gyro_emulator.sensor.model.GyroModel` (the one
    simulator) on the z axis, configured by :func:`_sensor_config` and
    driven by the true rate (plus handling motion) with the effects it
    lacks applied (:func:`.effects.rate_into_the_part`), with bias and
    scale-factor schedules applied between samples (:func:`config_schedule`),
    run over the profile by
    :func:`gyro_emulator.emulation.run_profile.run_over_profile`.
    The viscosity effect changes the physics of the device itself (a
    Sutherland gas law).

    Parameters
    ----------
    profile : gyro_emulator.emulation.profiles.SampledProfile
        True rate, temperature and acceleration.
    effects : tuple of str
        Hidden effects (:func:`.effects.parse_effects`).
    params : dict
        Their parameters (:func:`.effects.draw_effect_parameters`).
    rng : numpy.random.Generator
        Source of randomness; the sensor's noise streams are spawned from it.
    preset : str
        Physics preset of the simulated device.
    noise : dict, optional
        Override noise and calibration-error terms (:func:`_draw_part_errors`).
    outliers : str, optional
        'spikes', 'motion' or 'spikes+motion'.
    record_temperature : bool
        Write the temperature reading (False: a log without temperature).

    Returns
    -------
    (Record, dict)
        The record and the truth (effects, parameters, noise, outliers).

    """
    device = physics_preset(preset)
    t, temp, accel = profile.time_s, profile.temp_c, profile.accel_m_s2
    n = len(t)
    kinds = _parse_outliers(outliers)
    drawn = _draw_part_errors(rng, noise)
    part = device
    if 'viscosity_temperature' in effects:
        part = device.with_gas(viscosity_law='sutherland',
                               sutherland_constant_k=params['sutherland_constant_k'])
    config = _sensor_config(part, effects, params, drawn)
    model = GyroModel(config, 1.0 / float(t[1] - t[0]), rng)
    rate_in = te.rate_into_the_part(profile, effects, params, device)
    motion_spans = []
    if 'motion' in kinds:
        motion, motion_spans = handling_motion(rng, t)
        rate_in = rate_in + motion
    bias, sf = te.schedules(profile, effects, params)
    driven = replace(profile, rate_rad_s=rate_about_z(rate_in))
    out = np.concatenate([chunk.batch.gyro_rad_s[:, 2] for chunk in run_over_profile(
        model, OwnSamples(driven), configs=config_schedule(config, bias, sf))])
    spikes = np.zeros(0, dtype=int)
    if 'spikes' in kinds:
        spikes, values = logger_spikes(rng, n)
        out[spikes] += values
    reading = temp + rng.normal(0.0, TEMP_READING_NOISE_C, n)
    data = Record.from_arrays(
        t, out, rate_rad_s=profile.rate_rad_s[:, 2],
        temp_c=reading if record_temperature else None,
        accel_m_s2=accel + rng.normal(0.0, ACCEL_NOISE_M_S2, accel.shape),
        path=f'truth:{profile.name}')
    truth = {'effect': '+'.join(effects) or 'none', 'effects': list(effects),
             'parameters': dict(params), 'preset': preset, 'noise': drawn,
             'profile': profile.name, 'duration_s': float(t[-1] - t[0] + t[1] - t[0]),
             'sample_rate_hz': 1.0 / float(t[1] - t[0]),
             'outliers': {'spikes': int(len(spikes)), 'spike_times_s': t[spikes].tolist(),
                          'motion_s': motion_spans}}
    return data, truth


def _pick_random(rng, has_rate):
    """Draw one effect (or none) that the profile can show."""
    allowed = [e for e in TRUTH_EFFECTS if has_rate or e not in te.NEEDS_RATE]
    return str(rng.choice(allowed))


def make_truth(effect, seed, profile='lab', sample_rate_hz=25.0, levels=5, params=None,
               preset='paper', noise=None, duration_s=None, outliers=None,
               record_temperature=True, max_duration_s=None):
    """
    One simulated measured record with hidden effects.

    Parameters
    ----------
    effect : str
        One of :data:`TRUTH_EFFECTS`, several joined by ``+``, or 'random'
        to draw one from the seed.
    seed : int
        Seed of the one ``numpy.random.Generator`` used.
    profile : str
        One of :data:`gyro_emulator.emulation.truth.SAMPLED_PROFILES`.
    sample_rate_hz : float
        Output data rate, Hz.
    levels : int
        Temperature levels of the lab profile.
    params : dict, optional
        Fix some effect parameters instead of drawing them.
    preset : str
        Physics preset of the simulated device.
    noise : dict, optional
        Override noise and calibration-error terms (see :func:`make_record`).
    duration_s : float, optional
        Cut the lab profile at this duration, or set the length of the
        thermal and static profiles, s.
    outliers : str, optional
        'spikes', 'motion' or 'spikes+motion' (see :func:`make_record`).
    record_temperature : bool
        Write the temperature column.
    max_duration_s : float, optional
        Old name of ``duration_s`` for the lab profile.

    Returns
    -------
    (Record, dict)
        The record and the hidden truth.

    """
    check_range('truth', 'sample_rate_hz', sample_rate_hz, 1e-3, 2000.0, 'Hz',
                low_open=False)
    check_range('truth', 'levels', levels, 3, 12, '', low_open=False)
    if duration_s is not None:
        check_range('truth', 'duration_s', duration_s, 60.0, 1e7, 's', low_open=False)
    rng = np.random.default_rng(check_seed('truth', seed))
    prof = draw_profile(profile, rng, sample_rate_hz, levels=levels,
                        duration_s=duration_s if duration_s is not None else max_duration_s)
    has_rate = prof.max_rate_rad_s > 0.0
    if effect == 'random':
        effect = _pick_random(rng, has_rate)
    effects = te.parse_effects(effect)
    static = [e for e in effects if e in te.NEEDS_RATE and not has_rate]
    if static:
        raise ValueError(f'truth.effect = {static[0]!r} needs an applied rate: the '
                         f'{profile} profile has none')
    drawn = te.draw_effect_parameters(effects, rng, prof)
    unknown = sorted(set(params or {}) - set(drawn))
    if unknown:
        raise ValueError(
            f'truth.params: {", ".join(unknown)} is not a parameter of '
            f'{"+".join(effects) or "none"}; allowed: {", ".join(sorted(drawn)) or "(none)"}')
    drawn.update({k: float(v) for k, v in (params or {}).items()})
    return make_record(prof, effects, drawn, rng, preset=preset, noise=noise,
                       outliers=outliers, record_temperature=record_temperature)
