"""
The emulator's records as bags, and offline replay of a bag through the model.

This module gathers the public names of four others:

- :mod:`.emulator_bag` -- the bag layout of emulator records (the node's
  topics on the sample clock) and its writers;
- :mod:`.replay_inputs` -- what drives the model, read from a bag
  (``command`` or ``imu`` source), and :func:`emulate`;
- :mod:`.replay_report` -- the comparison of emulated and measured output
  (residual statistics, Allan deviations), the report and the plots;
- :mod:`.replay_run` -- :func:`replay_bag`, one whole run (what
  ``gyro-emulator replay`` does).

The same bag, configuration and seed give the identical emulated output.
"""

from gyro_emulator.analysis.emulator_bag import (
    ACCEL_TOPIC, DIE_TEMPERATURE_TOPIC, EmulatorBagWriter, IMU_TOPIC, MEASURED_TOPIC, RATE_TOPIC,
    RESIDUAL_TOPIC, simulation_custom_data, TEMPERATURE_COMMAND_TOPIC, TRUTH_FIELDS,
    TRUTH_NAMESPACE, white_noise_sigma, write_output_bag, write_simulation_bag)
from gyro_emulator.analysis.replay_inputs import (
    emulate, estimate_rate_hz, hold, load_inputs, ReplayInputs, SOURCES)
from gyro_emulator.analysis.replay_report import (
    compare, Comparison, plot_report, report_text, write_report)
from gyro_emulator.analysis.replay_run import replay_bag, ReplayRun

__all__ = [
    'ACCEL_TOPIC', 'compare', 'Comparison', 'DIE_TEMPERATURE_TOPIC', 'emulate',
    'EmulatorBagWriter', 'estimate_rate_hz', 'hold', 'IMU_TOPIC', 'load_inputs',
    'MEASURED_TOPIC', 'plot_report', 'RATE_TOPIC', 'replay_bag', 'ReplayInputs', 'ReplayRun',
    'report_text', 'RESIDUAL_TOPIC', 'simulation_custom_data', 'SOURCES',
    'TEMPERATURE_COMMAND_TOPIC', 'TRUTH_FIELDS', 'TRUTH_NAMESPACE', 'white_noise_sigma',
    'write_output_bag', 'write_report', 'write_simulation_bag']
