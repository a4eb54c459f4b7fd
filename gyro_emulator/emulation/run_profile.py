"""
Run over a profile: the one chunk loop that steps the sensor model over inputs.

:func:`run_over_profile` runs a :class:`~gyro_emulator.sensor.model.GyroModel`
over the samples of a profile (:class:`~gyro_emulator.emulation.profiles.Profile`)
chunk by chunk (bounded memory), applies a fault schedule to the output
where one is given, and yields :class:`ProfileChunk`. ``simulate`` (scripted
and recorded profiles), the truth generator, replay, the fleet's sensor runs
and, through ``simulate``, the calibrate twin all run the model here.

Which samples, and at which times, is a *timeline* (``count`` samples;
``inputs(start, stop)`` gives their times, profile samples and which are
published):

* :class:`OnClock`: the model's own clock, sample n at n T (``simulate``,
  the fleet's sensor runs);
* :class:`OwnSamples`: a sampled profile's own samples, as they are (the
  truth generator, replay);
* :meth:`~gyro_emulator.emulation.recorded_profile.RecordedProfile.on_model_grid`:
  a measured record on the model's uniform grid (``simulate --profile LOG``).

A profile that leaves its specific force to the motion (its samples'
``accel_m_s2`` is None: :mod:`gyro_emulator.emulation.profiles`) gets it
here (:class:`MotionForce`): the attitude integrated from the profile's
``initial_attitude_wxyz`` with its rate held from sample to sample
(:class:`gyro_emulator.physics.kinematics.AttitudeTrack`), and
f = a_body - R(q)^T (0, 0, -g). The model (a
:class:`~gyro_emulator.sensor.model.GyroModel` or an
:class:`~gyro_emulator.sensor.imu.ImuModel`) gets that f: the gyro's
g-sensitivity and the accelerometer alike.

The model's batch API is partition-invariant (its random draws happen in
the same order however a record is cut), and so is the attitude, so the
chunk size changes no result.
"""

from dataclasses import dataclass, replace

from gyro_emulator.emulation.profiles import ProfileSamples
from gyro_emulator.physics import kinematics
from gyro_emulator.sensor import faults as sensor_faults
from gyro_emulator.units import STANDARD_GRAVITY_M_S2
import numpy as np

#: Samples per chunk of :func:`run_over_profile`.
CHUNK_SAMPLES = 1 << 16


@dataclass(frozen=True)
class ProfileChunk:
    """
    One chunk of a run: times, profile inputs and the sensor output.

    ``published`` (N,) is False for the samples a ``dropout`` fault withholds
    or a record's grid has no sample for (None: all are published); the
    writers leave them out of the output. ``batch`` is a ``SensorBatch``
    (a GyroModel) or an ``ImuBatch`` (an ImuModel). ``attitude_wxyz`` (N, 4)
    is the attitude integrated from the rate (None in a run without specific
    force); ``profile`` then carries both the specific force and the applied
    linear acceleration (:meth:`MotionForce.complete`).
    """

    time_s: np.ndarray
    profile: ProfileSamples
    batch: object
    published: np.ndarray = None
    attitude_wxyz: np.ndarray = None


class MotionForce:
    """
    The specific force of a profile that leaves it to the motion (module docstring).

    Parameters
    ----------
    profile : gyro_emulator.emulation.profiles.Profile
        Its ``initial_attitude_wxyz`` and ``gravity_m_s2`` are used.

    """

    def __init__(self, profile):
        self.gravity_m_s2 = kinematics.check_gravity(
            getattr(profile, 'gravity_m_s2', STANDARD_GRAVITY_M_S2), 'profile')
        self.track = kinematics.AttitudeTrack(
            getattr(profile, 'initial_attitude_wxyz', kinematics.LEVEL_WXYZ))

    def complete(self, time_s, samples):
        """
        Return ``(samples, attitudes)``: the samples with both accelerations, and the attitudes.

        The attitude is integrated either way. Samples that leave their
        specific force to the motion get it, f = a_body - R(q)^T (0, 0, -g)
        (their applied ``linear_accel_m_s2`` zero where None); samples that
        give it get the applied linear acceleration that gives it at that
        attitude, a_body = f + R(q)^T (0, 0, -g) (what a bag's
        ``cmd/linear_acceleration`` holds: the node adds gravity back). The
        next samples of the record follow in the next call.
        """
        attitudes = self.track.at(time_s, samples.rate_rad_s)
        if samples.accel_m_s2 is not None:
            gravity = kinematics.specific_force(attitudes, None, self.gravity_m_s2)
            return replace(samples, linear_accel_m_s2=samples.accel_m_s2 - gravity + 0.0), \
                attitudes
        linear = samples.linear_accel_m_s2
        if linear is None:
            linear = np.zeros((len(time_s), 3))
        force = kinematics.specific_force(attitudes, linear, self.gravity_m_s2)
        return replace(samples, accel_m_s2=force, linear_accel_m_s2=linear), attitudes


@dataclass(frozen=True)
class OnClock:
    """
    A profile on the model's clock: sample n at time n ``period_s`` (s).

    ``period_s`` is the part's sample period
    (:attr:`~gyro_emulator.sensor.model.GyroModel.sample_period_s`, clock
    drift included).
    """

    profile: object
    count: int
    period_s: float

    def inputs(self, start, stop):
        """Return the times, the profile's samples there and None (all published)."""
        time_s = np.arange(start, stop) * self.period_s
        return time_s, self.profile.samples(time_s), None


@dataclass(frozen=True)
class OwnSamples:
    """A sampled profile's own samples, at its own times, as they are (no interpolation)."""

    profile: object

    @property
    def count(self):
        """Return the number of samples."""
        return len(self.profile.time_s)

    def inputs(self, start, stop):
        """Return the times, the samples and None (all published)."""
        return self.profile.time_s[start:stop], self.profile.own_samples(start, stop), None


def samples_with_force(profile, time_s):
    """
    Return ``profile.samples(time_s)`` with its specific force, from the motion if need be.

    The attitude starts at the profile's initial attitude at the first time
    and the rate is held from each time to the next (:class:`MotionForce`),
    as the chunk loop does on a run's own samples: ``time_s`` is a record's
    sample times from its start, non-decreasing.
    """
    time_s = np.asarray(time_s, dtype=float)
    return MotionForce(profile).complete(time_s, profile.samples(time_s))[0]


def fault_injector(faults, config, rng):
    """
    Return the injector of a fault schedule (None without faults).

    ``noise_burst`` draws from ``rng``'s SeedSequence child after the
    model's streams (:func:`gyro_emulator.sensor.faults.fault_generator`);
    the output saturates at ``config.range_rad_s``.
    """
    if not faults:
        return None
    return sensor_faults.Injector(faults, config.range_rad_s,
                                  sensor_faults.fault_generator(rng.bit_generator.seed_seq))


def chunk_edges(count, chunk_samples, breaks=()):
    """Return the chunk boundaries: every ``chunk_samples`` and at each break, 0 to ``count``."""
    edges = set(range(0, int(count), int(chunk_samples)))
    edges.update(int(k) for k in breaks if 0 < k < count)
    return sorted(edges) + [int(count)]


def run_over_profile(model, timeline, chunk_samples=CHUNK_SAMPLES, injector=None,
                     specific_force=True, configs=None):
    """
    Run ``model`` over a timeline's samples, chunk by chunk.

    Parameters
    ----------
    model : gyro_emulator.sensor.model.GyroModel
        The part, at the timeline's rate; its state runs on from chunk to chunk.
    timeline : OnClock, OwnSamples or a recorded profile's model grid
        Which samples, at which times (module docstring).
    chunk_samples : int
        Samples per chunk (the result does not depend on it).
    injector : gyro_emulator.sensor.faults.Injector, optional
        Faults applied to the output as the node applies them
        (:func:`fault_injector`); a dropout withholds samples.
    specific_force : bool
        Give the model the profile's specific force, the profile's own or
        from the motion (:class:`MotionForce`) (False: none, so the gyro's
        g-sensitivity sees none and an accelerometer reads zero: a noise run).
    configs : dict, optional
        Sample index -> SensorConfig, applied with
        :meth:`~gyro_emulator.sensor.model.GyroModel.update_config` before
        that sample (a schedule of the part's configuration; chunks also
        end there).

    Yields
    ------
    ProfileChunk

    """
    configs = configs or {}
    edges = chunk_edges(timeline.count, chunk_samples, configs)
    motion = MotionForce(timeline.profile) if specific_force else None
    for start, stop in zip(edges[:-1], edges[1:]):
        if start in configs:
            model.update_config(configs[start])
        time_s, samples, published = timeline.inputs(start, stop)
        attitudes = None
        if motion is not None:
            samples, attitudes = motion.complete(time_s, samples)
        batch = model.run(samples.rate_rad_s, samples.temp_c,
                          samples.accel_m_s2 if specific_force else None)
        if injector is not None:
            effect = injector.apply(time_s, batch.gyro_rad_s)
            batch = replace(batch, gyro_rad_s=effect.gyro_rad_s,
                            saturated=batch.saturated | effect.saturated)
            published = effect.published if published is None else published & effect.published
        yield ProfileChunk(time_s, samples, batch, published, attitudes)


def join_chunks(chunks):
    """
    Return a whole run from its chunks: (time_s, ProfileSamples, batch).

    The batch is of the model's kind (``SensorBatch`` or ``ImuBatch``).
    ``published`` is not joined: a run with withheld samples is written from
    its chunks, not joined.
    """
    chunks = list(chunks)
    return (np.concatenate([c.time_s for c in chunks]),
            ProfileSamples.concatenate([c.profile for c in chunks]),
            type(chunks[0].batch).concatenate([c.batch for c in chunks]))
