"""
The ``gyro-emulator`` command line: one subcommand per capability.

Each subcommand lives in ``gyro_emulator.cli.<name>`` and provides
``HELP`` (one line), ``add_arguments(parser)`` and ``run(args) -> int``.
Command modules import their heavy dependencies inside ``run`` so that
``gyro-emulator --help`` stays fast.
"""

import argparse
import importlib
import re
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
    ('ros', 'gyro_emulator.cli.ros'),
)


#: reStructuredText roles (``:func:`x```) and literals (````x````) in docstrings.
_ROLE = re.compile(r':[a-z]+:`~?([^`<]*?)\s*(?:<[^`>]*>)?`')
_LITERAL = re.compile(r'``([^`]*)``')


def plain_text(text):
    """
    Return docstring text as ``--help`` shows it: RST markup removed.

    ````x```` becomes ``x``; a role ``:func:`name``` becomes ``name`` (with
    ``~`` only the last part, with ``title <target>`` the title).
    """
    if not text:
        return text

    def role(match):
        name = match.group(1)
        return name.rsplit('.', 1)[-1] if match.group(0).startswith(':') and '`~' in \
            match.group(0) else name
    return _LITERAL.sub(r'\1', _ROLE.sub(role, text))


class PlainParser(argparse.ArgumentParser):
    """
    An ArgumentParser whose option help is shown without RST markup.

    It keeps its options' spellings by destination (``rate_hz`` ->
    ``--rate-hz``) in the parsed arguments (``option_names``), so that an
    error about a value names the option the user typed (:func:`as_option`).
    """

    def __init__(self, *args, **kwargs):
        self.option_names = {}
        super().__init__(*args, **kwargs)
        self.set_defaults(option_names=self.option_names)

    def add_argument(self, *args, **kwargs):
        """Add an argument as ArgumentParser does, its ``help`` as :func:`plain_text`."""
        if isinstance(kwargs.get('help'), str):
            kwargs['help'] = plain_text(kwargs['help'])
        action = super().add_argument(*args, **kwargs)
        if action.option_strings:
            self.option_names[action.dest] = action.option_strings[-1]
        return action


#: An error that starts with a field: ``rate_hz = 0.0 is out of range ...``.
_FIELD_FIRST = re.compile(r'([A-Za-z_][A-Za-z0-9_]*) = ')


def as_option(args, message):
    """
    Return ``message`` with a leading ``field = value`` named as the command's option.

    Checks below the command line name the field they check (``rate_hz =
    0.0 is out of range``); where that field is an option of the command
    (its destination) and the value is the option's, the message names the
    option as typed (``--rate-hz 0.0 is out of range``). Other messages (a
    log's ``temp_c`` column, a file's field) are returned as they are.
    """
    names = getattr(args, 'option_names', None) or {}
    match = _FIELD_FIRST.match(message)
    if match is None or match.group(1) not in names:
        return message
    rest = message[match.end():]
    value = getattr(args, match.group(1), None)
    if value is None or rest.split(' ', 1)[0] not in (repr(value), str(value)):
        return message             # the same name, another value: not the option's check
    return f'{names[match.group(1)]} {rest}'


def build_parser():
    """Return the argument parser with every registered subcommand."""
    parser = argparse.ArgumentParser(
        prog='gyro-emulator',
        description='A virtual MEMS vibratory gyroscope built from physics.')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND', parser_class=PlainParser)
    sub.required = True
    for name, module_name in COMMANDS:
        module = importlib.import_module(module_name)
        sub_parser = sub.add_parser(
            name, help=plain_text(module.HELP), description=plain_text(module.__doc__),
            formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(sub_parser)
        sub_parser.set_defaults(run=module.run)
    return parser


#: Longest error message printed, characters (a value quoted whole could be megabytes).
MAX_MESSAGE_CHARS = 600


def one_line(message, limit=MAX_MESSAGE_CHARS):
    """Return ``message`` on one line, its middle cut when longer than ``limit``."""
    text = ' '.join(str(message).split())
    if len(text) <= limit:
        return text
    half = (limit - 30) // 2
    return f'{text[:half]} ...[{len(text) - 2 * half} characters cut]... {text[-half:]}'


def main(argv=None, signals=False):
    """
    Run the command line; return the process exit status.

    With ``signals`` (the ``gyro-emulator`` entry point), SIGTERM and SIGHUP
    stop a command as Ctrl-C does: its unfinished outputs are removed
    (:class:`gyro_emulator.interrupts.Terminated`), and the status is 143 or
    129; once the command's work is done they are ignored until the process
    exits (the outputs are complete by then). A command stopped by a signal
    (SIGINT too) ends the process once its clean-up has run, without the
    interpreter's finalization (:func:`gyro_emulator.interrupts.end_process`).
    ``gyro-emulator ros`` keeps the ROS programs' own handling.
    """
    from gyro_emulator.interrupts import TERMINATING_SIGNALS, TerminateOnSignal, end_process

    args = None
    guard = TerminateOnSignal(TERMINATING_SIGNALS if signals else (), defer=True)
    try:
        with guard:
            args = build_parser().parse_args(argv)
            if args.command == 'ros':
                guard.restore()                 # the ROS programs' own handling
            guard.arm()                         # a signal while parsing stops here
            status = int(args.run(args) or 0)
            guard.close()                       # done: a later signal waits for the exit
        if guard.received is not None:         # raised where a library swallowed it
            raise guard.received
        return status
    except BaseException as exc:                # noqa: B902 (a signal may surface as any)
        stop = guard.received or exc
        status = _failed(args, stop)
        if signals and isinstance(stop, KeyboardInterrupt):
            end_process(status)                 # see there: no exit after a cut-short library
        return status


def _failed(args, exc):
    """
    Say in one line why a command stopped; return its exit status.

    A signal wins over the exception it surfaced as (raised inside a
    compiled module's import, it becomes an ImportError: "initialization
    failed"). What is not a signal, a bad input or an OS error (``--help``'s
    SystemExit, a bug) is raised again.
    """
    from gyro_emulator.interrupts import Terminated

    if isinstance(exc, Terminated):
        print(f'{_label(args)}: stopped by {exc.name}; unfinished outputs removed',
              file=sys.stderr)
        return exc.status
    if isinstance(exc, KeyboardInterrupt):
        print(f'{_label(args)}: interrupted', file=sys.stderr)
        return 130
    if not isinstance(exc, (ValueError, OSError)):
        raise exc
    print(f'{_label(args)}: error: {one_line(as_option(args, str(exc)))}', file=sys.stderr)
    return 2


def _label(args):
    """Return ``gyro-emulator COMMAND`` for a message (before parsing: ``gyro-emulator``)."""
    return 'gyro-emulator' + (f' {args.command}' if args is not None else '')
