"""
Standard normals of the error model: one numpy ``Generator`` per noise stream.

Every noise term and axis draws from its own stream, so switching one term
on or off leaves the others' numbers unchanged. Stream ``k`` is::

    children = rng.bit_generator.seed_seq.spawn(STREAM_COUNT)
    numpy.random.Generator(numpy.random.SFC64(children[k])).standard_normal

for the injected generator ``rng`` (a generator without a SeedSequence seeds
one from four of its own draws first). The streams, in order: turn-on bias,
timestamp jitter, then white noise, flicker and rate random walk for the
axes x, y, z.

:class:`NormalStreams` draws each stream in blocks (up to :data:`BLOCK`,
as many as a call needs) into a buffer row that the compiled kernel reads in
order. A block is drawn by :func:`fill_standard_normal`: the generator's own
``standard_normal`` through numba's supported numpy ``Generator`` API, the
same numbers as ``Generator.standard_normal(out=...)`` bit for bit (numpy's
ziggurat on the same bit generator state; tested) at about 2.5x the speed,
because the draw is compiled into the loop instead of called per element.
numpy's normal stream does not depend on how the draws are split into calls,
so the k-th normal of a stream is the same whatever the block boundaries, the
record split or the call pattern (``run`` over a record or ``step`` sample by
sample).
"""

import hashlib

import numba
import numpy as np

#: Streams (rows of :attr:`NormalStreams.buffer`): turn-on, jitter, then white,
#: flicker and rate random walk for axes x, y, z.
TURN_ON, JITTER, WHITE, FLICKER, RRW = 0, 1, 2, 5, 8
STREAM_COUNT = 11

#: Capacity of a stream's buffer row: the most samples one kernel call may
#: consume (the model splits longer records into calls of BLOCK).
BLOCK = 16384
#: Fewest normals drawn per refill (a streaming caller asking for a few
#: samples at a time refills little and often, not a whole row at once).
MIN_REFILL = 1024


@numba.njit(cache=True)
def fill_standard_normal(generator, out):
    """
    Fill ``out`` with the next standard normals of ``generator``, in order.

    numba's supported ``numpy.random.Generator.standard_normal`` (numpy's
    ziggurat on the generator's own bit generator, whose state it advances):
    the numbers of ``generator.standard_normal(out=out)``, bit for bit.

    Parameters
    ----------
    generator : numpy.random.Generator
        The stream's generator.
    out : numpy.ndarray
        1-d float64 array to fill.

    """
    for i in range(out.shape[0]):
        out[i] = generator.standard_normal()


def spawn_generators(rng, count=STREAM_COUNT):
    """
    Return ``count`` independent child generators of ``rng`` (SFC64).

    The children are spawned from ``rng``'s SeedSequence (as
    ``Generator.spawn`` does, which advances the parent's spawn counter);
    a generator without one seeds a SeedSequence from its own draws.

    Parameters
    ----------
    rng : numpy.random.Generator
        The injected parent generator.
    count : int
        Number of streams.

    Returns
    -------
    list of numpy.random.Generator

    """
    try:
        children = rng.bit_generator.seed_seq.spawn(count)
    except (AttributeError, TypeError, ValueError, NotImplementedError):
        children = np.random.SeedSequence(
            rng.integers(0, 2 ** 63, size=4).tolist()).spawn(count)
    return [np.random.Generator(np.random.SFC64(child)) for child in children]


def _clone(generator):
    """Return an independent generator in the same state (faster than deepcopy)."""
    bits = generator.bit_generator
    twin = type(bits)(bits.seed_seq)
    twin.state = bits.state
    return np.random.Generator(twin)


class NormalStreams:
    """
    Buffered standard normals of the :data:`STREAM_COUNT` streams.

    ``buffer[k, pos[k]:end[k]]`` holds the next unread normals of stream
    ``k``, in stream order. The kernel reads ``buffer[k, pos[k] + m]`` for the
    m-th sample of a call and advances ``pos``; :meth:`reserve` refills the
    rows beforehand (at least the call's need, at least :data:`MIN_REFILL`)
    and :meth:`draw` takes normals on the Python side.

    Parameters
    ----------
    rng : numpy.random.Generator
        The injected generator the streams are spawned from.

    """

    def __init__(self, rng):
        self.generators = spawn_generators(rng)
        self.buffer = np.empty((STREAM_COUNT, BLOCK))
        self.pos = np.zeros(STREAM_COUNT, dtype=np.int64)
        self.end = np.zeros(STREAM_COUNT, dtype=np.int64)          # all rows empty
        # Unread normals common to every stream of the last reserve(), less what
        # it reserved: an O(1) answer for the next reserve of the same streams
        # (the kernel consumes exactly one normal per sample of each).
        self._headroom_streams, self._headroom = None, 0

    def reserve(self, streams, count):
        """Make at least ``count`` (<= BLOCK) unread normals ready in each of ``streams``."""
        if streams is self._headroom_streams and self._headroom >= count:
            self._headroom -= count
            return
        pos, end = self.pos, self.end
        for k in streams:
            if end[k] - pos[k] < count:
                self._refill(k, count)
        unread = min((int(end[k] - pos[k]) for k in streams), default=BLOCK)
        self._headroom_streams, self._headroom = streams, unread - count

    def draw(self, stream, count):
        """Return the next ``count`` normals of ``stream`` (consumed)."""
        self._headroom_streams = None
        out = np.empty(count)
        done = 0
        while done < count:
            if self.pos[stream] == self.end[stream]:
                self._refill(stream, count - done)
            start = self.pos[stream]
            take = min(count - done, int(self.end[stream]) - start)
            out[done:done + take] = self.buffer[stream, start:start + take]
            self.pos[stream] = start + take
            done += take
        return out

    def _refill(self, stream, need):
        """Move the unread normals of ``stream`` to the front; draw ``need`` or more after them."""
        row = self.buffer[stream]
        pos, end = int(self.pos[stream]), int(self.end[stream])
        unread = end - pos
        row[:unread] = row[pos:end]
        stop = min(BLOCK, unread + max(need, MIN_REFILL))
        fill_standard_normal(self.generators[stream], row[unread:stop])
        self.pos[stream], self.end[stream] = 0, stop

    def snapshot(self):
        """
        Return what :meth:`restore` needs to continue every stream from here (a copy's worth).

        The unread normals, the read positions and each generator's state:
        only the unread normals are ever read again (a refill moves them to
        the front first), and a generator continues from its state.
        """
        return (tuple(self.buffer[k, int(self.pos[k]):int(self.end[k])].copy()
                      for k in range(STREAM_COUNT)),
                tuple(g.bit_generator.state for g in self.generators))

    def restore(self, snapshot):
        """Put every stream back where it was at :meth:`snapshot` (the same normals follow)."""
        unread, states = snapshot
        for k, (row, state) in enumerate(zip(unread, states)):
            self.buffer[k, :len(row)] = row
            self.pos[k], self.end[k] = 0, len(row)
            self.generators[k].bit_generator.state = state
        self._headroom_streams, self._headroom = None, 0

    def __deepcopy__(self, memo):
        """Return an independent copy that continues every stream identically."""
        twin = NormalStreams.__new__(NormalStreams)
        twin.generators = [_clone(g) for g in self.generators]
        # Only the unread normals are ever read again (a refill moves them to the
        # front first): copying them alone keeps a copy cheap (the node's block
        # stepper copies the model every block).
        twin.buffer = np.empty_like(self.buffer)
        for k in range(STREAM_COUNT):
            start, stop = int(self.pos[k]), int(self.end[k])
            twin.buffer[k, start:stop] = self.buffer[k, start:stop]
        twin.pos = self.pos.copy()
        twin.end = self.end.copy()
        twin._headroom_streams, twin._headroom = None, 0
        memo[id(self)] = twin
        return twin


#: Largest seed :func:`seed_from_name` returns (a ROS int64 parameter holds it).
NAME_SEED_MAX = 2 ** 63 - 1


def seed_from_name(name):
    """
    Return a seed for a named instance: independent per name, the same on every run.

    The name's UTF-8 bytes seed a ``numpy.random.SeedSequence`` (entropy:
    the SHA-256 of the name, so similar names share nothing), whose first
    63-bit word is the seed. Passed to ``numpy.random.default_rng`` like any
    explicit seed, it reproduces the instance exactly.

    Parameters
    ----------
    name : str
        E.g. a node's fully qualified name, ``/robot/imu_left/gyro_emulator``.

    Returns
    -------
    int
        In [0, :data:`NAME_SEED_MAX`].

    """
    if not isinstance(name, str) or not name:
        raise ValueError(f'seed_from_name: name = {name!r} is not allowed: a non-empty string')
    entropy = int.from_bytes(hashlib.sha256(name.encode('utf-8')).digest(), 'little')
    word = np.random.SeedSequence(entropy).generate_state(1, np.uint64)[0]
    return int(word) >> 1
