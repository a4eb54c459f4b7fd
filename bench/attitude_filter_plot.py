"""
The node feeding attitude filters: truth against Madgwick and Mahony (``ahrs``), plotted.

    .venv/bin/python bench/attitude_filter_plot.py [--out docs/img/attitude_filters.png]

Runs a real node on sim time over the tilt-and-turn scenario of
``test/attitude_reference.py`` (the ``consumer`` preset with its noise terms
only, 100 Hz, seed 11), exactly as ``test/test_ahrs_consumers.py`` does:
``imu/data_raw`` and ``~/truth/imu`` recorded from the first message, the
gyro's turn-on bias (the first ``~/truth/bias``) removed, both filters from
their own accelerometer initialisation. Prints the roll/pitch RMS and peak
errors against the accelerometer's predicted tilt sigma and the final heading
drift against the predicted heading sigma, and plots roll, pitch and yaw.
"""

import argparse
import os
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'test'))
os.environ.setdefault('MPLBACKEND', 'Agg')


def main(argv=None):
    """Run the node, the filters and the plot; print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--out', default=os.path.join(ROOT, 'docs', 'img',
                                                      'attitude_filters.png'))
    opts = parser.parse_args(argv)
    import pathlib

    import attitude_reference as ref
    from gyro_emulator import plotting
    from gyro_emulator.sensor.config import config_yaml
    import numpy as np
    from test_ahrs_consumers import arrays, orientations, run_nodes
    from test_node import vector

    config = ref.noise_only_config()
    rates = ref.scenario_rates()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        sensor = tmp / 'noise_only.yaml'
        sensor.write_text(config_yaml(config))
        run = run_nodes(tmp, [('part', str(sensor), 11)], rates, ref.RATE_HZ)
    _, gyro, accel = arrays(run.imu['part'])
    truth = orientations(run.truth['part'])
    gyro = gyro - np.array(vector(run.bias['part'][0].vector))
    tilt = ref.tilt_sigma_deg(config)[0]
    heading = ref.heading_sigma_deg(config, len(rates) / ref.RATE_HZ)
    print(f'{len(gyro)} samples at {ref.RATE_HZ:g} Hz; predicted: tilt sigma {tilt:.4f} deg '
          f'(accelerometer noise), heading sigma {heading:.4f} deg (gyro N, B, K)')
    estimates = ref.run_filters(gyro, accel)
    t = np.arange(len(truth) - 1) / ref.RATE_HZ
    plt = plotting.pyplot()
    fig, axes = plt.subplots(3, 2, figsize=(11, 7.5), sharex=True)
    true_rpy = ref.roll_pitch_yaw_deg(truth[1:])
    for i, angle in enumerate(('roll', 'pitch', 'yaw')):
        axes[i, 0].plot(t, true_rpy[:, i], 'k', lw=2.5, label='truth (~/truth/imu)')
        for name, estimate in estimates.items():
            axes[i, 0].plot(t, ref.roll_pitch_yaw_deg(estimate[:-1])[:, i], lw=1, label=name)
            axes[i, 1].plot(t, ref.errors_deg(estimate, truth)[:, i], lw=0.8, label=name)
        bound = tilt if i < 2 else 2 * heading
        for sign in (1, -1):
            axes[i, 1].axhline(sign * bound, color='grey', ls='--', lw=0.8,
                               label=None if sign < 0 else (
                                   'sigma_a / g' if i < 2 else 'predicted 2 sigma'))
        plotting.label(axes[i, 0], 'time (s)' if i == 2 else '', f'{angle} (deg)')
        plotting.label(axes[i, 1], 'time (s)' if i == 2 else '', f'{angle} error (deg)')
    for name, estimate in estimates.items():
        error = ref.errors_deg(estimate, truth)
        rms = np.sqrt(np.mean(error[:, :2] ** 2, axis=0))
        peak = np.abs(error[:, :2]).max(axis=0)
        print(f'{name}: roll/pitch RMS {rms[0]:.4f}/{rms[1]:.4f} deg, peak {peak[0]:.4f}/'
              f'{peak[1]:.4f} deg (bounds: RMS {tilt:.4f}, peak {5 * tilt:.4f}); heading '
              f'drift {error[-1, 2]:+.4f} deg (2 sigma {2 * heading:.4f})')
    fig.suptitle('imu/data_raw into ahrs Madgwick and Mahony: tilt-and-turn, consumer noise')
    fig.tight_layout()
    plotting.save(fig, opts.out)
    print(f'wrote {opts.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
