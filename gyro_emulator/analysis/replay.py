"""
The emulator's records as bags, and offline replay of a bag through the model.

This module gathers the public names of :mod:`.emulator_bag` (writing
records), :mod:`.replay_inputs` (reading what drives the model) and
:mod:`.replay_report` (comparison, report and plots).

Bag layout. A record in our format has the topics of the ROS node
(:mod:`gyro_emulator.ros.node`), all stamped on the sample clock:

========================================  ================================  ==============
topic                                     type                              content
========================================  ================================  ==============
``/cmd/angular_velocity``                 geometry_msgs/Vector3Stamped      true rate, rad/s
``/cmd/temperature``                      sensor_msgs/Temperature           ambient, deg C
``/cmd/linear_acceleration``              geometry_msgs/Vector3Stamped      specific force
``/imu/data_raw``                         sensor_msgs/Imu                   gyro output
``/imu/temperature``                      sensor_msgs/Temperature           die temperature
``/gyro_emulator/truth/{rate,bias,...}``  geometry_msgs/Vector3Stamped      model truth
========================================  ================================  ==============

``gyro-emulator simulate --out DIR`` writes it with :func:`write_simulation_bag`
(sample n at ``start_ns + round(n / rate_hz * 1e9)``; the Imu stamp adds the
model's output delay, as the node does).

Offline replay (:func:`load_inputs`, :func:`emulate`, :func:`compare`) drives
the error model from a bag:

- ``command`` source: the commanded rate, temperature and specific force of
  our own bags. A command takes effect at the first sample at or after its
  header stamp (within half a sample: zero-order hold, as the node applies
  commands at their stamps). When the rate commands are themselves a regular
  stream at the sample rate, their stamps are the sample times.
- ``imu`` source: the ``angular_velocity`` of a real robot's sensor_msgs/Imu
  is taken as the true rate, one emulated sample per recorded message.

The emulated output is compared with the measured one (the bag's
``imu/data_raw``, or the real IMU itself): residual statistics per axis and
the overlapping Allan deviation (NIST SP 1065 Eq 14) of both. The same bag,
configuration and seed give the identical emulated output.
"""

from gyro_emulator.analysis.emulator_bag import (
    ACCEL_TOPIC, DIE_TEMPERATURE_TOPIC, EmulatorBagWriter, IMU_TOPIC, MEASURED_TOPIC, RATE_TOPIC,
    RESIDUAL_TOPIC, simulation_custom_data, TEMPERATURE_COMMAND_TOPIC, TRUTH_FIELDS,
    TRUTH_NAMESPACE, white_noise_sigma, write_output_bag, write_simulation_bag)
from gyro_emulator.analysis.replay_inputs import (
    emulate, estimate_rate_hz, hold, load_inputs, ReplayInputs, SOURCES)
from gyro_emulator.analysis.replay_report import (
    compare, Comparison, plot_report, report_text, write_report)

__all__ = [
    'ACCEL_TOPIC', 'compare', 'Comparison', 'DIE_TEMPERATURE_TOPIC', 'emulate',
    'EmulatorBagWriter', 'estimate_rate_hz', 'hold', 'IMU_TOPIC', 'load_inputs',
    'MEASURED_TOPIC', 'plot_report', 'RATE_TOPIC', 'ReplayInputs', 'report_text',
    'RESIDUAL_TOPIC', 'simulation_custom_data', 'SOURCES', 'TEMPERATURE_COMMAND_TOPIC',
    'TRUTH_FIELDS', 'TRUTH_NAMESPACE', 'white_noise_sigma', 'write_output_bag', 'write_report',
    'write_simulation_bag']
