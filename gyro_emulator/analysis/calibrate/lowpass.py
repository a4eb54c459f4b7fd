"""
The part's digital low-pass, identified from the PSD of its noise: the twin's output filter.

A part's output filter (its ASIC's low-pass, a decimation filter) takes
power out of the top of the band: the PSD of its noise falls below the
white level N^2 and the Allan deviation at the shortest taus below
N / sqrt(tau). The IEEE Std 952 fit leaves those taus out
(:mod:`gyro_emulator.analysis.allan.band`); the twin puts the filter back,
as the emulator's output filter term (``output_filter_hz``,
``output_filter_order``: a digital Butterworth low-pass of order 1 or 2,
``scipy.signal.butter(order, cutoff_hz, fs=rate_hz)``, the coefficients
:class:`gyro_emulator.sensor.plan.Plan` runs).

The cut-off is identified from the PSD where the Allan deviation sees it.
The relative change of the Allan variance at tau that the PSD S(f) makes
against the white level N^2 (NIST SP 1065 Eq 65, the kernel
|H_tau(f)|^2 = 2 sin^4(pi f tau) / (pi f tau)^2,
:func:`~gyro_emulator.analysis.allan.band.variance_change`)::

    d(tau) = sum_f (S(f) / N^2 - 1) |H_tau(f)|^2 / sum_f |H_tau(f)|^2

is measured on the log's pooled Welch PSD at the band-limited taus (those
the fit left out), and the filter's own change, with S = N^2 |H(f)|^2 of the
Butterworth, matched to it over the cut-off: least squares in
log(1 + d), the relative error of the Allan variance (a filter takes most
of the variance at the shortest tau, where a small error in d is a large one
in the deviation), for order 1 and order 2; the order with the smaller sum
of squares is kept. The white
level N^2 is the fit's (the twin's own N), so the filtered twin keeps the
fitted Allan curve at the longer taus. One filter serves every axis (the
emulator has one): the axes that show a band-limited departure downward
are fitted together.

No filter is identified when no tau was left out, when the departure at the
shortest tau is not below the white level by more than
:data:`~gyro_emulator.analysis.allan.band.VARIANCE_TOLERANCE` and four times
its scatter (a PSD that rises is quantisation, a line ripples), when the
best filter explains less than :data:`MIN_EXPLAINED` of the departure, or
when its cut-off runs to the top of the search (no low-pass below Nyquist).
"""

from dataclasses import dataclass

from gyro_emulator.analysis.allan.band import pooled_psd, variance_change, VARIANCE_TOLERANCE
import numpy as np
from scipy import optimize, signal

#: Orders of the Butterworth low-pass tried.
ORDERS = (1, 2)
#: Fraction of the departure's sum of squares the filter must explain.
MIN_EXPLAINED = 0.75
#: Search range of the cut-off, as fractions of the sample rate.
CUTOFF_RANGE = (0.02, 0.49)
#: Grid points of the search (log-spaced) before the bounded refinement.
GRID_POINTS = 48


@dataclass(frozen=True)
class OutputFilter:
    """
    The identified low-pass and what it was matched to.

    Attributes
    ----------
    cutoff_hz : float
        -3 dB cut-off of the digital Butterworth, Hz.
    order : int
        1 or 2.
    rate_hz : float
        The sample rate it runs at, Hz.
    axes : tuple of str
        The axes it was fitted on.
    taus_s : tuple of float
        The band-limited taus matched, s (those of the first axis).
    measured : tuple of float
        The Allan variance change d(tau) the log's PSD makes there (first axis).
    fitted : tuple of float
        The filter's own change at the same taus.
    explained : float
        1 - (sum of squares left) / (sum of squares of the departure), in log(1 + d).

    """

    cutoff_hz: float
    order: int
    rate_hz: float
    axes: tuple
    taus_s: tuple
    measured: tuple
    fitted: tuple
    explained: float

    def describe(self):
        """Return one line for the YAML provenance and the report."""
        pct = ', '.join(f'{100 * d:+.0f}' for d in self.measured)
        fit = ', '.join(f'{100 * d:+.0f}' for d in self.fitted)
        taus = ', '.join(f'{t:.3g}' for t in self.taus_s)
        kind = 'first' if self.order == 1 else 'second'
        return (f'{kind}-order Butterworth low-pass at {self.cutoff_hz:.4g} Hz '
                f'({self.rate_hz:.6g} Hz sampling), identified from the PSD of axes '
                f'{", ".join(self.axes)}: the Allan variance at tau {taus} s is changed by '
                f'{pct} % against the white level, the filter changes it by {fit} % '
                f'({100 * self.explained:.0f} % of the departure explained)')


def filter_gain(cutoff_hz, order, rate_hz, freq_hz):
    """Return |H(f)|^2 of the digital Butterworth low-pass the emulator runs (DC gain 1)."""
    b, a = signal.butter(order, cutoff_hz, fs=rate_hz)
    _, h = signal.freqz(b, a, worN=np.asarray(freq_hz, dtype=float), fs=rate_hz)
    return np.abs(h) ** 2


@dataclass(frozen=True)
class _Departure:
    """One axis: its PSD grid, the fitted white level, the taus, d(tau) and its scatter."""

    axis: str
    freq_hz: np.ndarray
    white: float
    taus_s: np.ndarray
    measured: np.ndarray
    spread: np.ndarray

    def filtered(self, cutoff_hz, order, rate_hz):
        """Return d(tau) of white noise at the white level through the low-pass."""
        gain = filter_gain(cutoff_hz, order, rate_hz, self.freq_hz)
        return variance_change(self.freq_hz, self.white * gain, self.white, 0.0, self.taus_s)


def _departure(item, rate_hz):
    """Return the band-limited departure of one axis (:class:`_Departure`), or None."""
    taus = np.asarray(item.result.taus_s, dtype=float)
    dropped = taus[taus < item.fit.tau_range_s[0] * (1.0 - 1e-9)]
    white = float(item.fit.arw_rad_s_sqrt_hz) ** 2
    if len(dropped) == 0 or white <= 0.0:
        return None
    pooled = pooled_psd(item.segments, rate_hz)
    if pooled is None:
        return None
    freq, psd, windows = pooled
    change, spread = variance_change(freq, psd, white, 0.0, dropped, windows, len(freq))
    if not change[0] < -max(VARIANCE_TOLERANCE, 4.0 * spread[0]):
        return None
    return _Departure(item.axis, freq, white, dropped, change, spread)


def _fit_order(parts, order, rate_hz):
    """Return (sum of squares, cut-off Hz) of the best low-pass of ``order`` for ``parts``."""
    def cost(log_fc):
        fc = float(np.exp(log_fc))
        return float(sum(np.sum((np.log1p(p.filtered(fc, order, rate_hz))
                                 - np.log1p(p.measured)) ** 2) for p in parts))

    lo, hi = (np.log(f * rate_hz) for f in CUTOFF_RANGE)
    grid = np.linspace(lo, hi, GRID_POINTS)
    costs = [cost(g) for g in grid]
    j = int(np.argmin(costs))
    if j == len(grid) - 1:
        return costs[j], float(np.exp(grid[j]))
    found = optimize.minimize_scalar(cost, bounds=(grid[max(j - 1, 0)], grid[j + 1]),
                                     method='bounded', options={'xatol': 1e-4})
    return float(found.fun), float(np.exp(found.x))


def identify_output_filter(calibration):
    """
    Identify the twin's output low-pass from a noise calibration (module docstring).

    Parameters
    ----------
    calibration : gyro_emulator.analysis.calibrate.noise.NoiseCalibration
        The log's noise calibration (its axes' segments, Allan results and fits).

    Returns
    -------
    OutputFilter or None
        None when the log shows no low-pass (module docstring).

    """
    rate_hz = float(calibration.rate_hz)
    parts = [p for p in (_departure(item, rate_hz) for item in calibration.axes)
             if p is not None]
    if not parts:
        return None
    none = float(sum(np.sum(np.log1p(p.measured) ** 2) for p in parts))
    fits = {order: _fit_order(parts, order, rate_hz) for order in ORDERS}
    order = min(fits, key=lambda k: fits[k][0])
    left, cutoff = fits[order]
    explained = 1.0 - left / none
    if explained < MIN_EXPLAINED or cutoff >= 0.99 * CUTOFF_RANGE[1] * rate_hz:
        return None
    first = parts[0]
    return OutputFilter(
        cutoff_hz=cutoff, order=order, rate_hz=rate_hz, axes=tuple(p.axis for p in parts),
        taus_s=tuple(float(t) for t in first.taus_s),
        measured=tuple(float(d) for d in first.measured),
        fitted=tuple(float(d) for d in first.filtered(cutoff, order, rate_hz)),
        explained=float(explained))
