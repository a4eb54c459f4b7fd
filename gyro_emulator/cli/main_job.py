"""
The README's main job (``./dev.sh main``): the paper's validation test, live.

1. Reproduce the paper (Table 1, Fig 5, Fig 6; skip with ``--skip-paper``).
2. Start the emulator node (``python -m gyro_emulator.ros.node``) with the
   profile's ``node_parameters``, and the bag recorder when it is installed,
   on a private ROS domain restricted to this machine.
3. Wait for the node itself (its subscriptions and its ``imu/data_raw``
   publisher, not the recorder's) and its first Imu sample, however long
   its start takes on a loaded machine, saying every 10 s what it still
   waits for; give up after :data:`NODE_START_TIMEOUT_S`, or at once when
   the node process ends.
4. Play ``config/scenario_paper_validation.yaml`` (0, 10, 20, 40 RPM at 25
   to 85 C, time-compressed to 32 s) against the node and print, per step,
   commanded vs measured rate and the error in deg/s, beside the error the
   first-order physics predicts at the measured die temperature (Fig 6). A
   step without samples is an error that names it.
5. Stop everything with SIGINT (every child is killed on the way out) and
   say the exit status and why in one line: 0 every step measured, 1 a
   step without samples or no node, 2 bad input, 130 interrupted (Ctrl-C).
"""

import argparse
import importlib.util
import math
import os
import signal
import subprocess
import sys
import time

from gyro_emulator import atomic, cli
from gyro_emulator.emulation import scenario
from gyro_emulator.physics import first_order, presets
import yaml

#: Longest wait for the node to run (on the graph and its first sample), s.
NODE_START_TIMEOUT_S = 300.0
#: How often the wait for the node is reported, s.
WAITING_LINE_S = 10.0
STOP_TIMEOUT_S = 10.0


def build_parser():
    """Return the main job's argument parser."""
    parser = argparse.ArgumentParser(
        prog='./dev.sh main', description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--skip-paper', action='store_true',
                        help='do not reproduce Table 1 / Fig 5 / Fig 6 first')
    parser.add_argument('--paper-only', action='store_true',
                        help='only reproduce the paper (the previous main job)')
    parser.add_argument('--profile', default=None, metavar='YAML',
                        help='scenario profile (default: the paper validation test)')
    parser.add_argument('--seed', type=int, default=0, help='node seed (default: 0)')
    parser.add_argument('--sensor-config', default=None, metavar='NAME|YAML',
                        help='sensor preset or YAML for the node (default: the '
                             "profile's, else paper)")
    parser.add_argument('--out-dir', default='out/main', metavar='DIR',
                        help='node log, bag and summary.json (default: %(default)s)')
    parser.add_argument('--no-record', action='store_true',
                        help='do not record a bag even when the recorder exists')
    return parser


def _ros_environment():
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.setdefault('ROS_DOMAIN_ID', str(10 + os.getpid() % 90))
    env['PYTHONUNBUFFERED'] = '1'
    return env


def _write_params(path, node_parameters, seed, sensor_config=None):
    values = dict(node_parameters)
    values['seed'] = seed
    if sensor_config:
        values['sensor_config'] = sensor_config
    with atomic.open_atomic(path) as handle:
        yaml.safe_dump({'/**': {'ros__parameters': values}}, handle, sort_keys=False)


def _stop(proc, name):
    if proc is None or proc.poll() is not None:
        return
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(STOP_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        print(f'main: {name} did not stop on SIGINT; killing it', file=sys.stderr)
        proc.kill()
        proc.wait()


def physics_error_deg_s(rate_rad_s, die_temp_c):
    """Error the first-order physics predicts for the paper device (Fig 6), deg/s."""
    if not math.isfinite(die_temp_c):
        return float('nan')
    apparent = first_order.apparent_rate_rad_s(presets.PAPER_DEVICE, rate_rad_s, die_temp_c)
    return math.degrees(float(apparent) - rate_rad_s)


def format_table(profile, results):
    """Return the summary table of a scenario's results with the physics prediction column."""
    lines = scenario.format_summary(results).split('\n')
    lines[0] += f' {"physics err":>11}'
    lines[1] = '-' * len(lines[0])
    for i, r in enumerate(results):
        rate = profile.rate_along_axis_rad_s(r.step)
        error = physics_error_deg_s(rate, r.die_temp_c)
        lines[i + 2] += f' {error:>+11.3f}' if math.isfinite(error) else f' {"-":>11}'
    return '\n'.join(lines)


def samples_line(imu, elapsed_s):
    """
    Say how many Imu samples came, over what span of their stamps, at what rate.

    The rate is (n - 1) over the span from the first stamp to the last; the
    wall time beside it also holds the node's start-up and the wait for
    its first sample, so n over it is not the output rate.
    """
    if len(imu) < 2:
        return f'{len(imu)} Imu samples ({elapsed_s:.1f} s wall with the node start-up)'
    span_s = (imu[-1][0] - imu[0][0]) / 1e9
    rate = (len(imu) - 1) / span_s if span_s > 0 else float('nan')
    return (f'{len(imu)} Imu samples over {span_s:.1f} s of stamps ({rate:.1f} Hz); '
            f'{elapsed_s:.1f} s wall with the node start-up')


def _watch(node):
    """Return play's ``waiting``: a line every WAITING_LINE_S; RuntimeError once the node ended."""
    from gyro_emulator.ros.scenario import waiting_printer
    say = waiting_printer('main', NODE_START_TIMEOUT_S, WAITING_LINE_S)

    def waiting(elapsed_s, missing):
        code = node.poll()
        if code is not None:
            raise RuntimeError(f'the node exited with status {code} after {elapsed_s:.0f} s, '
                               'before it ran')
        say(elapsed_s, missing)
    return waiting


def run_scenario(opts):
    """Start node (+ recorder), play the profile, print and save the summary; (status, why)."""
    # rclpy (0.2 s) only for the scenario part: `--paper-only` loads no ROS.
    from gyro_emulator.ros.scenario import play

    profile = scenario.load_scenario(opts.profile)
    os.makedirs(opts.out_dir, exist_ok=True)
    env = _ros_environment()
    os.environ.update({k: env[k] for k in ('ROS_AUTOMATIC_DISCOVERY_RANGE',
                                           'ROS_DOMAIN_ID')})
    params_path = os.path.join(opts.out_dir, 'node_params.yaml')
    _write_params(params_path, profile.node_parameters, opts.seed, opts.sensor_config)
    node_log = os.path.join(opts.out_dir, 'node.log')
    print(f'\n== scenario {profile.name}: {len(profile.steps)} steps, '
          f'{profile.duration_s:g} s, against the emulator node '
          f'(ROS_DOMAIN_ID={env["ROS_DOMAIN_ID"]}, localhost only)', flush=True)
    node = recorder = None
    # The node's log streams as it runs (not staged: what was written is kept).
    with open(node_log, 'w', encoding='utf-8') as log:
        try:
            node = subprocess.Popen(
                [sys.executable, '-m', 'gyro_emulator.ros.node', '--ros-args',
                 '--params-file', params_path], env=env, stdout=log,
                stderr=subprocess.STDOUT)
            record = not opts.no_record and importlib.util.find_spec(
                'gyro_emulator.ros.recorder') is not None
            if record:
                bag_dir = os.path.join(opts.out_dir, 'bag')
                recorder = subprocess.Popen(
                    [sys.executable, '-m', 'gyro_emulator.ros.recorder', '-o', bag_dir,
                     '--overwrite'], env=env, stdout=log, stderr=subprocess.STDOUT)
            started = time.monotonic()

            def progress(index, step):
                print(f'  step {index + 1:>2}/{len(profile.steps)}: {step.label:>8} at '
                      f'{step.temp_start_c:5.1f} C', flush=True)

            player = play(profile, collect=True, wait_s=NODE_START_TIMEOUT_S,
                          progress=progress, waiting=_watch(node))
            elapsed = time.monotonic() - started
        except RuntimeError as exc:
            print(f'main: {exc}; node log: {node_log}', file=sys.stderr)
            return 1, 'the emulator node did not run (above)'
        finally:
            _stop(recorder, 'recorder')
            _stop(node, 'node')
    results = player.results()
    if player.interrupted:
        print(f'\nmain: the scenario was {player.interrupted}')
    print(f'\nCommanded vs measured along {list(profile.axis)} (mean after each '
          f"step's settle time; physics err = Fig 6 first-order prediction at T_die):")
    print(format_table(profile, results))
    measured = [r for r in results if r.samples]
    line = samples_line(player.imu, elapsed)
    if measured:
        worst = max(measured, key=lambda r: abs(r.error_deg_s))
        line = (f'largest |error|: {worst.error_deg_s:+.3f} deg/s at {worst.step.label}, '
                f'{worst.step.temp_start_c:g} C; {line}')
    print(line)
    doc = scenario.results_json(profile, results, player.interrupted)
    for row, r in zip(doc['steps'], results):
        row['physics_error_deg_s'] = scenario.number_or_none(physics_error_deg_s(
            profile.rate_along_axis_rad_s(r.step), r.die_temp_c))
    summary = os.path.join(opts.out_dir, 'summary.json')
    atomic.write_json(summary, doc, indent=1)
    print(f'wrote {summary}; node log {node_log}'
          + (f'; bag {os.path.join(opts.out_dir, "bag")}' if recorder else ''))
    return verdict(results, player.interrupted, len(player.imu), node_log)


def verdict(results, interrupted, imu_count, node_log):
    """
    Return the scenario's (exit status, why): 130 interrupted, 1 a step without samples, 0.

    An interrupted scenario is 130 even when every step got a sample (a
    Ctrl-C late in the last step): it did not run to its end.
    """
    missing = scenario.unmeasured(results)
    if missing:
        print(f'main: error: {missing}', file=sys.stderr)
    if interrupted:
        return 130, f'the scenario was {interrupted}'
    if missing:
        return 1, f'{missing}; node log {node_log}'
    return 0, f'all {len(results)} steps measured ({imu_count} Imu samples)'


def _run(opts):
    """Run the paper part and the scenario; return (exit status, why in a few words)."""
    if not opts.skip_paper:
        print('== paper reproduction', flush=True)
        status = cli.main(['paper', '--json', 'out/paper/paper.json', '--overwrite'])
        if status:
            return status, 'the paper reproduction failed (above)'
        if opts.paper_only:
            return 0, 'the paper reproduced (--paper-only)'
    try:
        return run_scenario(opts)
    except (ValueError, OSError) as exc:
        print(f'main: error: {exc}', file=sys.stderr)
        return 2, 'bad input or a file error (above)'
    except KeyboardInterrupt:
        print('main: interrupted', file=sys.stderr)
        return 130, 'interrupted'


def main(argv=None):
    """Run the main job; return the exit status, said in its last line."""
    opts = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    status, why = _run(opts)
    print(f'main: exit status {status}: {why}', file=sys.stderr if status else sys.stdout,
          flush=True)
    return status


if __name__ == '__main__':
    sys.exit(main())
