"""
One sense channel on the compiled kernel: its plan, its state and its random streams.

The gyro (:class:`~gyro_emulator.sensor.model.GyroModel`) is one
:class:`SenseChannel`; an IMU (:class:`~gyro_emulator.sensor.imu.ImuModel`)
adds the accelerometer as a second one. A channel holds what carries over
between calls: the plan (:class:`~gyro_emulator.sensor.plan.Plan`, the
kernel's read-only coefficients), the kernel's state (die temperature,
filter, flicker and random-walk states) and its own normal streams
(:class:`~gyro_emulator.sensor.streams.NormalStreams`, one per noise term
and axis). :meth:`SenseChannel.apply` takes a new plan keeping the states;
:meth:`SenseChannel.advance` runs the kernel over a record in blocks.
"""

from gyro_emulator.sensor import kernel, noise, streams
import numpy as np

#: Stand-in for "no specific force" or "no extended terms" (an empty row set).
NONE_ROWS = np.zeros((0, 3))
NONE_ROWS.flags.writeable = False


def new_outputs(n):
    """Return empty kernel outputs for ``n`` samples."""
    return kernel.Outputs(np.empty((n, 3)), np.empty(n), np.empty((n, 3)), np.empty((n, 3)),
                          np.empty((n, 3), dtype=np.bool_), np.empty(n))


class SenseChannel:
    """
    A sense channel's plan, kernel state and normal streams (module docstring).

    Parameters
    ----------
    rng : numpy.random.Generator
        The streams are spawned from its SeedSequence
        (:func:`gyro_emulator.sensor.streams.spawn_generators`); the first
        three normals of the turn-on stream are drawn at once
        (:attr:`turn_on_z`, the run-to-run turn-on bias).

    """

    def __init__(self, rng):
        self.normals = streams.NormalStreams(rng)
        self.kernel = kernel.State(
            ints=np.zeros(4, dtype=np.int64),   # sample index, ready flags
            die_c=np.zeros(1),                  # die temperature of the last sample
            dyn_z=np.zeros((3, 2)), lpf_z=np.zeros((3, 1)),
            flicker=np.zeros((3, 1)),           # (axes, sections)
            rrw=np.zeros(3))
        self.flicker_key = None
        self.plan = None
        self.turn_on_z = self.normals.draw(streams.TURN_ON, 3)

    def apply(self, plan):
        """
        Take a new plan, keeping the states.

        Die temperature, random walk, flicker and filter states carry over. A
        filter whose coefficients change restarts from steady state at its
        next input; a changed flicker band (or sample period) redraws its
        states from the stationary distribution.
        """
        old, state = self.plan, self.kernel
        if old is None or not (np.array_equal(old.dyn_b, plan.dyn_b)
                               and np.array_equal(old.dyn_a, plan.dyn_a)):
            state.ints[kernel.I_DYN_READY] = 0
            state = state._replace(dyn_z=np.zeros((3, plan.dyn_a.shape[1] - 1)))
        if old is None or not (np.array_equal(old.lpf_b, plan.lpf_b)
                               and np.array_equal(old.lpf_a, plan.lpf_a)):
            state.ints[kernel.I_LPF_READY] = 0
            state = state._replace(lpf_z=np.zeros((3, plan.lpf_a.shape[1] - 1)))
        if plan.flicker is not None:
            key = (tuple(plan.flicker.corr_times_s), plan.dt)
            if self.flicker_key != key:
                count = len(plan.flicker.phi)
                z = np.array([self.normals.draw(streams.FLICKER + i, count) for i in range(3)])
                state = state._replace(flicker=np.ascontiguousarray(
                    noise.flicker_initial_state(plan.flicker, plan.flicker_b, z.T).T))
                self.flicker_key = key
        self.kernel = state
        self.plan = plan

    def snapshot(self):
        """Return the channel's state and streams as they are now (:meth:`restore`)."""
        return (self.plan, tuple(a.copy() for a in self.kernel), self.flicker_key,
                self.normals.snapshot())

    def restore(self, snapshot):
        """
        Put the state and streams back to a :meth:`snapshot` of the same plan.

        The samples that follow are those that followed the snapshot, bit for
        bit. A plan applied since (a new configuration or rate) refuses it.
        """
        plan, arrays, key, normals = snapshot
        if plan is not self.plan:
            raise ValueError('SenseChannel.restore: the snapshot is of another plan '
                             '(a configuration or rate applied since)')
        for now, then in zip(self.kernel, arrays):
            now[...] = then
        self.flicker_key = key
        self.normals.restore(normals)

    def restart_filters(self):
        """Restart the sense-mode and output filters from steady state at the next input."""
        ints = self.kernel.ints
        ints[kernel.I_DYN_READY] = 0
        ints[kernel.I_LPF_READY] = 0

    @property
    def die_temp_c(self):
        """Die temperature after the last sample (None before the first)."""
        state = self.kernel
        return float(state.die_c[0]) if state.ints[kernel.I_DIE_READY] else None

    @property
    def sample_index(self):
        """Return the number of samples produced so far."""
        return int(self.kernel.ints[kernel.I_INDEX])

    def die_temp_after_c(self, die_temp_c, ambient_temp_c, count):
        """
        Return the die temperature ``count`` samples after one at ``die_temp_c``, deg C.

        The kernel's lag with the ambient held at ``ambient_temp_c``; the
        channel's state does not move. None: it leaves the model range.
        """
        state = self.kernel._replace(ints=self.kernel.ints.copy(),
                                     die_c=np.array([float(die_temp_c)]))
        state.ints[kernel.I_DIE_READY] = 1
        die = np.empty(int(count))
        if kernel.die_temperatures(np.full(int(count), float(ambient_temp_c)),
                                   self.plan.coefficients, state, die):
            return None
        return float(state.die_c[0])

    def white_sigma(self, initial_die_temp_c=None, die_temp_c=None):
        """
        Per-sample sigma of the white noise at the output, (3,), in the channel's unit.

        N(T_die) sqrt(f_s) times the output filter's RMS noise gain, at the
        die temperature ``die_temp_c`` (None: the current one; before the
        first sample ``initial_die_temp_c`` if given, else the calibration
        temperature).
        """
        plan = self.plan
        if not plan.white:
            return np.zeros(3)
        die = self.die_temp_c if die_temp_c is None else die_temp_c
        if die is not None:
            temps = np.full(3, die)
        elif initial_die_temp_c is not None:
            temps = np.full(3, initial_die_temp_c)
        else:
            temps = plan.cal_temp_c
        sq = plan.elec_sq.copy()
        for curve, axes in plan.mech_curves:
            sq[axes] += curve(temps[axes])
        return np.sqrt(sq) * plan.sqrt_fs * plan.lpf_noise_gain

    def advance(self, rate, temp, accel, out, extended=None):
        """
        Run the kernel over a validated record, in blocks of :data:`streams.BLOCK`.

        ``rate`` (n, 3) is the channel's input, ``temp`` (n,) the ambient the
        kernel lags into the die temperature, ``accel`` the specific force
        for a g-sensitivity (:data:`NONE_ROWS`: none), ``out`` the
        :func:`new_outputs`. ``extended`` is None or ``(plan, state)`` of the
        extended terms (:mod:`gyro_emulator.sensor.extensions`), evaluated on
        ``state`` block by block. Returns 0, or 1 + the index of the first
        die temperature out of the model range (nothing else written: state
        and streams intact).
        """
        n = rate.shape[0]
        plan, normals = self.plan, self.normals
        xbias = xgain = NONE_ROWS
        if extended is not None:
            xbias, xgain = extended[0].buffers_for(streams.BLOCK)
        for start in range(0, n, streams.BLOCK):
            stop = min(start + streams.BLOCK, n)
            normals.reserve(plan.streams, stop - start)
            if extended is not None:
                extended[0].evaluate(temp[start:stop], extended[1], xbias, xgain)
            bad = kernel.advance(rate, temp, accel, xbias, xgain, plan.coefficients, self.kernel,
                                 normals.buffer, normals.pos, out, start, stop)
            if bad:
                return bad
        return 0
