"""Large scratch arrays kept between calls, so that a call does not page its scratch memory in again.

A parallel call on a large sensor (:func:`~evedge.detector._tiles.intra_tiled` on
1280 x 720: the strips' state copies, ~90 MB, and per-event slots, ~60 MB)
allocates its scratch afresh each time. The allocator returns such blocks to
the system at the end of the call (they are ``mmap``-ed), so the next call
faults every page in again: on this project's 2-core VM that was 20-120 ms of
kernel time per call on the Gen4-sized input, twice as variable as the work
itself, and the faults of two threads touching fresh memory at once wait on
each other (numbers: the README's speed section).

:data:`WORKSPACE` keeps the blocks it lent, up to a bound, and lends them
again: a scope (:meth:`Workspace.scope`) takes arrays and gives them all back
when it ends. Arrays are views of cached byte buffers: their contents are
whatever the last user left (:meth:`_Scope.zeros` clears them), and no array
taken in a scope may outlive it (the next scope may write to it), so the
scratch never reaches a caller. :meth:`Workspace.lease` lends for as long as an
owner object lives (a stream's strips' state: a one-shot call's estimator dies
with the call, and its buffers serve the next call). Small requests (below ``min_bytes``) are plain
``numpy.empty``: the allocator keeps small blocks itself.

Thread-safe: concurrent scopes take distinct buffers.
"""

from __future__ import annotations

import contextlib
import threading
import weakref

import numpy as np

#: Requests below this size are not cached (the allocator's own free lists keep them mapped).
MIN_BYTES = 1 << 20

#: Most bytes kept between calls; beyond it the largest unused buffers are dropped.
MAX_CACHED_BYTES = 1 << 29


def _request(shape, dtype):
    """``(shape tuple, dtype, bytes)`` of a request."""
    dtype = np.dtype(dtype)
    shape = (int(shape),) if np.ndim(shape) == 0 else tuple(int(s) for s in shape)
    return shape, dtype, int(np.prod(shape, dtype=np.int64)) * dtype.itemsize


class Workspace:
    """A cache of byte buffers lent as arrays within scopes.

    Parameters
    ----------
    max_cached_bytes : int
        Most bytes of free buffers kept between scopes.
    min_bytes : int
        Requests smaller than this get a new array (not cached).

    Examples
    --------
    >>> ws = Workspace(min_bytes=0)
    >>> with ws.scope() as take:
    ...     a = take.empty((3, 4), np.float64)
    ...     a.shape, a.dtype.name
    ((3, 4), 'float64')
    >>> with ws.scope() as take:
    ...     b = take.zeros((2, 6), np.float64)  # the buffer ``a`` had, cleared
    ...     bool(np.shares_memory(a, b)), int(b.sum()), ws.cached_bytes
    (True, 0, 0)
    >>> ws.cached_bytes
    96
    """

    def __init__(self, max_cached_bytes: int = MAX_CACHED_BYTES, min_bytes: int = MIN_BYTES) -> None:
        self.max_cached_bytes = int(max_cached_bytes)
        self.min_bytes = int(min_bytes)
        self._free: list[np.ndarray] = []  # uint8 buffers, not lent
        self._lock = threading.Lock()

    @property
    def cached_bytes(self) -> int:
        """Bytes held in free buffers (not lent)."""
        with self._lock:
            return sum(b.size for b in self._free)

    def clear(self) -> None:
        """Drop every free buffer (lent ones return to the cache when their scope ends)."""
        with self._lock:
            self._free.clear()

    def _take(self, nbytes: int) -> np.ndarray:
        with self._lock:
            best = -1
            for i, b in enumerate(self._free):
                # the smallest free buffer that holds the request, at most twice its size (a small
                # request does not pin a huge buffer that a large one will want)
                if nbytes <= b.size <= 2 * nbytes and (best < 0 or b.size < self._free[best].size):
                    best = i
            if best >= 0:
                return self._free.pop(best)
        return np.empty(nbytes, np.uint8)

    def _give(self, buffers: list[np.ndarray]) -> None:
        with self._lock:
            self._free.extend(buffers)
            total = sum(b.size for b in self._free)
            self._free.sort(key=lambda b: b.size)
            while self._free and total > self.max_cached_bytes:
                total -= self._free.pop().size  # the largest first

    def lease(self, shape, dtype, owner) -> np.ndarray:
        """An array like :meth:`_Scope.empty`'s, lent until ``owner`` is garbage-collected (then cached again).

        For scratch that lives as long as an object (a stream's strips' state):
        a one-shot call's object dies with the call and its buffers serve the next.
        """
        shape, dtype, nbytes = _request(shape, dtype)
        if nbytes < self.min_bytes:
            return np.empty(shape, dtype)
        buf = self._take(nbytes)
        weakref.finalize(owner, self._give, [buf])
        return buf[:nbytes].view(dtype).reshape(shape)

    @contextlib.contextmanager
    def scope(self):
        """A scope lending arrays (:class:`_Scope`); they return to the cache when it ends."""
        lent = _Scope(self)
        try:
            yield lent
        finally:
            self._give(lent._buffers)
            lent._buffers = []


class _Scope:
    """Arrays lent by a :class:`Workspace` until the end of the ``with`` block that made it."""

    def __init__(self, workspace: Workspace) -> None:
        self._ws = workspace
        self._buffers: list[np.ndarray] = []

    def empty(self, shape, dtype) -> np.ndarray:
        """An array of ``shape`` and ``dtype`` with arbitrary contents (a cached buffer's view when large)."""
        shape, dtype, nbytes = _request(shape, dtype)
        if nbytes < self._ws.min_bytes:
            return np.empty(shape, dtype)
        buf = self._ws._take(nbytes)
        self._buffers.append(buf)
        return buf[:nbytes].view(dtype).reshape(shape)

    def zeros(self, shape, dtype) -> np.ndarray:
        """:meth:`empty`, cleared."""
        a = self.empty(shape, dtype)
        a.fill(0)
        return a


#: The process's workspace (:mod:`evedge.detector._tiles`); ``WORKSPACE.clear()`` frees its memory.
WORKSPACE = Workspace()


def free_scratch() -> int:
    """Release the detector's cached scratch memory (what the parallel strips keep mapped between calls).

    Returns
    -------
    int
        Bytes released (buffers still lent, e.g. to a live stream's strips, stay).

    Examples
    --------
    >>> from evedge.detector import free_scratch
    >>> free_scratch() >= 0
    True
    """
    released = WORKSPACE.cached_bytes
    WORKSPACE.clear()
    return released
