"""
Allan deviation of a gyro record, with the N (ARW), B and K noise fit.

Reads a CSV with ``time_s`` and ``gyro_rad_s`` or ``gyro_{x,y,z}_rad_s``
(``.csv.gz`` too; our ``simulate`` output and measured logs alike), or a
rosbag2 MCAP bag (directory or ``.mcap``) with a sensor_msgs/Imu topic. The
samples are taken as uniformly spaced at the median time step (repeated
timestamps of a jittery logger are accepted); a step longer than
``--gap-factor`` times the median is a gap, and the Allan variance is then
pooled over the contiguous segments.

Units: N (angle random walk) in deg/sqrt(h), B (bias instability, Allan floor
0.664 B) in deg/h, K (rate random walk) in deg/h/sqrt(h) (IEEE Std 952).
"""

import os

from gyro_emulator.cli.jsonout import write_json

HELP = 'overlapping Allan deviation of a gyro record and its N, B, K fit'


def add_arguments(parser):
    """Register the ``allan`` options."""
    parser.add_argument('file', metavar='FILE',
                        help='CSV (time_s + gyro_rad_s or gyro_{x,y,z}_rad_s; .gz ok) '
                             'or an MCAP bag')
    parser.add_argument('--axis', choices=('x', 'y', 'z'), default=None,
                        help='axis of a 3-axis record (default: x)')
    parser.add_argument('--topic', default=None,
                        help='Imu topic of a bag (default: the only Imu topic)')
    parser.add_argument('--json', metavar='OUT', help='write the results as JSON')
    parser.add_argument('--plot', metavar='PNG', help='write the Allan deviation plot')
    parser.add_argument('--gap-factor', type=float, default=3.0, metavar='F',
                        help='a time step over F median steps is a gap '
                             '(default: %(default)s)')
    parser.add_argument('--max-tau-fraction', type=float, default=0.25, metavar='F',
                        help='longest tau as a fraction of the longest segment '
                             '(default: %(default)s)')


def _read_bag(path, axis, topic):
    from gyro_emulator.recording import bag

    reader = bag.BagReader(path, tolerant=True)
    imu = [name for name, info in reader.topics.items()
           if info.type_name == 'sensor_msgs/msg/Imu']
    if topic is None:
        if len(imu) != 1:
            raise ValueError(f'{path}: {len(imu)} sensor_msgs/Imu topics '
                             f'({", ".join(imu) or "none"}): choose one with --topic')
        topic = imu[0]
    elif topic not in imu:
        raise ValueError(f'{path}: topic {topic!r} is not a sensor_msgs/Imu topic; '
                         f'Imu topics: {", ".join(imu) or "none"}')
    arrays = reader.read_arrays(topic)
    index = 'xyz'.index(axis or 'x')
    time_s = arrays.stamp_ns * 1e-9
    return time_s - time_s[0], arrays.field('angular_velocity')[:, index], \
        f'{topic} angular_velocity.{axis or "x"}'


def analyse(path, axis=None, topic=None, max_tau_fraction=0.25, gap_factor=3.0):
    """Return the JSON-ready analysis of one record (see the module docstring)."""
    import numpy as np

    from gyro_emulator import units
    from gyro_emulator.analysis import allan
    from gyro_emulator.recording import csvio

    if os.path.isdir(path) or str(path).endswith('.mcap'):
        time_s, rate, column = _read_bag(path, axis, topic)
        csvio.check_increasing(time_s, f'{path}: header stamps', strict=False)
    else:
        time_s, rate, column = csvio.read_gyro_csv(path, axis, time_order='nondecreasing')
    rate_hz, bounds = csvio.sample_rate_and_segments(time_s, gap_factor)
    segments = [rate[a:b] for a, b in bounds if b - a >= 3]
    if not segments:
        raise ValueError(f'{path}: no segment has 3 or more samples')
    longest = max(len(s) for s in segments)
    taus = allan.tau_multiples(longest, 10, max_tau_fraction) / rate_hz
    result = allan.overlapping_adev(segments, rate_hz, taus=taus)
    fit = allan.fit_noise_terms(result)
    classic = allan.classic_readings(result)
    return {
        'file': str(path), 'column': column, 'sample_rate_hz': rate_hz,
        'n_samples': result.n_samples, 'segments': len(segments),
        'repeated_timestamps': int(np.sum(np.diff(time_s) == 0.0)),
        'duration_s': float(time_s[-1] - time_s[0]),
        'arw_deg_sqrt_h': fit.arw_deg_sqrt_h,
        'bias_instability_deg_h': fit.bias_instability_deg_h,
        'rrw_deg_h_sqrt_h': fit.rrw_deg_h_sqrt_h,
        'arw_rad_s_sqrt_hz': fit.arw_rad_s_sqrt_hz,
        'bias_instability_rad_s': fit.bias_instability_rad_s,
        'rrw_rad_s_sqrt_s': fit.rrw_rad_s_sqrt_s,
        'arw_at_1s_deg_sqrt_h': float(units.rad_s_sqrt_hz_to_arw_deg_sqrt_h(
            classic['arw_at_1s'])),
        'bias_instability_min_deg_h': float(units.rad_s_to_deg_h(
            classic['bias_instability_min'])),
        'tau_at_min_s': classic['tau_min_s'],
        'taus_s': result.taus_s.tolist(), 'adev_rad_s': result.adev.tolist(),
        'adev_lo_rad_s': result.adev_lo.tolist(), 'adev_hi_rad_s': result.adev_hi.tolist(),
        'edf': result.edf.tolist(), 'ci': result.ci,
        'units': {'arw': 'deg/sqrt(h)', 'bias_instability': 'deg/h (Allan floor 0.664 B)',
                  'rrw': 'deg/h/sqrt(h)', 'adev': 'rad/s'},
    }, result, fit


def run(args):
    """Analyse the record, print the summary, write JSON and plot if asked."""
    from gyro_emulator.analysis import allan

    info, result, fit = analyse(args.file, args.axis, args.topic,
                                args.max_tau_fraction, args.gap_factor)
    print(f'{info["file"]} [{info["column"]}]: {info["n_samples"]} samples at '
          f'{info["sample_rate_hz"]:.4g} Hz, {info["duration_s"]:.1f} s, '
          f'{info["segments"]} segment(s), {info["repeated_timestamps"]} repeated '
          'timestamp(s)')
    print(f'  fit  N (ARW)              {info["arw_deg_sqrt_h"]:10.4g} deg/sqrt(h)')
    print(f'  fit  B (bias instability) {info["bias_instability_deg_h"]:10.4g} deg/h')
    print(f'  fit  K (rate random walk) {info["rrw_deg_h_sqrt_h"]:10.4g} deg/h/sqrt(h)')
    print(f'  read ADEV(1 s) sqrt(1 s)  {info["arw_at_1s_deg_sqrt_h"]:10.4g} deg/sqrt(h)')
    print(f'  read min ADEV / 0.664     {info["bias_instability_min_deg_h"]:10.4g} deg/h '
          f'at tau = {info["tau_at_min_s"]:.4g} s')
    if args.json:
        write_json(args.json, info)
    if args.plot:
        os.makedirs(os.path.dirname(os.path.abspath(args.plot)), exist_ok=True)
        allan.plot_adev(result, fit, args.plot,
                        title=f'{os.path.basename(str(args.file))} [{info["column"]}]')
        print(f'wrote {args.plot}')
    return 0
