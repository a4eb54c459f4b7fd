"""Subcommands of the ``gyro-emulator`` command line (see ``gyro_emulator.cli``)."""
