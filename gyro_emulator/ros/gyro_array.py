"""
Redundant IMUs: N emulator nodes with per-instance presets and tolerances.

``ros2 launch gyro_emulator gyro_array.launch.py [spec:=FILE]``,
``ros2 run gyro_emulator array [FILE]`` and, without the ``ros2`` CLI,
``gyro-emulator-array [FILE]`` (or ``gyro-emulator ros run array [FILE]``) start
one node per instance of an
array spec (default ``config/gyro_array.yaml``)::

    namespace: imu_array              # the instances live under /imu_array/<name>
    parameters: {rate_hz: 400.0}      # node parameters of every instance
    tolerances:                       # 1-sigma part-to-part spread, drawn per instance
      scale_factor_error: 0.002       # ratio, added per axis to the preset's value
      turn_on_bias_rad_s: 0.001       # rad/s, per axis
      misalignment: 0.0005            # rad, each off-diagonal element
    instances:
      - {name: gyro_a, sensor_config: consumer}
      - {name: gyro_b, sensor_config: consumer}
      - {name: gyro_c, sensor_config: tactical, parameters: {seed: 7}}

Each instance is a node named ``gyro_emulator`` in namespace
``/<namespace>/<name>``, so its noise seed is derived from its own fully
qualified name (``seed: -1``, a SeedSequence of the name): the instances are
independent and each is the same on every run. Its tolerance draw comes from
a generator seeded the same way (name + ``/tolerances``), so a part keeps its
errors from run to run. An explicit ``seed`` in ``parameters`` fixes the
noise, not the part. Each instance publishes in a frame of its own,
``<name>_imu_link`` (``<name>_<frame_id>`` when the common ``parameters``
give a ``frame_id``; an instance's own ``frame_id`` is taken as it is).

This module reads the spec and builds each instance's parameters (no ROS
imports); :func:`main` runs the nodes as child processes and stops them
together on SIGINT/SIGTERM. The nodes run in a process group of their own,
so a Ctrl-C in the terminal reaches the array only, and the array passes
exactly one SIGINT to each node. A stop by signal is a normal end: exit 0
when every node stopped cleanly (a node stopped while starting up, status
130, counts as clean here); otherwise the worst node status.
"""

import argparse
import ctypes
from dataclasses import dataclass
import os
import signal
import subprocess
import sys
import tempfile
import time

from gyro_emulator.interrupts import INTERRUPTED_STATUS
from gyro_emulator.resources import config_file, read_yaml
from gyro_emulator.ros import params
from gyro_emulator.sensor import config as sensor_config
from gyro_emulator.sensor.streams import seed_from_name
import numpy as np
import yaml

DEFAULT_SPEC = 'gyro_array.yaml'
#: The frame every instance's own frame_id ends with, unless the spec names one.
DEFAULT_FRAME = 'imu_link'
#: Seconds the array waits for its nodes to end after passing a stop on (then SIGKILL).
STOP_TIMEOUT_S = 120.0
#: prctl option: the signal a child gets when its parent dies (linux/prctl.h).
PR_SET_PDEATHSIG = 1
#: Node exit statuses that mean "stopped by the signal the array passed on".
STOPPED_STATUSES = (0, INTERRUPTED_STATUS, -signal.SIGINT, -signal.SIGTERM,
                    128 + signal.SIGTERM)
#: Error terms a spec's tolerances may spread, with their unit.
TOLERANCES = {'scale_factor_error': 'ratio', 'turn_on_bias_rad_s': 'rad/s',
              'misalignment': 'rad'}


@dataclass(frozen=True)
class Instance:
    """One node of the array: namespace and its node parameters (sensor.* included)."""

    namespace: str
    parameters: dict

    @property
    def node_name(self):
        """Return the node's fully qualified name."""
        return f'{self.namespace}/{params.NODE_NAME}'


def _name(where, value):
    if not isinstance(value, str) or not value or not all(
            c.isalnum() or c == '_' for c in value) or value[0].isdigit():
        raise ValueError(f'{where} = {value!r} is not allowed: a ROS name (letters, digits, '
                         '_, not starting with a digit)')
    return value


def _mapping(where, value):
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ValueError(f'{where} = {value!r} must be a mapping')
    return dict(value)


def _flatten(prefix, mapping):
    """Flatten nested parameter mappings into ``a.b.c`` names (as a params file nests them)."""
    out = {}
    for key, value in mapping.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            out.update(_flatten(name + '.', value))
        else:
            out[name] = value
    return out


def _draw(where, tolerances, config, rng):
    """Return the ``sensor.*`` values of one part drawn within the tolerances."""
    out = {}
    for term, sigma in tolerances.items():
        if term not in TOLERANCES:
            raise ValueError(f'{where}: unknown tolerance {term!r}; allowed: '
                             f'{", ".join(TOLERANCES)}')
        if isinstance(sigma, bool) or not isinstance(sigma, (int, float)) or \
                not 0.0 <= sigma <= 0.1:
            raise ValueError(f'{where}.{term} = {sigma!r} is out of range: allowed [0, 0.1] '
                             f'{TOLERANCES[term]} (1 sigma)')
        base = np.array(getattr(config, term), dtype=float)
        spread = sigma * rng.standard_normal(base.shape)
        if term == 'misalignment':
            np.fill_diagonal(spread, 0.0)
        out[f'sensor.{term}'] = (base + spread).ravel().tolist()
    return out


def load_spec(path=None):
    """
    Read an array spec and return its :class:`Instance` list.

    Raises ValueError naming the key, the value and what is allowed.
    """
    path = config_file(DEFAULT_SPEC) if path is None else path
    doc = read_yaml(path)
    if not isinstance(doc, dict):
        raise ValueError(f'{path}: expected a mapping with instances')
    allowed = ('namespace', 'parameters', 'tolerances', 'instances')
    unknown = sorted(set(doc) - set(allowed))
    if unknown:
        raise ValueError(f'{path}: unknown key(s) {", ".join(unknown)}; allowed: '
                         f'{", ".join(allowed)}')
    namespace = doc.get('namespace', '')
    namespace = '/' + _name(f'{path}: namespace', namespace) if namespace else ''
    common = _flatten('', _mapping(f'{path}: parameters', doc.get('parameters')))
    tolerances = _mapping(f'{path}: tolerances', doc.get('tolerances'))
    raw = doc.get('instances')
    if not isinstance(raw, list) or not raw:
        raise ValueError(f'{path}: instances = {raw!r} must be a non-empty list')
    instances, names = [], set()
    for i, entry in enumerate(raw):
        where = f'{path}: instances[{i}]'
        entry = _mapping(where, entry)
        extra = sorted(set(entry) - {'name', 'sensor_config', 'parameters'})
        if extra:
            raise ValueError(f'{where}: unknown key(s) {", ".join(extra)}; allowed: name, '
                             'sensor_config, parameters')
        name = _name(f'{where}.name', entry.get('name'))
        if name in names:
            raise ValueError(f'{where}.name = {name!r} is used twice')
        names.add(name)
        values = dict(common)
        # Each part has its own frame: <name>_<common frame_id or imu_link>, unless set.
        values['frame_id'] = f'{name}_{common.get("frame_id", DEFAULT_FRAME)}'
        values.update(_flatten('', _mapping(f'{where}.parameters', entry.get('parameters'))))
        if 'sensor_config' in entry:
            values['sensor_config'] = entry['sensor_config']
        instance = Instance(f'{namespace}/{name}', values)
        config = sensor_config.load_sensor_config(values.get('sensor_config', 'paper'))
        rng = np.random.default_rng(seed_from_name(instance.node_name + '/tolerances'))
        drawn = _draw(f'{path}: tolerances', tolerances, config, rng)
        drawn.update(values)
        instances.append(Instance(instance.namespace, drawn))
    return instances


def params_file_text(instance):
    """Return a ``--params-file`` YAML for one instance (its node's section)."""
    section = {f'{instance.node_name}': {'ros__parameters': instance.parameters}}
    return yaml.safe_dump(section, default_flow_style=None, sort_keys=True)


def node_command(instance, params_path, extra_ros_args=()):
    """Return the command line that runs one instance's node from this Python."""
    return [sys.executable, '-m', 'gyro_emulator.ros.node', '--ros-args',
            '-r', f'__ns:={instance.namespace}', '--params-file', params_path,
            *extra_ros_args]


def _end_with_parent():
    """In a node process (Linux): SIGTERM when the array dies, even by SIGKILL."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    except (AttributeError, OSError):
        pass                              # not Linux: the nodes outlive a killed array


def _parser():
    parser = argparse.ArgumentParser(
        prog='gyro-emulator-array',
        description='Run N gyro emulator nodes from an array spec (what '
                    'gyro_array.launch.py launches), without the ros2 CLI.')
    parser.add_argument('spec', nargs='?', default=None,
                        help='array spec YAML (default: config/gyro_array.yaml)')
    parser.add_argument('--print', action='store_true', dest='show',
                        help='print each instance and its parameters, then exit')
    return parser


def main(args=None):
    """Run every instance until SIGINT/SIGTERM; return the worst exit status."""
    argv = sys.argv[1:] if args is None else list(args)
    ros_args = argv[argv.index('--ros-args') + 1:] if '--ros-args' in argv else []
    opts = _parser().parse_args(argv[:argv.index('--ros-args')] if ros_args else argv)
    try:
        instances = load_spec(opts.spec)
    except (ValueError, OSError) as exc:
        print(f'array: error: {exc}', file=sys.stderr)
        return 2
    if opts.show:
        for instance in instances:
            print(params_file_text(instance), end='')
        return 0
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.append(signum))
    with tempfile.TemporaryDirectory(prefix='gyro_array_') as tmp:
        procs = []
        for k, instance in enumerate(instances):
            path = os.path.join(tmp, f'instance_{k}.yaml')
            with open(path, 'w', encoding='utf-8') as handle:
                handle.write(params_file_text(instance))
            # A group of their own: the terminal's Ctrl-C goes to the array, which
            # passes one SIGINT on (else each node would get two).
            procs.append(subprocess.Popen(node_command(instance, path, ros_args),
                                          process_group=0, preexec_fn=_end_with_parent))
        print(f'array: {len(procs)} gyro emulator nodes: '
              + ', '.join(i.node_name for i in instances), flush=True)
        while not stop and all(p.poll() is None for p in procs):
            time.sleep(0.1)
        for p in procs:
            if p.poll() is None:
                p.send_signal(stop[0] if stop else signal.SIGINT)
        codes = _wait_for_nodes(procs, stop)
    return exit_status(codes, stopped=bool(stop))


def _wait_for_nodes(procs, stop):
    """
    Wait for the nodes to end after the signal passed on; return their statuses.

    A node that is shutting down (closing its bag, ending rclpy) is not cut
    short: on a loaded machine that took over 15 s once, and a SIGKILL then
    would lose what it was writing. A second Ctrl-C or SIGTERM to the array
    (``stop`` grows) ends the nodes still running at once (SIGKILL), and
    so does :data:`STOP_TIMEOUT_S` without one.
    """
    signals_seen = len(stop)
    deadline = time.monotonic() + STOP_TIMEOUT_S
    while (any(p.poll() is None for p in procs) and len(stop) == signals_seen
           and time.monotonic() < deadline):
        time.sleep(0.1)
    for p in procs:
        if p.poll() is None:
            p.kill()
    return [p.wait() for p in procs]


def exit_status(codes, stopped):
    """
    Return the array's exit status from its nodes' statuses.

    Parameters
    ----------
    codes : list of int
        ``Popen.returncode`` of each node (negative: killed by that signal).
    stopped : bool
        The array was stopped by SIGINT/SIGTERM and passed it on.

    """
    if stopped:
        codes = [0 if c in STOPPED_STATUSES else c for c in codes]
    worst = max(codes, key=abs)
    return 128 + abs(worst) if worst < 0 else worst


if __name__ == '__main__':
    sys.exit(main())
