"""
The twin chain on a measured log: from the log to an emulator that behaves like it.

  python bench/twin_chain.py [LOG.csv] [--axis x] [--out-dir DIR] [--img-dir docs/img]

Runs the commands a user runs (each a ``gyro-emulator`` subprocess)::

  calibrate noise LOG --format preset --out twin.yaml
  diagnose LOG --axis x --config twin.yaml --write-config part.yaml --noise --json d1.json
  diagnose LOG --axis x --config part.yaml --json d2.json
  simulate --config part.yaml --profile LOG --axis x --out emulated.csv
  simulate --config twin.yaml --profile LOG --axis x --out twin.csv

then prints the figures (held-out RMSE before and after with their 95 %
intervals, the second run's verdict, the mean difference between the
measured and the emulated output per 0.5 K temperature bin against the
standard error of the bin means, the Allan deviation of the measured and
emulated outputs at the shortest taus, where the part's output filter
shapes it) and draws the measured and emulated
outputs against temperature and time side by side (samples as dots, the
mean of each stretch between the log's gaps as markers). Default LOG: the
LSM6DSM chamber log (x axis) of ``../shared/data/real``.
"""

import argparse
import json
import os
import subprocess
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
LOG = os.path.join(os.path.dirname(ROOT), 'shared', 'data', 'real', 'lsm6dsm_thermal_chamber',
                   'lsm6dsm_tvc_x.csv')
#: Temperature bin of the mean-difference figure, K.
BIN_K = 0.5


def cli(*args):
    """Run ``gyro-emulator ARGS``; stop with its stderr on failure."""
    proc = subprocess.run([sys.executable, '-m', 'gyro_emulator.cli', *args], cwd=ROOT,
                          capture_output=True, text=True,
                          env=dict(os.environ, MPLBACKEND='Agg'))
    if proc.returncode != 0:
        sys.exit(f'gyro-emulator {" ".join(args)} failed:\n{proc.stderr}')
    return proc.stdout


def chain(log, axis, out):
    """Run the chain; return the paths it wrote."""
    p = {name: os.path.join(out, name) for name in (
        'twin.yaml', 'part.yaml', 'd1.json', 'd2.json', 'emulated.csv', 'twin.csv')}
    cli('calibrate', 'noise', log, '--format', 'preset', '--out', p['twin.yaml'])
    cli('diagnose', log, '--axis', axis, '--config', p['twin.yaml'], '--write-config',
        p['part.yaml'], '--noise', '--overwrite', '--json', p['d1.json'])
    cli('diagnose', log, '--axis', axis, '--config', p['part.yaml'], '--json', p['d2.json'])
    for config, csv in (('part.yaml', 'emulated.csv'), ('twin.yaml', 'twin.csv')):
        cli('simulate', '--config', p[config], '--profile', log, '--axis', axis, '--out',
            p[csv], '--overwrite')
    return p


def read_csv(path, names):
    """Return the named columns of a CSV (header row), as arrays."""
    data = np.genfromtxt(path, delimiter=',', names=True)
    return [np.asarray(data[n], dtype=float) for n in names]


def binned_difference(temp_c, measured, emulated):
    """Per temperature bin: centre, mean difference, its standard error (both outputs' noise)."""
    edges = np.arange(np.floor(temp_c.min() / BIN_K) * BIN_K, temp_c.max() + BIN_K, BIN_K)
    rows = []
    for lo in edges[:-1]:
        m = (temp_c >= lo) & (temp_c < lo + BIN_K)
        if m.sum() < 20:
            continue
        d = measured[m] - emulated[m]
        se = np.sqrt(np.var(measured[m]) / m.sum() + np.var(emulated[m]) / m.sum())
        rows.append((lo + BIN_K / 2, float(d.mean()), float(se)))
    return np.array(rows)


def short_tau_adev(log, emulated, twin, axis, count=3):
    """Return the shortest taus and the Allan deviation there: measured, emulated, twin."""
    from gyro_emulator.analysis.calibrate.noise import calibrate_noise
    from gyro_emulator.recording.record import load_record

    out = []
    for path, name in ((log, None), (emulated, axis), (twin, axis)):
        record = load_record(path)
        result = calibrate_noise(record, axes=None if name is None else [name]).axes[0].result
        out.append(result.adev[:count])
    return result.taus_s[:count], out


def burst_means(t, *columns, gap_s=10.0):
    """Return the mean of each column over each stretch of samples between gaps > ``gap_s``."""
    edges = np.r_[0, np.flatnonzero(np.diff(t) > gap_s) + 1, len(t)]
    return [np.array([c[i:j].mean() for i, j in zip(edges[:-1], edges[1:])]) for c in columns]


def plot(t, temp, measured, emulated, twin, path, title):
    """Measured and emulated output against temperature and against time, side by side."""
    from gyro_emulator import plotting

    plt = plotting.pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.5))
    deg = 180.0 / np.pi
    means = burst_means(t, t / 3600.0, temp, measured * deg, emulated * deg, twin * deg)
    for ax, x, xm in ((a, temp, means[1]), (b, t / 3600.0, means[0])):
        ax.plot(x, twin * deg, ',', color='0.75')
        ax.plot(x, measured * deg, ',', color='C0', alpha=0.5)
        ax.plot(x, emulated * deg, ',', color='C1', alpha=0.5)
        ax.plot(xm, means[4], 's', color='0.5', ms=4, label='twin.yaml (noise only): means')
        ax.plot(xm, means[2], 'o', color='C0', mfc='none', ms=7, label='measured: means')
        ax.plot(xm, means[3], 'x', color='C1', ms=6, label='emulated (part.yaml): means')
    a.invert_xaxis()
    lo, hi = np.percentile(np.r_[measured, emulated, twin] * deg, [0.05, 99.95])
    for ax in (a, b):
        ax.set_ylim(lo - 0.05 * (hi - lo), hi + 0.05 * (hi - lo))
    plotting.label(a, 'temperature, C (axis reversed: the chamber cools, time runs left to right)',
                   'gyro output, deg/s', title)
    plotting.label(b, 'time, h', 'gyro output, deg/s', title)
    plotting.save(fig, path)


def main(argv=None):
    """Run the chain on a log, print the figures, draw the plots."""
    from gyro_emulator.sensor.config import load_sensor_config

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('log', nargs='?', default=LOG)
    parser.add_argument('--axis', default='x', choices=('x', 'y', 'z'))
    parser.add_argument('--out-dir', default=os.path.join(ROOT, 'build', 'twin_chain'))
    parser.add_argument('--img-dir', default=os.path.join(ROOT, 'docs', 'img'))
    parser.add_argument('--name', default='twin_lsm6dsm_x')
    args = parser.parse_args(argv)
    os.makedirs(args.out_dir, exist_ok=True)
    p = chain(args.log, args.axis, args.out_dir)
    d1, d2 = (json.load(open(p[k], encoding='utf-8')) for k in ('d1.json', 'd2.json'))
    ext = d1['selected'][-1]
    print(f'first run  (config twin.yaml): baseline held-out RMSE '
          f"{d1['baseline']['rmse_rad_s']:.4g} rad/s; verdict {d1['verdict']}; causes "
          f"{[e['effect'] for e in d1['selected']]}")
    print(f"  claimed for the extension: RMSE {ext['rmse_rad_s']:.4g} rad/s, 95 % "
          f"[{ext['rmse_interval_rad_s'][0]:.4g}, {ext['rmse_interval_rad_s'][1]:.4g}]; gain "
          f"{100 * ext['gain']:.2f} % [{100 * ext['gain_interval'][0]:.2f}, "
          f"{100 * ext['gain_interval'][1]:.2f}]")
    own = d2['baseline']['rmse_rad_s']
    lo, hi = ext['rmse_interval_rad_s']
    print(f"second run (config part.yaml): held-out RMSE of the emulator's output {own:.4g} "
          f"rad/s ({'within' if lo <= own <= hi else 'OUTSIDE'} the interval; gain "
          f"{100 * (1 - own / d1['baseline']['rmse_rad_s']):.2f} %); verdict {d2['verdict']}; "
          f"causes {[e['effect'] for e in d2['selected']]}")
    col = f'gyro_{args.axis}_rad_s'
    t, temp, emulated = read_csv(p['emulated.csv'], ('time_s', 'temp_c', col))
    twin, = read_csv(p['twin.csv'], (col,))
    measured, = read_csv(args.log, ('gyro_rad_s',))
    rows = binned_difference(temp, measured, emulated)
    z = rows[:, 1] / rows[:, 2]
    print(f'measured - emulated per {BIN_K:g} K bin ({len(rows)} bins): mean differences '
          f'{1e3 * np.abs(rows[:, 1]).max():.3g} mrad/s at most, rms z '
          f'{np.sqrt(np.mean(z ** 2)):.2f} (|z| max {np.abs(z).max():.2f}; 1 = the noise of '
          'the bin means)')
    print(f'  whole record: mean {1e3 * np.mean(measured - emulated):+.3g} mrad/s; std measured '
          f'{1e3 * np.std(measured):.4g}, emulated {1e3 * np.std(emulated):.4g} mrad/s; '
          f'twin.yaml alone: mean - measured {1e3 * np.mean(twin - measured):+.3g} mrad/s, '
          f'rms {1e3 * np.sqrt(np.mean((twin - measured) ** 2)):.3g} mrad/s vs part.yaml '
          f'{1e3 * np.sqrt(np.mean((emulated - measured) ** 2)):.3g}')
    step = np.diff(t) < 1.5 * np.median(np.diff(t))        # neighbours, not across a gap
    for label, values in (('measured', measured), ('emulated', emulated)):
        print(f'  {label}: sample-to-sample sigma (first differences / sqrt 2, across no gap) '
              f'{1e3 * np.std(np.diff(values)[step]) / np.sqrt(2):.4g} mrad/s')
    taus, (m_adev, e_adev, t_adev) = short_tau_adev(args.log, p['emulated.csv'], p['twin.csv'],
                                                    args.axis)
    part = load_sensor_config(p['part.yaml'])
    lowpass = (f'{part.output_filter_hz:.4g} Hz, order {part.output_filter_order}'
               if part.terms.output_filter and part.output_filter_hz > 0.0 else 'none')
    print(f'Allan deviation at the shortest taus (output filter of part.yaml: {lowpass}):')
    for k, tau in enumerate(taus):
        print(f'  tau {tau:.3g} s: measured {1e3 * m_adev[k]:.4g} mrad/s; emulated '
              f'{1e3 * e_adev[k]:.4g} ({100 * (e_adev[k] / m_adev[k] - 1):+.1f} %); twin.yaml '
              f'{1e3 * t_adev[k]:.4g} ({100 * (t_adev[k] / m_adev[k] - 1):+.1f} %)')
    os.makedirs(args.img_dir, exist_ok=True)
    path = os.path.join(args.img_dir, f'{args.name}.png')
    plot(t, temp, measured, emulated, twin, path,
         f'{os.path.basename(args.log)}: measured and emulated')
    print(f'wrote {path}')


if __name__ == '__main__':
    main()
