"""
The emulator's records as bags, and offline replay of a bag through the model.

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

from dataclasses import dataclass, field
import json
import os

from gyro_emulator import units
from gyro_emulator.analysis import allan
from gyro_emulator.recording import bag, cdr
from gyro_emulator.sensor.config import load_sensor_config, SensorConfig
from gyro_emulator.sensor.model import GyroModel
import numpy as np

NS_PER_S = 1_000_000_000
IMU = 'sensor_msgs/msg/Imu'
TEMPERATURE = 'sensor_msgs/msg/Temperature'
VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'

RATE_TOPIC = '/cmd/angular_velocity'
TEMPERATURE_COMMAND_TOPIC = '/cmd/temperature'
ACCEL_TOPIC = '/cmd/linear_acceleration'
IMU_TOPIC = '/imu/data_raw'
DIE_TEMPERATURE_TOPIC = '/imu/temperature'
TRUTH_NAMESPACE = '/gyro_emulator/truth'
TRUTH_FIELDS = (('rate', 'true_rate_rad_s'), ('bias', 'bias_rad_s'),
                ('scale_factor', 'scale_factor'))
MEASURED_TOPIC = '/replay/measured'
RESIDUAL_TOPIC = '/replay/residual'
SOURCES = ('auto', 'command', 'imu')
DEFAULT_FRAME_ID = 'imu_link'
DEFAULT_TEMP_C = 25.0


# --------------------------------------------------------------------------
# Writing emulator records
# --------------------------------------------------------------------------

def _imu_values(gyro_rad_s, sigma_rad_s, accel_m_s2=None):
    """Return the 37 float64 fields of sensor_msgs/Imu (REP 145: absent = -1)."""
    layout = cdr.LAYOUTS[IMU]
    values = np.zeros((len(gyro_rad_s), len(layout.fields)))
    values[:, layout.columns('angular_velocity')] = gyro_rad_s
    start = layout.columns('angular_velocity_covariance').start
    sigma_sq = np.asarray(sigma_rad_s, dtype=float) ** 2
    for i in range(3):
        values[:, start + 4 * i] = sigma_sq[i]
    values[:, layout.index('orientation_covariance[0]')] = -1.0
    if accel_m_s2 is None:
        values[:, layout.index('linear_acceleration_covariance[0]')] = -1.0
    else:
        values[:, layout.columns('linear_acceleration')] = accel_m_s2
    return values


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
    commands : bool
        Also write the ``cmd/*`` inputs.
    truth : bool
        Also write the ``truth/*`` topics.
    extra : dict of str to str
        Extra Vector3Stamped topics written by :meth:`write_vectors`.

    """

    def __init__(self, writer, frame_id=DEFAULT_FRAME_ID, sigma_rad_s=(0.0, 0.0, 0.0),
                 commands=True, truth=True, extra=()):
        self.writer = writer
        self.frame_id = frame_id
        self.sigma_rad_s = np.asarray(sigma_rad_s, dtype=float)
        self.commands = commands
        self.truth = truth
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
        for topic in extra:
            writer.add_topic(topic, VECTOR3_STAMPED)

    def write(self, stamp_ns, rate_rad_s, temp_c, accel_m_s2, batch):
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
        accel_m_s2 : numpy.ndarray, shape (N, 3), or None
            Specific force, m/s^2 (None: not commanded).
        batch : gyro_emulator.sensor.model.SensorBatch
            The model output of these samples.

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
            if accel_m_s2 is not None:
                batches.append((ACCEL_TOPIC, cdr.encode(VECTOR3_STAMPED, stamp_ns,
                                                        accel_m_s2, frame), stamp_ns))
        batches.append((IMU_TOPIC, cdr.encode(
            IMU, imu_stamp, _imu_values(batch.gyro_rad_s, self.sigma_rad_s), frame), stamp_ns))
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
        self.writer.write_batches(batches)

    def write_vectors(self, topic, stamp_ns, values):
        """Write an extra Vector3Stamped topic (log time = stamp)."""
        stamp_ns = np.asarray(stamp_ns, dtype=np.int64)
        self.writer.write_batches([(topic, cdr.encode(VECTOR3_STAMPED, stamp_ns, values,
                                                      self.frame_id), stamp_ns)])


def white_noise_sigma(config, rate_hz):
    """Return the model's per-sample white-noise sigma at ``rate_hz`` (3,), rad/s."""
    return GyroModel(config, rate_hz, np.random.default_rng(0)).white_noise_sigma_rad_s


def simulation_custom_data(config_name, profile, duration_s, rate_hz, seed, temp_c):
    """Return the rosbag2 ``custom_data`` of a simulated record (how to reproduce it)."""
    return {'generator': 'gyro-emulator simulate', 'sensor_config': str(config_name),
            'profile': str(profile), 'duration_s': repr(float(duration_s)),
            'rate_hz': repr(float(rate_hz)), 'seed': str(int(seed)),
            'temp_c': repr(float(temp_c))}


def write_simulation_bag(path, chunks, progress=None, total=None, config=None,
                         rate_hz=None, custom_data=None, start_ns=0,
                         frame_id=DEFAULT_FRAME_ID, compression='zstd'):
    """
    Write simulation chunks as a rosbag2 bag directory in the emulator layout.

    Parameters
    ----------
    path : str
        Bag directory to create.
    chunks : iterable of gyro_emulator.analysis.simulate.SimulationChunk
        From ``simulate.iter_simulation``.
    progress : callable, optional
        ``progress(done, total)`` after each chunk.
    total : int, optional
        Total samples, passed to ``progress``.
    config : SensorConfig, optional
        The model configuration: its white-noise sigma at ``rate_hz`` fills
        the Imu ``angular_velocity_covariance`` (zeros if omitted).
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

    Returns
    -------
    int
        Samples written.

    """
    sigma = np.zeros(3)
    if config is not None and rate_hz is not None:
        sigma = white_noise_sigma(config, rate_hz)
    done = 0
    with bag.BagWriter(path, compression=compression, custom_data=custom_data,
                       flush_interval_s=60.0) as writer:
        out = EmulatorBagWriter(writer, frame_id, sigma)
        for chunk in chunks:
            stamp_ns = start_ns + np.round(chunk.time_s * NS_PER_S).astype(np.int64)
            out.write(stamp_ns, chunk.profile.rate_rad_s, chunk.profile.temp_c,
                      chunk.profile.accel_m_s2, chunk.batch)
            done += len(chunk.time_s)
            if progress is not None:
                progress(done, total)
    return done


# --------------------------------------------------------------------------
# Reading replay inputs
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class ReplayInputs:
    """
    What the model is driven with, and what it is compared against.

    Attributes
    ----------
    source : str
        ``command`` or ``imu``.
    stamp_ns : numpy.ndarray of int64, shape (N,)
        Sample times, ns.
    rate_rad_s : numpy.ndarray, shape (N, 3)
        True rate at each sample, rad/s.
    temp_c : numpy.ndarray, shape (N,)
        Ambient temperature at each sample, deg C.
    accel_m_s2 : numpy.ndarray, shape (N, 3), or None
        Specific force at each sample, m/s^2.
    rate_hz : float
        Model sample rate, Hz.
    measured_stamp_ns : numpy.ndarray of int64 or None
        Stamps of the measured gyro output.
    measured_rad_s : numpy.ndarray, shape (M, 3), or None
        Measured gyro output, rad/s.
    topics : dict
        The bag topics used for each role.
    frame_id : str
        Frame of the measured sensor (or of the commands).
    notes : list of str
        How the inputs were derived (sample-rate origin, defaults used).

    """

    source: str
    stamp_ns: np.ndarray
    rate_rad_s: np.ndarray
    temp_c: np.ndarray
    accel_m_s2: np.ndarray
    rate_hz: float
    measured_stamp_ns: np.ndarray = None
    measured_rad_s: np.ndarray = None
    topics: dict = field(default_factory=dict)
    frame_id: str = DEFAULT_FRAME_ID
    notes: list = field(default_factory=list)


def _find_topic(reader, explicit, suffix, type_name, role):
    """Return the bag topic for a role: explicit, else the one named ``*suffix``."""
    if explicit:
        if explicit not in reader.topics:
            raise ValueError(f'{role} topic {explicit} is not in bag {reader.path}: topics '
                             f'are {", ".join(sorted(reader.topics)) or "(none)"}')
        actual = reader.topics[explicit].type_name
        if actual != type_name:
            raise ValueError(f'{role} topic {explicit} has type {actual}: expected '
                             f'{type_name}')
        return explicit
    if suffix is None:
        return None
    found = sorted(name for name, info in reader.topics.items()
                   if (name == suffix or name.endswith(suffix))
                   and info.type_name == type_name and info.message_count)
    return found[0] if found else None


def _sorted_stream(arrays, use_log_time=False):
    stamps = arrays.log_time_ns if use_log_time or not np.any(arrays.stamp_ns) \
        else arrays.stamp_ns
    order = np.argsort(stamps, kind='stable')
    return stamps[order], order


def hold(source_stamp_ns, source_values, query_ns, tolerance_ns, before=None):
    """
    Zero-order hold: the latest source value stamped at or before each query.

    Parameters
    ----------
    source_stamp_ns : numpy.ndarray of int64, sorted
        Stamps of the source values, ns.
    source_values : numpy.ndarray, shape (M, ...)
        Source values.
    query_ns : numpy.ndarray of int64
        Times to evaluate, ns.
    tolerance_ns : int
        A value stamped up to this much after a query already counts for it
        (half a sample absorbs rounding of the stamps).
    before : array_like, optional
        Value before the first source stamp (default: the first value).

    """
    idx = np.searchsorted(source_stamp_ns, query_ns + tolerance_ns, side='right') - 1
    out = source_values[np.clip(idx, 0, len(source_values) - 1)].copy()
    if before is not None and np.any(idx < 0):
        out[idx < 0] = before
    return out


def estimate_rate_hz(stamp_ns):
    """
    Estimate the sample rate of a stamped stream, Hz.

    The mean interval over the stream, leaving out gaps (intervals above 1.5
    times the median: dropped messages); snapped to a whole number of Hz when
    within 0.1 % of it (stamp jitter), else rounded to 6 significant digits.
    """
    dt = np.diff(np.asarray(stamp_ns, dtype=np.int64))
    dt = dt[dt > 0]
    if dt.size == 0:
        raise ValueError('cannot infer the sample rate: fewer than two distinct stamps '
                         '(pass --rate-hz)')
    dt = dt[dt <= 1.5 * np.median(dt)]
    rate = NS_PER_S / float(np.mean(dt))
    whole = round(rate)
    if whole > 0 and abs(rate - whole) <= 1e-3 * whole:
        return float(whole)
    return float(f'{rate:.6g}')


def load_inputs(reader, source='auto', rate_topic=None, temperature_topic=None,
                accel_topic=None, measured_topic=None, rate_hz=None, temp_c=None,
                use_log_time=False):
    """
    Read what drives the model from a bag.

    Parameters
    ----------
    reader : gyro_emulator.recording.bag.BagReader
        The bag.
    source : str
        ``command`` (``cmd/angular_velocity`` of our bags), ``imu`` (a
        sensor_msgs/Imu's angular velocity as truth) or ``auto`` (command if
        the bag has rate commands, else imu).
    rate_topic : str, optional
        Rate topic: Vector3Stamped (command) or Imu (imu source).
    temperature_topic : str, optional
        sensor_msgs/Temperature with the ambient temperature.
    accel_topic : str, optional
        Vector3Stamped with the specific force (command source).
    measured_topic : str, optional
        sensor_msgs/Imu with the measured output to compare against.
    rate_hz : float, optional
        Model sample rate, Hz (default: the bag's ``custom_data`` rate_hz,
        else :func:`estimate_rate_hz` of the measured or rate stream).
    temp_c : float, optional
        Ambient temperature when the bag has none, deg C (default 25).
    use_log_time : bool
        Use log (receive) times instead of header stamps.

    Returns
    -------
    ReplayInputs

    """
    from gyro_emulator.validation import check_choice
    check_choice('replay', 'source', source, SOURCES)
    notes = []
    if source == 'auto':
        if rate_topic:
            info = reader.topics.get(rate_topic)
            source = 'command' if info is not None and info.type_name == VECTOR3_STAMPED \
                else 'imu'
        else:
            found = _find_topic(reader, None, 'cmd/angular_velocity', VECTOR3_STAMPED, 'rate')
            source = 'command' if found else 'imu'
    if temp_c is None:
        temp_c = DEFAULT_TEMP_C
    topics = {}
    if source == 'command':
        topics['rate'] = _find_topic(reader, rate_topic, 'cmd/angular_velocity',
                                     VECTOR3_STAMPED, 'rate')
        topics['measured'] = _find_topic(reader, measured_topic, 'imu/data_raw', IMU,
                                         'measured')
        topics['accel'] = _find_topic(reader, accel_topic, 'cmd/linear_acceleration',
                                      VECTOR3_STAMPED, 'acceleration')
        default_temp_topic = 'cmd/temperature'
    else:
        topics['rate'] = _find_topic(reader, rate_topic or measured_topic, None, IMU, 'imu')
        if topics['rate'] is None:
            imus = sorted(n for n, t in reader.topics.items()
                          if t.type_name == IMU and t.message_count)
            if not imus:
                raise ValueError(
                    f'bag {reader.path} has neither cmd/angular_velocity '
                    '(geometry_msgs/Vector3Stamped) nor a sensor_msgs/Imu topic to replay; '
                    f'topics: {", ".join(sorted(reader.topics)) or "(none)"}')
            topics['rate'] = imus[0]
            if len(imus) > 1:
                notes.append(f'several Imu topics; using {imus[0]} (choose with --rate-topic)')
        topics['measured'] = topics['rate']
        default_temp_topic = None
    if topics['rate'] is None:
        raise ValueError(f'no rate commands in bag {reader.path}: expected a '
                         'geometry_msgs/Vector3Stamped topic named */cmd/angular_velocity '
                         '(or pass --rate-topic)')
    topics['temperature'] = _find_topic(reader, temperature_topic, default_temp_topic,
                                        TEMPERATURE, 'temperature')

    rate_arrays = reader.read_arrays(topics['rate'])
    if rate_arrays.log_time_ns.size < 2:
        raise ValueError(f'{topics["rate"]} has {rate_arrays.log_time_ns.size} message(s): '
                         'need at least 2')
    rate_stamp, order = _sorted_stream(rate_arrays, use_log_time)
    if source == 'command':
        rate_values = rate_arrays.field('vector')[order]
    else:
        rate_values = rate_arrays.field('angular_velocity')[order]
    frame_id = str(rate_arrays.decoded.frame_id[0]) or DEFAULT_FRAME_ID

    measured_stamp = measured = None
    if topics['measured'] is not None:
        m = rate_arrays if topics['measured'] == topics['rate'] else \
            reader.read_arrays(topics['measured'])
        measured_stamp, m_order = _sorted_stream(m, use_log_time)
        measured = m.field('angular_velocity')[m_order]
        frame_id = str(m.decoded.frame_id[0]) or frame_id

    if rate_hz is None and 'rate_hz' in reader.custom_data:
        rate_hz = float(reader.custom_data['rate_hz'])
        notes.append(f'sample rate {rate_hz:g} Hz from the bag custom_data')
    if rate_hz is None:
        basis = measured_stamp if measured_stamp is not None and measured_stamp.size > 1 \
            else rate_stamp
        rate_hz = estimate_rate_hz(basis)
        notes.append(f'sample rate {rate_hz:g} Hz from the mean stamp interval')
    from gyro_emulator.validation import check_range
    rate_hz = check_range('replay', 'rate_hz', rate_hz, 0.0, 1e6, 'Hz')
    period_ns = NS_PER_S / rate_hz

    if source == 'imu':
        stamp = rate_stamp
        rate = rate_values
        accel = None
        cov0 = rate_arrays.field('linear_acceleration_covariance[0]')[order]
        if np.all(cov0 != -1.0):
            accel = rate_arrays.field('linear_acceleration')[order]
            notes.append('specific force from the Imu linear_acceleration')
    else:
        diffs = np.diff(rate_stamp)
        regular = diffs.size and np.all(np.abs(diffs - period_ns) <= 0.01 * period_ns)
        if regular:
            stamp = rate_stamp
            rate = rate_values
            notes.append('one sample per rate command (a regular stream at the sample rate)')
        else:
            count = int(np.floor((rate_stamp[-1] - rate_stamp[0]) / period_ns + 1e-9)) + 1
            stamp = rate_stamp[0] + np.round(np.arange(count) * period_ns).astype(np.int64)
            rate = hold(rate_stamp, rate_values, stamp, int(period_ns // 2))
            notes.append(f'rate commands held (zero-order) on a {rate_hz:g} Hz grid')
        accel = None
        if topics['accel'] is not None:
            acc = reader.read_arrays(topics['accel'])
            acc_stamp, acc_order = _sorted_stream(acc, use_log_time)
            accel = hold(acc_stamp, acc.field('vector')[acc_order], stamp,
                         int(period_ns // 2), before=np.zeros(3))
    if topics['temperature'] is not None:
        tmp = reader.read_arrays(topics['temperature'])
        tmp_stamp, tmp_order = _sorted_stream(tmp, use_log_time)
        temp = hold(tmp_stamp, tmp.field('temperature')[tmp_order], stamp,
                    int(period_ns // 2), before=temp_c)
    else:
        temp = np.full(len(stamp), float(temp_c))
        notes.append(f'no temperature topic: ambient held at {temp_c:g} C')
    return ReplayInputs(source=source, stamp_ns=np.asarray(stamp, dtype=np.int64),
                        rate_rad_s=np.ascontiguousarray(rate, dtype=float),
                        temp_c=np.ascontiguousarray(temp, dtype=float),
                        accel_m_s2=None if accel is None else np.ascontiguousarray(accel),
                        rate_hz=rate_hz, measured_stamp_ns=measured_stamp,
                        measured_rad_s=measured, topics=topics, frame_id=frame_id,
                        notes=notes)


def emulate(inputs, config, seed):
    """
    Run the error model over the replay inputs.

    Parameters
    ----------
    inputs : ReplayInputs
        From :func:`load_inputs`.
    config : SensorConfig or str
        Error model (or a preset name / YAML path).
    seed : int
        Seed of ``numpy.random.default_rng`` given to the model.

    Returns
    -------
    model : GyroModel
        The model after the run.
    batch : gyro_emulator.sensor.model.SensorBatch
        One output per input sample.

    """
    if not isinstance(config, SensorConfig):
        config = load_sensor_config(config)
    model = GyroModel(config, inputs.rate_hz, np.random.default_rng(int(seed)))
    return model, model.run(inputs.rate_rad_s, inputs.temp_c, inputs.accel_m_s2)


# --------------------------------------------------------------------------
# Comparison
# --------------------------------------------------------------------------

@dataclass(frozen=True)
class Comparison:
    """
    Emulated vs measured gyro output at matched samples.

    Attributes
    ----------
    stamp_ns : numpy.ndarray of int64
        Emulated output stamps of the matched samples, ns.
    emulated_rad_s, measured_rad_s, truth_rad_s : numpy.ndarray, shape (K, 3)
        Outputs and the true (input) rate at the matched samples.
    matched : int
        Samples matched (measured within half a period of an emulated one).
    emulated_count, measured_count : int
        Samples of each stream.
    stats : dict
        Residual statistics (see :func:`compare`).
    adev : dict
        Allan deviation curves, per signal and axis.

    """

    stamp_ns: np.ndarray
    emulated_rad_s: np.ndarray
    measured_rad_s: np.ndarray
    truth_rad_s: np.ndarray
    matched: int
    emulated_count: int
    measured_count: int
    stats: dict
    adev: dict


def _axis_stats(x):
    return {'mean': float(np.mean(x)), 'std': float(np.std(x)),
            'rms': float(np.sqrt(np.mean(x * x))), 'max_abs': float(np.max(np.abs(x))),
            'p95_abs': float(np.percentile(np.abs(x), 95))}


def _adev_curves(signal, rate_hz):
    if signal.shape[0] < 16:
        return None
    curves = []
    for axis in range(3):
        result = allan.overlapping_adev(signal[:, axis], rate_hz)
        curves.append({'taus_s': result.taus_s.tolist(), 'adev_rad_s': result.adev.tolist()})
    return curves


def compare(inputs, batch):
    """
    Match emulated and measured samples and compute the residual statistics.

    Each emulated output (stamped sample time + output delay) is paired with
    the measured sample nearest in stamp, if within half a sample period.
    ``residual = emulated - measured``. With the command source the error
    signals ``output - true rate`` of both are also summarised and their
    Allan deviations overlaid; with the imu source (truth = measured) the
    Allan deviations of the two outputs are.

    Returns
    -------
    Comparison

    """
    delay_ns = np.round(np.asarray(batch.output_delay_s, dtype=float) * NS_PER_S)
    emulated_stamp = inputs.stamp_ns + delay_ns.astype(np.int64)
    if inputs.source == 'imu':
        emulated_stamp = inputs.stamp_ns
    n = len(emulated_stamp)
    stats = {'source': inputs.source, 'rate_hz': inputs.rate_hz, 'samples': n}
    if inputs.measured_rad_s is None or inputs.measured_stamp_ns.size == 0:
        empty = np.zeros((0, 3))
        stats['matched'] = 0
        return Comparison(emulated_stamp[:0], empty, empty, empty, 0, n, 0, stats,
                          {'emulated_error' if inputs.source == 'command' else 'emulated':
                           _adev_curves(batch.gyro_rad_s - inputs.rate_rad_s, inputs.rate_hz)})
    m_stamp = inputs.measured_stamp_ns
    half = NS_PER_S / inputs.rate_hz / 2.0
    right = np.clip(np.searchsorted(m_stamp, emulated_stamp), 0, len(m_stamp) - 1)
    left = np.clip(right - 1, 0, len(m_stamp) - 1)
    pick = np.where(np.abs(m_stamp[left] - emulated_stamp) <=
                    np.abs(m_stamp[right] - emulated_stamp), left, right)
    ok = np.abs(m_stamp[pick] - emulated_stamp) <= half
    # one measured sample pairs with at most one emulated sample
    ok &= np.concatenate(([True], pick[1:] != pick[:-1]))
    emulated = batch.gyro_rad_s[ok]
    measured = inputs.measured_rad_s[pick[ok]]
    truth = inputs.rate_rad_s[ok]
    matched = int(ok.sum())
    stats['matched'] = matched
    stats['measured_samples'] = int(len(m_stamp))
    adev = {}
    if matched:
        residual = emulated - measured
        axes = 'xyz'
        stats['residual_rad_s'] = {axes[i]: _axis_stats(residual[:, i]) for i in range(3)}
        stats['identical'] = bool(np.array_equal(emulated, measured))
        if inputs.source == 'command':
            for name, out in (('measured_error_rad_s', measured),
                              ('emulated_error_rad_s', emulated)):
                err = out - truth
                stats[name] = {axes[i]: _axis_stats(err[:, i]) for i in range(3)}
            adev['measured_error'] = _adev_curves(measured - truth, inputs.rate_hz)
            adev['emulated_error'] = _adev_curves(emulated - truth, inputs.rate_hz)
        else:
            adev['measured'] = _adev_curves(measured, inputs.rate_hz)
            adev['emulated'] = _adev_curves(emulated, inputs.rate_hz)
    return Comparison(emulated_stamp[ok], emulated, measured, truth, matched, n,
                      int(len(m_stamp)), stats, adev)


def write_output_bag(path, inputs, batch, comparison, sigma_rad_s, custom_data=None):
    """
    Write the replay result as a bag: inputs, emulated output, truth, measured, residual.

    Parameters
    ----------
    path : str
        Bag directory to create.
    inputs : ReplayInputs
        What drove the model.
    batch : gyro_emulator.sensor.model.SensorBatch
        The emulated output.
    comparison : Comparison
        Matched measured samples (written on ``/replay/measured`` and
        ``/replay/residual`` at the emulated output stamps).
    sigma_rad_s : array_like
        White-noise sigma for the Imu covariance.
    custom_data : dict, optional
        rosbag2 ``custom_data``.

    """
    with bag.BagWriter(path, custom_data=custom_data, flush_interval_s=60.0) as writer:
        out = EmulatorBagWriter(writer, inputs.frame_id, sigma_rad_s,
                                extra=(MEASURED_TOPIC, RESIDUAL_TOPIC)
                                if comparison.matched else ())
        out.write(inputs.stamp_ns, inputs.rate_rad_s, inputs.temp_c, inputs.accel_m_s2,
                  batch)
        if comparison.matched:
            out.write_vectors(MEASURED_TOPIC, comparison.stamp_ns, comparison.measured_rad_s)
            out.write_vectors(RESIDUAL_TOPIC, comparison.stamp_ns,
                              comparison.emulated_rad_s - comparison.measured_rad_s)


# --------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------

def report_text(comparison, inputs, header=()):
    """Return the comparison as Markdown (residual table in deg/s and deg/h)."""
    lines = ['# Replay report', '']
    lines += [f'- {h}' for h in header]
    used = ', '.join(f'{k}={v}' for k, v in inputs.topics.items() if v)
    lines += [f'- source: {inputs.source} ({used})',
              f'- sample rate: {inputs.rate_hz:g} Hz, {comparison.emulated_count} emulated '
              f'samples, {comparison.measured_count} measured, {comparison.matched} matched']
    lines += [f'- {note}' for note in inputs.notes]
    stats = comparison.stats
    if not comparison.matched:
        lines += ['', 'No measured gyro output to compare with.']
        return '\n'.join(lines) + '\n'
    lines += ['', '## Residual (emulated - measured)', '',
              '| axis | mean (deg/h) | std (deg/s) | RMS (deg/s) | max abs (deg/s) |',
              '|---|---|---|---|---|']
    for axis, s in stats['residual_rad_s'].items():
        lines.append(f'| {axis} | {units.rad_s_to_deg_h(s["mean"]):.4g} | '
                     f'{np.rad2deg(s["std"]):.4g} | {np.rad2deg(s["rms"]):.4g} | '
                     f'{np.rad2deg(s["max_abs"]):.4g} |')
    if 'measured_error_rad_s' in stats:
        lines += ['', '## Errors against the commanded rate (output - truth)', '',
                  '| axis | measured bias (deg/h) | emulated bias (deg/h) | measured std '
                  '(deg/s) | emulated std (deg/s) |', '|---|---|---|---|---|']
        for axis in 'xyz':
            m, e = stats['measured_error_rad_s'][axis], stats['emulated_error_rad_s'][axis]
            lines.append(f'| {axis} | {units.rad_s_to_deg_h(m["mean"]):.4g} | '
                         f'{units.rad_s_to_deg_h(e["mean"]):.4g} | '
                         f'{np.rad2deg(m["std"]):.4g} | {np.rad2deg(e["std"]):.4g} |')
    if stats.get('identical'):
        lines += ['', 'The emulated output is identical to the measured one.']
    return '\n'.join(lines) + '\n'


def plot_report(comparison, inputs, out_dir):
    """Write rates.png, residual.png and allan.png; return their paths."""
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib import pyplot as plt

    paths = []
    if not comparison.matched:
        return paths
    t = (comparison.stamp_ns - comparison.stamp_ns[0]) / NS_PER_S
    step = max(1, len(t) // 20000)
    deg = np.rad2deg
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    for i, ax in enumerate(axes):
        ax.plot(t[::step], deg(comparison.measured_rad_s[::step, i]), lw=0.6,
                label='measured')
        ax.plot(t[::step], deg(comparison.emulated_rad_s[::step, i]), lw=0.6, alpha=0.8,
                label='emulated')
        if inputs.source == 'command':
            ax.plot(t[::step], deg(comparison.truth_rad_s[::step, i]), 'k--', lw=0.6,
                    label='commanded')
        ax.set_ylabel(f'{"xyz"[i]} (deg/s)')
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8, loc='upper right')
    axes[-1].set_xlabel('time (s)')
    fig.suptitle('Gyro output: measured vs emulated')
    fig.tight_layout()
    paths.append(os.path.join(out_dir, 'rates.png'))
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    residual = deg(comparison.emulated_rad_s - comparison.measured_rad_s)
    fig, axes = plt.subplots(3, 2, figsize=(10, 7), gridspec_kw={'width_ratios': [3, 1]})
    for i in range(3):
        axes[i, 0].plot(t[::step], residual[::step, i], lw=0.5)
        axes[i, 0].set_ylabel(f'{"xyz"[i]} (deg/s)')
        axes[i, 0].grid(True, alpha=0.3)
        axes[i, 1].hist(residual[:, i], bins=60)
    axes[-1, 0].set_xlabel('time (s)')
    fig.suptitle('Residual: emulated - measured')
    fig.tight_layout()
    paths.append(os.path.join(out_dir, 'residual.png'))
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)

    curves = {k: v for k, v in comparison.adev.items() if v}
    if curves:
        fig, axes = plt.subplots(1, 3, figsize=(12, 4), sharey=True)
        for i, ax in enumerate(axes):
            for name, per_axis in sorted(curves.items()):
                ax.loglog(per_axis[i]['taus_s'],
                          units.rad_s_to_deg_h(np.asarray(per_axis[i]['adev_rad_s'])),
                          'o-' if name.startswith('measured') else 's--', ms=3,
                          label=name.replace('_', ' '))
            ax.set_title(f'{"xyz"[i]} axis')
            ax.set_xlabel('tau (s)')
            ax.grid(True, which='both', alpha=0.3)
        axes[0].set_ylabel('Allan deviation (deg/h)')
        axes[0].legend(fontsize=8)
        fig.suptitle('Overlapping Allan deviation: measured vs emulated')
        fig.tight_layout()
        paths.append(os.path.join(out_dir, 'allan.png'))
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    return paths


def write_report(out_dir, comparison, inputs, header=(), plots=True):
    """Write report.json, report.md and the PNG plots into ``out_dir``; return the paths."""
    os.makedirs(out_dir, exist_ok=True)
    paths = []
    data = {'stats': comparison.stats, 'topics': inputs.topics, 'notes': inputs.notes,
            'header': list(header), 'adev': comparison.adev}
    path = os.path.join(out_dir, 'report.json')
    with open(path, 'w', encoding='utf-8') as handle:
        json.dump(data, handle, indent=1)
    paths.append(path)
    path = os.path.join(out_dir, 'report.md')
    with open(path, 'w', encoding='utf-8') as handle:
        handle.write(report_text(comparison, inputs, header))
    paths.append(path)
    if plots:
        paths += plot_report(comparison, inputs, out_dir)
    return paths
