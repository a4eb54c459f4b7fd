"""
Offline replay: what drives the model, read from a bag, and the emulated output.

Offline replay (:func:`load_inputs`, :func:`emulate`, :func:`compare`) drives
the error model from a bag:

- ``command`` source: the commanded rate, temperature and applied linear
  acceleration of our own bags (``cmd/linear_acceleration``: body frame,
  gravity excluded, as the node takes it; gravity is turned in from the
  attitude integrated from the rate, as the node does, through
  :class:`~gyro_emulator.emulation.run_profile.MotionForce`). A bag written
  when that topic held the specific force (no ``custom_data``
  ``cmd_linear_acceleration: applied``) has it read as the specific force,
  with a note (:func:`gyro_emulator.recording.record.load_record`). A
  command takes effect at the first sample at or after its header stamp
  (within half a sample: zero-order hold, as the node applies commands at
  their stamps). When the rate commands are themselves a regular
  stream at the sample rate, their stamps are the sample times.
- ``imu`` source: the ``angular_velocity`` of a real robot's sensor_msgs/Imu
  (or a simulator's) is taken as the true rate, one emulated sample per
  recorded message, and its ``linear_acceleration`` (unless marked absent,
  REP 145) as the true specific force.

The model is an :class:`~gyro_emulator.sensor.imu.ImuModel`: the gyro and
the accelerometer both see that specific force; a bag without either leaves it
to the motion (gravity turning with the replayed rate from a level start,
:mod:`gyro_emulator.emulation.profiles`).

The emulated output is compared with the measured one (the bag's
``imu/data_raw``, or the real IMU itself): residual statistics per axis and
the overlapping Allan deviation (NIST SP 1065 Eq 14) of both. The same bag,
configuration and seed give the identical emulated output.
"""

from dataclasses import dataclass, field

from gyro_emulator.emulation.emulator_bag import DEFAULT_FRAME_ID
from gyro_emulator.emulation.profiles import SampledProfile
from gyro_emulator.emulation.run_profile import MotionForce, OwnSamples, run_over_profile
from gyro_emulator.recording import record
from gyro_emulator.sensor.config import load_sensor_config, SensorConfig
from gyro_emulator.sensor.imu import ImuBatch, ImuModel
from gyro_emulator.units import AXES, NS_PER_S
from gyro_emulator.validation import check_choice, check_rate_hz, check_record_values
import numpy as np

SOURCES = record.DRIVE_SOURCES


DEFAULT_TEMP_C = 25.0


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
        Specific force at each sample, m/s^2 (None: left to the motion).
    linear_accel_m_s2 : numpy.ndarray, shape (N, 3), or None
        Applied linear acceleration at each sample, body frame, gravity
        excluded, m/s^2, with a specific force left to the motion (None: zero).
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
    linear_accel_m_s2: np.ndarray = None

    def profile(self):
        """
        Return the inputs as a sampled profile on the stamps (specific force as given).

        Its times are from the first stamp, s (nanosecond-exact where an
        epoch time in seconds would round each step to 0.24 us).
        """
        start_ns = self.stamp_ns[0]
        return SampledProfile(f'replay:{self.source}', (self.stamp_ns - start_ns) / NS_PER_S,
                              self.rate_rad_s, self.temp_c, self.accel_m_s2,
                              linear_accel_m_s2=self.linear_accel_m_s2)

    def completed(self):
        """
        Return the profile's samples with the specific force and the applied acceleration.

        What the chunk loop gives the model, whole
        (:meth:`~gyro_emulator.emulation.run_profile.MotionForce.complete`).
        """
        profile = self.profile()
        count = len(profile.time_s)
        return MotionForce(profile).complete(profile.time_s, profile.own_samples(0, count))[0]


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


def load_inputs(bag, source='auto', rate_topic=None, temperature_topic=None,
                accel_topic=None, measured_topic=None, rate_hz=None, temp_c=None,
                use_log_time=False):
    """
    Read what drives the model from a bag.

    The topics are chosen by :func:`gyro_emulator.recording.record.drive_topics`
    and read by :func:`gyro_emulator.recording.record.load_record`;
    :func:`replay_inputs` turns the record into the inputs.

    Parameters
    ----------
    bag : str or gyro_emulator.recording.bag.BagReader
        The bag: a directory or ``.mcap`` file, or one already open.
    source : str
        ``command`` (``cmd/angular_velocity`` of our bags), ``imu`` (a
        sensor_msgs/Imu's angular velocity as truth) or ``auto`` (command if
        the bag has rate commands, else imu).
    rate_topic : str, optional
        Rate topic: Vector3Stamped (command) or Imu (imu source).
    temperature_topic : str, optional
        sensor_msgs/Temperature with the ambient temperature.
    accel_topic : str, optional
        Vector3Stamped with the applied linear acceleration (command source;
        body frame, gravity excluded).
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
    check_choice('replay', 'source', source, SOURCES)
    reader = record.open_bag(bag)
    source, roles, notes = record.drive_topics(reader, source, rate_topic, temperature_topic,
                                               accel_topic, measured_topic)
    rec = record.load_record(reader, roles, use_log_time=use_log_time)
    # how the record was read (stamps, older acceleration commands); the bag's damage is
    # the caller's (reader.problems)
    notes += [note for note in rec.recovery if note not in reader.problems]
    return replay_inputs(rec, source, notes, rate_hz, temp_c)


def replay_inputs(rec, source, notes=(), rate_hz=None, temp_c=None):
    """
    Return the :class:`ReplayInputs` of a bag record.

    Parameters
    ----------
    rec : gyro_emulator.recording.record.Record
        Read with the roles of :func:`gyro_emulator.recording.record.drive_topics`:
        the rate (commands, or the Imu as truth), the measured gyro, the
        specific force and the temperature, on their native stamps.
    source : str
        ``command`` or ``imu``.
    notes : sequence of str
        Notes so far (how the topics were chosen, how the record was read:
        its stamps, acceleration commands of an older bag).
    rate_hz, temp_c : float, optional
        See :func:`load_inputs`.

    Returns
    -------
    ReplayInputs

    """
    notes = list(notes)
    linear = None
    temp_c = DEFAULT_TEMP_C if temp_c is None else temp_c
    rate_stamp, rate_values = rec.rate.stamp_ns, rec.rate.values
    if len(rate_stamp) < 2:
        raise ValueError(f'{rec.topics["rate"]} has {len(rate_stamp)} message(s): need at least 2')
    _check_drive(rec)
    frame_id = rec.frames.get('gyro') or rec.frames['rate'] or DEFAULT_FRAME_ID
    measured_stamp = measured = None
    if rec.gyro:
        measured_stamp = rec.gyro_stamp_ns
        measured = np.column_stack([rec.gyro[a] for a in AXES])
    rate_hz = _sample_rate_hz(rec.metadata, rate_hz, measured_stamp, rate_stamp, notes)
    half_ns = int(NS_PER_S / rate_hz // 2)
    if source == 'imu':
        stamp, rate, accel = rate_stamp, rate_values, None
        if rec.accel is not None:
            accel = rec.accel.values
            notes.append('specific force from the Imu linear_acceleration')
    else:
        stamp, rate = _command_grid(rate_stamp, rate_values, rate_hz, notes)
        accel = None
        if rec.accel is not None:
            accel = hold(rec.accel.stamp_ns, rec.accel.values, stamp, half_ns,
                         before=np.zeros(3))
        if rec.linear_accel is not None:
            linear = hold(rec.linear_accel.stamp_ns, rec.linear_accel.values, stamp, half_ns,
                          before=np.zeros(3))
    if stamp[0] < 0:        # the emulated bag's log times: MCAP's are unsigned
        raise ValueError(f'{rec.path}: {rec.topics["rate"]} times start at '
                         f'{stamp[0] / NS_PER_S:g} s: allowed >= 0 (the emulated bag stores '
                         'them as its log times); try --use-log-time')
    if rec.temp is not None:
        temp = hold(rec.temp.stamp_ns, rec.temp.values, stamp, half_ns, before=temp_c)
    else:
        temp = np.full(len(stamp), float(temp_c))
        notes.append(f'no temperature topic: ambient held at {temp_c:g} C')
    return ReplayInputs(source=source, stamp_ns=np.asarray(stamp, dtype=np.int64),
                        rate_rad_s=np.ascontiguousarray(rate, dtype=float),
                        temp_c=np.ascontiguousarray(temp, dtype=float),
                        accel_m_s2=None if accel is None else np.ascontiguousarray(accel),
                        linear_accel_m_s2=None if linear is None
                        else np.ascontiguousarray(linear, dtype=float),
                        rate_hz=rate_hz, measured_stamp_ns=measured_stamp,
                        measured_rad_s=measured, topics=_role_topics(rec, source),
                        frame_id=frame_id, notes=notes)


def _check_drive(rec):
    """
    Refuse a drive no part could have had, in one line naming the topic field and message.

    The rule ``simulate --profile`` and ``diagnose`` apply to a record: every
    rate, temperature and acceleration finite, the rate and the ambient
    within :data:`gyro_emulator.validation.RECORD_LIMITS`.
    """
    owner = str(rec.path)
    for role, kind in (('rate', 'rate'), ('temp', 'temp'), ('accel', None),
                       ('linear_accel', None)):
        channel = getattr(rec, role)
        if channel is None:
            continue
        values = np.asarray(channel.values, dtype=float)
        bad = ~np.isfinite(values.reshape(len(values), -1)).all(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(
                f'{owner}: {channel.source} is not finite at message {i} ({int(bad.sum())} of '
                f'{len(bad)} messages): expected finite values')
        if kind is not None:
            check_record_values(owner, channel.source, values, kind)


def _role_topics(rec, source):
    """Return the bag topic of each replay role: rate, measured, accel (command), temperature."""
    roles = {'rate': rec.topics.get('rate'), 'measured': rec.topics.get('gyro')}
    if source == 'command':
        roles['accel'] = rec.topics.get('accel') or rec.topics.get('linear_accel')
    roles['temperature'] = rec.topics.get('temp')
    return roles


def _sample_rate_hz(metadata, rate_hz, measured_stamp, rate_stamp, notes):
    """Return the model rate: given, else the bag's custom_data, else from the stamps."""
    if rate_hz is None and 'rate_hz' in metadata:
        rate_hz = float(metadata['rate_hz'])
        notes.append(f'sample rate {rate_hz:g} Hz from the bag custom_data')
    if rate_hz is None:
        basis = measured_stamp if measured_stamp is not None and measured_stamp.size > 1 \
            else rate_stamp
        rate_hz = estimate_rate_hz(basis)
        notes.append(f'sample rate {rate_hz:g} Hz from the mean stamp interval')
    return check_rate_hz(rate_hz)


def _command_grid(rate_stamp, rate_values, rate_hz, notes):
    """Sample times and rates: the commands themselves, or held on a regular grid."""
    period_ns = NS_PER_S / rate_hz
    diffs = np.diff(rate_stamp)
    if diffs.size and np.all(np.abs(diffs - period_ns) <= 0.01 * period_ns):
        notes.append('one sample per rate command (a regular stream at the sample rate)')
        return rate_stamp, rate_values
    count = int(np.floor((rate_stamp[-1] - rate_stamp[0]) / period_ns + 1e-9)) + 1
    stamp = rate_stamp[0] + np.round(np.arange(count) * period_ns).astype(np.int64)
    notes.append(f'rate commands held (zero-order) on a {rate_hz:g} Hz grid')
    return stamp, hold(rate_stamp, rate_values, stamp, int(period_ns // 2))


def emulate(inputs, config, seed):
    """
    Run the error model over the replay inputs, one output per input sample.

    The inputs are a sampled profile run at its own samples by the one
    chunk loop (:func:`gyro_emulator.emulation.run_profile.run_over_profile`);
    without a specific-force topic the specific force comes from the motion.

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
    model : gyro_emulator.sensor.imu.ImuModel
        The model after the run.
    batch : gyro_emulator.sensor.imu.ImuBatch
        One output per input sample (gyro and accelerometer).

    """
    if not isinstance(config, SensorConfig):
        config = load_sensor_config(config)
    model = ImuModel(config, inputs.rate_hz, np.random.default_rng(int(seed)))
    chunks = run_over_profile(model, OwnSamples(inputs.profile()))
    return model, ImuBatch.concatenate([chunk.batch for chunk in chunks])
