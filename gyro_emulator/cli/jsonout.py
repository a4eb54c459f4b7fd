"""JSON output of the ``gyro-emulator`` subcommands: indented, NumPy scalars as floats, atomic."""

import os

from gyro_emulator import atomic


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
