"""
One measured record: times, applied rate, temperature, gyro and acceleration, from CSV or a bag.

A :class:`Record` holds what a record carries, each part optional where the
source lacks it, with the column or topic field each came from, what a
damaged bag lost, and its timing (rate, segments and missing samples: a
:class:`gyro_emulator.recording.timing.Timing`, worked out on first use and
kept, :meth:`Record.timing`) and value grid (:func:`grid_step`).
It is built from plain arrays (a synthetic record) or by
:func:`load_record`, the one loader of CSV (``.gz`` too, through
:func:`gyro_emulator.recording.csvio.read_csv`) and bags (a directory or
``.mcap`` file through :class:`gyro_emulator.recording.bag.BagReader`,
tolerant of damage). ``allan``, ``calibrate``, ``diagnose`` and ``replay``
all read their input here, so a record means the same thing to all of them.

Roles. The CSV column of each role is :data:`CSV_COLUMNS`; the bag topic
of each role is the one the user names (:func:`find_topic`: exact, with a
leading ``/``, or a unique suffix) or the default of :data:`DEFAULT_TOPICS`
(names from :mod:`gyro_emulator.recording.topics`); the field of each
message type is :data:`VECTOR_FIELDS` / :data:`SCALAR_FIELDS`. What drives a
model replaying a bag (the commands, or an Imu as truth) and its topics is
:func:`drive_topics`.

The stamp rule (a message's time: its header stamp, else its log time) is
:mod:`gyro_emulator.recording.streams`'s.
"""

from dataclasses import dataclass, field, replace
import math
import os
from types import MappingProxyType

from gyro_emulator.recording import bag, binning, csvio, topics as table
from gyro_emulator.recording.streams import read_stream
from gyro_emulator.recording.timing import check_increasing, GAP_FACTOR, timing_of
from gyro_emulator.units import AXES
import numpy as np


def _resolve_name(topics, name):
    """Return the topic called ``name``: exact, with a leading '/', or a unique suffix."""
    for candidate in (name, '/' + name.lstrip('/')):
        if candidate in topics:
            return candidate
    tail = [t for t in topics if t.endswith('/' + name.lstrip('/'))]
    return tail[0] if len(tail) == 1 else None


def find_topic(reader, role, name=None, default=None, types=None):
    """
    Return the bag topic that plays ``role``, or None when a default is absent.

    Parameters
    ----------
    reader : gyro_emulator.recording.bag.BagReader
        The bag.
    role : str
        What the topic is for, for error messages (e.g. ``'rate'``).
    name : str, optional
        The user's choice: the exact topic, the topic with a leading ``/``,
        or the one topic whose name ends with ``/name``. A name that matches
        nothing, or a topic of a type outside ``types``, raises ValueError.
    default : str, optional
        Without ``name``: the topics named ``default`` or ending with
        ``/default`` (a namespace prefix is allowed) that have messages and a
        type in ``types``; the first in name order, or None.
    types : sequence of str, optional
        Allowed message types (``pkg/msg/Type``); None allows any.

    Returns
    -------
    str or None

    """
    topics = reader.topics
    if name:
        found = _resolve_name(topics, name)
        if found is None:
            raise ValueError(f'bag {reader.path}: no topic {name!r} for the {role}; topics: '
                             f'{", ".join(sorted(topics)) or "(none)"}')
        actual = topics[found].type_name
        if types is not None and actual not in types:
            raise ValueError(f'{role} topic {found} has type {actual}: expected '
                             f'{" or ".join(types)}')
        return found
    if default is None:
        return None
    key = default.lstrip('/')
    found = sorted(t for t, info in topics.items()
                   if (t.lstrip('/') == key or t.endswith('/' + key)) and info.message_count
                   and (types is None or info.type_name in types))
    return found[0] if found else None


def is_bag(path):
    """Return whether ``path`` is a bag (a directory or an ``.mcap`` file), else a CSV file."""
    return os.path.isdir(path) or str(path).endswith('.mcap')


#: CSV column of each role (gyro: one of the layouts of :func:`csvio.gyro_columns`).
#: rate_axes: the applied rate about each axis, as ``simulate`` writes it (read when the
#: file has no single ``rate_cmd_rad_s`` column).
CSV_COLUMNS = MappingProxyType({'time': 'time_s', 'rate': 'rate_cmd_rad_s', 'temp': 'temp_c',
                                'rate_axes': tuple(f'rate_{a}_rad_s' for a in AXES),
                                'gyro': (csvio.GYRO_SINGLE,) + csvio.GYRO_AXES,
                                'accel': ('accel_x_m_s2', 'accel_y_m_s2', 'accel_z_m_s2')})
#: Default bag topic of each role when the user names none (gyro: the only Imu topic;
#: temp: the commanded ambient; die_temp: the die temperature the node publishes).
DEFAULT_TOPICS = MappingProxyType({
    'gyro': None, 'rate': table.RATE_CMD.name, 'temp': table.TEMPERATURE_CMD.name,
    'die_temp': table.DIE_TEMPERATURE_OUT.name, 'accel': table.ACCEL_CMD.name,
    'output': table.IMU_OUT.name})
#: Message field of a 3-vector role by type (``{kind}``: :data:`FIELD_KIND`).
VECTOR_FIELDS = MappingProxyType({
    'geometry_msgs/msg/Vector3Stamped': 'vector.{axis}',
    'geometry_msgs/msg/TwistStamped': 'twist.angular.{axis}',
    'geometry_msgs/msg/AccelStamped': 'accel.linear.{axis}',
    'sensor_msgs/msg/Imu': '{kind}.{axis}',
    'geometry_msgs/msg/Vector3': '{axis}',
    'std_msgs/msg/Float64': 'data'})
#: Message field of the temperature by type.
SCALAR_FIELDS = MappingProxyType({'sensor_msgs/msg/Temperature': 'temperature',
                                  'std_msgs/msg/Float64': 'data'})
#: The Imu field of each vector role.
FIELD_KIND = MappingProxyType({'rate': 'angular_velocity', 'gyro': 'angular_velocity',
                               'accel': 'linear_acceleration'})
#: What each role is called in messages.
ROLE_LABELS = MappingProxyType({'gyro': 'gyro', 'rate': 'rate', 'temp': 'temperature',
                                'accel': 'acceleration'})
#: A grid is a quantisation step when every sample lies on it within this fraction.
GRID_TOLERANCE = 0.02


def grid_step(values, max_unique=200_000):
    """
    Return the grid samples lie on, whatever its size, or 0, and their distinct values.

    The smallest gap between distinct values, refined over all gaps, is a
    grid when every sample is on it within :data:`GRID_TOLERANCE` of a step
    and there are 2 to ``max_unique`` distinct values.
    """
    values = np.asarray(values, dtype=float)
    unique = np.unique(values)
    if len(unique) < 2 or len(unique) > max_unique:
        return 0.0, len(unique)
    gaps = np.diff(unique)
    smallest = float(np.min(gaps))
    if not smallest > 0.0:
        return 0.0, len(unique)
    # A subnormal smallest gap or values near the float limits overflow: no grid.
    with np.errstate(over='ignore', invalid='ignore', divide='ignore'):
        counts = np.round(gaps / smallest)
        step = float(np.sum(gaps) / np.sum(counts))
        offsets = (unique - unique[0]) / step
        misfit = np.max(np.abs(offsets - np.round(offsets)))
    if not (math.isfinite(step) and step > 0.0 and misfit <= GRID_TOLERANCE):
        return 0.0, len(unique)
    return step, len(unique)


@dataclass(frozen=True)
class Channel:
    """
    One input of a record on its own times: the applied rate, a temperature or acceleration.

    Attributes
    ----------
    time_s : numpy.ndarray
        Sample times, s, on the record's clock (:attr:`Record.time_s`).
    values : numpy.ndarray
        Shape (n,) for a temperature, (n, 3) for a vector (x, y, z), or
        (n,) for a CSV's single applied-rate column (the sense axis).
    source : str
        The column(s) or ``topic field`` it came from.
    stamp_ns : numpy.ndarray of int64 or None
        A bag's message times, ns (the stamp rule); None for CSV.

    """

    time_s: np.ndarray
    values: np.ndarray
    source: str
    stamp_ns: np.ndarray = None

    def axis(self, axis):
        """Return the values of ``axis`` ('x', 'y', 'z'): a column of a vector, else the values."""
        values = np.asarray(self.values)
        return values if values.ndim == 1 else values[:, AXES.index(axis)]


@dataclass(frozen=True)
class Record:
    """
    One measured record, SI units; parts a source lacks are None (or empty).

    Attributes
    ----------
    time_s : numpy.ndarray
        Gyro sample times, s, non-decreasing: a CSV's ``time_s``, or a
        bag's stamps from the first gyro message.
    gyro : dict
        Axis ('x', 'y', 'z') -> gyro output, rad/s: the axes the record
        has (a single-axis CSV's ``gyro_rad_s`` is taken as axis 'x').
    gyro_sources : dict
        Axis -> the column or topic field it came from.
    rate, temp, accel : Channel or None
        Applied (true) rate, rad/s; temperature, deg C; specific force
        (gravity included: a CSV's accelerometer, an Imu's, an older bag's
        commands), m/s^2, each on its own times (a CSV's share ``time_s``).
    linear_accel : Channel or None
        Applied linear acceleration, body frame, gravity excluded, m/s^2: a
        bag's ``cmd/linear_acceleration`` where its ``custom_data`` says so
        (:func:`~gyro_emulator.recording.topics.accel_commands_applied`).
    path : str
        Where it was read from (a synthetic record: a name).
    recovery : tuple of str
        What a damaged bag lost, what reading a long CSV averaged away
        (``max_rows`` of :func:`load_record`), or that a bag's acceleration
        commands were read as the specific force, one note each; () if none.
    gyro_stamp_ns : numpy.ndarray of int64 or None
        A bag's gyro message times, ns; None for CSV.
    names : tuple of str
        The CSV columns read (for messages); () for a bag.
    topics : dict
        Role -> the bag topic it came from.
    frames : dict
        Role -> the ``header.frame_id`` of its topic's first message (bag
        order); {} for CSV.
    metadata : dict
        A bag's ``custom_data`` (:class:`gyro_emulator.recording.bag.BagReader`);
        {} for CSV.

    The gyro's timing is worked out once per gap factor and kept
    (:meth:`timing`).

    """

    time_s: np.ndarray
    gyro: dict = field(default_factory=dict)
    gyro_sources: dict = field(default_factory=dict)
    rate: Channel = None
    temp: Channel = None
    accel: Channel = None
    path: str = ''
    recovery: tuple = ()
    gyro_stamp_ns: np.ndarray = None
    names: tuple = ()
    topics: dict = field(default_factory=dict)
    frames: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)
    linear_accel: Channel = None
    _timings: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @classmethod
    def from_arrays(cls, time_s, gyro_rad_s, rate_rad_s=None, temp_c=None, accel_m_s2=None,
                    path=''):
        """
        Build a record from plain arrays on one time base (a synthetic record, no file).

        ``gyro_rad_s`` is (n,) (axis 'x', as a single-axis CSV) or (n, 3);
        ``rate_rad_s`` (n,) or (n, 3); ``temp_c`` (n,); ``accel_m_s2`` (n, 3).
        """
        t = np.asarray(time_s, dtype=float)
        g = np.asarray(gyro_rad_s, dtype=float)
        gyro = {'x': g} if g.ndim == 1 else {a: g[:, i] for i, a in enumerate(AXES)}
        sources = ({'x': csvio.GYRO_SINGLE} if g.ndim == 1
                   else dict(zip(AXES, csvio.GYRO_AXES)))

        def channel(values, source):
            return None if values is None else Channel(t, np.asarray(values, dtype=float),
                                                       source)

        return cls(t, gyro, sources, channel(rate_rad_s, CSV_COLUMNS['rate']),
                   channel(temp_c, CSV_COLUMNS['temp']),
                   channel(accel_m_s2, ', '.join(CSV_COLUMNS['accel'])), path)

    @property
    def is_bag(self):
        """Return whether the record was read from a bag."""
        return self.gyro_stamp_ns is not None

    def timing(self, gap_factor=GAP_FACTOR):
        """
        Return the :class:`~gyro_emulator.recording.timing.Timing` of the gyro's times.

        Worked out on the first call for each ``gap_factor``
        (:func:`~gyro_emulator.recording.timing.timing_of`) and kept: every
        axis and every analysis of the record reads the same one.
        """
        key = float(gap_factor)
        if key not in self._timings:
            self._timings[key] = timing_of(self.time_s, key)
        return self._timings[key]

    def gyro_axis(self, axis=None):
        """
        Return (gyro output, rad/s; its column or topic field) of ``axis`` ('x', 'y', 'z').

        None: the record's first axis. A missing axis is a ValueError naming
        the ones the record has (:func:`gyro_emulator.recording.csvio.gyro_column_of`).
        """
        column = csvio.gyro_column_of(self.require_gyro().gyro_sources, axis, self.path)
        axis = next(a for a, c in self.gyro_sources.items() if c == column)
        return self.gyro[axis], column

    def accel_axis(self, axis):
        """
        Return (specific force, m/s^2; its column or topic field) of accelerometer ``axis``.

        ValueError when the record has no accelerometer.
        """
        if self.accel is None:
            raise ValueError(f'{self.path}: no accelerometer (columns '
                             f'{", ".join(CSV_COLUMNS["accel"])}, or an Imu topic\'s '
                             'linear_acceleration)')
        i = AXES.index(axis)
        names = self.accel.source.split(', ')
        column = names[i] if len(names) == 3 else f'{self.accel.source}.{axis}'
        return np.asarray(self.accel.values, dtype=float)[:, i], column

    def accel_timing(self, gap_factor=GAP_FACTOR):
        """
        Return the :class:`~gyro_emulator.recording.timing.Timing` of the accelerometer's times.

        The gyro's (:meth:`timing`) when they are the same samples (a CSV,
        or an Imu's linear_acceleration), else worked out once and kept.
        """
        times = self.accel.time_s
        if len(times) == len(self.time_s) and np.array_equal(times, self.time_s):
            return self.timing(gap_factor)
        key = ('accel', float(gap_factor))
        if key not in self._timings:
            self._timings[key] = timing_of(times, float(gap_factor))
        return self._timings[key]

    def require_gyro(self):
        """Return the record; ValueError naming the accepted gyro columns when it has none."""
        if not self.gyro:
            csvio.gyro_columns(self.names, self.path)
        return self

    def grid_step(self, axis, scale=1.0):
        """Return the grid the samples of ``axis`` (times ``scale``) lie on (:func:`grid_step`)."""
        return grid_step(self.gyro[axis] * scale if scale != 1.0 else self.gyro[axis])


def load_record(path, topics=None, required=('time_s',), only=None,
                time_order='nondecreasing', use_log_time=False, max_rows=None):
    """
    Read a record: a bag directory or ``.mcap`` file, else a CSV file (``.gz`` ok).

    Parameters
    ----------
    path : str, os.PathLike or gyro_emulator.recording.bag.BagReader
        The record, or a bag already open (:func:`open_bag`).
    topics : dict, optional
        Bag: role ('gyro', 'rate', 'temp' or 'die_temp', 'accel' or
        'imu_accel') -> the topic to read it from, read in the order given.
        A role given as None takes its default from :data:`DEFAULT_TOPICS`
        when the bag has one of a fitting type (the gyro: the bag's only
        sensor_msgs/Imu topic); an accel of ``'none'`` is skipped; a role
        left out is not read (without 'gyro' the record has no gyro and its
        clock starts at the first message read). 'die_temp' fills
        :attr:`Record.temp`; 'imu_accel' (a named sensor_msgs/Imu; None:
        the gyro's, when 'gyro' comes first) fills :attr:`Record.accel` with
        its ``linear_acceleration`` unless the Imu marks it absent (REP 145:
        covariance element 0 = -1). 'accel' from a Vector3Stamped (commands)
        fills :attr:`Record.linear_accel` when the bag marks them applied,
        else :attr:`Record.accel`, said in :attr:`Record.recovery`
        (:func:`~gyro_emulator.recording.topics.old_accel_note`). Default:
        the gyro only.
    required, only, time_order
        CSV: see :func:`gyro_emulator.recording.csvio.read_csv`.
    use_log_time : bool
        Bag: log (receive) times for every topic (the module's stamp rule).
    max_rows : int, optional
        CSV: most rows held; a longer file is read in blocks and averaged over
        time bins to at most this many (:mod:`gyro_emulator.recording.binning`,
        said in :attr:`Record.recovery`). Default: every row.

    Returns
    -------
    Record

    """
    roles = {'gyro': None} if topics is None else dict(topics)
    if isinstance(path, bag.BagReader):
        return _load_bag(path, path.path, roles, use_log_time)
    path = os.fspath(path)
    if is_bag(path):
        return _load_bag(bag.BagReader(path, tolerant=True), path, roles, use_log_time)
    columns, note = binning.read_csv_bounded(path, required, time_order, only, max_rows)
    record = _from_columns(path, columns)
    return record if note is None else replace(record, recovery=(str(note),))


def _rate_channel(t, columns):
    """
    Return a CSV's applied rate as a :class:`Channel`, or None.

    Its ``rate_cmd_rad_s`` column (the sense axis), else its
    ``rate_{x,y,z}_rad_s`` columns as a vector (as ``simulate`` writes).
    """
    if CSV_COLUMNS['rate'] in columns:
        return Channel(t, columns[CSV_COLUMNS['rate']], CSV_COLUMNS['rate'])
    axes = CSV_COLUMNS['rate_axes']
    if all(c in columns for c in axes):
        return Channel(t, np.column_stack([columns[c] for c in axes]), ', '.join(axes))
    return None


def _from_columns(path, columns):
    """Return the :class:`Record` of CSV ``columns`` (the roles of :data:`CSV_COLUMNS`)."""
    t = columns['time_s']
    try:
        found = csvio.gyro_columns(columns, path)
    except ValueError:
        found = {}
    accel = CSV_COLUMNS['accel']

    def channel(values, source):
        return None if values is None else Channel(t, values, source)

    return Record(
        t, {a: columns[c] for a, c in found.items()}, found, rate=_rate_channel(t, columns),
        temp=channel(columns.get(CSV_COLUMNS['temp']), CSV_COLUMNS['temp']),
        accel=channel(np.column_stack([columns[c] for c in accel]), ', '.join(accel))
        if all(c in columns for c in accel) else None,
        path=path, names=tuple(columns))


def _measured_first(names):
    """Return the topics of ``names`` that are not a node's truth, or all when none is not."""
    return [name for name in names if not table.is_truth(name)] or list(names)


def _only_imu(reader, path, notes):
    """
    Return the bag's one Imu topic (a node's ``~/truth/imu`` only alone), or the one with messages.

    Choosing among several is said in ``notes``; ValueError naming the topics
    when none or more than one has messages.
    """
    imu = _measured_first([name for name, info in reader.topics.items()
                           if info.type_name == table.IMU])
    if len(imu) == 1:
        return imu[0]
    full = [name for name in imu if reader.topics[name].message_count]
    if len(imu) > 1 and len(full) == 1:
        empty = ', '.join(name for name in imu if name != full[0])
        notes.append(f'{len(imu)} sensor_msgs/Imu topics: using {full[0]}, the only one with '
                     f'messages ({empty} has none)')
        return full[0]
    raise ValueError(f'{path}: {len(imu)} sensor_msgs/Imu topics '
                     f'({", ".join(imu) or "none"}): choose one with --topic')


#: What drives a model replaying a bag: ``command`` (the rate, temperature and
#: acceleration commands of the emulator's layout), ``imu`` (a sensor_msgs/Imu's
#: angular velocity taken as the true rate); ``auto``: command when the bag has
#: rate commands, else imu.
DRIVE_SOURCES = ('auto', 'command', 'imu')


def _drive_source(reader, source, rate):
    """Turn ``auto`` into ``command`` (the bag has rate commands) or ``imu``."""
    if source != 'auto':
        return source
    if rate:
        found = find_topic(reader, 'rate', rate)
        return 'command' if reader.topics[found].type_name == table.VECTOR3_STAMPED else 'imu'
    found = find_topic(reader, 'rate', default=table.RATE_CMD.name,
                       types=(table.VECTOR3_STAMPED,))
    return 'command' if found else 'imu'


def _first_imu(reader, notes):
    """Return the first Imu topic with messages, a node's truth only alone (noted when several)."""
    imus = _measured_first(sorted(n for n, t in reader.topics.items()
                                  if t.type_name == table.IMU and t.message_count))
    if not imus:
        raise ValueError(
            f'bag {reader.path} has neither {table.RATE_CMD.name} '
            '(geometry_msgs/Vector3Stamped) nor a sensor_msgs/Imu topic to replay; '
            f'topics: {", ".join(sorted(reader.topics)) or "(none)"}')
    if len(imus) > 1:
        notes.append(f'several Imu topics; using {imus[0]} (choose with --rate-topic)')
    return imus[0]


def drive_topics(reader, source='auto', rate=None, temp=None, accel=None, gyro=None):
    """
    Return what drives a model replaying a bag, and the topic of each role.

    Parameters
    ----------
    reader : gyro_emulator.recording.bag.BagReader
        The bag (:func:`open_bag`).
    source : str
        One of :data:`DRIVE_SOURCES`.
    rate, temp, accel, gyro : str, optional
        The user's topics (:func:`find_topic`): the rate commands
        (Vector3Stamped) or the Imu taken as truth; the ambient temperature
        (sensor_msgs/Temperature); the specific force commands
        (Vector3Stamped); the measured output (sensor_msgs/Imu).

    Returns
    -------
    source : str
        ``command`` or ``imu``.
    roles : dict
        The ``topics`` of :func:`load_record`, in reading order. command:
        'rate', 'gyro' (the measured output), 'accel', 'temp' (defaults
        from :data:`DEFAULT_TOPICS`); imu: the Imu as 'rate', 'gyro' and
        'imu_accel', and 'temp' when named. Roles the bag lacks are left out.
    notes : list of str
        How a topic was chosen (several Imu topics).

    """
    notes = []
    source = _drive_source(reader, source, rate)
    if source == 'command':
        vector = (table.VECTOR3_STAMPED,)
        found = {'rate': find_topic(reader, 'rate', rate, table.RATE_CMD.name, vector),
                 'gyro': find_topic(reader, 'measured', gyro, table.IMU_OUT.name,
                                    (table.IMU,)),
                 'accel': find_topic(reader, 'acceleration', accel, table.ACCEL_CMD.name,
                                     vector)}
        default_temp = table.TEMPERATURE_CMD.name
        if found['rate'] is None:
            raise ValueError(f'no rate commands in bag {reader.path}: expected a '
                             f'geometry_msgs/Vector3Stamped topic named */{table.RATE_CMD.name} '
                             '(or pass --rate-topic)')
    else:
        imu = find_topic(reader, 'imu', rate or gyro, types=(table.IMU,))
        if imu is None:
            imu = _first_imu(reader, notes)
        found = {'rate': imu, 'gyro': imu, 'imu_accel': imu}
        default_temp = None
    found['temp'] = find_topic(reader, 'temperature', temp, default_temp, (table.TEMPERATURE,))
    return source, {k: v for k, v in found.items() if v is not None}, notes


def _role_values(stream, role, axis_fields=AXES):
    """Return the (n,) or (n, 3) values of ``role`` in ``stream`` and the field names."""
    table_ = SCALAR_FIELDS if role == 'temp' else VECTOR_FIELDS
    if stream.type_name not in table_:
        raise ValueError(
            f'bag topic {stream.topic} has type {stream.type_name}, which cannot give '
            f'the {role}: allowed {", ".join(sorted(table_))}')
    fmt = table_[stream.type_name]
    if role == 'temp':
        return stream.field(fmt), fmt
    if fmt == 'data':
        if role == 'accel':
            raise ValueError(f'bag topic {stream.topic}: a Float64 cannot hold a '
                             '3-axis acceleration')
        values = stream.field(fmt)
        return np.column_stack([values] * 3), fmt
    names = [fmt.format(kind=FIELD_KIND[role], axis=a) for a in axis_fields]
    return np.column_stack([stream.field(name) for name in names]), names[0][:-2]


#: The roles a bag record reads, and the Record part each fills.
_BAG_ROLES = MappingProxyType({'gyro': 'gyro', 'rate': 'rate', 'temp': 'temp',
                               'die_temp': 'temp', 'accel': 'accel', 'imu_accel': 'accel'})


def _role_topic(reader, path, key, given, notes):
    """Return the topic of role ``key`` (:func:`load_record`), or None to skip it."""
    role = _BAG_ROLES[key]
    if key == 'gyro':
        return (_only_imu(reader, path, notes) if given is None
                else find_topic(reader, 'gyro', given))
    if key == 'accel' and given == 'none':
        return None
    if given:
        return find_topic(reader, ROLE_LABELS[role], given)
    types = tuple(SCALAR_FIELDS if role == 'temp' else VECTOR_FIELDS)
    return find_topic(reader, ROLE_LABELS[role], default=DEFAULT_TOPICS.get(key), types=types)


def _imu_accel_absent(stream):
    """Return whether an Imu marks its linear_acceleration absent (REP 145: covariance[0] = -1)."""
    if stream.type_name != table.IMU:
        raise ValueError(f'bag topic {stream.topic} has type {stream.type_name}: the Imu '
                         f'acceleration needs {table.IMU}')
    return not np.all(stream.field('linear_acceleration_covariance[0]') != -1.0)


def _load_bag(reader, path, roles, use_log_time=False):
    """Read the roles of a bag (see :func:`load_record`) onto the gyro's clock."""
    streams, read, notes = {}, {}, []
    for key, given in roles.items():
        if key not in _BAG_ROLES:
            continue
        if key == 'imu_accel' and given is None and 'gyro' in read:
            given = read['gyro'][0].topic           # the gyro's own Imu
        topic = _role_topic(reader, path, key, given, notes)
        if topic is None:
            continue
        if topic not in streams:
            streams[topic] = read_stream(reader, topic, use_log_time)
            notes.extend(streams[topic].notes)
        stream = streams[topic]
        if len(stream) == 0:
            raise ValueError(f'bag {path}: topic {topic} is empty')
        if key == 'imu_accel' and _imu_accel_absent(stream):
            continue
        role = _BAG_ROLES[key]
        if key == 'accel' and stream.type_name != table.IMU:    # acceleration commands
            if table.accel_commands_applied(reader.custom_data):
                role = 'linear_accel'
            else:
                notes.append(table.old_accel_note(topic))
        read[role] = (stream, *_role_values(stream, _BAG_ROLES[key]))
    first = read['gyro'] if 'gyro' in read else next(iter(read.values()), None)
    t0 = first[0].times_ns[0] if first is not None else 0
    gyro_stamp_ns, time_s, gyro, sources = np.zeros(0, dtype=np.int64), np.zeros(0), {}, {}
    if 'gyro' in read:
        stream, block, fieldname = read['gyro']
        gyro_stamp_ns = stream.times_ns
        time_s = (gyro_stamp_ns - t0) * 1e-9
        check_increasing(time_s, f'{path}: header stamps', strict=False)
        gyro = {a: block[:, i] for i, a in enumerate(AXES)}
        sources = {a: f'{stream.topic} {fieldname}.{a}' for a in AXES}
    channels = {role: Channel((stream.times_ns - t0) * 1e-9, values, f'{stream.topic} {source}',
                              stream.times_ns)
                for role, (stream, values, source) in read.items() if role != 'gyro'}
    return Record(time_s, gyro, sources, path=path, recovery=tuple(reader.problems + notes),
                  gyro_stamp_ns=gyro_stamp_ns,
                  topics={role: r[0].topic for role, r in read.items()},
                  frames={role: str(r[0].arrays.decoded.frame_id[0]) for role, r in read.items()},
                  metadata=dict(reader.custom_data), **channels)


def open_bag(path):
    """
    Open a bag for stream-level reading (:func:`find_topic`, :func:`read_stream`), tolerant.

    A bag already open (a :class:`gyro_emulator.recording.bag.BagReader`) is returned as it is.
    """
    if isinstance(path, bag.BagReader):
        return path
    return bag.BagReader(os.fspath(path), tolerant=True)
