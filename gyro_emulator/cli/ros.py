"""
Stand-ins for the ros2 CLI, built on rclpy: run, launch, param, topic.

The pip-only venv (Debian 12, Python 3.11, PyPI) has rclpy but no ros2cli,
launch or launch_ros. These do what the README's ``ros2`` lines do:

  gyro-emulator ros run node [ARGS]          ros2 run gyro_emulator node [ARGS]
  gyro-emulator ros launch gyro_emulator gyro_emulator.launch.py [NAME:=VALUE ...]
                                             ros2 launch (the same arguments)
  gyro-emulator ros param set /gyro_emulator fault.type stuck
  gyro-emulator ros param get /gyro_emulator rate_hz
  gyro-emulator ros topic list
  gyro-emulator ros topic hz imu/data_raw [--count N]
  gyro-emulator ros topic echo imu/data_raw [--count N]

``run`` runs the executable in this process (node, scenario, recorder, replay,
array). ``launch`` reads a launch file against small stand-ins for the parts
of ``launch``/``launch_ros`` this package's files use (DeclareLaunchArgument,
LaunchConfiguration, OpaqueFunction, launch_ros Node) and starts each Node as
a child process with its name, namespace, parameters and remappings; a file
that uses anything else is refused with the name of what it needs. A value
is parsed as YAML, as ``ros2 param set`` does; an integer given for a double
parameter is sent as a double. ``topic`` commands wait for the topic to
appear and take its type from the graph (or ``--type``).
"""

import argparse

from gyro_emulator.cli.executables import ROS_EXECUTABLES

HELP = 'ros2 CLI stand-ins on rclpy: run, launch, param set/get, topic list/hz/echo'


def add_arguments(parser):
    """Register the ``ros`` verbs."""
    sub = parser.add_subparsers(dest='verb', metavar='VERB')
    sub.required = True
    run = sub.add_parser('run', help='run an executable of this package (ros2 run)')
    run.add_argument('executable', choices=sorted(ROS_EXECUTABLES), metavar='EXECUTABLE',
                     help='one of ' + ', '.join(sorted(ROS_EXECUTABLES)))
    run.add_argument('args', nargs=argparse.REMAINDER,
                     help='its arguments, --ros-args included')
    launch = sub.add_parser('launch', help='start the nodes of a launch file (ros2 launch)')
    launch.add_argument('target', nargs='+', metavar='[PACKAGE] FILE [NAME:=VALUE ...]',
                        help='a launch file path, or a package and a launch file in its '
                             'share directory; then launch arguments')
    launch.add_argument('--show-args', action='store_true',
                        help='list the launch arguments, then exit')
    launch.add_argument('--print', action='store_true', dest='dry_run',
                        help='print the commands it would start, then exit')
    _add_param_arguments(sub)
    _add_topic_arguments(sub)


def _add_param_arguments(sub):
    param = sub.add_parser('param', help='set or get a node parameter (ros2 param)')
    actions = param.add_subparsers(dest='action', metavar='ACTION')
    actions.required = True
    set_ = actions.add_parser('set', help='set a parameter')
    get = actions.add_parser('get', help='print a parameter')
    for action in (set_, get):
        action.add_argument('node', metavar='NODE', help='node name, e.g. /gyro_emulator')
        action.add_argument('name', metavar='NAME', help='parameter name, e.g. fault.type')
    set_.add_argument('value', metavar='VALUE', help='new value, parsed as YAML')
    for action in (set_, get):
        action.add_argument('--timeout', type=float, default=10.0, metavar='S',
                            help='wait at most S s for the node (default: %(default)s)')


def _add_topic_arguments(sub):
    topic = sub.add_parser('topic', help='list, measure or print topics (ros2 topic)')
    actions = topic.add_subparsers(dest='action', metavar='ACTION')
    actions.required = True
    listing = actions.add_parser('list', help='print the topics and their types')
    listing.add_argument('--spin-time', type=float, default=1.0, metavar='S',
                         help='discover for S s before printing (default: %(default)s)')
    hz = actions.add_parser('hz', help='print the receive rate of a topic each second')
    hz.add_argument('--window', type=int, default=10000, metavar='N',
                    help='rate over the last N messages (default: %(default)s)')
    echo = actions.add_parser('echo', help='print the messages of a topic as YAML')
    echo.add_argument('--once', action='store_const', const=1, dest='count',
                      help='print one message, then exit')
    for action in (hz, echo):
        action.add_argument('topic', metavar='TOPIC', help='topic name, e.g. imu/data_raw')
        action.add_argument('--type', default=None, metavar='TYPE',
                            help='message type, e.g. sensor_msgs/msg/Imu (default: '
                                 'from the graph, waiting for the topic to appear)')
        action.add_argument('--count', type=int, default=None, metavar='N',
                            help='stop after N messages (default: run until Ctrl-C)')


def run(args):
    """Dispatch to the verb; return the exit status."""
    if args.verb == 'run':
        from gyro_emulator.cli.executables import run_executable
        return run_executable(args.executable, args.args)
    # The launcher, and rclpy for param and topic (0.3 s), are imported here:
    # `gyro-emulator --help` imports every command module.
    if args.verb == 'launch':
        from gyro_emulator.cli import ros_launch
        return ros_launch.run(args.target, show_args=args.show_args, dry_run=args.dry_run)
    from gyro_emulator.cli import ros_graph
    if args.verb == 'param':
        return ros_graph.param(args.action, args.node, args.name,
                               getattr(args, 'value', None), args.timeout)
    if args.action == 'list':
        return ros_graph.topic_list(args.spin_time)
    if args.count is not None and args.count < 1:
        raise ValueError(f'--count = {args.count} is out of range: allowed 1 or more')
    if args.action == 'hz':
        if args.window < 2:
            raise ValueError(f'--window = {args.window} is out of range: allowed 2 or more')
        return ros_graph.topic_hz(args.topic, args.type, args.window, args.count)
    return ros_graph.topic_echo(args.topic, args.type, args.count)
