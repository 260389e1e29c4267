"""numba kernels of the streaming detector's per-chunk bookkeeping (:class:`evedge.detector.pipeline.Detector`).

The event buffer's slots (:class:`evedge.detector.buffer.EventBuffer`: the
pending events and their int64 columns) are filled and released here in one
pass each, instead of one numpy call per field; the buffer's rules stay in
:mod:`evedge.detector._buffer_kernels` (called from Python, so their compiled
code is never cached inside these kernels).
"""

import numpy as np
from numba import njit

@njit(cache=True)
def _fill_slots(events, width, height, t_last, has_until, until, ev, x, y, t, p, a):
    """Check a chunk and copy it into slots ``[a, a + n)`` of the buffer's arrays (records and int64 columns).

    Returns False when an event lies outside the sensor or the times decrease
    (starting from ``t_last``), or ``until`` (when ``has_until``) is before the
    newest event: the caller then runs the full checks, which name the
    offending event, and no slot counts (the slots past the pending ones may
    have been written, nothing else).
    """
    n = events.shape[0]
    prev = t_last
    for k in range(n):
        e = events[k]
        if e.x < 0 or e.x >= width or e.y < 0 or e.y >= height or e.t < prev:
            return False
        prev = e.t
    if has_until and until < prev:
        return False
    for k in range(n):
        e = events[k]
        ev[a + k] = e
        x[a + k] = e.x
        y[a + k] = e.y
        t[a + k] = e.t
        p[a + k] = 1 if e.p else 0
    return True


@njit(cache=True)
def _release_slots(ev, x, y, t, p, supported, start, r):
    """The supported events of slots ``[start, start + r)``: records and their x, y, t, p (new arrays)."""
    m = 0
    for j in range(start, start + r):
        if supported[j]:
            m += 1
    out = np.empty(m, dtype=ev.dtype)
    ox = np.empty(m, np.int64)
    oy = np.empty(m, np.int64)
    ot = np.empty(m, np.int64)
    op = np.empty(m, np.int64)
    i = 0
    for j in range(start, start + r):
        if supported[j]:
            out[i] = ev[j]
            ox[i] = x[j]
            oy[i] = y[j]
            ot[i] = t[j]
            op[i] = p[j]
            i += 1
    return out, ox, oy, ot, op
