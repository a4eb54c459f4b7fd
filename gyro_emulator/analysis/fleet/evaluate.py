"""
Per-device physics of a fleet over a temperature grid, its metrics and its specs.

For a block of drawn parts (fields of shape (n,)) and the grid (a column
(T, 1), plus the calibration temperature when the grid lacks it), one call
of :func:`gyro_emulator.physics.first_order.first_order_response` gives
every first-order quantity as (T, n) (Eq 5-21). From it:

* ``f_drive_hz``, ``q_drive``, ``q_sense`` at the calibration temperature
  (Eq 7, 14, 19);
* ``split_hz`` = f_y - f_x: f_y from the same stiffness law (Eq 6) with the
  beam widths the sense mode sees (plus ``mismatch.sense_beam_width_m``);
* ``sf_m_per_rad_s``: Y_sense per rad/s at calibration (Eq 13-20);
  ``sf_error_pct``: the largest |SF(T) / SF(T_cal) - 1| over the grid;
  ``sf_tempco_ppm_k`` and ``sf_residual_pct``: the least-squares slope of
  SF(T) / SF(T_cal) and the largest residual from that line (what is left
  after a linear temperature compensation);
* ``arw_deg_sqrt_h``: the largest over the grid of sqrt(N_brown(T)^2 +
  N_elec^2), N_brown the mechanical-thermal ARW
  (:func:`gyro_emulator.sensor.noise.brownian_arw_from_response`);
* with an extended ``scale_factor_temperature`` term (the fleet's
  ``extended:``, :mod:`gyro_emulator.sensor.extensions`), the ratio is
  multiplied by the term's read-out gain relative to calibration,
  q(T) / q(T_cal) with q(T) = 1 + c1 (T - T_ref) + c2 (T - T_ref)^2, T_ref
  the term's ``ref_temp_c`` (else T_cal): ``sf_error_pct``,
  ``sf_tempco_ppm_k``, ``sf_residual_pct``, ``sf_ratio`` (and
  ``sf_error_exact_pct``) see it, as the emulator's output would at a
  constant rate. ``sf_m_per_rad_s`` and ``range_dps`` stay the mechanical
  sense amplitude. The other extended terms act in time (steps, drifts,
  warm-up, pressure drift from P_ref at the start) or on the bias path
  (hysteresis, dT/dt), not on a static temperature grid: they act in the
  sensor runs only;
* ``bias_tempco_deg_s_k``: the read-out's bias temperature coefficient;
* ``range_dps``: the rate at which the sense amplitude reaches
  ``sense_limit_fraction`` of the comb gap, the lowest over the grid;
* with ``exact: true``: ``exact_ratio``, the exact 2-DOF sense amplitude at
  the part's own split over the first-order one at calibration
  (:func:`gyro_emulator.physics.exact.exact_steady_state`), and
  ``sf_error_exact_pct``, ``sf_error_pct`` from the exact amplitudes.

Nothing here draws random numbers; the same parts give the same numbers.
"""

from gyro_emulator import units
from gyro_emulator.analysis.fleet import sampling
from gyro_emulator.physics import exact, first_order
from gyro_emulator.sensor import noise
import numpy as np


def _grid(config):
    """
    Return the temperatures to evaluate, as a column, and the calibration row.

    The grid, plus the calibration temperature as a last row when the grid
    does not hold it already.
    """
    temps = list(config.temperatures_c)
    if config.calibration_temp_c in temps:
        return np.array(temps)[:, np.newaxis], temps.index(config.calibration_temp_c)
    return np.array(temps + [config.calibration_temp_c])[:, np.newaxis], len(temps)


def _rows(arr, width, n):
    """Broadcast a (T, n) quantity that may have come out (T, 1) or scalar."""
    return np.broadcast_to(np.asarray(arr, dtype=float), (width, n))


def _per_device(values, config, name, n):
    arr = values[name] if name in values else config.parameters[name].nominal
    return np.broadcast_to(np.asarray(arr, dtype=float), (n,))


def _sf_temperature(config, values, temps, n):
    """
    Return the extended scale_factor_temperature gain q(T) over the grid, (T, n), or None.

    q = 1 + c1 dT + c2 dT^2, dT = T - T_ref (sensor.extensions, the ``s_x``
    factor of its module docstring).
    """
    if config.extended is None or config.extended.get('scale_factor_temperature') is None:
        return None
    prefix = 'extended.scale_factor_temperature.'
    c1, c2, ref = (_per_device(values, config, prefix + name, n) for name in (
        'sf_temp_coeff_per_k', 'sf_temp_coeff2_per_k2', 'ref_temp_c'))
    d = temps - ref
    return 1.0 + (c1 * d + c2 * d * d)


def _sf_metrics(ratio, temps_c):
    """Largest |ratio - 1|, least-squares slope (1/K), largest residual from the line."""
    tc = temps_c - temps_c.mean()
    slope = np.zeros(ratio.shape[1])
    for row, t in zip(ratio, tc):           # row by row: no BLAS, one summation order
        slope += t * row
    slope /= float(np.sum(tc * tc))
    centre = ratio.mean(axis=0)
    error = np.zeros(ratio.shape[1])
    residual = np.zeros(ratio.shape[1])
    for row, t in zip(ratio, tc):
        np.maximum(error, np.abs(row - 1.0), out=error)
        np.maximum(residual, np.abs(row - (centre + slope * t)), out=residual)
    return error, slope, residual


def evaluate(config, values, n):
    """
    Metrics of n parts (see the module docstring).

    Parameters
    ----------
    config : FleetConfig
        The fleet.
    values : dict
        Parameter name -> array of n drawn values (checked).
    n : int
        Number of parts.

    Returns
    -------
    dict
        Metric name -> float64 array (n,), plus ``sf_ratio`` (T, n): SF(T) /
        SF(T_cal), one row per grid temperature.

    """
    temps, cal = _grid(config)
    grid = len(config.temperatures_c)
    width = len(temps)
    device = sampling.device_of(config, values)
    resp = first_order.first_order_response(device, 1.0, temps)
    p = resp.params
    sf = _rows(resp.sense_amplitude_m, width, n)
    ratio = sf[:grid] / sf[cal]
    gain = _sf_temperature(config, values, temps, n)
    if gain is not None:
        ratio = ratio * (gain[:grid] / gain[cal])
    error, slope, residual = _sf_metrics(ratio, temps[:grid, 0])
    brown = _rows(noise.brownian_arw_from_response(resp, temps), width, n)[:grid]
    elec = _per_device(values, config, 'electronics.noise_rad_s_sqrt_hz', n)
    arw = np.sqrt(brown.max(axis=0) ** 2 + elec ** 2)
    k_y = first_order.stiffness_n_m(sampling.sense_geometry(config, device.geometry, values),
                                    device.material, config.calibration_temp_c)
    f_x = _rows(p.freq_x_hz, width, n)[cal]
    split = np.broadcast_to(first_order.resonant_frequency_hz(k_y, p.mass_kg), (n,)) - f_x
    gap = np.broadcast_to(device.geometry.comb_gap_m, (n,))
    out = {
        'f_drive_hz': f_x.copy(),
        'split_hz': split,
        'q_drive': _rows(p.q_drive, width, n)[cal].copy(),
        'q_sense': _rows(p.q_sense, width, n)[cal].copy(),
        'sf_m_per_rad_s': sf[cal].copy(),
        'sf_error_pct': 100.0 * error,
        'sf_tempco_ppm_k': 1e6 * slope,
        'sf_residual_pct': 100.0 * residual,
        'arw_deg_sqrt_h': units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(arw),
        'bias_tempco_deg_s_k': np.degrees(
            _per_device(values, config, 'electronics.bias_temp_coeff_rad_s_k', n)),
        'range_dps': np.degrees(config.sense_limit_fraction * gap / sf[:grid].max(axis=0)),
        'sf_ratio': ratio,
    }
    if config.exact:
        steady = exact.exact_steady_state(device, 1.0, temps, split)
        exact_ratio = _rows(steady.ratio_to_first_order, width, n)
        exact_sf = sf * exact_ratio if gain is None else sf * exact_ratio * gain
        out['exact_ratio'] = exact_ratio[cal].copy()
        out['sf_error_exact_pct'] = 100.0 * np.abs(exact_sf[:grid] / exact_sf[cal] - 1.0).max(
            axis=0)
    return out


def passes(config, metrics, invalid):
    """
    Pass flags per spec and overall for evaluated parts.

    Returns
    -------
    (dict, numpy.ndarray)
        Spec metric -> bool array (n,), and the overall pass (every spec and
        a valid part). A NaN metric fails.

    """
    per_spec = within(config.specs, metrics, invalid)
    ok = ~invalid
    for flag in per_spec.values():
        ok = ok & flag
    return per_spec, ok


def within(bounds, metrics, invalid):
    """Metric -> bool array (n,): the valid parts inside each bound (a NaN metric is not)."""
    out = {}
    for spec in bounds:
        value = metrics[spec.metric]
        if spec.absolute:
            value = np.abs(value)
        out[spec.metric] = (value >= spec.low) & (value <= spec.high) & ~invalid
    return out


#: Parts evaluated at once: every quantity is per part, so chunks change no
#: number; (T, 16384) temporaries stay near the L2 cache and a block's peak
#: memory a quarter of what it would be.
CHUNK = 16384


def evaluate_draw(config, draw, without=None):
    """Check, evaluate and judge a block's parts (``without``: a source left at nominal)."""
    values, invalid, clipped = sampling.checked(config, draw.values(without), draw.n)
    parts = []
    with np.errstate(all='ignore'):     # a clipped extreme part may divide by ~0: NaN fails
        for start in range(0, draw.n, CHUNK):
            stop = min(start + CHUNK, draw.n)
            parts.append(evaluate(config, {k: v[start:stop] for k, v in values.items()},
                                  stop - start))
    metrics = parts[0] if len(parts) == 1 else {
        name: np.concatenate([part[name] for part in parts], axis=-1) for name in parts[0]}
    per_spec, ok = passes(config, metrics, invalid)
    if invalid.any():
        for name, arr in metrics.items():
            arr[..., invalid] = np.nan
    return values, invalid, clipped, metrics, per_spec, ok
