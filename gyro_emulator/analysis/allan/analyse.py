"""
Noise identification of a record, as ``gyro-emulator allan`` and ``calibrate noise`` run it.

The record is a :class:`gyro_emulator.recording.record.Record` (its gyro
axes, their columns, and the timing of their stamps, a
:class:`gyro_emulator.recording.timing.Timing` worked out once and read
here, never again); :func:`identify` runs the IEEE Std 952
procedure on one axis: overlapping
Allan deviation with confidence intervals, the band-limited short-tau region
(:mod:`~gyro_emulator.analysis.allan.band`), the five-term fit and its
intervals (:mod:`~gyro_emulator.analysis.allan.fit`), the read-offs, and the
warnings when they disagree; :func:`analyse_record` does both for one axis
and returns the JSON summary.
"""

from dataclasses import replace

from gyro_emulator import units
from gyro_emulator.analysis import outliers
from gyro_emulator.analysis.allan import adev, band, fit as fitting
from gyro_emulator.analysis.sense import GYRO
from gyro_emulator.recording.timing import slow_step_note
from gyro_emulator.validation import check_range
import numpy as np

#: Longest tau as a share of the longest segment (``identify``): 2 tau fit in it.
MAX_TAU_FRACTION = 0.5
#: A stretch set aside no longer than this is filled with its neighbours' mean,
#: a longer one splits the record, s.
FILL_MAX_S = 10.0


def segments_of(timing, rate):
    """Return ``rate`` split at the gaps of ``timing`` (a Timing): the segments of >= 3 samples."""
    segments = timing.segments(rate, min_samples=3)
    if not segments:
        raise ValueError('no segment has 3 or more samples')
    return segments


def screened_segments(timing, rate, threshold=outliers.THRESHOLD, what='the axis', sense=GYRO):
    """
    Set a static record's spikes and motion aside, then split it at gaps.

    ``timing`` is the :class:`gyro_emulator.recording.timing.Timing` of the
    samples' stamps (:meth:`gyro_emulator.recording.record.Record.timing`).
    The stretches :func:`gyro_emulator.analysis.outliers.screen_at_rest`
    finds are filled with the mean of the kept samples within
    :data:`gyro_emulator.analysis.outliers.LOCAL_HALF_S` of them when they
    last at most :data:`FILL_MAX_S` (the angle is interpolated straight
    across: the long averaging times survive, and the short ones lose at
    most the filled share of their variance), and cut out otherwise (the
    record splits there, as at a logging gap, and the rate is that of the
    samples kept, :meth:`~gyro_emulator.recording.timing.Timing.kept`).
    ``sense`` (:mod:`gyro_emulator.analysis.sense`) gives the samples' unit
    and physical limits: a constant such as gravity on a static
    accelerometer is a level, which the local high-pass takes out.

    Returns
    -------
    (float, list of numpy.ndarray, SetAside, dict)
        The nominal rate, Hz, the segments (:func:`segments_of`), what was
        set aside, and ``{'filled': samples, 'cut': samples}``.

    Raises
    ------
    gyro_emulator.analysis.outliers.HeldOutput
        When the output is stuck or saturated (named as ``what``,
        :func:`gyro_emulator.analysis.outliers.check_not_held`).

    """
    time_s = timing.time_s
    rate = np.asarray(rate, dtype=float)
    outliers.check_not_held(rate, timing.rate_hz, what)
    screened = outliers.screen_at_rest(time_s, rate, 1.0 / timing.rate_hz, threshold, what,
                                       sense.limits, sense.unit)
    filled = rate.copy()
    cut = np.zeros(len(rate), bool)
    n_filled = 0
    steps = outliers.level_shifts(time_s, rate, screened.keep, screened.spans, threshold)
    stepped = {(lo, hi) for lo, hi, _ in steps}
    for lo, hi, _ in screened.spans:
        inside = (time_s >= lo) & (time_s <= hi)
        around = (screened.keep & (time_s >= lo - outliers.LOCAL_HALF_S)
                  & (time_s <= hi + outliers.LOCAL_HALF_S))
        if hi - lo <= FILL_MAX_S and np.any(around) and (lo, hi) not in stepped:
            filled[inside] = np.mean(rate[around])
            n_filled += int(np.count_nonzero(inside))
        else:
            cut |= inside
    kept = timing.kept(~cut)
    return kept.rate_hz, segments_of(kept, filled[~cut]), screened, {
        'filled': n_filled, 'cut': int(np.count_nonzero(cut)),
        'level_shifts': [{'start_s': lo, 'end_s': hi, shift_key(sense): d}
                         for lo, hi, d in steps]}


def shift_key(sense=GYRO):
    """Return the JSON key of a level step in ``sense``'s SI unit (``shift_rad_s``, ...)."""
    return 'shift_' + sense.unit.replace('/', '_').replace('^', '')


#: Windows a record is cut into to look for a start-up transient (each a 1/n of it).
TRANSIENT_WINDOWS = (20, 40)


def start_transient(segment, rate_hz, threshold=6.0):
    """
    Return a warning when the start of the record trends away from the rest, else None.

    The Allan variance is half the mean square difference of adjacent
    window means (IEEE Std 952), so for n windows the n - 1 differences are
    alike in a stationary record. The difference between the first two is
    compared with the robust spread (1.4826 MAD) of the others, for n = 20
    and 40 (fewer differences make the spread too uncertain): beyond
    ``threshold`` of it, the start is a transient that the noise terms would
    read as random walk or rate ramp. Over 3000 seeded records without one
    (white, flicker as Gauss-Markov terms of 30 s to 3000 s, random walk)
    it warned in none.
    """
    x = np.asarray(segment, dtype=float)
    for n in TRANSIENT_WINDOWS:
        m = len(x) // n
        if m < 10:
            continue
        means = x[:m * n].reshape(n, m).mean(axis=1)
        diffs = np.diff(means)
        spread = 1.4826 * float(np.median(np.abs(diffs[1:] - np.median(diffs[1:]))))
        if spread > 0.0 and abs(diffs[0]) > threshold * spread:
            return (f'the first {m / rate_hz:.4g} s differ from the next by '
                    f'{abs(diffs[0]) / spread:.0f}x the spread of the rest of the record '
                    '(a warm-up or another start-up transient): it reads as random walk or '
                    'rate ramp and inflates K and R; trim the start of the log and fit again')
    return None


def identify(segments, rate_hz, max_tau_fraction=0.25, ci=0.683):
    """
    IEEE Std 952 noise identification of one axis.

    Returns ``(AllanResult, NoiseFit)``: the overlapping Allan deviation of
    the pooled segments over about 10 taus per decade (bands at level
    ``ci``), and the five-term fit (95 % term intervals)
    above the band-limited region, with its ``band``, ``readings`` and the
    warnings of the fit, of the read-off comparison and of the band limit.
    ``max_tau_fraction``, the longest tau as a share of the longest segment,
    lies in (0, 0.5] (the overlapping Allan variance needs 2 tau within it).
    """
    check_range('allan', 'max_tau_fraction', max_tau_fraction, 0.0, MAX_TAU_FRACTION)
    longest = max(len(s) for s in segments)
    taus = adev.tau_multiples(longest, 10, max_tau_fraction) / rate_hz
    result = adev.overlapping_adev(segments, rate_hz, taus=taus, ci=ci)
    limit = band.band_limit(segments, rate_hz, result.taus_s, result.adev)
    usable = result.taus_s >= limit.tau_min_s * (1 - 1e-9)
    if np.count_nonzero(usable) < 3:
        raise ValueError(f'only {np.count_nonzero(usable)} averaging times above the '
                         f'band-limited region (tau >= {limit.tau_min_s:.3g} s): the record '
                         'is too short for a noise fit')
    found = fitting.fit_noise_terms(result, (limit.tau_min_s, result.taus_s[-1]))
    read = fitting.readings(result.taus_s[usable], result.adev[usable])
    warnings = list(found.warnings) + fitting.compare_readings(found, result, read)
    transient = start_transient(max(segments, key=len), rate_hz)
    if transient:
        warnings.append(transient)
    return result, replace(found, band=limit, readings=read, warnings=tuple(warnings))


def summary(fit, sense=GYRO):
    """Return a :class:`NoiseFit` as JSON: values, intervals, read-offs (datasheet units)."""
    terms = {}
    for term in fitting.TERMS:
        to, unit = sense.shown[term]
        interval = fit.intervals.get(term)
        reading = fit.readings.get(term)
        share = None
        if reading is not None and fit.adev([reading.tau_s])[0] > 0:
            share = float((fit.term_adev(term, [reading.tau_s])[0]
                           / fit.adev([reading.tau_s])[0]) ** 2)
        terms[term] = {
            'value': float(to(fit.value(term))), 'unit': unit,
            'si': fit.value(term),
            'interval': None if interval is None else [
                float(to(interval.low)), float(to(interval.high))],
            'resolved': fit.resolved(term),
            'read_off': None if reading is None else float(to(reading.value)),
            'read_off_tau_s': None if reading is None else reading.tau_s,
            'read_off_identified': None if reading is None else reading.identified,
            'share_at_read_off': share}
    limit = fit.band
    return {'terms': terms, 'ci': fit.ci, 'tau_range_s': list(fit.tau_range_s),
            'misfit': fit.misfit, 'warnings': list(fit.warnings),
            'band_limit': None if limit is None else {
                'tau_min_s': limit.tau_min_s, 'method': limit.method,
                'edge_hz': limit.edge_hz, 'quantisation': limit.quantisation,
                'note': limit.note}}


def set_aside_summary(screened, handled, sense=GYRO):
    """JSON form of what :func:`screened_segments` set aside, with the filled and cut counts."""
    line = screened.describe()
    to, unit = sense.shift
    for step in handled.get('level_shifts', ()):
        line += (f'; the level steps by {float(to(step[shift_key(sense)])):+.3g} '
                 f'{unit} across {step["start_s"]:.1f}-{step["end_s"]:.1f} s (a shock?): the '
                 'record is split there')
    return dict(screened.as_dict(), **handled, description=line)


def missing_note(timing):
    """
    Say how many samples are missing between the stamps, and what that does (or nothing).

    ``timing`` is the record's :class:`gyro_emulator.recording.timing.Timing`;
    its rate is the nominal one (:func:`gyro_emulator.recording.timing.dropped_samples`)
    and the Allan deviation joins the samples on either side of a missing
    one: the white noise N is right (its per-sample spread and the sample
    period are), but the correlated terms see a share p of their time
    removed, so a random walk reads 1 / sqrt(1 - p) high in K; B, a
    scale-free term, hardly moves.
    """
    missing = timing.missing
    if not missing:
        return ()
    share = missing / (len(timing.time_s) + missing)
    return (f'{missing} samples ({100 * share:.2g} %) are missing between stamps (steps of '
            f'2 or more sample periods, not a slower clock): N is unaffected; the Allan '
            f'deviation joins the samples around each, so K may read up to '
            f'{100 * (1 / np.sqrt(1 - share) - 1):.2g} % high',)


def slow_clock_note(timing):
    """Say which unit the stamps may be in when they give under 1 Hz (or nothing)."""
    note = slow_step_note(timing.time_s, timing.median_step_s)
    return (note,) if note else ()


def gap_note(timing):
    """
    Say how the record's gaps split it, and what that does (or nothing).

    ``timing`` is the record's :class:`gyro_emulator.recording.timing.Timing`.
    The Allan deviation pools the segments: its longest tau is a fraction
    of the longest one, not of the span the header gives.
    """
    bounds = timing.bounds
    if len(bounds) < 2:
        return ()
    t = timing.time_s
    gaps = [float(t[a] - t[b - 1]) for (_, b), (a, _) in zip(bounds[:-1], bounds[1:])]
    longest = max(float(t[b - 1] - t[a]) for a, b in bounds)
    return (f'{len(gaps)} gap(s) in the stamps (longest {max(gaps):.4g} s) split the record into '
            f'{len(bounds)} segments: the Allan deviation pools them, and its longest tau is set '
            f'by the longest segment ({longest:.4g} s), not by the {float(t[-1] - t[0]):.4g} s '
            'span',)


def timing_notes(timing):
    """
    Say what the record's stamps do to the fit, in one note (or nothing).

    The samples missing between stamps (:func:`missing_note`), the gaps that
    split the record (:func:`gap_note`) and a clock under 1 Hz
    (:func:`slow_clock_note`), joined: ``allan`` and ``calibrate noise``.
    """
    parts = missing_note(timing) + gap_note(timing) + slow_clock_note(timing)
    return ('; '.join(parts),) if parts else ()


def analyse_record(record, axis=None, max_tau_fraction=0.25, gap_factor=3.0,
                   outlier_threshold=outliers.THRESHOLD):
    """
    Analyse one axis of a record as ``gyro-emulator allan`` does.

    ``record`` is a :class:`gyro_emulator.recording.record.Record`; its
    timing (:meth:`~gyro_emulator.recording.record.Record.timing` at
    ``gap_factor``) is read, not worked out again. Returns
    ``(JSON-ready dict, AllanResult, NoiseFit)``. Spikes and motion are set
    aside first (:func:`screened_segments`; ``outlier_threshold``
    ``math.inf`` keeps every sample) and ``set_aside`` says what went.
    """
    path = record.path
    rate, column = record.gyro_axis(axis)
    try:
        timing = record.timing(gap_factor)
        rate_hz, segments, screened, handled = screened_segments(
            timing, rate, outlier_threshold, what=column)
    except ValueError as exc:
        raise ValueError(f'{path}: {exc}') from None
    result, found = identify(segments, rate_hz, max_tau_fraction)
    time_s = record.time_s
    info = {
        'file': str(path), 'column': column, 'sample_rate_hz': rate_hz,
        'recovery': list(record.recovery),
        'timing': list(timing_notes(timing)),
        'set_aside': set_aside_summary(screened, handled),
        'n_samples': result.n_samples, 'segments': len(segments),
        'repeated_timestamps': int(np.sum(np.diff(time_s) == 0.0)),
        'duration_s': float(time_s[-1] - time_s[0]),
        'arw_deg_sqrt_h': found.arw_deg_sqrt_h,
        'bias_instability_deg_h': found.bias_instability_deg_h,
        'rrw_deg_h_sqrt_h': found.rrw_deg_h_sqrt_h,
        'arw_rad_s_sqrt_hz': found.arw_rad_s_sqrt_hz,
        'bias_instability_rad_s': found.bias_instability_rad_s,
        'rrw_rad_s_sqrt_s': found.rrw_rad_s_sqrt_s,
        'quantization_rad': found.quantization_rad,
        'rate_ramp_rad_s2': found.rate_ramp_rad_s2,
        'arw_at_1s_deg_sqrt_h': float(units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(
            found.readings['arw'].value)),
        'bias_instability_min_deg_h': float(units.rad_s_to_deg_h(
            found.readings['bias_instability'].value)),
        'tau_at_min_s': found.readings['bias_instability'].tau_s,
        'fit': summary(found),
        'taus_s': result.taus_s.tolist(), 'adev_rad_s': result.adev.tolist(),
        'adev_lo_rad_s': result.adev_lo.tolist(), 'adev_hi_rad_s': result.adev_hi.tolist(),
        'edf': result.edf.tolist(), 'ci': result.ci,
        'units': {'arw': 'deg/sqrt(h)', 'bias_instability': 'deg/h (Allan floor 0.664 B)',
                  'rrw': 'deg/h/sqrt(h)', 'adev': 'rad/s', 'quantization': 'rad',
                  'rate_ramp': 'rad/s^2'},
    }
    return info, result, found
