"""
One model sample per tick at block cost, exactly (no ROS imports).

``GyroModel.step`` runs the compiled kernel on one sample, but its Python
argument handling makes it ~15 us a call. At 1 kHz the node then used
1.33-1.41x the CPU of a bare rclpy Imu publisher, against 1.13-1.26x with
blocks of 50 (``bench/bench_node.py``). :class:`BlockStepper`
calls ``GyroModel.run`` on K samples of the current (held) input ahead of
time and hands them out one per tick. When the input changes before the block is used
up, it restores a snapshot of the model taken before the block and re-runs only
the samples already handed out, so the model is exactly where per-sample
stepping would have left it. ``GyroModel`` guarantees that ``run`` and
``step`` give identical samples however a record is split into calls, so
the output equals ``step`` per tick bit for bit, for any input sequence.

Blocks pay off only while the input holds. A block starts once the input
has been unchanged for ``max_block`` ticks, or, at a change, when the last
:data:`HOLDS_KEPT` inputs each held for two ticks or more. At a steady
pace (the longest at most :data:`STEADY` times the shortest) the block is
as long as the shortest of them (at most ``max_block``), so an input that
changes at a steady pace (a simulator's commands) uses its blocks up
without rewinds. At an unsteady pace (commands from a timer on a loaded
machine) it is as long as the hold of rank :data:`UNSTEADY_RANK` among
them, shortest first: shorter holds rewind, longer ones go on in single
samples, which costs less than a step per sample as long as the snapshot
a rewind restores is cheap (``model.snapshot``, a few tens of
microseconds). Otherwise (a hold of one tick among the last) the model
steps one sample per tick. A rate that changes every tick therefore costs
what ``step`` costs, and a held rate a few microseconds.

"Holds" includes a specific force that changes every sample in a known way
(gravity turning with a held rate): given a ``course``
(:class:`.attitude.AttitudeState`), the block runs on the forces the course
forecasts for its samples, and each tick checks that its force is the
forecast one, bit for bit; any other force is a change.

The snapshot taken before a block (``model.snapshot``: the model's states
and unread normals, not a copy of the model) is kept across the blocks
that follow while the input holds (at most :data:`CHECKPOINT_SPAN`
samples): a rewind restores it and re-runs, in one call, every sample
handed out since. A held input then pays one snapshot per span instead of
one per block.

The white-noise sigmas (the published covariances, at the die temperature)
are refreshed where a stepper of fixed blocks (a block of ``max_block``
once the input held that long, and every ``max_block`` single steps) would
refresh them, at the die temperature it would have then: this stepper's
own blocks change no output, covariances included.
"""

from collections import deque

from gyro_emulator.emulation.driver.attitude import same_bits
import numpy as np

#: Most samples of one model call that runs dropped samples (:meth:`BlockStepper.skip`).
SKIP_CHUNK = 10000
#: Most samples handed out since the snapshot a rewind starts from (then a new one).
CHECKPOINT_SPAN = 1000
#: How many of the last inputs' hold lengths set the block at a change.
HOLDS_KEPT = 8
#: Longest / shortest of those holds up to which the pace is steady (blocks at a change).
STEADY = 1.25
#: At an unsteady pace, the block at a change is the hold of this rank (0: the shortest).
UNSTEADY_RANK = 3
#: The "block" of a single sample stepped on the kept snapshot (all of it used at once).
_SINGLE = (None,)


def _accel_sigma(model):
    """Return the accelerometer's white-noise sigma of an ImuModel, m/s^2 (None: a gyro)."""
    sigma = getattr(model, 'accel_white_noise_sigma_m_s2', None)
    return None if sigma is None else np.asarray(sigma, dtype=float)


class BlockStepper:
    """
    Serve ``GyroModel`` (or ``ImuModel``) samples one per tick from blocks computed ahead.

    Parameters
    ----------
    model : gyro_emulator.sensor.model.GyroModel or gyro_emulator.sensor.imu.ImuModel
        The model; it advances only through this object from now on.
    max_block : int
        Largest block, samples (1: call ``step`` every tick).

    """

    def __init__(self, model, max_block=50):
        self.model = model
        self.max_block = max(1, int(max_block))
        self.rewinds = 0
        self.model_calls = 0
        self._batch = None
        self._used = 0
        self._key = None
        self._inputs = None
        self._forces = None
        self._checkpoint = None
        self._replay = []
        self._replay_samples = 0
        self._last_key = None
        self._held = 0
        self._holds = deque(maxlen=HOLDS_KEPT)
        self._fixed_key = self._fixed_last = None
        self._fixed_left = self._fixed_held = 0
        self.sigma_rad_s = np.asarray(model.white_noise_sigma_rad_s, dtype=float)
        self.accel_sigma_m_s2 = _accel_sigma(model)
        self.sigma_version = 0
        self._since_sigma = 0

    def step(self, rate_rad_s, ambient_temp_c, accel_m_s2=None, course=None):
        """
        Return the next sample for this tick's inputs (a ``SensorSample``).

        Parameters
        ----------
        rate_rad_s : tuple of float
            True rate (x, y, z), rad/s.
        ambient_temp_c : float
            Ambient temperature, deg C.
        accel_m_s2 : tuple of float or None
            Specific force (x, y, z), m/s^2; None = none.
        course : object or None
            Where the specific force goes while ``course.key`` holds:
            ``course.forces(n)`` returns this tick's force and the next
            ``n - 1`` as tuples (:meth:`.attitude.AttitudeState.forces`).
            None: the force holds while it is equal.

        """
        rate, temp = tuple(rate_rad_s), float(ambient_temp_c)
        force = None if accel_m_s2 is None else tuple(accel_m_s2)
        fixed = self._fixed_tick((rate, temp, force))
        sample = self._next((rate, temp, force if course is None else course.key),
                            accel_m_s2, course)
        self._fixed_done(fixed, sample)
        return sample

    def _next(self, key, accel_m_s2, course):
        """Return this tick's sample (the blocks of the module docstring)."""
        batch = self._batch
        if batch is not None:
            used = self._used
            if key == self._key and used < len(batch) and self._on_course(accel_m_s2, used):
                self._used = used + 1
                self._held += 1
                return batch.sample(used)
            if used < len(batch):
                self._rewind()
                key_held = False            # a force off its course is a change
            else:
                self._chain()
                key_held = key == self._last_key
            self._batch = None
        else:
            key_held = key == self._last_key
        if key_held:
            self._held += 1
        else:
            if self._last_key is not None:
                self._holds.append(self._held + 1)
            self._held = 0
        self._last_key = key
        n = self.block
        if n == 1 and (self._checkpoint is None or not self._steady_hold()):
            return self._step_one(key[0], key[1], accel_m_s2)
        return self._start_block(key, accel_m_s2, course, n)

    def _on_course(self, accel_m_s2, index):
        """Tell whether this tick's force is the block's at ``index`` (always: no course)."""
        forces = self._forces
        if forces is None:
            return True
        want = forces[index]
        return accel_m_s2 is want or same_bits(accel_m_s2, want)

    def _step_one(self, rate, temp, accel):
        """Step the model one sample (the snapshot before it is no start for a rewind now)."""
        self._drop_checkpoint()
        self.model_calls += 1
        return self.model.step(rate, temp, None if accel is None else tuple(accel))

    @property
    def block(self):
        """Return how many samples the next model call computes (module docstring)."""
        held = self._held
        if held >= self.max_block:
            return self.max_block
        return 1 if held else max(1, min(self.max_block, self._steady_hold()))

    def _steady_hold(self):
        """Return the block at a change from the last holds (module docstring), else 0."""
        holds = self._holds
        if len(holds) < HOLDS_KEPT:
            return 0
        ranked = sorted(holds)
        if ranked[0] < 2:
            return 0            # an input that changes every tick: steps
        return ranked[0] if ranked[0] * STEADY >= ranked[-1] else ranked[UNSTEADY_RANK]

    def _start_block(self, key, accel_m_s2, course, n):
        """Run ``n`` samples of this tick's inputs (n = 1: chained on the kept snapshot)."""
        if self._checkpoint is None or self._replay_samples >= CHECKPOINT_SPAN:
            self._checkpoint = self.model.snapshot()
            self._replay, self._replay_samples = [], 0
        if n == 1:
            return self._single(key, accel_m_s2)
        forces = None
        if accel_m_s2 is None:
            accel = None
        elif course is None:
            accel = np.tile(np.asarray(accel_m_s2, dtype=float), (n, 1))
        else:
            forces = course.forces(n)
            n = len(forces)
            accel = np.array(forces, dtype=float)
        inputs = (np.tile(np.asarray(key[0], dtype=float), (n, 1)), np.full(n, key[1]), accel)
        self.model_calls += 1
        try:
            batch = self.model.run(*inputs)
        except ValueError:
            self._restore()
            raise
        self._batch = batch
        self._key = key
        self._inputs = inputs
        self._forces = forces
        self._used = 1
        return batch.sample(0)

    def _single(self, key, accel_m_s2):
        """Step one sample chained on the kept snapshot (``step``: ``run`` of one, cheaper)."""
        force = None if accel_m_s2 is None else tuple(accel_m_s2)
        self.model_calls += 1
        try:
            sample = self.model.step(key[0], key[1], force)
        except ValueError:
            self._restore()
            raise
        self._batch = _SINGLE
        self._key = key
        self._inputs = (np.array((key[0],), dtype=float), np.array((key[1],)),
                        None if force is None else np.array((force,), dtype=float))
        self._forces = None
        self._used = 1
        return sample

    def _chain(self):
        """Add the block just used up to what a rewind re-runs after the snapshot."""
        self._replay.append(self._inputs)
        self._replay_samples += len(self._inputs[0])
        self._inputs = self._forces = None

    def _restore(self):
        """Put the model back to the snapshot, re-run the blocks used up since; none is kept."""
        self.model.restore(self._checkpoint)
        replay = self._replay
        self._drop_checkpoint()
        if replay:
            self.model_calls += 1
            self.model.run(*_joined(replay))

    def _drop_checkpoint(self):
        self._checkpoint = None
        self._replay, self._replay_samples = [], 0

    def _rewind(self):
        """Put the model back to just after the samples handed out so far."""
        used = self._used
        rates, temps, accel = self._inputs
        self._replay.append((rates[:used], temps[:used], None if accel is None else accel[:used]))
        self._inputs = self._forces = None
        self.rewinds += 1
        self._restore()

    def skip(self, count, rate_rad_s, ambient_temp_c, accel_m_s2=None):
        """
        Run ``count`` samples of a held input whose output nobody reads (dropped samples).

        The model advances as ``count`` calls of :meth:`step` would move it,
        in calls of at most :data:`SKIP_CHUNK` samples (bounded memory).
        """
        self.sync()
        rate = np.asarray(rate_rad_s, dtype=float)
        accel = None if accel_m_s2 is None else np.asarray(accel_m_s2, dtype=float)
        left = int(count)
        while left > 0:
            n = min(left, SKIP_CHUNK)
            self.model_calls += 1
            self.model.run(np.tile(rate, (n, 1)), np.full(n, float(ambient_temp_c)), accel)
            left -= n
        self._last_key = self._fixed_last = None
        self._held = self._fixed_held = 0

    def sync(self):
        """
        Drop the samples computed ahead so the model stands at the current tick.

        The model is then the caller's to change (restart its filters, set its
        record time): the snapshot a rewind would start from is dropped too.
        """
        batch = self._batch
        if batch is not None and self._used < len(batch):
            self._rewind()
        self._batch = None
        self._inputs = self._forces = None
        self._drop_checkpoint()
        self._fixed_left = 0

    def update_config(self, config):
        """Apply a new SensorConfig from the next tick on, keeping the model's states."""
        self.sync()
        self.model.update_config(config)
        self._refresh_sigma()

    def set_sample_rate(self, sample_rate_hz):
        """Run the model at a new rate from the next tick on (``GyroModel.set_sample_rate``)."""
        self.sync()
        self.model.set_sample_rate(sample_rate_hz)
        self._last_key = self._fixed_last = None
        self._held = self._fixed_held = 0
        self._refresh_sigma()

    # --- the white-noise sigmas, on the schedule of fixed blocks -------------

    def _fixed_tick(self, key):
        """
        Follow a stepper of fixed blocks on this tick's inputs; return what it does.

        ``'served'`` (from its block), ``'step'`` (one sample) or ``'block'``
        (a new block of ``max_block``). The sigmas (the published
        covariances, at the die temperature) are refreshed where it refreshed
        them, so they do not depend on this stepper's own blocks.
        """
        if self._fixed_left and key == self._fixed_key:
            self._fixed_left -= 1
            return 'served'
        self._fixed_left = 0
        self._fixed_held = self._fixed_held + 1 if key == self._fixed_last else 0
        self._fixed_last = key
        return 'step' if self._fixed_held < self.max_block else 'block'

    def _fixed_done(self, fixed, sample):
        """Refresh the sigmas as the stepper of fixed blocks did after this tick."""
        if fixed == 'step':
            self._since_sigma += 1
            if self._since_sigma >= self.max_block:
                self._refresh_sigma(sample.die_temp_c)
        elif fixed == 'block':
            # it refreshed after running its block: at the die temperature of its last sample
            self._fixed_key, self._fixed_left = self._fixed_last, self.max_block - 1
            die = self.model.die_temp_after_c(sample.die_temp_c, self._fixed_key[1],
                                              self.max_block - 1)
            if die is not None:
                self._refresh_sigma(die)

    def _refresh_sigma(self, die_temp_c=None):
        """Take the sigmas at ``die_temp_c``, deg C (None: the model's current die)."""
        model = self.model
        if die_temp_c is None:
            self.sigma_rad_s = np.asarray(model.white_noise_sigma_rad_s, dtype=float)
            self.accel_sigma_m_s2 = _accel_sigma(model)
        else:
            self.sigma_rad_s = np.asarray(model.white_noise_sigma_at(die_temp_c), dtype=float)
            accel_at = getattr(model, 'accel_white_noise_sigma_at', None)
            self.accel_sigma_m_s2 = None if accel_at is None else np.asarray(
                accel_at(die_temp_c), dtype=float)
        self.sigma_version += 1
        self._since_sigma = 0


def _joined(segments):
    """Return the (rates, temperatures, forces) of input segments as one record."""
    rates = np.concatenate([r for r, _, _ in segments])
    temps = np.concatenate([t for _, t, _ in segments])
    accel = None if segments[0][2] is None else np.concatenate([a for _, _, a in segments])
    return rates, temps, accel
