"""Subcommands of the ``gyro-emulator`` command line (see ``gyro_emulator.cli``)."""

import json
import os


def write_json(path, doc):
    """
    Write ``doc`` as indented JSON at ``path``, creating its directory.

    NumPy scalars are written as floats. Prints ``wrote PATH``.
    """
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, 'w', encoding='utf-8') as handle:
        json.dump(doc, handle, indent=1, default=float)
    print(f'wrote {path}')
