"""
Writing the emulator's records as rosbag2 bags, in the node's topic layout.

Bag layout. A record in our format has the topics of the ROS node
(:mod:`gyro_emulator.ros.node`), all stamped on the sample clock:

========================================  ================================  ==============
topic                                     type                              content
========================================  ================================  ==============
``/cmd/angular_velocity``                 geometry_msgs/Vector3Stamped      true rate, rad/s
``/cmd/temperature``                      sensor_msgs/Temperature           ambient, deg C
``/cmd/linear_acceleration``              geometry_msgs/Vector3Stamped      applied accel.
``/imu/data_raw``                         sensor_msgs/Imu                   gyro, accel output
``/imu/temperature``                      sensor_msgs/Temperature           die temperature
``/gyro_emulator/truth/{rate,bias,...}``  geometry_msgs/Vector3Stamped      model truth
``/gyro_emulator/truth/imu``              sensor_msgs/Imu                   true attitude,
                                                                            rate, force
========================================  ================================  ==============

``truth/imu`` is written where the run integrated an attitude (an
``ImuModel`` run): as the node's, ``orientation`` is the attitude of the
sample (sensor frame to the ENU world, REP 103), ``angular_velocity`` the
true rate and ``linear_acceleration`` the true specific force, covariances 0
(exact).

``gyro-emulator simulate --out DIR`` writes it with :func:`write_simulation_bag`
(sample n at ``start_ns + round(t_n 1e9)``, t_n = n ``GyroModel.sample_period_s``;
the Imu stamp adds the
model's output delay, as the node does).

``cmd/linear_acceleration`` is the applied linear acceleration in the body
frame, gravity excluded, m/s^2, as the node takes it: the node (and every
offline reader) adds gravity from the attitude it integrates from
``cmd/angular_velocity``. A profile that gives its specific force f itself
is written as the applied acceleration that gives f at the attitude
integrated from its rate (:meth:`~gyro_emulator.emulation.run_profile.MotionForce.complete`).
Every bag written here carries ``custom_data``
:data:`~gyro_emulator.recording.topics.ACCEL_CMD_MEANING`
(``cmd_linear_acceleration: applied``), which tells it from a bag written
when that topic held the specific force.

Every ``imu/data_raw`` message carries the gyro's ``angular_velocity`` and,
from an :class:`~gyro_emulator.sensor.imu.ImuModel`, the accelerometer's
``linear_acceleration``, each with the diagonal covariance of the model's
white noise at the output (sigma^2: :attr:`ImuModel.white_noise_sigma_rad_s`,
:attr:`ImuModel.accel_white_noise_sigma_m_s2`); ``orientation_covariance[0]``
is -1 (REP 145: no orientation), and so is ``linear_acceleration_covariance[0]``
when the batch has no accelerometer.
"""

import itertools

from gyro_emulator.recording import bag, cdr, topics
from gyro_emulator.sensor.imu import ImuModel
from gyro_emulator.units import NS_PER_S
import numpy as np

IMU = topics.IMU


TEMPERATURE = topics.TEMPERATURE


VECTOR3_STAMPED = topics.VECTOR3_STAMPED


#: Topics of emulator records (as a bag recorded at the root namespace names them).
RATE_TOPIC = topics.RATE_CMD.bag_name


TEMPERATURE_COMMAND_TOPIC = topics.TEMPERATURE_CMD.bag_name


ACCEL_TOPIC = topics.ACCEL_CMD.bag_name


IMU_TOPIC = topics.IMU_OUT.bag_name


DIE_TEMPERATURE_TOPIC = topics.DIE_TEMPERATURE_OUT.bag_name


TRUTH_NAMESPACE = topics.TRUTH_NAMESPACE


TRUTH_FIELDS = (('rate', 'true_rate_rad_s'), ('bias', 'bias_rad_s'),
                ('scale_factor', 'scale_factor'))


TRUTH_IMU_TOPIC = f'{TRUTH_NAMESPACE}/imu'


MEASURED_TOPIC = topics.REPLAY_MEASURED.bag_name


RESIDUAL_TOPIC = topics.REPLAY_RESIDUAL.bag_name


DEFAULT_FRAME_ID = 'imu_link'


def _imu_values(gyro_rad_s, sigma_rad_s, accel_m_s2=None, accel_sigma_m_s2=(0.0, 0.0, 0.0)):
    """Return the 37 float64 fields of sensor_msgs/Imu (REP 145: absent = -1)."""
    layout = cdr.LAYOUTS[IMU]
    values = np.zeros((len(gyro_rad_s), len(layout.fields)))
    values[:, layout.columns('angular_velocity')] = gyro_rad_s
    _diagonal(values, layout.columns('angular_velocity_covariance').start, sigma_rad_s)
    values[:, layout.index('orientation_covariance[0]')] = -1.0
    if accel_m_s2 is None:
        values[:, layout.index('linear_acceleration_covariance[0]')] = -1.0
    else:
        values[:, layout.columns('linear_acceleration')] = accel_m_s2
        _diagonal(values, layout.columns('linear_acceleration_covariance').start,
                  accel_sigma_m_s2)
    return values


def _truth_imu_values(attitude_wxyz, rate_rad_s, specific_force_m_s2):
    """Return the Imu fields of ``truth/imu``: attitude, true rate and force, covariances 0."""
    layout = cdr.LAYOUTS[IMU]
    q = np.asarray(attitude_wxyz, dtype=float)
    values = np.zeros((len(q), len(layout.fields)))
    values[:, layout.columns('orientation')] = q[:, [1, 2, 3, 0]]      # (x, y, z, w)
    values[:, layout.columns('angular_velocity')] = rate_rad_s
    values[:, layout.columns('linear_acceleration')] = specific_force_m_s2
    return values


def _diagonal(values, start, sigma):
    """Write diag(sigma^2) into the 3x3 row-major covariance at column ``start``."""
    sigma_sq = np.asarray(sigma, dtype=float) ** 2
    for i in range(3):
        values[:, start + 4 * i] = sigma_sq[i]


class EmulatorBagWriter:
    """
    Write emulator samples (inputs, output, truth) into a :class:`bag.BagWriter`.

    Parameters
    ----------
    writer : gyro_emulator.recording.bag.BagWriter
        Destination (topics are added here).
    frame_id : str
        ``header.frame_id`` of every message.
    sigma_rad_s : array_like, shape (3,)
        White-noise sigma for ``angular_velocity_covariance`` (diag sigma^2).
    accel_sigma_m_s2 : array_like, shape (3,)
        The accelerometer's, for ``linear_acceleration_covariance``.
    commands : bool
        Also write the ``cmd/*`` inputs.
    truth : bool
        Also write the ``truth/*`` topics.
    extra : dict of str to str
        Extra Vector3Stamped topics written by :meth:`write_vectors`.
    truth_imu : bool
        With ``truth``, also write ``truth/imu`` (module docstring) from the
        attitudes given to :meth:`write`.

    """

    def __init__(self, writer, frame_id=DEFAULT_FRAME_ID, sigma_rad_s=(0.0, 0.0, 0.0),
                 commands=True, truth=True, extra=(), accel_sigma_m_s2=(0.0, 0.0, 0.0),
                 truth_imu=False):
        self.writer = writer
        self.frame_id = frame_id
        self.sigma_rad_s = np.asarray(sigma_rad_s, dtype=float)
        self.accel_sigma_m_s2 = np.asarray(accel_sigma_m_s2, dtype=float)
        self.commands = commands
        self.truth = truth
        self.truth_imu = truth and truth_imu
        sensor_qos = [bag.qos_profile('best_effort', depth=5)]
        if commands:
            writer.add_topic(RATE_TOPIC, VECTOR3_STAMPED, qos_profiles=sensor_qos)
            writer.add_topic(TEMPERATURE_COMMAND_TOPIC, TEMPERATURE, qos_profiles=sensor_qos)
            writer.add_topic(ACCEL_TOPIC, VECTOR3_STAMPED, qos_profiles=sensor_qos)
        writer.add_topic(IMU_TOPIC, IMU, qos_profiles=sensor_qos)
        writer.add_topic(DIE_TEMPERATURE_TOPIC, TEMPERATURE, qos_profiles=sensor_qos)
        if truth:
            for name, _ in TRUTH_FIELDS:
                writer.add_topic(f'{TRUTH_NAMESPACE}/{name}', VECTOR3_STAMPED,
                                 qos_profiles=sensor_qos)
        if self.truth_imu:
            writer.add_topic(TRUTH_IMU_TOPIC, IMU, qos_profiles=sensor_qos)
        for topic in extra:
            writer.add_topic(topic, VECTOR3_STAMPED)

    def write(self, stamp_ns, rate_rad_s, temp_c, linear_accel_m_s2, batch, published=None,
              attitude_wxyz=None):
        """
        Write one block of samples.

        Parameters
        ----------
        stamp_ns : array_like of int, shape (N,)
            Sample times, ns (the log time of every message of the sample).
        rate_rad_s : numpy.ndarray, shape (N, 3)
            True (commanded) rate, rad/s.
        temp_c : numpy.ndarray, shape (N,)
            Ambient temperature, deg C.
        linear_accel_m_s2 : numpy.ndarray, shape (N, 3), or None
            Applied linear acceleration, body frame, gravity excluded, m/s^2
            (``cmd/linear_acceleration``; None: not written).
        batch : gyro_emulator.sensor.model.SensorBatch
            The model output of these samples (an ImuBatch: with the
            accelerometer's, written as the Imu ``linear_acceleration``).
        published : numpy.ndarray of bool, shape (N,), optional
            The samples with an ``imu/data_raw`` (a dropout withholds the
            others); None: all.
        attitude_wxyz : numpy.ndarray, shape (N, 4), optional
            The attitude of each sample, for ``truth/imu`` (written when the
            writer has that topic).

        """
        stamp_ns = np.asarray(stamp_ns, dtype=np.int64)
        frame = self.frame_id
        delay_ns = np.round(np.asarray(batch.output_delay_s, dtype=float) * NS_PER_S)
        imu_stamp = stamp_ns + delay_ns.astype(np.int64)
        batches = []
        if self.commands:
            temp = np.column_stack([temp_c, np.zeros(len(stamp_ns))])
            batches += [
                (RATE_TOPIC, cdr.encode(VECTOR3_STAMPED, stamp_ns, rate_rad_s, frame), stamp_ns),
                (TEMPERATURE_COMMAND_TOPIC, cdr.encode(TEMPERATURE, stamp_ns, temp, frame),
                 stamp_ns)]
            if linear_accel_m_s2 is not None:
                batches.append((ACCEL_TOPIC, cdr.encode(VECTOR3_STAMPED, stamp_ns,
                                                        linear_accel_m_s2, frame), stamp_ns))
        keep = slice(None) if published is None else np.asarray(published, dtype=bool)
        measured = getattr(batch, 'accel_m_s2', None)
        imu = _imu_values(batch.gyro_rad_s[keep], self.sigma_rad_s,
                          None if measured is None else measured[keep], self.accel_sigma_m_s2)
        batches.append((IMU_TOPIC, cdr.encode(IMU, imu_stamp[keep], imu, frame),
                        stamp_ns[keep]))
        die = np.column_stack([batch.die_temp_c, np.zeros(len(stamp_ns))])
        batches.append((DIE_TEMPERATURE_TOPIC, cdr.encode(TEMPERATURE, stamp_ns, die, frame),
                        stamp_ns))
        if self.truth:
            for name, attr in TRUTH_FIELDS:
                values = np.broadcast_to(np.asarray(getattr(batch, attr), dtype=float),
                                         (len(stamp_ns), 3))
                batches.append((f'{TRUTH_NAMESPACE}/{name}',
                                cdr.encode(VECTOR3_STAMPED, stamp_ns, values, frame),
                                stamp_ns))
        if self.truth_imu and attitude_wxyz is not None:
            truth_imu = _truth_imu_values(attitude_wxyz, batch.true_rate_rad_s,
                                          batch.true_specific_force_m_s2)
            batches.append((TRUTH_IMU_TOPIC, cdr.encode(IMU, stamp_ns, truth_imu, frame),
                            stamp_ns))
        self.writer.write_batches(batches)

    def write_vectors(self, topic, stamp_ns, values):
        """Write an extra Vector3Stamped topic (log time = stamp)."""
        stamp_ns = np.asarray(stamp_ns, dtype=np.int64)
        self.writer.write_batches([(topic, cdr.encode(VECTOR3_STAMPED, stamp_ns, values,
                                                      self.frame_id), stamp_ns)])


def white_noise_sigma(config, rate_hz):
    """Return the gyro's per-sample white-noise sigma at ``rate_hz`` (3,), rad/s."""
    return noise_sigmas(config, rate_hz)[0]


def noise_sigmas(config, rate_hz):
    """
    Return the per-sample white-noise sigmas of the gyro (rad/s) and the accelerometer (m/s^2).

    :attr:`ImuModel.white_noise_sigma_rad_s` and
    :attr:`ImuModel.accel_white_noise_sigma_m_s2` at ``rate_hz``, (3,) each:
    the Imu message's covariances (diag sigma^2).
    """
    model = ImuModel(config, rate_hz, np.random.default_rng(0))
    return model.white_noise_sigma_rad_s, model.accel_white_noise_sigma_m_s2


def simulation_custom_data(config_name, profile, duration_s, rate_hz, seed, temp_c):
    """Return the rosbag2 ``custom_data`` of a simulated record (how to reproduce it)."""
    return {'generator': 'gyro-emulator simulate', 'sensor_config': str(config_name),
            'profile': str(profile), 'duration_s': repr(float(duration_s)),
            'rate_hz': repr(float(rate_hz)), 'seed': str(int(seed)),
            'temp_c': repr(float(temp_c))}


def _marked(custom_data):
    """Return ``custom_data`` with :data:`topics.ACCEL_CMD_MEANING` (module docstring)."""
    return {**(custom_data or {}), **topics.ACCEL_CMD_MEANING}


def write_simulation_bag(path, chunks, progress=None, total=None, config=None,
                         rate_hz=None, custom_data=None, start_ns=0,
                         frame_id=DEFAULT_FRAME_ID, compression='zstd', name=None):
    """
    Write simulation chunks as a rosbag2 bag directory in the emulator layout.

    Parameters
    ----------
    path : str
        Bag directory to create.
    chunks : iterable of gyro_emulator.emulation.run_profile.ProfileChunk
        From ``simulate.iter_simulation``.
    progress : callable, optional
        ``progress(done, total)`` after each chunk.
    total : int, optional
        Total samples, passed to ``progress``.
    config : SensorConfig, optional
        The model configuration: its white-noise sigmas at ``rate_hz`` fill
        the Imu ``angular_velocity_covariance`` and
        ``linear_acceleration_covariance`` (zeros if omitted).
    rate_hz : float, optional
        Sample rate, Hz (with ``config``).
    custom_data : dict, optional
        rosbag2 ``custom_data`` (see :func:`simulation_custom_data`).
    start_ns : int
        Bag time of sample 0, ns.
    frame_id : str
        ``header.frame_id``.
    compression : str
        MCAP chunk compression.
    name : str, optional
        The bag's final name when ``path`` is a staging temporary (it names
        the MCAP file; default: ``path``'s).

    Returns
    -------
    int
        Samples written.

    """
    sigma = accel_sigma = np.zeros(3)
    if config is not None and rate_hz is not None:
        sigma, accel_sigma = noise_sigmas(config, rate_hz)
    done = 0
    chunks = iter(chunks)
    first = next(chunks, None)
    with bag.BagWriter(path, compression=compression, custom_data=_marked(custom_data),
                       flush_interval_s=60.0, name=name) as writer:
        out = EmulatorBagWriter(writer, frame_id, sigma, accel_sigma_m_s2=accel_sigma,
                                truth_imu=getattr(first, 'attitude_wxyz', None) is not None)
        for chunk in itertools.chain(() if first is None else (first,), chunks):
            stamp_ns = start_ns + np.round(chunk.time_s * NS_PER_S).astype(np.int64)
            out.write(stamp_ns, chunk.profile.rate_rad_s, chunk.profile.temp_c,
                      chunk.profile.linear_accel_m_s2, chunk.batch, chunk.published,
                      chunk.attitude_wxyz)
            done += len(chunk.time_s)
            if progress is not None:
                progress(done, total)
    return done


def write_output_bag(path, inputs, batch, comparison, sigma_rad_s, custom_data=None,
                     accel_sigma_m_s2=(0.0, 0.0, 0.0), name=None):
    """
    Write the replay result as a bag: inputs, emulated output, truth, measured, residual.

    Parameters
    ----------
    path : str
        Bag directory to create.
    inputs : ReplayInputs
        What drove the model.
    batch : gyro_emulator.sensor.model.SensorBatch
        The emulated output (an ImuBatch: with the accelerometer's).
    comparison : Comparison
        Matched measured samples (written on ``/replay/measured`` and
        ``/replay/residual`` at the emulated output stamps).
    sigma_rad_s : array_like
        White-noise sigma for the Imu covariance.
    custom_data : dict, optional
        rosbag2 ``custom_data``.
    accel_sigma_m_s2 : array_like
        The accelerometer's white-noise sigma for its covariance.
    name : str, optional
        The bag's final name when ``path`` is a staging temporary (it names
        the MCAP file).

    """
    with bag.BagWriter(path, custom_data=_marked(custom_data), flush_interval_s=60.0,
                       name=name) as writer:
        out = EmulatorBagWriter(writer, inputs.frame_id, sigma_rad_s,
                                extra=(MEASURED_TOPIC, RESIDUAL_TOPIC)
                                if comparison.matched else (), accel_sigma_m_s2=accel_sigma_m_s2)
        out.write(inputs.stamp_ns, inputs.rate_rad_s, inputs.temp_c,
                  inputs.completed().linear_accel_m_s2, batch)
        if comparison.matched:
            out.write_vectors(MEASURED_TOPIC, comparison.stamp_ns, comparison.measured_rad_s)
            out.write_vectors(RESIDUAL_TOPIC, comparison.stamp_ns,
                              comparison.emulated_rad_s - comparison.measured_rad_s)
