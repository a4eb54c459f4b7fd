"""
``node --help``: the node's parameters and topics, printed without starting ROS.

The text is built from the same tables the node uses (:data:`parameters.NODE_PARAMS`,
the ``sensor.*`` fields of :class:`~gyro_emulator.sensor.config.SensorConfig`
and the topic table), so it cannot drift from what the node declares.
"""

import textwrap

from gyro_emulator.emulation.driver import parameters
from gyro_emulator.recording import topics
from gyro_emulator.ros import params

USAGE = """\
usage: ros2 run gyro_emulator node [--help] [--ros-args ...]
       gyro-emulator-node [--help] [--ros-args ...]      (the pip venv, no ros2)

The virtual MEMS gyro as a ROS 2 driver node (docs/node.md). Set parameters
with --ros-args -p NAME:=VALUE or --params-file FILE (start from a copy of
config/gyro_emulator.yaml); remap with -r FROM:=TO, e.g. -r __ns:=/gyro.

With seed -1 (the default) the seed comes from the node's fully qualified
name, so every node of the same name is the same part: the same turn-on bias
and noise on every run (/gyro_emulator with sensor_config consumer: z -7.92
deg/s). Give each gyro its own namespace or seed for independent parts, and
set startup_bias_calibration (seconds at rest) to remove the bias at start,
as a driver's start-up calibration does."""


def wants_help(argv):
    """Return True if ``-h``/``--help`` comes before any ``--ros-args``."""
    for arg in argv:
        if arg == '--ros-args':
            return False
        if arg in ('-h', '--help'):
            return True
    return False


def _wrap(name, text, width=100, indent=32):
    lines = textwrap.wrap(text, width - indent) or ['']
    head = f'  {name:<{indent - 3}} ' if len(name) < indent - 3 else f'  {name}\n' + ' ' * indent
    return head + lines[0] + ''.join('\n' + ' ' * indent + line for line in lines[1:])


def _constraint(spec):
    if spec.choices:
        return 'one of ' + ', '.join(spec.choices)
    if spec.kind == 'double_array':
        return f'3 numbers in [{spec.low:g}, {spec.high:g}]'
    if spec.kind == 'integer' and spec.low is not None:
        return f'[{int(spec.low)}, {int(spec.high)}]'
    if spec.low is not None:
        return f'{"(" if spec.low_open else "["}{spec.low:g}, {spec.high:g}]'
    return spec.kind


def help_text():
    """Return the ``--help`` text: usage, parameters with defaults, topics."""
    defaults = params.node_defaults()
    out = [USAGE, '', 'parameters (read-only ones are fixed once the node runs):']
    for spec in parameters.NODE_PARAMS:
        flag = ', read-only' if spec.read_only else ''
        default = defaults[spec.name]
        default = str(default).lower() if isinstance(default, bool) else repr(default)
        out.append(_wrap(spec.name, f'{spec.description} (default {default}; '
                                    f'{_constraint(spec)}{flag})'))
    structural = ('terms', 'extended', 'accelerometer', 'device')
    fields = ', '.join(sorted(k for k in parameters.SENSOR_DESCRIPTIONS
                              if k not in structural))
    out.append(_wrap('sensor.<field>', 'one error-model parameter per SensorConfig '
                     f'field, default from sensor_config, settable at run time: {fields}'))
    out.append(_wrap('sensor.terms.<term>', 'on/off switch of each error term, settable '
                     'at run time'))
    out.append(_wrap('sensor.device', f'{parameters.SENSOR_DESCRIPTIONS["device"]} '
                                      '(read-only)'))
    out.append(_wrap('accelerometer', parameters.SENSOR_DESCRIPTIONS['accelerometer']))
    out.append(_wrap('extended terms', parameters.SENSOR_DESCRIPTIONS['extended']))
    out += ['', 'topics (relative names follow the namespace; ~/ is under the node name):']
    for topic in topics.NODE_TOPICS:
        out.append(_wrap(f'{topic.direction:>3} {topic.name}',
                         f'{topic.type_name.replace("/msg/", "/")}: {topic.description}'))
    return '\n'.join(out)
