"""
Overlapping Allan deviation and the IEEE Std 952 noise identification.

One implementation, in parts: :mod:`.adev` (the estimator, its degrees of
freedom and confidence intervals), :mod:`.band` (the short-tau region shaped
by band-limiting, from the PSD or the slope), :mod:`.fit` (the five-term
fit, its intervals and the read-offs), :mod:`.record` (a record through all
of it) and :mod:`.plot`.
"""

from gyro_emulator.analysis.allan.adev import (  # noqa: F401
    AllanResult, confidence_interval, edf_overlapping, local_slopes, overlapping_adev,
    pooled_edf, tau_multiples)
from gyro_emulator.analysis.allan.analyse import (  # noqa: F401
    analyse_record, identify, screened_segments, segments_of,
    start_transient)
from gyro_emulator.analysis.allan.band import band_limit, BandLimit  # noqa: F401
from gyro_emulator.analysis.allan.fit import (  # noqa: F401
    compare_readings, fit_noise_terms, model_adev, NoiseFit, readings, TERMS)
from gyro_emulator.analysis.allan.plot import plot_adev  # noqa: F401
