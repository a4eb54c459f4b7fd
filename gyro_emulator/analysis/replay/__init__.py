"""
Offline replay of a bag through the model, and the comparison with what was measured.

- :mod:`.inputs` -- what drives the model, read from a bag (``command`` or
  ``imu`` source), and :func:`~.inputs.emulate`;
- :mod:`.report` -- the comparison of emulated and measured output
  (residual statistics, Allan deviations), the report and the plots;
- :mod:`.run` -- :func:`~.run.replay_bag`, one whole run (what
  ``gyro-emulator replay`` does).

The bag layout of emulator records and its writers are
:mod:`gyro_emulator.emulation.emulator_bag`. The same bag, configuration and
seed give the identical emulated output.
"""
