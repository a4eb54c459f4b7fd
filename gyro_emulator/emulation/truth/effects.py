"""
What the truth generator can hide in a part, and how each acts on GyroModel.

Three families, any of which can be combined (``'bias_step+time_delay'``):

- the nine causes of the diagnose catalogue (:data:`CATALOGUE_TRUTHS`);
- mechanisms that only a generic competitor of the catalogue describes, or
  that no catalogue entry describes at all (:data:`EXTRA_TRUTHS`): an
  electronics gain temperature coefficient, a factory-compensated part whose
  scale factor does not follow the physics, a one-time scale-factor or bias
  step (a shock), a bias warm-up and heating/cooling hysteresis of the bias.

Each acts on the one simulator, :class:`gyro_emulator.sensor.model.GyroModel`,
in one of four ways (:func:`part_config`, :func:`rate_into_the_part`,
:func:`schedules`):

- as a term of its error model (bias temperature coefficients, die thermal
  lag, g-sensitivity, quadratic nonlinearity; the physics' SF(T) switched
  off for a compensated part; the gas law of the device for viscosity);
- on the rate the sensing element sees, before the part's gain (delay, the
  cubic nonlinearity term, a drifting mode split or cavity pressure through
  the physics, an electronics gain that follows temperature);
- as a schedule of the part's turn-on bias or scale-factor error, applied
  with ``GyroModel.update_config`` between samples where it changes (steps,
  warm-up, a bias following dT/dt, hysteresis).
"""

from gyro_emulator.physics import first_order
from gyro_emulator.units import AXES, deg_s_to_rad_s, SECONDS_PER_HOUR, STANDARD_GRAVITY_M_S2
import numpy as np

#: The catalogue causes the generator can hide: the physical causes of the first
#: diagnose catalogue, in its order (diagnose lists them first from here).
CATALOGUE_TRUTHS = ('viscosity_temperature', 'bias_temperature', 'thermal_lag',
                    'scale_factor_nonlinearity', 'g_sensitivity', 'time_delay', 'pressure_drift',
                    'mode_split_drift', 'temperature_rate_bias')
#: Mechanisms beyond the catalogue's physical causes.
EXTRA_TRUTHS = ('electronics_sf_tempco', 'factory_compensation', 'scale_factor_step',
                'bias_step', 'bias_warmup', 'bias_hysteresis')
#: Everything :func:`parse_effects` accepts, 'none' (clean data) included.
TRUTH_EFFECTS = CATALOGUE_TRUTHS + EXTRA_TRUTHS + ('none',)
#: Effects that need an applied rate (scale-factor effects).
NEEDS_RATE = frozenset({'viscosity_temperature', 'thermal_lag', 'scale_factor_nonlinearity',
                        'time_delay', 'pressure_drift', 'mode_split_drift',
                        'electronics_sf_tempco', 'factory_compensation', 'scale_factor_step'})


def parse_effects(effect):
    """
    Split ``'a+b'`` into a tuple of known effect names ('none' -> ()).

    Raises ValueError naming the unknown entry and the allowed ones.
    """
    names = tuple(e.strip() for e in str(effect).split('+') if e.strip())
    if not names:
        raise ValueError(f'truth.effect = {effect!r} names no effect: choose one of random, '
                         f'{", ".join(TRUTH_EFFECTS)} (or several joined by +)')
    for name in names:
        if name not in TRUTH_EFFECTS:
            raise ValueError(f'truth.effect = {name!r} is not allowed: choose one of '
                             f'random, {", ".join(TRUTH_EFFECTS)} (or several joined by +)')
    if len(set(names)) != len(names):
        raise ValueError(f'truth.effect = {effect!r} names an effect twice')
    return tuple(n for n in names if n != 'none')


def _span_k(profile):
    return max(abs(profile.temp_c.max() - 25.0), abs(profile.temp_c.min() - 25.0), 1.0)


def _draw_catalogue(effect, rng, profile):
    """Random magnitude of a catalogue cause, realistic and detectable."""
    sign = float(rng.choice([-1.0, 1.0]))
    span = _span_k(profile)
    r_max = max(profile.max_rate_rad_s, 1e-3)
    if effect == 'viscosity_temperature':
        return {'sutherland_constant_k': rng.uniform(80.0, 250.0)}
    if effect == 'bias_temperature':
        b1 = sign * deg_s_to_rad_s(rng.uniform(0.05, 0.5)) / span
        return {'bias_temp_coeff_rad_s_k': b1,
                'bias_temp_coeff2_rad_s_k2': rng.uniform(-0.5, 0.5) * abs(b1) / span}
    if effect == 'thermal_lag':
        return {'thermal_time_constant_s': rng.uniform(120.0, 600.0)}
    if effect == 'scale_factor_nonlinearity':
        return {'nonlinearity_quadratic_s_rad': rng.uniform(-0.003, 0.003) / r_max,
                'nonlinearity_cubic_s2_rad2': sign * rng.uniform(0.002, 0.01) / r_max ** 2}
    if effect == 'g_sensitivity':
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        mag = deg_s_to_rad_s(rng.uniform(0.03, 0.15)) / STANDARD_GRAVITY_M_S2
        return {f'g_sensitivity_{a}_rad_s_per_m_s2': float(mag * direction[k])
                for k, a in enumerate(AXES)}
    if effect == 'time_delay':
        return {'delay_s': rng.uniform(0.002, 0.02)}
    if effect == 'pressure_drift':
        hours = profile.time_s[-1] / SECONDS_PER_HOUR
        return {'pressure_rate_per_h': sign * rng.uniform(0.1, 0.4) / hours}
    if effect == 'mode_split_drift':
        return {'mode_split_at_ref_hz': rng.uniform(-5.0, 5.0),
                'mode_split_temp_coeff_hz_k': sign * rng.uniform(0.4, 1.5)}
    return {'gradient_time_constant_s': rng.uniform(10.0, 120.0),
            'bias_per_temp_rate_rad_s_per_k_s': sign * deg_s_to_rad_s(rng.uniform(1.0, 5.0))}


def _draw_extra(effect, rng, profile):
    """Random magnitude of a mechanism beyond the catalogue's physical causes."""
    sign = float(rng.choice([-1.0, 1.0]))
    duration = float(profile.time_s[-1] - profile.time_s[0])
    when = profile.time_s[0] + rng.uniform(0.25, 0.75) * duration
    if effect == 'electronics_sf_tempco':
        return {'sf_tempco_ppm_k': sign * rng.uniform(100.0, 600.0)}
    if effect == 'factory_compensation':
        return {}
    if effect == 'scale_factor_step':
        return {'sf_step': sign * rng.uniform(0.003, 0.02), 'sf_step_time_s': when}
    if effect == 'bias_step':
        return {'bias_step_rad_s': sign * deg_s_to_rad_s(rng.uniform(0.02, 0.2)),
                'bias_step_time_s': when}
    if effect == 'bias_warmup':
        return {'warmup_rad_s': sign * deg_s_to_rad_s(rng.uniform(0.05, 0.3)),
                'warmup_time_constant_s': rng.uniform(0.05, 0.25) * duration}
    return {'hysteresis_rad_s': deg_s_to_rad_s(rng.uniform(0.03, 0.2)),
            'hysteresis_width_k': rng.uniform(2.0, 8.0)}


def draw_effect_parameters(effects, rng, profile):
    """
    Random magnitudes of the hidden effects, realistic and detectable.

    Parameters
    ----------
    effects : tuple of str
        From :func:`parse_effects`.
    rng : numpy.random.Generator
        Source of randomness.
    profile : gyro_emulator.emulation.profiles.SampledProfile
        The profile (its temperature span, rates and length set the scales).

    Returns
    -------
    dict
        Parameter name -> value (SI; names as in the diagnose report where
        the catalogue has the effect).

    """
    params = {}
    for effect in effects:
        if effect in CATALOGUE_TRUTHS:
            params.update(_draw_catalogue(effect, rng, profile))
        else:
            params.update(_draw_extra(effect, rng, profile))
    return params


def part_config(effects, params):
    """
    Return the error-model terms switched on and their fields for ``effects``.

    Returns ``(on, fields, off)``: term names to switch on, SensorConfig
    fields (z axis) and term names to switch off (a compensated part's
    physics SF(T)).
    """
    on, fields, off = set(), {}, set()
    if 'bias_temperature' in effects:
        on.add('bias_temperature')
        fields['bias_temp_coeff_rad_s_k'] = (0.0, 0.0, params['bias_temp_coeff_rad_s_k'])
        fields['bias_temp_coeff2_rad_s_k2'] = (0.0, 0.0, params['bias_temp_coeff2_rad_s_k2'])
    if 'thermal_lag' in effects:
        on.add('thermal_lag')
        fields['thermal_time_constant_s'] = params['thermal_time_constant_s']
    if 'g_sensitivity' in effects:
        on.add('g_sensitivity')
        row = tuple(params[f'g_sensitivity_{a}_rad_s_per_m_s2'] for a in AXES)
        fields['g_sensitivity_rad_s_m_s2'] = ((0.0,) * 3, (0.0,) * 3, row)
    if 'scale_factor_nonlinearity' in effects:
        on.add('nonlinearity')
        fields['nonlinearity_s_rad'] = (0.0, 0.0, params['nonlinearity_quadratic_s_rad'])
    if 'factory_compensation' in effects:
        off.add('scale_factor_temperature')
    return on, fields, off


def rate_into_the_part(profile, effects, params, device):
    """
    Return the rate the error model sees: the true rate with the effects it lacks.

    Delay (the part's latency term only stamps its samples, it does not
    shift them), the cubic term of the nonlinearity (x = Omega (1 + a3
    Omega^2); the part adds its quadratic term, x + a2 x^2, so the output is
    Omega (1 + a2 Omega + a3 Omega^2) to within 2 a3 Omega^2 <= 2 % of the
    quadratic term), the scale-factor changes of a drifting mode split (Eq 4
    off resonance) or a leaking cavity (Eq 5-12 at the new pressure), and an
    electronics gain (1 + c (T - T_ref)) act on the sensed rate before the
    part's own gain.
    """
    t, rate, temp = profile.time_s, profile.rate_rad_s[:, 2], profile.temp_c
    tref = device.calibration_temp_c
    rate_in = rate
    if 'time_delay' in effects:
        rate_in = np.interp(t - params['delay_s'], t, rate, left=rate[0])
    if 'scale_factor_nonlinearity' in effects:
        rate_in = rate_in * (1.0 + params['nonlinearity_cubic_s2_rad2'] * rate_in ** 2)
    if 'mode_split_drift' in effects:
        p = first_order.lumped_parameters(device, temp)
        split = params['mode_split_at_ref_hz'] + params[
            'mode_split_temp_coeff_hz_k'] * (temp - tref)
        rate_in = rate_in / np.sqrt(1.0 + (2.0 * p.q_sense * split / p.freq_y_hz) ** 2)
    if 'pressure_drift' in effects:
        coarse = np.arange(0, len(t), max(1, int(round(1.0 / float(t[1] - t[0])))))
        pr = 1.0 + params['pressure_rate_per_h'] * t[coarse] / SECONDS_PER_HOUR
        sf_p = first_order.sense_scale_factor_m_per_rad_s(
            device.with_gas(pressure_pa=device.gas.pressure_pa * pr),
            temp[coarse]) / first_order.sense_scale_factor_m_per_rad_s(
            device, temp[coarse])
        rate_in = rate_in * np.interp(t, t[coarse], sf_p)
    if 'electronics_sf_tempco' in effects:
        rate_in = rate_in * (1.0 + 1e-6 * params['sf_tempco_ppm_k'] * (temp - tref))
    return rate_in


def _smooth_hysteresis(temp_c, width_k):
    """
    Branch offset in [-1, 1] of a smooth hysteresis (not the play operator of diagnose).

    The offset o relaxes toward -sign(dT) exponentially in the temperature
    traversed: do = (-sign(dT) - o) |dT| / w; it holds through soaks.
    Heating drives it to -1, cooling to +1.
    """
    o = np.empty(len(temp_c))
    state = 0.0
    for i in range(len(temp_c)):
        d = temp_c[i] - temp_c[i - 1] if i else 0.0
        if d != 0.0:
            target = -np.sign(d)
            state = target + (state - target) * np.exp(-abs(d) / width_k)
        o[i] = state
    return o


def _body_rate(t, temp, tau_s):
    """
    dT_b/dt of a body that follows ``temp`` through a first-order lag tau, K/s.

    tau dT_b/dt = T - T_b, solved exactly for T linear between samples
    (the recursion of :meth:`.data.Prepared.lagged_temp_on_bins`), from
    equilibrium.
    """
    # scipy.signal costs 1 s, and `gyro-emulator --help` imports this module
    # (the effect names of `truth`): imported when a record is made.
    from scipy.signal import lfilter, lfilter_zi

    h = float(t[1] - t[0])
    a = np.exp(-h / tau_s)
    c = tau_s * (1.0 - a) / h
    b_coef, a_coef = [1.0 - c, c - a], [1.0, -a]
    lagged, _ = lfilter(b_coef, a_coef, temp, zi=lfilter_zi(b_coef, a_coef) * temp[0])
    return (temp - lagged) / tau_s


def schedules(profile, effects, params):
    """
    Bias and scale-factor changes applied between samples, per sample.

    Returns ``(bias_rad_s, sf_error)``, each an array or None: the bias of a
    step, a warm-up ``A exp(-t/tau)``, a bias ``c dT_b/dt`` following the
    chamber's ramps (a thermal gradient, which builds up through the body's
    time constant: :func:`_body_rate`) and hysteresis ``h o`` with ``o`` a
    smooth branch offset (:func:`_smooth_hysteresis`: heating and cooling
    leave opposite offsets that persist through soaks); the scale-factor
    error of a step.
    """
    t, temp = profile.time_s, profile.temp_c
    bias = np.zeros(len(t))
    used = False
    if 'bias_step' in effects:
        bias += np.where(t >= params['bias_step_time_s'], params['bias_step_rad_s'], 0.0)
        used = True
    if 'bias_warmup' in effects:
        bias += params['warmup_rad_s'] * np.exp(-(t - t[0]) / params['warmup_time_constant_s'])
        used = True
    if 'temperature_rate_bias' in effects:
        bias += params['bias_per_temp_rate_rad_s_per_k_s'] * _body_rate(
            t, temp, params['gradient_time_constant_s'])
        used = True
    if 'bias_hysteresis' in effects:
        step = max(1, len(t) // 20000)
        coarse = _smooth_hysteresis(temp[::step], params['hysteresis_width_k'])
        bias += params['hysteresis_rad_s'] * np.interp(t, t[::step], coarse)
        used = True
    sf = None
    if 'scale_factor_step' in effects:
        sf = np.where(t >= params['sf_step_time_s'], params['sf_step'], 0.0)
    return (bias if used else None), sf


def change_points(values, tolerance):
    """
    Return the indices where a piecewise-held copy of ``values`` must change.

    The held value is the first value of each segment; a new segment starts
    where ``values`` leaves it by more than ``tolerance``. Returns the start
    index of every segment (0 first).
    """
    starts = [0]
    held = values[0]
    for i in np.flatnonzero(np.abs(np.diff(values)) > 0.0) + 1:
        if abs(values[i] - held) > tolerance:
            starts.append(int(i))
            held = values[i]
    return np.asarray(starts)
