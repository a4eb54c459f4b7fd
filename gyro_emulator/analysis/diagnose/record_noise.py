"""
The record's noise terms, for ``diagnose --write-config --noise``.

One implementation: the IEEE Std 952 identification ``calibrate noise``
runs (:func:`gyro_emulator.analysis.calibrate.noise.calibrate_noise`) and
the emulator fit its ``--format preset`` writes
(:func:`gyro_emulator.analysis.calibrate.export_noise.twin_noise`), here run
on what the written model leaves of the record::

    e(t) = y(t) - o(t) - s r(t)

o and r are the offset and the rate part of the written configuration's
deterministic output (noise off, :func:`.emulated.offset_and_rate`: what
``simulate --profile RECORD`` outputs, rate dynamics and output filter
included) on the record's inputs; s is one scale factor fitted by least
squares with a constant (1 when the record has no rate excitation), the
user's calibration as diagnose's baseline has it. The noise terms are those
of e, not of y: a bias that follows temperature, now a term of the model,
would otherwise be counted twice (as the term, and as bias instability and
rate random walk in the Allan deviation of y). The LSB is that of y (the
output is quantised, e is not: ``calibrate_noise(..., output=y)``).
The record must give the terms: the fit must span at least
:data:`MIN_TAU_SPAN` in tau and resolve N (else a one-line error says which
is missing). The mean of e over the
samples the identification keeps is the turn-on bias, so that the emulator's
mean follows the record's.
"""

from dataclasses import dataclass
import math

from gyro_emulator.analysis.calibrate import export_noise
from gyro_emulator.analysis.calibrate.noise import calibrate_noise
from gyro_emulator.analysis.calibrate.provenance import axis_lines
from gyro_emulator.analysis.diagnose import emulated
from gyro_emulator.analysis.diagnose.baseline import MIN_RATE_RMS_RAD_S
from gyro_emulator.recording.record import Record
import numpy as np

#: Shortest tau span (longest / shortest tau used) that separates N from B and K.
MIN_TAU_SPAN = 10.0


@dataclass(frozen=True)
class RecordNoise:
    """
    The noise of one record's axis: the calibration, the sensor YAML fields, the scale factor.

    ``fields`` is a :class:`~gyro_emulator.analysis.calibrate.export_noise.TwinNoise`
    of the one axis; ``scale_factor`` the s of the module docstring.
    """

    axis: str
    calibration: object
    fields: object
    scale_factor: float

    def comment_lines(self):
        """Provenance: the source, the IEEE Std 952 terms with intervals, the twin values."""
        cal = self.calibration
        values = self.fields.per_axis[self.axis]
        band = self.fields.shared['bias_instability_band_s']
        lines = [f'Noise (--noise): IEEE Std 952 fit of calibrate noise on the record minus '
                 f'this model (noise off), {cal.rate_hz:.6g} Hz, {cal.duration_s:.1f} s; '
                 f'scale factor s = {self.scale_factor:.6g} fitted with the bias.']
        lines += axis_lines(cal.axes[0])
        lines.append(
            f"  written (the emulator's noise model fitted to the same Allan curve, as "
            f"calibrate noise --format preset): N {values['electronics_arw_deg_sqrt_h']:.4g} "
            f"deg/sqrt(h), B {values['bias_instability_deg_h']:.4g} deg/h, K "
            f"{values['rate_random_walk_deg_h_sqrt_h']:.4g} deg/h/sqrt(h), turn-on bias "
            f"{values['turn_on_bias_deg_s']:.6g} deg/s, flicker band {band[0]:.3g} .. "
            f'{band[1]:.4g} s (every axis)')
        if self.fields.output_filter is not None:
            lines.append(f'  output filter: {self.fields.output_filter.describe()}')
        return lines


def residual(config, data, axis):
    """Return (e(t), s) of the module docstring for a sensor configuration."""
    offset, applied = emulated.offset_and_rate(config, data, axis)
    y = np.asarray(data.gyro_rad_s, dtype=float) - offset
    if math.sqrt(float(np.mean(applied ** 2))) < MIN_RATE_RMS_RAD_S:
        return y, 1.0
    design = np.column_stack([np.ones(len(y)), applied])
    coef = np.linalg.lstsq(design, y, rcond=None)[0]
    return y - coef[1] * applied, float(coef[1])


def identify(config, data, axis, outlier_threshold):
    """
    Return the :class:`RecordNoise` of ``data`` against a sensor configuration.

    Parameters
    ----------
    config : gyro_emulator.sensor.config.SensorConfig
        The extended model (without noise terms from this record:
        :attr:`.export.ExtendedModel.config`).
    data : gyro_emulator.analysis.diagnose.data.MeasuredData
        The record.
    axis : str
        The diagnosed axis, 'x', 'y' or 'z'.
    outlier_threshold : float
        Robust standard deviations beyond which samples are set aside before
        the Allan deviation (as ``calibrate noise --outlier-sigma``).

    Raises
    ------
    ValueError
        One line saying what the record lacks for the identification.

    """
    e, scale = residual(config, data, axis)
    record = Record(time_s=np.asarray(data.time_s, dtype=float), gyro={axis: e},
                    gyro_sources={axis: 'the record minus the model'},
                    path=data.source or 'the record')
    try:
        cal = calibrate_noise(record, (axis,), outlier_threshold=outlier_threshold,
                              output=np.asarray(data.gyro_rad_s, dtype=float))
        fields = export_noise.twin_noise(cal)
    except ValueError as exc:
        raise ValueError(f'--noise: the record cannot give its noise terms: {exc}') from None
    _check_span(cal)
    return RecordNoise(axis, cal, fields, scale)


def _check_span(cal):
    """Raise a one-line ValueError when the fit cannot separate the terms (module docstring)."""
    fit = cal.axes[0].fit
    lo, hi = fit.tau_range_s
    why = None
    if hi < MIN_TAU_SPAN * lo:
        why = (f'its Allan fit spans tau {lo:.3g} .. {hi:.3g} s, less than the factor '
               f'{MIN_TAU_SPAN:g} that separates white noise from bias instability and random '
               f'walk ({cal.duration_s:.3g} s at {cal.rate_hz:.4g} Hz: record longer)')
    elif not fit.resolved('arw'):
        why = ('its white noise N is not resolved (the 95 % interval reaches 0): record '
               'longer or at a higher rate')
    if why:
        raise ValueError(f'--noise: the record cannot give its noise terms: {why}')
