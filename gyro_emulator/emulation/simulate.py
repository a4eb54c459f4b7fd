"""
Offline simulation: a profile through the IMU model (gyro and accelerometer), in chunks.

:func:`iter_simulation` yields the record chunk by chunk (bounded memory, for
long runs and for any writer: CSV here, a rosbag2 writer later);
:func:`run_simulation` returns it whole. Neither writes files.
:func:`write_simulation_csv` writes the CSV layout of :data:`CSV_COLUMNS`;
:func:`write_record` simulates into a CSV file or a bag directory, staged so
that a failed run leaves nothing behind (what ``gyro-emulator simulate`` does).

Sample n is at time_s = n T, T the part's sample period (1 / rate_hz, made
shorter or longer by its clock drift: ``GyroModel.sample_period_s``). The
model (:class:`~gyro_emulator.sensor.imu.ImuModel`: the gyro and the
accelerometer of ``SensorConfig.accelerometer``; the gyro's samples are
those of a ``GyroModel`` on the same seed) runs over the profile in the one
chunk loop, :func:`gyro_emulator.emulation.run_profile.run_over_profile`;
the record is identical whatever the chunk size. The specific force is the
profile's, or from the motion (gravity turning with the rate).
"""

import contextlib
from dataclasses import replace
import datetime
import os
import time

from gyro_emulator import atomic, outputs
from gyro_emulator.emulation.emulator_bag import simulation_custom_data, write_simulation_bag
from gyro_emulator.emulation.profiles import make_profile
from gyro_emulator.emulation.recorded_profile import RecordedProfile
from gyro_emulator.emulation.run_profile import (CHUNK_SAMPLES, fault_injector, join_chunks,
                                                 OnClock, run_over_profile)
from gyro_emulator.recording import csvio
from gyro_emulator.sensor.config import load_sensor_config, SensorConfig
from gyro_emulator.sensor.imu import ImuModel
from gyro_emulator.validation import check_seed
import numpy as np

#: Columns of the simulation CSV, in order: the accelerometer's output under the
#: names of the measured-record CSV (:data:`gyro_emulator.recording.record.CSV_COLUMNS`).
CSV_COLUMNS = ('time_s', 'rate_x_rad_s', 'rate_y_rad_s', 'rate_z_rad_s', 'temp_c',
               'gyro_x_rad_s', 'gyro_y_rad_s', 'gyro_z_rad_s',
               'accel_x_m_s2', 'accel_y_m_s2', 'accel_z_m_s2')
CSV_FORMATS = ('%.9f',) + ('%.10g',) * 10

#: Longest simulation accepted, samples (about 2.4 GB of output arrays).
MAX_SAMPLES = 20_000_000


def _resolve(config, profile, duration_s, rate_hz, temp_c):
    if not isinstance(config, SensorConfig):
        config = load_sensor_config(config)
    n = sample_count(duration_s, rate_hz)
    duration_s, rate_hz = float(duration_s), float(rate_hz)
    if isinstance(profile, (str, os.PathLike)):
        profile = make_profile(profile, duration_s, temp_c)
    return config, profile, n, rate_hz


def _rng(seed):
    """Return the run's generator, the seed checked first (:func:`check_seed`)."""
    return np.random.default_rng(check_seed('simulate', seed))


def iter_simulation(config, profile, duration_s, rate_hz, seed=0, temp_c=25.0,
                    chunk_samples=CHUNK_SAMPLES, faults=()):
    """
    Simulate chunk by chunk.

    Parameters
    ----------
    config : SensorConfig or str
        Error model, or a preset name / YAML path for :func:`load_sensor_config`.
    profile : gyro_emulator.emulation.profiles.Profile or str
        Any kind of profile (a recorded one runs on its own times), or a
        built-in name / YAML path for :func:`make_profile`.
    duration_s : float
        Length, s; floor(duration_s rate_hz) samples.
    rate_hz : float
        Sample rate, Hz.
    seed : int
        Seed of the ``numpy.random.default_rng`` given to the model.
    temp_c : float
        Ambient temperature of the ``static`` and ``steps`` profiles, deg C.
    chunk_samples : int
        Samples per chunk.
    faults : sequence of gyro_emulator.sensor.faults.Fault
        A fault schedule on the record's time (``sensor.faults``), applied to
        the output as the node applies its faults; ``noise_burst`` draws from
        the seed's SeedSequence child after the model's streams.

    Yields
    ------
    gyro_emulator.emulation.run_profile.ProfileChunk

    """
    if isinstance(profile, RecordedProfile):
        yield from _iter_recorded(config, profile, seed, chunk_samples, faults)
        return
    config, profile, n, rate_hz = _resolve(config, profile, duration_s, rate_hz, temp_c)
    rng = _rng(seed)
    model = ImuModel(config, rate_hz, rng)
    yield from run_over_profile(model, OnClock(profile, n, model.sample_period_s), chunk_samples,
                                fault_injector(faults, config, rng))


def _iter_recorded(config, profile, seed, chunk_samples, faults):
    """
    Simulate over a measured record's inputs; output at the record's sample times.

    The model runs at the record's median rate on the grid of
    :meth:`RecordedProfile.on_model_grid` (inputs interpolated to the grid
    times); the grid samples of the record's samples are published with the
    record's times, the others withheld. The extended terms' clock starts at
    the record's first sample (``extended.start_time_s``), as in
    ``diagnose --config``.
    """
    if not isinstance(config, SensorConfig):
        config = load_sensor_config(config)
    config = replace(config, extended=replace(config.extended,
                                              start_time_s=float(profile.time_s[0])))
    rng = _rng(seed)
    model = ImuModel(config, profile.rate_hz, rng)
    grid = profile.on_model_grid(model.sample_period_s)
    if grid.count > MAX_SAMPLES:
        raise ValueError(f'{profile.name}: {grid.count} samples at {profile.rate_hz:g} Hz '
                         f'is out of range: allowed <= {MAX_SAMPLES}')
    yield from run_over_profile(model, grid, chunk_samples, fault_injector(faults, config, rng))


def sample_count(duration_s, rate_hz):
    """
    Return the number of samples of a simulation: floor(duration_s rate_hz).

    Raises ValueError, one line naming the value and its range, unless
    ``duration_s`` > 0 and 0 < ``rate_hz`` <= 1e6 are finite and give 1 to
    :data:`MAX_SAMPLES` samples.
    """
    duration_s = float(duration_s)
    rate_hz = float(rate_hz)
    if not (np.isfinite(duration_s) and duration_s > 0.0):
        raise ValueError(f'duration_s = {duration_s!r} is out of range: allowed > 0 s')
    if not (np.isfinite(rate_hz) and 0.0 < rate_hz <= 1e6):
        raise ValueError(f'rate_hz = {rate_hz!r} is out of range: allowed (0, 1e6] Hz')
    n = int(np.floor(duration_s * rate_hz + 1e-9))
    if n < 1:
        raise ValueError(f'duration_s = {duration_s!r} at {rate_hz:g} Hz gives no sample')
    if n > MAX_SAMPLES:
        raise ValueError(f'duration_s x rate_hz = {n} samples is out of range: allowed '
                         f'<= {MAX_SAMPLES}')
    return n


def run_simulation(config, profile, duration_s, rate_hz, seed=0, temp_c=25.0,
                   progress=None):
    """
    Simulate a whole record (no files written).

    Parameters are those of :func:`iter_simulation`; ``progress(done, total)``
    is called after each chunk if given.

    Returns
    -------
    time_s : numpy.ndarray
        Sample times, s, shape (N,).
    profile : ProfileSamples
        True rates (N, 3), ambient temperatures (N,) and specific force (N, 3).
    batch : gyro_emulator.sensor.imu.ImuBatch
        The sensor output (gyro and accelerometer).

    """
    total = sample_count(duration_s, rate_hz)

    def counted(chunks):
        done = 0
        for chunk in chunks:
            done += len(chunk.time_s)
            if progress is not None:
                progress(done, total)
            yield chunk

    return join_chunks(counted(iter_simulation(config, profile, duration_s, rate_hz, seed,
                                               temp_c)))


def csv_columns(chunk):
    """Return the :data:`CSV_COLUMNS` arrays of a chunk's published samples, in order."""
    rate, gyro, accel = chunk.profile.rate_rad_s, chunk.batch.gyro_rad_s, chunk.batch.accel_m_s2
    columns = [chunk.time_s, rate[:, 0], rate[:, 1], rate[:, 2], chunk.profile.temp_c,
               gyro[:, 0], gyro[:, 1], gyro[:, 2], accel[:, 0], accel[:, 1], accel[:, 2]]
    if chunk.published is None:
        return columns
    return [column[chunk.published] for column in columns]


def write_simulation_csv(path, chunks, progress=None, total=None):
    """
    Write simulation chunks to a CSV file (``.gz`` compresses), complete or absent.

    Parameters
    ----------
    path : str or os.PathLike
        Output file (:class:`gyro_emulator.recording.csvio.CsvWriter` stages it).
    chunks : iterable of gyro_emulator.emulation.run_profile.ProfileChunk
        From :func:`iter_simulation`.
    progress : callable, optional
        ``progress(done, total)`` after each chunk.
    total : int, optional
        Total samples, passed to ``progress``.

    Returns
    -------
    int
        Rows written.

    """
    return csvio.write_csv_blocks(path, CSV_COLUMNS, (csv_columns(chunk) for chunk in chunks),
                                  CSV_FORMATS, progress, total)


def output(out):
    """Return the :class:`gyro_emulator.outputs.Output` of ``--out``: a CSV file or a bag."""
    out = os.path.abspath(out) if out else out      # '' is said as such by outputs.check
    return (outputs.file if is_csv_path(out) else outputs.directory)('--out', out)


def check_output(out, overwrite=False):
    """Refuse an existing ``out`` unless ``overwrite`` (:mod:`.outputs`); make its folder."""
    outputs.check([output(out)], overwrite=overwrite)
    out = os.path.abspath(out)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    return out


@contextlib.contextmanager
def staged_output(out, overwrite=False):
    """
    Stage the bag directory ``out``: yield a temporary path that becomes ``out`` on success.

    :func:`gyro_emulator.atomic.staged` stages it (fsync, ``os.replace``,
    the temporary removed on any exception), so a run that fails (or is
    interrupted) leaves nothing behind. An existing ``out`` is replaced only
    with ``overwrite`` (:func:`check_output`; the old directory is removed
    just before the new one takes its place). The bag writer is given the
    final name, which its MCAP file follows.
    """
    out = check_output(out, overwrite)
    with atomic.staged(out) as partial:
        yield partial
        if os.path.isdir(out):
            atomic.remove(out)


def is_csv_path(path):
    """Return whether ``path`` names a CSV record (``.csv`` or ``.csv.gz``), else a bag."""
    return str(path).endswith(('.csv', '.csv.gz'))


def parse_start_time(text):
    """
    Return a bag start time in ns since the Unix epoch from ``now``, seconds or ISO 8601.

    ``now`` (the default of ``simulate --start-time``) is the current time;
    a number is seconds since 1970-01-01 UTC (``0``: the epoch itself); an
    ISO 8601 date-time without a zone is UTC (``2026-03-01T12:00:00``).
    """
    text = str(text).strip()
    if text == 'now':
        return time.time_ns()
    try:
        seconds = float(text)
    except ValueError:
        try:
            moment = datetime.datetime.fromisoformat(text.replace('Z', '+00:00'))
        except ValueError:
            raise ValueError(f'start_time = {text!r} is not understood: allowed now, seconds '
                             'since the epoch, or an ISO 8601 date-time such as '
                             '2026-03-01T12:00:00') from None
        if moment.tzinfo is None:
            moment = moment.replace(tzinfo=datetime.timezone.utc)
        seconds = moment.timestamp()
    if not (np.isfinite(seconds) and 0.0 <= seconds < 2 ** 31):
        raise ValueError(f'start_time = {text!r} is out of range: allowed [0, 2^31) s since '
                         'the epoch (1970 to 2038, as builtin_interfaces/Time holds it)')
    return int(round(seconds * 1e9))


def write_record(out, config, profile, duration_s, rate_hz, seed=0, temp_c=25.0,
                 overwrite=False, progress=None, start_time_ns=None, faults=()):
    """
    Simulate (:func:`iter_simulation`) and write the record, complete or absent.

    Parameters
    ----------
    out : str
        ``.csv``/``.csv.gz``: :func:`write_simulation_csv`; anything else: a
        rosbag2 bag directory in the emulator layout
        (:func:`gyro_emulator.emulation.emulator_bag.write_simulation_bag`,
        whose ``custom_data`` records how to reproduce the run).
    config, profile, duration_s, rate_hz, seed, temp_c
        As for :func:`iter_simulation`; ``config`` and ``profile`` names are
        recorded in a bag's ``custom_data``.
    overwrite : bool
        Replace an existing ``out``; without it that is an error.
    progress : callable, optional
        ``progress(done, total)`` after each chunk.
    start_time_ns : int, optional
        Bag time of sample 0, ns since the epoch (None: now), so that a bag
        opens at its date in Foxglove or ``ros2 bag``; recorded in
        ``custom_data``. The CSV's ``time_s`` counts from 0 either way.
    faults : sequence of gyro_emulator.sensor.faults.Fault
        A fault schedule (:func:`iter_simulation`); a dropout leaves its
        samples out of the CSV and the bag's ``imu/data_raw``.

    Returns
    -------
    int
        Samples written.

    """
    start_ns = time.time_ns() if start_time_ns is None else int(start_time_ns)
    check_seed('simulate', seed)
    sensor = config if isinstance(config, SensorConfig) else load_sensor_config(config)
    if isinstance(profile, RecordedProfile):
        duration_s, rate_hz, total = profile.duration_s, profile.rate_hz, len(profile.time_s)
    else:
        total = sample_count(duration_s, rate_hz)
    chunks = iter_simulation(sensor, profile, duration_s, rate_hz, seed=seed, temp_c=temp_c,
                             faults=faults)
    if is_csv_path(out):
        return write_simulation_csv(check_output(out, overwrite), chunks, progress=progress,
                                    total=total)
    custom = simulation_custom_data(config, getattr(profile, 'name', profile), duration_s,
                                    rate_hz, seed, temp_c)
    custom['start_time_ns'] = str(start_ns)
    if faults:
        custom['faults'] = '; '.join(f.describe() for f in faults)
    with staged_output(out, overwrite) as partial:
        return write_simulation_bag(partial, chunks, config=sensor, rate_hz=rate_hz,
                                    custom_data=custom, start_ns=start_ns, progress=progress,
                                    total=total, name=os.path.abspath(out))
