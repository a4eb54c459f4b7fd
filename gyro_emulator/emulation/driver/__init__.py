"""
The gyro driver under the ROS node: from times and inputs to output records.

Plain Python (no ROS imports), tested without a ROS graph. :mod:`.core`
holds :class:`~.core.Driver`, which owns everything between the inputs a
node receives and the samples it publishes; its records are in
:mod:`.records`. The driver runs on the machinery here: :mod:`.sample_clock`
(due samples, catch-up and drops), :mod:`.imu_timeline` (one sample per
simulator message), :mod:`.commands` (input checks and stamped command
streams), :mod:`.block_stepper` (the model at block cost),
:mod:`.fault_state` (the injected fault on the clock), :mod:`.record_clock`
(the extended terms' record time), :mod:`.bias_calibration` (the start-up
bias calibration), :mod:`.parameters` (the parameter table and checks) and
:mod:`.book` (the diagnostics counters).
"""
