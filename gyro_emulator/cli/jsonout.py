"""
What the ``gyro-emulator`` subcommands share about their outputs.

``--overwrite`` (:func:`add_overwrite`), the check of every output before
the work starts (:func:`gyro_emulator.outputs.check`), and the JSON writer:
indented, NumPy scalars as floats, atomic.
"""

import os

from gyro_emulator import atomic

OVERWRITE_HELP = 'replace existing outputs (default: refuse them, before any work)'


def add_overwrite(parser, text=OVERWRITE_HELP):
    """Register ``--overwrite``, the one switch that lets a command replace its outputs."""
    parser.add_argument('--overwrite', action='store_true', help=text)


def write_json(path, doc):
    """
    Write ``doc`` as indented JSON at ``path``, creating its directory.

    NumPy scalars are written as floats. The file is complete or absent
    (:func:`gyro_emulator.atomic.write_json`): an error or a signal half way
    leaves the old file. Prints ``wrote PATH``.
    """
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    atomic.write_json(path, doc, indent=1, default=float)
    print(f'wrote {path}')
