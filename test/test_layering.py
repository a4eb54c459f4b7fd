"""Imports run one way: units/params -> physics -> ... -> ROS edge -> CLI."""

import ast
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PKG = os.path.join(ROOT, 'gyro_emulator')

#: Layer of each module, matched by the longest dotted prefix. A new module
#: must be added here: the test fails for modules it cannot place.
LAYERS = {
    'gyro_emulator': 0,
    'gyro_emulator.units': 0,
    'gyro_emulator.atomic': 0,
    'gyro_emulator.validation': 0,
    'gyro_emulator.resources': 0,
    'gyro_emulator.plotting': 0,
    'gyro_emulator.interrupts': 0,
    'gyro_emulator.yaml_text': 0,
    'gyro_emulator.outputs': 0,
    # physics core: device parameters, Eq 5-22, 2-DOF dynamics, the paper
    'gyro_emulator.physics': 1,
    # the error model and the GyroModel API
    'gyro_emulator.sensor': 2,
    # bags, CDR, CSV, the topic table
    'gyro_emulator.recording': 3,
    # running the emulator: input profiles, offline runs, streaming inputs,
    # synthetic measured records
    'gyro_emulator.emulation': 4,
    # analysis: replay comparison, Allan, calibrate, diagnose, fleet
    'gyro_emulator.analysis': 5,
    # ROS edge: the only modules that import rclpy or message packages
    'gyro_emulator.ros': 6,
    # the command line and the console-script entry points
    'gyro_emulator.cli': 7,
}
ROS_EDGE = 6
ROS_MODULE_PREFIXES = ('rclpy', 'launch', 'launch_ros', 'rosidl', 'rcl_interfaces',
                       'builtin_interfaces', 'ament_index_python')
ROS_MODULE_SUFFIXES = ('_msgs', '_srvs', '_interfaces')


def layer_of(module):
    parts = module.split('.')
    for n in range(len(parts), 0, -1):
        key = '.'.join(parts[:n])
        if key in LAYERS and (n > 1 or len(parts) == 1):
            return LAYERS[key]
    return None


def modules():
    for dirpath, _, files in os.walk(PKG):
        for name in files:
            if name.endswith('.py'):
                rel = os.path.relpath(os.path.join(dirpath, name), ROOT)[:-3]
                mod = rel.replace(os.sep, '.')
                if mod.endswith('.__init__'):
                    mod = mod[:-len('.__init__')]
                yield mod, os.path.join(dirpath, name)


def imports_of(path, module):
    tree = ast.parse(open(path, encoding='utf-8').read())
    package = module if path.endswith('__init__.py') else module.rsplit('.', 1)[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split('.')
                base = base[:len(base) - node.level + 1]
                yield '.'.join(base + ([node.module] if node.module else []))
            else:
                yield node.module
                for alias in node.names:
                    # `from gyro_emulator import physics` names a module;
                    # `from gyro_emulator import __version__` does not.
                    sub = os.path.join(PKG, alias.name)
                    if node.module == 'gyro_emulator' and (
                            os.path.isdir(sub) or os.path.exists(sub + '.py')):
                        yield 'gyro_emulator.' + alias.name


ALL = sorted(modules())


@pytest.mark.parametrize('module,path', ALL, ids=[m for m, _ in ALL])
def test_module_respects_layers(module, path):
    own = layer_of(module)
    assert own is not None, f'{module}: add it to LAYERS in test/test_layering.py'
    for imported in imports_of(path, module):
        top = imported.split('.')[0]
        if top == 'gyro_emulator':
            other = layer_of(imported)
            if imported == 'gyro_emulator':
                continue
            assert other is not None, f'{module} imports unplaced {imported}'
            assert other <= own, (
                f'{module} (layer {own}) imports {imported} (layer {other}): '
                'imports must run from higher layers to lower ones')
        elif top.startswith(ROS_MODULE_PREFIXES) or top.endswith(ROS_MODULE_SUFFIXES):
            assert own >= ROS_EDGE, (
                f'{module} (layer {own}) imports {imported}: only the ROS edge '
                '(gyro_emulator.ros) and above may import ROS packages')


def test_the_core_imports_without_ros():
    """Importing the physics core must not pull rclpy into the process."""
    import subprocess
    import sys
    code = ('import sys, gyro_emulator.physics.first_order, gyro_emulator.physics.paper, '
            'gyro_emulator.sensor.model, gyro_emulator.analysis.diagnose, '
            'gyro_emulator.emulation.driver.core; '
            'sys.exit(1 if "rclpy" in sys.modules else 0)')
    assert subprocess.run([sys.executable, '-c', code], cwd=ROOT).returncode == 0


def test_the_command_lines_parser_loads_no_numerics():
    """``gyro-emulator --help`` and an option error load no scipy or numba (they cost 2 s)."""
    import subprocess
    import sys
    code = ('import sys; from gyro_emulator.cli import build_parser; build_parser(); '
            'heavy = sorted(m for m in ("scipy", "numba", "matplotlib", "rclpy") '
            'if m in sys.modules); print(heavy); sys.exit(1 if heavy else 0)')
    run = subprocess.run([sys.executable, '-c', code], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr


#: Size limits of the house (issue 11): small rooms are easier to read and test.
MAX_FUNCTION_LINES = 100
MAX_MODULE_LINES = 700


@pytest.mark.parametrize('module,path', ALL, ids=[m for m, _ in ALL])
def test_module_and_function_sizes(module, path):
    source = open(path, encoding='utf-8').read()
    lines = source.count('\n')
    assert lines <= MAX_MODULE_LINES, (
        f'{module} has {lines} lines: split it (at most {MAX_MODULE_LINES})')
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            length = node.end_lineno - node.lineno + 1
            assert length <= MAX_FUNCTION_LINES, (
                f'{module}.{node.name} (line {node.lineno}) has {length} lines: '
                f'split it (at most {MAX_FUNCTION_LINES})')


def test_the_size_check_can_fail(tmp_path):
    """The size check reads real definitions: a long function is caught."""
    body = '\n'.join(f'    x{i} = {i}' for i in range(MAX_FUNCTION_LINES + 1))
    path = tmp_path / 'long.py'
    path.write_text(f'def long():\n{body}\n', encoding='utf-8')
    with pytest.raises(AssertionError, match='long'):
        test_module_and_function_sizes('long', str(path))


@pytest.mark.parametrize('line,message', [
    ('from gyro_emulator.ros import node', 'imports must run from higher layers'),
    ('import rclpy', 'only the ROS edge'),
    ('from sensor_msgs.msg import Imu', 'only the ROS edge'),
])
def test_the_layer_check_can_fail(tmp_path, line, message):
    """An upward import, or a ROS import below the edge, in a physics module is caught."""
    path = tmp_path / 'fake.py'
    path.write_text(f'{line}\n', encoding='utf-8')
    with pytest.raises(AssertionError, match=message):
        test_module_respects_layers('gyro_emulator.physics.fake', str(path))


#: The modules that may rename a file over another: the one atomic write, and the bag
#: repair, which swaps a bag's files in place (its ``.repair-tmp`` recovery protocol).
RENAMERS = {'gyro_emulator.atomic', 'gyro_emulator.recording.repair'}
#: Calls that rename a file over another.
RENAMING_CALLS = {('os', 'replace'), ('os', 'rename'), ('shutil', 'move')}


def renames_in(path):
    """Yield the line of each rename call (``os.replace(``, ``os.rename(``, ``shutil.move(``)."""
    tree = ast.parse(open(path, encoding='utf-8').read())
    for node in ast.walk(tree):
        func = node.func if isinstance(node, ast.Call) else None
        if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name) and (
                func.value.id, func.attr) in RENAMING_CALLS:
            yield node.lineno
        elif isinstance(node, ast.ImportFrom) and any(
                (node.module, alias.name) in RENAMING_CALLS for alias in node.names):
            yield node.lineno


def renaming_modules(paths):
    """Return the modules of ``paths`` ((module, path) pairs) that rename files."""
    return {module for module, path in paths if any(True for _ in renames_in(path))}


def test_only_the_atomic_writer_and_bag_repair_rename_files():
    """Every output is written through gyro_emulator.atomic (one way to write a file whole)."""
    found = renaming_modules(ALL)
    assert found == RENAMERS, (
        f'{sorted(found - RENAMERS)} rename files themselves: write '
        'through gyro_emulator.atomic (staged, open_atomic, write_text, write_json)')


@pytest.mark.parametrize('line', ['import os\nos.replace(a, b)\n', 'from os import rename\n',
                                  'import shutil\nshutil.move(a, b)\n'])
def test_the_rename_check_can_fail(tmp_path, line):
    """A module that renames a file itself is caught."""
    path = tmp_path / 'fake.py'
    path.write_text(line, encoding='utf-8')
    assert renaming_modules([('gyro_emulator.physics.fake', str(path))]) == {
        'gyro_emulator.physics.fake'}
