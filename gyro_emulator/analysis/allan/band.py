"""
Where the Allan deviation is shaped by output filtering or band-limiting.

A digital low-pass, a decimation filter or a spectral line changes the
short-tau end of an Allan deviation: filtered white noise falls below its
N / sqrt(tau) line (the slope is shallower than -1/2), a line makes it
ripple. IEEE Std 952 practice drops that region before reading or fitting
the noise terms. It is found here from the power spectral density, where
the effects are plain:

1. Welch PSD of the rate, pooled over the segments, in log-frequency bins.
2. The white level S_w: the mean PSD over the highest-frequency run of
   bins, at least half an octave wide, whose local log-log slope is flat (|slope| <= 0.1; a 1/f
   flicker spectrum has -1, a filter's roll-off steepens below -0.1 near
   its corner).
3. The relative departure r(f) = S(f) / S_w - 1 above that run changes the
   Allan variance at tau by (NIST SP 1065 Eq 65, the Allan transfer
   function |H(f)|^2 = 2 sin^4(pi f tau) / (pi f tau)^2)::

       d(tau) = sum_f r(f) |H(f)|^2 df / sum_f |H(f)|^2 df

   The band-limited region is every tau up to the last where |d| > 1 %
   (0.5 % in deviation) and more than four times its own scatter (the PSD
   is an estimate): a spectral line's effect ripples with tau (zero where
   tau is a whole number of its periods), so the region does not end at
   the first tau that looks clean.

A PSD that rises toward Nyquist (above the white level by more than 10 %,
log-log slope >= +0.3 over the top octave) is the signature of quantisation
(white phase) noise, the IEEE Std 952
tau^-1 term: that region is kept and fitted, not dropped. When no white run
exists (flicker or a filter everywhere), :func:`slope_band_limit` reads the
region from the Allan slope instead: up to the first tau, no later than the
curve's minimum, whose slope is within :data:`SLOPE_MARGIN` of -1/2, when
the slope has steepened to it from a shallower start.
"""

from dataclasses import dataclass

from gyro_emulator.analysis.allan.adev import local_slopes

import numpy as np
from scipy import signal

#: Allowed change of the Allan variance by the band limit (1 % = 0.5 % in deviation).
VARIANCE_TOLERANCE = 0.01
#: Log-frequency bins per decade of the smoothed PSD.
BINS_PER_DECADE = 16
#: A run of bins is white when its local log-log PSD slope is within this of 0.
WHITE_SLOPE = 0.1
#: Top-octave PSD slope (log-log) of quantisation noise rising toward Nyquist.
RISING_SLOPE = 0.3
#: Allan slope above -1/2 by more than this marks band-limiting (fallback).
SLOPE_MARGIN = 0.02


@dataclass(frozen=True)
class BandLimit:
    """
    The short-tau region shaped by band-limiting, and how it was found.

    Attributes
    ----------
    tau_min_s : float
        Shortest tau the noise terms may use, s.
    method : str
        ``'psd'``, ``'slope'`` or ``'none'`` (nothing to drop).
    white_band_hz : tuple of float or None
        The flat PSD run used as the white level, Hz.
    white_level : float or None
        Its two-sided PSD, (unit/s)^2/Hz (rad^2/s^2/Hz for gyro data).
    edge_hz : float or None
        Highest frequency of the white run: above it the PSD departs.
    quantisation : bool
        The PSD rises toward Nyquist (kept for the tau^-1 term).
    note : str
        One line for the report.

    """

    tau_min_s: float
    method: str
    white_band_hz: tuple = None
    white_level: float = None
    edge_hz: float = None
    quantisation: bool = False
    note: str = ''


def pooled_psd(segments, rate_hz, max_nperseg=1 << 14):
    """
    Two-sided PSD of rate data pooled over segments (Welch, Hann, 50 % overlap).

    Returns ``(freq_hz, psd, averages)``: frequencies from 0 to Nyquist, the
    two-sided density (unit^2/Hz; one-sided / 2) weighted by each segment's
    window count, and the number of windows averaged. ``None`` when no
    segment has 64 samples.
    """
    longest = max(len(s) for s in segments)
    nperseg = int(2 ** np.clip(np.floor(np.log2(max(longest, 2) / 8.0)), 6, np.log2(max_nperseg)))
    if longest < nperseg or longest < 64:
        nperseg = int(2 ** np.floor(np.log2(longest))) if longest >= 64 else 0
    if nperseg < 64:
        return None
    total, windows = None, 0
    for seg in segments:
        if len(seg) < nperseg:
            continue
        count = 1 + (len(seg) - nperseg) // (nperseg // 2)
        freq, psd = signal.welch(np.asarray(seg, dtype=float), fs=rate_hz, window='hann',
                                 nperseg=nperseg, detrend='constant')
        total = psd * count if total is None else total + psd * count
        windows += count
    return freq, total / windows / 2.0, windows


def _log_bins(freq, psd, lowest_hz):
    """Mean PSD in log-frequency bins above ``lowest_hz``: (centres, levels, counts)."""
    top = freq[-1]
    edges = np.logspace(np.log10(lowest_hz), np.log10(top), int(
        np.ceil(np.log10(top / lowest_hz) * BINS_PER_DECADE)) + 1)
    idx = np.digitize(freq, edges) - 1
    centres, levels, counts = [], [], []
    for b in range(len(edges) - 1):
        sel = idx == b
        if np.any(sel):
            centres.append(np.sqrt(edges[b] * edges[b + 1]))
            levels.append(float(np.mean(psd[sel])))
            counts.append(int(np.sum(sel)))
    return np.array(centres), np.array(levels), np.array(counts)


def _white_run(centres, levels):
    """Index range (lo, hi) of the highest-frequency flat run of log bins, or None."""
    lf, lp = np.log10(centres), np.log10(np.maximum(levels, 1e-300))
    half = BINS_PER_DECADE // 6 or 1           # about an octave across
    flat = np.zeros(len(lf), dtype=bool)
    for i in range(half, len(lf) - half):
        x = lf[i - half:i + half + 1]
        y = lp[i - half:i + half + 1]
        slope = np.polyfit(x, y, 1)[0]
        flat[i] = abs(slope) <= WHITE_SLOPE
    runs, start = [], None
    for i, ok in enumerate(np.append(flat, False)):
        if ok and start is None:
            start = i
        elif not ok and start is not None:
            runs.append((start, i - 1))
            start = None
    wide = [(a, b) for a, b in runs if lf[b] - lf[a] >= np.log10(2.0) / 2.0]
    return wide[-1] if wide else None


#: A Welch grid resolves the Allan kernel's ripple (period 1 / tau in f) when
#: tau df is at most this; beyond it the ripple is averaged (sin^4 -> 3/8).
RESOLVED_TAU_DF = 0.25


def variance_change(freq, psd, white_level, edge_hz, taus_s, windows=None, white_bins=None):
    """
    Relative change d(tau) of the Allan variance caused by the PSD above ``edge_hz``.

    d = integral r(f) |H_tau(f)|^2 df / integral |H_tau(f)|^2 df, with
    r = S / S_w - 1 above the edge and 0 below, |H_tau(f)|^2 =
    2 sin^4(pi f tau) / (pi f tau)^2 (NIST SP 1065 Eq 65). Where the Welch
    grid (spacing df) resolves the kernel's ripple (tau df <=
    :data:`RESOLVED_TAU_DF`) both integrals are sums over the grid; at longer
    taus the grid would sample the ripple at arbitrary phases (on its zeros
    when tau df is a whole number), so the numerator uses the ripple's
    mean, 3 / (4 (pi f tau)^2), and the denominator its exact value from 0
    to Nyquist, 1 / (2 tau) less the tail above Nyquist. With ``windows``
    (Welch averages) and ``white_bins`` (grid bins behind S_w) it also
    returns the standard deviation of d from the scatter of the estimate
    (relative variance 1 / windows per bin, 1 / (windows white_bins) for S_w).
    """
    f = np.asarray(freq[1:], dtype=float)
    df = float(freq[1] - freq[0])
    above = f > edge_hz
    r = np.where(above, psd[1:] / white_level - 1.0, 0.0)
    taus = np.asarray(taus_s, dtype=float)[:, np.newaxis]
    x = np.pi * f[np.newaxis, :] * taus
    resolved = taus[:, 0] * df <= RESOLVED_TAU_DF
    kernel = np.where(resolved[:, np.newaxis], 2.0 * np.sin(x) ** 4 / x ** 2,
                      0.75 / x ** 2) * df
    nyquist = float(freq[-1]) + 0.5 * df
    exact = 0.5 / taus[:, 0] - 0.75 / (np.pi ** 2 * taus[:, 0] ** 2 * nyquist)
    total = np.where(resolved, kernel.sum(axis=1), exact)
    change = (kernel @ r) / total
    if windows is None:
        return change
    weight = kernel[:, above]
    spread = np.sqrt(np.sum(weight ** 2, axis=1) / windows
                     + (weight.sum(axis=1) ** 2) / (windows * max(white_bins, 1))) / total
    return change, spread


def psd_band_limit(segments, rate_hz, taus_s):
    """
    Find the band-limited short-tau region from the PSD (module docstring).

    Parameters
    ----------
    segments : sequence of numpy.ndarray
        Contiguous rate segments.
    rate_hz : float
        Sample rate, Hz.
    taus_s : numpy.ndarray
        The Allan deviation's taus, s.

    Returns
    -------
    BandLimit or None
        None when the PSD has no white run (use :func:`slope_band_limit`).

    """
    pooled = pooled_psd(segments, rate_hz)
    if pooled is None:
        return None
    freq, psd, windows = pooled
    lowest = max(4.0 * freq[1], 1e-6)
    centres, levels, counts = _log_bins(freq, psd, lowest)
    if len(centres) < 8:
        return None
    run = _white_run(centres, levels)
    if run is None:
        return None
    lo, hi = run
    start = float(centres[lo] * 10 ** (-0.5 / BINS_PER_DECADE))
    edge = float(centres[hi] * 10 ** (0.5 / BINS_PER_DECADE))
    in_run = (freq >= start) & (freq <= edge)
    white = float(np.mean(psd[in_run]))
    top = centres >= centres[-1] / 2.0
    rising = bool(len(centres[top]) >= 3 and np.mean(levels[top]) > 1.1 * white
                  and np.polyfit(np.log10(centres[top]), np.log10(levels[top]), 1)[0]
                  >= RISING_SLOPE)
    taus = np.asarray(taus_s, dtype=float)
    white_bins = int(np.count_nonzero(in_run))
    change, spread = variance_change(freq, psd, white, edge, taus, windows, white_bins)
    bad = np.abs(change) > np.maximum(VARIANCE_TOLERANCE, 4.0 * spread)
    tau_min = float(taus[0])
    if not rising and np.any(bad):
        last = int(np.flatnonzero(bad)[-1])
        tau_min = float(taus[min(last + 1, len(taus) - 1)])
    if rising:
        note = (f'PSD rises toward Nyquist above {edge:.3g} Hz: quantisation (white phase) '
                'noise, kept for the tau^-1 term')
    elif tau_min > taus[0]:
        note = (f'PSD departs from its white level above {edge:.3g} Hz (filter, decimation '
                f'or a spectral line): tau < {tau_min:.3g} s dropped (changes the Allan '
                f'variance by more than {100 * VARIANCE_TOLERANCE:.0f} %)')
    else:
        note = 'no band-limiting found in the PSD: every tau used'
    return BandLimit(tau_min_s=tau_min, method='psd', white_band_hz=(start, edge),
                     white_level=white, edge_hz=edge, quantisation=bool(rising), note=note)


def slope_band_limit(taus_s, adev, slopes=None):
    """
    Band-limited region from the Allan slope (fallback without data or a white PSD run).

    Filtered white noise has a local slope shallower than -1/2 at short tau
    that steepens toward -1/2. The region ends at the first tau whose slope
    is within :data:`SLOPE_MARGIN` of -1/2 or steeper, searched no later
    than the curve's minimum (the white region comes before it: a noisy
    slope at the long end is no anchor), and only when the slope has
    steepened to it by more than :data:`SLOPE_MARGIN` from the shortest
    tau (a slope that rises from the start is a longer-tau term lifting the
    white region, not a filter). Otherwise nothing is dropped.
    """
    taus = np.asarray(taus_s, dtype=float)
    slopes = local_slopes(taus, adev, half_width=1) if slopes is None else slopes
    searched = int(np.argmin(adev)) + 1
    ok = np.flatnonzero(slopes[:searched] <= -0.5 + SLOPE_MARGIN)
    if len(ok) == 0 or slopes[0] - slopes[ok[0]] <= SLOPE_MARGIN:
        return BandLimit(tau_min_s=float(taus[0]), method='none',
                         note='no band-limited region found from the Allan slope')
    first = int(ok[0])
    return BandLimit(tau_min_s=float(taus[first]), method='slope',
                     note=(f'Allan slope shallower than -1/2 below {taus[first]:.3g} s '
                           '(output filter): that region dropped'))


def band_limit(segments, rate_hz, taus_s, adev):
    """Band-limited region: from the PSD when it has a white run, else from the slope."""
    found = psd_band_limit(segments, rate_hz, taus_s) if segments is not None else None
    return found if found is not None else slope_band_limit(taus_s, adev)
