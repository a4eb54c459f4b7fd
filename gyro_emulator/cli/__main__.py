"""``python -m gyro_emulator.cli``: the ``gyro-emulator`` command line."""

import sys

from gyro_emulator.cli.executables import run_cli

sys.exit(run_cli())
