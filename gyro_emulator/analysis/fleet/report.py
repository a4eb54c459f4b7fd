"""
The fleet's summary (yields, quantiles, attribution, speed) and its plots.

Yields count every part: a part that fails to be a valid device counts as
failing. Quantiles come from the first 131 072 parts (a random sample of
the fleet: the parts are independent draws), so they are the same for any
scheduler; at that size a 5 % quantile is known to about +-0.06 % in level.
Each yield comes with its 95 % Wilson interval (the pass count is
binomial). Model-validity checks (``model_checks``: does the first-order
model hold for the part?) are counted the same way, as a ``share`` of the
parts, apart from the specs: they are in neither the yield nor
``fails_most``. The attribution (which tolerance drives the yield) compares, on
the first ``attribution_devices`` parts, the pass count with each variation
source left at its nominal against the pass count with all of them: a
paired comparison whose gain has a 95 % interval; a source is named only
when its interval lies above zero, beside the sources it cannot be told
apart from.
"""

import math

from gyro_emulator import plotting
from gyro_emulator.analysis.fleet.engine import add_counts, metric_names, temperature_label
from gyro_emulator.analysis.fleet.sampling import BLOCK_DEVICES
import numpy as np
from scipy.stats import binomtest

#: Quantile levels of the summary, %.
LEVELS = (1.0, 5.0, 50.0, 95.0, 99.0)


def _merged_counts(results):
    total = {}
    for result in results:
        add_counts(total, result['counts'])
    return total


def sample_of(results):
    """Join the metrics of the quantile blocks in device order (valid parts only)."""
    parts = sorted((b, s) for r in results for b, s in r['sample'])
    if not parts:
        return {}
    joined = {name: np.concatenate([s[name] for _, s in parts], axis=-1)
              for name in parts[0][1]}
    valid = joined.pop('valid')
    return {name: arr[..., valid] for name, arr in joined.items()}


def _quantiles(config, sample):
    out = {}
    for name in metric_names(config):
        values = sample[name]
        out[name] = ({f'{q:g}%': float(v) for q, v in zip(LEVELS, np.percentile(values, LEVELS))}
                     if values.size else None)
    for row, temp in zip(sample.get('sf_ratio', ()), config.temperatures_c):
        key = 'sf_error_pct_at_' + temperature_label(temp)
        out[key] = {f'{q:g}%': float(v) for q, v in zip(
            LEVELS, np.percentile(100.0 * (row - 1.0), LEVELS))} if row.size else None
    return out


def wilson_interval(passed, n):
    """
    95 % Wilson score interval [low, high] of a yield ``passed / n`` (Wilson 1927).

    It keeps its coverage near 95 % for small fleets and yields near 0 or 1,
    where p +- z sqrt(p (1 - p) / n) does not (Brown, Cai and DasGupta 2001).
    The parts are independent draws, so the pass count is binomial; the
    interval is scipy's ``binomtest(passed, n).proportion_ci(method='wilson')``.
    """
    if n <= 0:
        return [None, None]
    ci = binomtest(passed, n).proportion_ci(confidence_level=0.95, method='wilson')
    return [float(ci.low), float(ci.high)]


#: Two-sided 95 % quantile of the standard normal.
Z95 = 1.959963984540054


def paired_gain(diff, flips, n):
    """
    Return a paired gain ``diff / n`` and the half-width of its 95 % interval.

    Removing a source changes each of the n parts' verdicts by d_i in
    {-1, 0, +1}; ``flips`` parts change. The gain g = mean(d_i) has variance
    (flips / n - g^2) / n (the paired, McNemar-type comparison: the parts
    are the same draws with and without the source). The half-width is at
    least 3 / n: no change in n parts still allows a rate of 3 / n at 95 %
    (the rule of three), where the normal approximation says 0.
    """
    gain = diff / n
    std_err = math.sqrt(max(flips / n - gain * gain, 0.0) / n)
    return gain, max(Z95 * std_err, 3.0 / n)


def _leader(order, gain_of):
    """
    Return the first source of ``order`` if its gain is established, and its rivals.

    Established: the 95 % interval of its gain lies above zero. Rivals: the
    sources whose gain it does not beat by more than the two half-widths
    together (at least as wide as the paired difference's interval), so
    these parts cannot tell them apart from it.
    """
    if not order:
        return None, []
    gain, (low, _) = gain_of(order[0])
    if low <= 0.0:
        return None, []
    rivals = []
    for source in order[1:]:
        other, (_, high) = gain_of(source)
        if gain - other <= (gain - low) + (high - other):
            rivals.append(source)
    return order[0], rivals


def _source_gains(entry, base, n):
    """Gain and 95 % interval of one source's removal, overall and per spec."""
    gain, half = paired_gain(entry['pass'] - base['pass'], entry['flips'], n)
    per_spec = {m: paired_gain(entry['spec_pass'][m] - base['spec_pass'][m],
                               entry['spec_flips'][m], n) for m in base['spec_pass']}
    return {'yield_without': entry['pass'] / n,
            'gain': gain, 'gain_ci95': [gain - half, gain + half],
            'spec_gain': {m: g for m, (g, _) in per_spec.items()},
            'spec_gain_ci95': {m: [g - h, g + h] for m, (g, h) in per_spec.items()}}


def _attribution(config, attribution):
    """
    Rank the sources by the yield their removal gains, with 95 % intervals.

    A source is named (``drives_the_yield``, ``spec_driver``) only when its
    gain's interval lies above zero, and with the sources these parts
    cannot tell apart from it (``indistinguishable_from``,
    ``spec_driver_indistinguishable_from``).
    """
    if attribution is None:
        return None
    n = attribution['devices']
    base = attribution['all']
    sources = {s: _source_gains(attribution[s], base, n) for s in config.sources()}
    ranked = sorted(sources, key=lambda s: -sources[s]['gain'])
    top, rivals = _leader(ranked, lambda s: (sources[s]['gain'], sources[s]['gain_ci95']))
    drivers, spec_rivals = {}, {}
    for metric in base['spec_pass']:
        order = sorted(sources, key=lambda s: -sources[s]['spec_gain'][metric])
        drivers[metric], spec_rivals[metric] = _leader(
            order, lambda s: (sources[s]['spec_gain'][metric],
                              sources[s]['spec_gain_ci95'][metric]))
    return {'devices': n, 'yield_all': base['pass'] / n, 'sources': sources,
            'ranking': ranked, 'drives_the_yield': top, 'indistinguishable_from': rivals,
            'spec_driver': drivers, 'spec_driver_indistinguishable_from': spec_rivals}


def summary(job, results, run):
    """Return the summary of a run (written as ``summary.json``)."""
    config = job.config
    counts = _merged_counts(results)
    n = counts['devices']
    specs = {spec.metric: _bounded(spec, counts['spec_pass'][spec.metric], n, 'yield')
             for spec in config.specs}
    worst = min(specs, key=lambda m: specs[m]['pass']) if specs else None
    if worst is not None and specs[worst]['pass'] == n:
        worst = None                    # no part fails a spec: none fails most
    attribution = next((r['attribution'] for r in results if r['attribution']), None)
    sample = sample_of(results)
    cpu = sum(r['cpu_s'] for r in results)
    checks = {'model_checks': {spec.metric: _bounded(spec, counts['check_pass'][spec.metric],
                                                     n, 'share')
                               for spec in config.model_checks}} if config.model_checks else {}
    return {
        'devices': n, 'seed': job.seed, 'block_devices': BLOCK_DEVICES,
        'config': config.source, 'temperatures_c': list(config.temperatures_c),
        'calibration_temp_c': config.calibration_temp_c,
        'varied': list(config.varied), 'invalid_policy': config.invalid,
        'valid': n - counts['invalid'], 'invalid': counts['invalid'],
        'clipped': counts['clipped'],
        'yield': counts['pass'] / n, 'yield_ci95': wilson_interval(counts['pass'], n),
        'pass': counts['pass'], 'specs': specs,
        'fails_most': worst,
        **checks,
        'quantile_devices': int(sample['f_drive_hz'].size) if sample else 0,
        'quantiles': _quantiles(config, sample) if sample else {},
        'attribution': _attribution(config, attribution),
        'sensor_runs': next((r['sensor_runs'] for r in results if r['sensor_runs']), []),
        'run': dict(run, cpu_s=cpu, devices_per_s=n / run['wall_s'] if run['wall_s'] else None,
                    devices_per_cpu_s=n / cpu if cpu else None),
    }


def _bounded(spec, passed, n, name):
    """Return a spec's (``yield``) or a model check's (``share``) entry."""
    return {'limits': {'min': None if spec.absolute else _finite(spec.low),
                       'max': _finite(spec.high), 'absolute': spec.absolute},
            'pass': passed, name: passed / n, name + '_ci95': wilson_interval(passed, n)}


def _finite(value):
    return float(value) if np.isfinite(value) else None


def _limits(ax, spec, vertical=True):
    if spec is None:
        return
    lines = [spec.high] + ([-spec.high] if spec.absolute else [spec.low])
    label = 'spec'
    for value in lines:
        if np.isfinite(value):
            (ax.axvline if vertical else ax.axhline)(value, color='k', ls='--', lw=1,
                                                     label=label)
            label = None


def _spec(config, metric):
    return next((s for s in config.specs if s.metric == metric), None)


def plot_envelope(config, sample, path):
    """SF(T) / SF(T_cal) - 1 over the grid: 5, 50 and 95 % of the parts."""
    plt = plotting.pyplot()
    fig, ax = plt.subplots(figsize=(6, 4))
    temps = np.array(config.temperatures_c)
    err = 100.0 * (sample['sf_ratio'] - 1.0)
    lo, mid, hi = np.percentile(err, [5.0, 50.0, 95.0], axis=1)
    ax.fill_between(temps, lo, hi, alpha=0.3, label='5-95 %')
    ax.plot(temps, mid, 'o-', label='median')
    spec = _spec(config, 'sf_error_pct')
    if spec is not None:
        _limits(ax, spec, vertical=False)
    plotting.label(ax, 'temperature, C', 'SF error vs calibration, %',
                   f'Scale factor over temperature ({err.shape[1]} parts)')
    plotting.save(fig, path)


def _histogram_bins(values, bins=100):
    """
    Return (bins, range) for ``np.histogram`` of ``values``.

    A metric the fleet does not move (a spec blind to every tolerance) is
    equal to rounding: its range is too narrow for 100 finite bins, so it
    gets one bin on a range widened around its value.
    """
    if values.size == 0:
        return bins, None
    low, high = float(values.min()), float(values.max())
    scale = max(abs(low), abs(high))
    if high - low > 1e-9 * scale and high - low > 1e-300:
        return bins, None
    pad = max(1e-6 * scale, 1e-12)
    return 1, (low - pad, high + pad)


def plot_histogram(config, sample, metric, path, title, driver=None):
    """
    Histogram of a metric over the sample, with the spec limits.

    With a ``driver`` parameter, a second panel shows the metric against it.
    """
    plt = plotting.pyplot()
    column = sample.get('param:' + str(driver))
    fig, axes = plt.subplots(1, 2 if column is not None else 1,
                             figsize=(10 if column is not None else 6, 4), squeeze=False)
    values = sample[metric]
    ax = axes[0, 0]
    finite = values[np.isfinite(values)]
    bins, span = _histogram_bins(finite)
    counts, edges = np.histogram(finite, bins=bins, range=span)
    # One artist, not 100 bars: the legend's 'best' placement tests each (2x faster).
    ax.stairs(counts, edges, fill=True, alpha=0.8, label=f'{values.size} parts')
    _limits(ax, _spec(config, metric))
    plotting.label(ax, metric, 'parts', title)
    if column is not None:
        ax = axes[0, 1]
        ax.hexbin(column, values, gridsize=60, bins='log', mincnt=1, cmap='Blues')
        _limits(ax, _spec(config, metric), vertical=False)
        plotting.label(ax, driver, metric, f'{metric} against its driver')
    plotting.save(fig, path)


def plot_yield(summary, path):
    """Yield per spec and overall."""
    plt = plotting.pyplot()
    names = list(summary['specs']) + ['all specs']
    entries = list(summary['specs'].values()) + [summary]
    values = [e['yield'] for e in entries]
    spread = np.array([[e['yield'] - e['yield_ci95'][0], e['yield_ci95'][1] - e['yield']]
                       for e in entries]).T
    fig, ax = plt.subplots(figsize=(6, 0.5 * len(names) + 1.5))
    ax.barh(names, [100.0 * v for v in values], color=['C0'] * (len(names) - 1) + ['C1'],
            xerr=100.0 * spread, capsize=3, label='yield (95 % interval)')
    for y, v in enumerate(values):
        ax.text(100.0 * v, y, f' {100.0 * v:.1f} %', va='center', fontsize=8)
    ax.set_xlim(0, 110)
    plotting.label(ax, 'yield, %', '', f'Yield of {summary["devices"]:,} parts')
    plotting.save(fig, path)


def plots(job, results, summary, out_dir):
    """Write the four plots of a run into ``out_dir``."""
    config = job.config
    sample = sample_of(results)
    if not sample or not sample['f_drive_hz'].size:
        return
    plot_envelope(config, sample, f'{out_dir}/sf_envelope.png')
    plot_histogram(config, sample, 'split_hz', f'{out_dir}/split_histogram.png',
                   'Drive-sense split')
    if summary['specs']:
        plot_yield(summary, f'{out_dir}/yield_per_spec.png')
    worst = summary['fails_most']
    if worst is not None:
        driver = (summary['attribution'] or {}).get('spec_driver', {}).get(worst)
        plot_histogram(config, sample, worst, f'{out_dir}/fails_most.png',
                       f'Fails most: {worst}\n{100 * summary["specs"][worst]["yield"]:.1f} % '
                       f'pass; driven by {driver}', driver)
