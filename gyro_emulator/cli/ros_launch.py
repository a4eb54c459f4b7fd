"""
``gyro-emulator ros launch``: start the nodes of a launch file without ``launch``.

``launch`` and ``launch_ros`` are not on PyPI. The launch file is run against
stand-ins for what this package's launch files use: ``LaunchDescription``,
``DeclareLaunchArgument``, ``LaunchConfiguration`` (``perform``),
``OpaqueFunction`` and ``launch_ros.actions.Node``. Any other name is refused
with a message that names it. Each Node becomes a child process:

* this package's executables run from this Python
  (``python -m gyro_emulator.cli ros run <executable>``), another package's from
  ``<prefix>/lib/<package>/<executable>`` as ``ros2 run`` finds it;
* ``name`` and ``namespace`` are ``-r __node:=`` and ``-r __ns:=``; a parameter
  file is ``--params-file``; a parameter dict is written to a temporary file
  under ``/**`` (as launch_ros does), a substituted value parsed as YAML;
  ``remappings`` are ``-r from:=to``.

The children share the terminal but not its process group: Ctrl-C reaches the
launcher only, which sends each child one SIGINT (a second Ctrl-C sends
SIGTERM, a third SIGKILL) and exits 0 when every child did.
"""

import os
import shlex
import signal
import subprocess
import sys
import tempfile
import types

from ament_index_python.packages import (get_package_prefix, get_package_share_directory,
                                         PackageNotFoundError)
from gyro_emulator.resources import load_yaml_text
import yaml

PACKAGE = 'gyro_emulator'


class LaunchConfiguration:
    """Stand-in for ``launch.substitutions.LaunchConfiguration``."""

    def __init__(self, variable_name, default=None):
        self.name = variable_name
        self.default = default

    def perform(self, context):
        """Return the argument's value in ``context``."""
        if self.name in context.arguments:
            return context.arguments[self.name]
        if self.default is not None:
            return perform(self.default, context)
        raise ValueError(f'launch argument {self.name!r} has no value: give {self.name}:=...')


class DeclareLaunchArgument:
    """Stand-in for ``launch.actions.DeclareLaunchArgument``."""

    def __init__(self, name, default_value=None, description='', choices=None, **_):
        self.name, self.default_value = name, default_value
        self.description, self.choices = description, choices


class OpaqueFunction:
    """Stand-in for ``launch.actions.OpaqueFunction``."""

    def __init__(self, function, args=None, kwargs=None):
        self.function, self.args, self.kwargs = function, args or [], kwargs or {}


class Node:
    """Stand-in for ``launch_ros.actions.Node``: what its child process needs."""

    def __init__(self, executable, package=None, name=None, namespace=None, parameters=None,
                 remappings=None, arguments=None, ros_arguments=None, **_):
        self.executable, self.package, self.name = executable, package, name
        self.namespace, self.parameters = namespace, parameters or []
        self.remappings, self.arguments = remappings or [], arguments or []
        self.ros_arguments = ros_arguments or []


class LaunchDescription:
    """Stand-in for ``launch.LaunchDescription``."""

    def __init__(self, initial_entities=None):
        self.entities = list(initial_entities or [])


STAND_INS = {
    'launch': {'LaunchDescription': LaunchDescription},
    'launch.actions': {'DeclareLaunchArgument': DeclareLaunchArgument,
                       'OpaqueFunction': OpaqueFunction},
    'launch.substitutions': {'LaunchConfiguration': LaunchConfiguration},
    'launch_ros': {},
    'launch_ros.actions': {'Node': Node},
}


def _stand_in_module(name, attrs):
    module = types.ModuleType(name)
    module.__dict__.update(attrs)

    def missing(attr):
        raise ImportError(f'{name}.{attr} is not provided by gyro-emulator ros launch (it '
                          'runs LaunchDescription, DeclareLaunchArgument, '
                          'LaunchConfiguration, OpaqueFunction and launch_ros Node); use '
                          'ros2 launch from a ROS 2 install')
    module.__getattr__ = missing
    module.__path__ = []  # a package: `import launch.actions` finds the stand-in
    return module


def load_description(path):
    """Run the launch file ``path`` against the stand-ins; return its LaunchDescription."""
    saved = {name: sys.modules.get(name) for name in STAND_INS}
    sys.modules.update({name: _stand_in_module(name, attrs)
                        for name, attrs in STAND_INS.items()})
    try:
        namespace = {'__file__': path, '__name__': os.path.basename(path).replace('.', '_')}
        with open(path, encoding='utf-8') as handle:
            code = compile(handle.read(), path, 'exec')
        exec(code, namespace)  # noqa: S102 - running the launch file is the point
        if 'generate_launch_description' not in namespace:
            raise ValueError(f'{path}: no generate_launch_description()')
        return namespace['generate_launch_description']()
    except ImportError as exc:
        raise ValueError(f'{path}: {exc}') from None
    finally:
        for name, module in saved.items():
            if module is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = module


def perform(value, context):
    """Return ``value`` with substitutions performed (a list of parts is joined)."""
    if isinstance(value, LaunchConfiguration):
        return value.perform(context)
    if isinstance(value, (list, tuple)):
        return ''.join(perform(part, context) for part in value)
    return value


class Context:
    """The launch arguments: declared defaults, overridden by NAME:=VALUE."""

    def __init__(self, declared, given):
        unknown = sorted(set(given) - {d.name for d in declared})
        if unknown:
            raise ValueError(f'launch argument {unknown[0]!r} is not declared; declared: '
                             + ', '.join(d.name for d in declared))
        self.arguments = {}
        for declaration in declared:
            if declaration.name in given:
                value = given[declaration.name]
            elif declaration.default_value is not None:
                value = perform(declaration.default_value, self)
            else:
                continue
            if declaration.choices and value not in declaration.choices:
                raise ValueError(f'{declaration.name}:={value!r} is not one of '
                                 + ', '.join(declaration.choices))
            self.arguments[declaration.name] = value


def nodes_of(description, given):
    """Return (declared arguments, Nodes) of a description, OpaqueFunctions evaluated."""
    declared = [e for e in description.entities if isinstance(e, DeclareLaunchArgument)]
    context = Context(declared, given)
    nodes = []
    pending = list(description.entities)
    while pending:
        entity = pending.pop(0)
        if isinstance(entity, Node):
            nodes.append(entity)
        elif isinstance(entity, OpaqueFunction):
            pending[:0] = entity.function(context, *entity.args, **entity.kwargs) or []
        elif not isinstance(entity, DeclareLaunchArgument):
            raise ValueError(f'{type(entity).__name__} is not run by gyro-emulator ros launch')
    return declared, nodes, context


def _has_substitution(value):
    parts = value if isinstance(value, (list, tuple)) else [value]
    return any(isinstance(part, LaunchConfiguration) for part in parts)


def _parameter_args(node, context, tmpdir, index):
    args = []
    for number, entry in enumerate(node.parameters):
        if isinstance(entry, dict):
            values = {}
            for key, value in entry.items():
                name = perform(key, context)
                if _has_substitution(value):  # launch_ros reads the result as YAML (bounded)
                    value = load_yaml_text(perform(value, context), f'parameter {name}')
                values[name] = value
            path = os.path.join(tmpdir, f'node{index}_params{number}.yaml')
            with open(path, 'w', encoding='utf-8') as handle:
                yaml.safe_dump({'/**': {'ros__parameters': values}}, handle)
            args += ['--params-file', path]
        else:
            args += ['--params-file', perform(entry, context)]
    return args


def node_command(node, context, tmpdir, index):
    """Return the command line of one Node."""
    package = perform(node.package, context) if node.package else PACKAGE
    executable = perform(node.executable, context)
    if package == PACKAGE:
        command = [sys.executable, '-m', 'gyro_emulator.cli', 'ros', 'run', executable]
    else:
        command = [os.path.join(get_package_prefix(package), 'lib', package, executable)]
    command += [perform(a, context) for a in node.arguments]
    ros_args = [perform(a, context) for a in node.ros_arguments]
    if node.name:
        ros_args += ['-r', f'__node:={perform(node.name, context)}']
    namespace = perform(node.namespace, context) if node.namespace else ''
    if namespace:
        ros_args += ['-r', f'__ns:={namespace if namespace.startswith("/") else "/" + namespace}']
    ros_args += _parameter_args(node, context, tmpdir, index)
    for source, target in node.remappings:
        ros_args += ['-r', f'{perform(source, context)}:={perform(target, context)}']
    return command + (['--ros-args'] + ros_args if ros_args else [])


def find_launch_file(target):
    """Return (launch file path, NAME:=VALUE arguments) of ``[PACKAGE] FILE [ARGS]``."""
    first, rest = target[0], list(target[1:])
    if os.path.isfile(first):
        return first, rest
    if not rest:
        raise OSError(f'{first}: no such launch file')
    try:
        share = get_package_share_directory(first)
    except PackageNotFoundError:
        raise OSError(f'package {first!r} not found (AMENT_PREFIX_PATH)') from None
    for dirpath, _, files in os.walk(share):
        if rest[0] in files:
            return os.path.join(dirpath, rest[0]), rest[1:]
    raise OSError(f'{rest[0]}: not in {share}')


def parse_arguments(items):
    """Return ``{name: value}`` of ``NAME:=VALUE`` items."""
    given = {}
    for item in items:
        name, sep, value = item.partition(':=')
        if not sep or not name:
            raise ValueError(f'{item!r}: launch arguments are NAME:=VALUE')
        given[name] = value
    return given


def _with_this_prefix():
    """Put this Python's prefix (the venv, where pip installed share/) on AMENT_PREFIX_PATH."""
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    if sys.prefix not in prefixes:
        os.environ['AMENT_PREFIX_PATH'] = os.pathsep.join(prefixes + [sys.prefix])


def run(target, show_args=False, dry_run=False):
    """Start the launch file's nodes and wait for them; return the exit status."""
    _with_this_prefix()
    path, items = find_launch_file(target)
    description = load_description(path)
    if show_args:
        for entity in description.entities:
            if isinstance(entity, DeclareLaunchArgument):
                print(f"    '{entity.name}':\n        {entity.description}\n"
                      f'        (default: {entity.default_value!r})')
        return 0
    declared, nodes, context = nodes_of(description, parse_arguments(items))
    with tempfile.TemporaryDirectory(prefix='gyro_emulator_launch_') as tmpdir:
        commands = [node_command(node, context, tmpdir, i) for i, node in enumerate(nodes)]
        if dry_run:
            for command in commands:
                print(shlex.join(command))
            return 0
        return supervise(commands)


def supervise(commands):
    """Start ``commands``, forward Ctrl-C once to each, reap them; 0 if all exit 0."""
    children = {}
    escalation = [signal.SIGINT, signal.SIGTERM, signal.SIGKILL]

    def forward(signum, frame):
        sent = escalation.pop(0) if len(escalation) > 1 else escalation[0]
        for pid in children:
            try:
                os.kill(pid, sent)
            except ProcessLookupError:
                pass

    previous = {s: signal.signal(s, forward) for s in (signal.SIGINT, signal.SIGTERM)}
    failed = []
    try:
        for command in commands:
            try:
                proc = subprocess.Popen(command, start_new_session=True)
            except OSError:
                forward(signal.SIGINT, None)  # stop the ones already started
                _reap(children, [])
                raise
            children[proc.pid] = proc
            print(f'[gyro-emulator ros launch] started [{proc.pid}]: {shlex.join(command)}',
                  file=sys.stderr, flush=True)
        _reap(children, failed)
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    return 1 if failed else 0


def _reap(children, failed):
    """Wait for every child of ``children`` (pid -> Popen); add those that failed."""
    while children:
        pid, status = os.waitpid(-1, 0)  # PEP 475: resumed after `forward` runs
        proc = children.pop(pid, None)
        if proc is None:
            continue
        proc.returncode = os.waitstatus_to_exitcode(status)
        print(f'[gyro-emulator ros launch] process [{pid}] exited with '
              f'{proc.returncode}', file=sys.stderr, flush=True)
        if proc.returncode != 0:
            failed.append(proc)
