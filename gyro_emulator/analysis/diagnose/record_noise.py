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

The accelerometer (:func:`identify_accel`) is identified as ``calibrate
noise`` identifies it, on the record's own accelerometer (a CSV's
``accel_{x,y,z}_m_s2``, a bag's output Imu ``linear_acceleration``), and
only on a static record: one whose applied rate stays below
:data:`~gyro_emulator.analysis.diagnose.baseline.MIN_RATE_RMS_RAD_S` rms
(gravity turns with the part otherwise). Its fields are the
accelerometer twin of ``calibrate noise --format preset``.
"""

from dataclasses import dataclass
import math

from gyro_emulator import units
from gyro_emulator.analysis.calibrate import export_noise
from gyro_emulator.analysis.calibrate.accel_figures import accel_figures
from gyro_emulator.analysis.calibrate.noise import calibrate_noise
from gyro_emulator.analysis.calibrate.provenance import axis_lines
from gyro_emulator.analysis.diagnose import emulated
from gyro_emulator.analysis.diagnose.baseline import MIN_RATE_RMS_RAD_S
from gyro_emulator.analysis.sense import ACCEL
from gyro_emulator.recording.record import is_bag, load_record, Record
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


@dataclass(frozen=True)
class AccelNoise:
    """
    The accelerometer of a record for ``--noise``: its calibration and twin fields, or why not.

    ``fields`` is the accelerometer's
    :class:`~gyro_emulator.analysis.calibrate.export_noise.TwinNoise` (SI
    AccelConfig names) or None, ``why`` then says why it was not identified.
    """

    calibration: object = None
    fields: object = None
    why: str = None

    def comment_lines(self):
        """Provenance: the IEEE Std 952 terms, the twin's values, or why none are written."""
        if self.fields is None:
            return [f'Accelerometer (--noise): not identified: {self.why}.']
        cal = self.calibration
        lines = ['Accelerometer (--noise): IEEE Std 952 fit of calibrate noise on the '
                 "record's accelerometer (a static record; as calibrate noise --format preset):"]
        for item in cal.axes:
            lines += axis_lines(item, ACCEL)
        lines += [f'  note: {note}' for note in cal.notes]
        for axis, v in self.fields.per_axis.items():
            n = float(units.m_s2_sqrt_hz_to_ug_sqrt_hz(v['electronics_noise_m_s2_sqrt_hz']))
            lines.append(
                f'  written, axis {axis}: N {n:.4g}'
                f" ug/sqrt(Hz), B {float(units.m_s2_to_mg(v['bias_instability_m_s2'])):.4g} mg, "
                f"K {v['random_walk_m_s3_sqrt_hz']:.4g} m/s^3/sqrt(Hz), turn-on bias "
                f"{v['turn_on_bias_m_s2']:.6g} m/s^2 (the mean less gravity along the mean "
                'direction: a bias across gravity cannot be told from a tilt and is taken as '
                'none)')
        return lines


def _accel_record(data, gyro_topic):
    """Return a record of the measured accelerometer of ``data``, or None when it has none."""
    if is_bag(data.source):
        record = load_record(data.source, {'gyro': gyro_topic, 'imu_accel': None})
        return record if record.accel is not None else None
    if data.accel_m_s2 is None:
        return None
    return Record.from_arrays(data.time_s, data.gyro_rad_s, accel_m_s2=data.accel_m_s2,
                              path=data.source or 'the record')


def identify_accel(data, outlier_threshold, gyro_topic=None):
    """
    Return the :class:`AccelNoise` of a record (module docstring), or None without one.

    ``gyro_topic`` is a bag's output Imu topic (its ``linear_acceleration``).
    """
    applied = np.asarray(data.rate_cmd_rad_s, dtype=float)
    record = _accel_record(data, gyro_topic)
    if record is None:
        return None
    rms = math.sqrt(float(np.mean(applied ** 2)))
    if rms >= MIN_RATE_RMS_RAD_S:
        return AccelNoise(why=f'the record is not static (applied rate '
                              f'{float(units.rad_s_to_deg_s(rms)):.3g} deg/s rms): gravity turns '
                              "with the part, and the accelerometer's noise needs it at rest")
    try:
        cal = calibrate_noise(record, outlier_threshold=outlier_threshold, sense=ACCEL)
        fields = export_noise.accel_twin_noise(accel_figures(cal))
    except ValueError as exc:
        return AccelNoise(why=str(exc))
    return AccelNoise(cal, fields)
