"""
The ``gyro-emulator`` command line: one subcommand per capability.

Each subcommand lives in ``gyro_emulator.cli.<name>`` and provides
``HELP`` (one line), ``add_arguments(parser)`` and ``run(args) -> int``.
Command modules import their heavy dependencies inside ``run`` so that
``gyro-emulator --help`` stays fast.
"""

import argparse
import importlib
import sys

#: (subcommand, module) in the order shown by ``--help``.
COMMANDS = (
    ('paper', 'gyro_emulator.cli.paper'),
    ('simulate', 'gyro_emulator.cli.simulate'),
    ('allan', 'gyro_emulator.cli.allan'),
    ('calibrate', 'gyro_emulator.cli.calibrate'),
    ('dynamics', 'gyro_emulator.cli.dynamics'),
    ('bag', 'gyro_emulator.cli.bag'),
    ('replay', 'gyro_emulator.cli.replay'),
    ('diagnose', 'gyro_emulator.cli.diagnose'),
    ('truth', 'gyro_emulator.cli.truth'),
    ('fleet', 'gyro_emulator.cli.fleet'),
)


def build_parser():
    """Return the argument parser with every registered subcommand."""
    parser = argparse.ArgumentParser(
        prog='gyro-emulator',
        description='A virtual MEMS vibratory gyroscope built from physics.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    sub.required = True
    for name, module_name in COMMANDS:
        module = importlib.import_module(module_name)
        sub_parser = sub.add_parser(
            name, help=module.HELP, description=module.__doc__,
            formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(sub_parser)
        sub_parser.set_defaults(run=module.run)
    return parser


def main(argv=None):
    """Run the command line; return the process exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except (ValueError, OSError) as exc:
        print(f'gyro-emulator {args.command}: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f'gyro-emulator {args.command}: interrupted', file=sys.stderr)
        return 130
