"""numba kernels of the streaming detector's per-chunk bookkeeping (:class:`evedge.detector.pipeline.Detector`).

The event buffer's slots (:class:`evedge.detector.buffer.EventBuffer`: the
pending events and their int64 columns) are filled and released here in one
pass each, instead of one numpy call per field; the buffer's rules stay in
:mod:`evedge.detector._buffer_kernels` (called from Python, so their compiled
code is never cached inside these kernels).
"""

import numpy as np
from numba import njit, prange

from ._chunks import chunk_bounds, n_chunks

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
    """The supported events of slots ``[start, start + r)``: their records and a (4, m) int64 array of x, y, t, p."""
    m = 0
    for j in range(start, start + r):
        if supported[j]:
            m += 1
    out = np.empty(m, dtype=ev.dtype)
    cols = np.empty((4, m), np.int64)  # one array for the four columns (its rows): one allocation, one return
    i = 0
    for j in range(start, start + r):
        if supported[j]:
            out[i] = ev[j]
            cols[0, i] = x[j]
            cols[1, i] = y[j]
            cols[2, i] = t[j]
            cols[3, i] = p[j]
            i += 1
    return out, cols


@njit(cache=True)
def _pack_lifetimes(lt, vx, vy, valid, out):
    """``out`` (a LIFETIME_DTYPE array) from the four plain columns, in one pass."""
    for k in range(lt.shape[0]):
        o = out[k]
        o.lifetime_us = lt[k]
        o.vx_px_s = vx[k]
        o.vy_px_s = vy[k]
        o.valid = valid[k]


@njit(cache=True, inline="always")
def _kept_chunk(events, kept, cols, lo, hi, i):
    """The kept events among ``[lo, hi)`` into ``cols[:, i:]``, in order."""
    for k in range(lo, hi):
        if kept[k]:
            e = events[k]
            cols[0, i] = e.x
            cols[1, i] = e.y
            cols[2, i] = e.t
            cols[3, i] = 1 if e.p else 0
            i += 1


@njit(cache=True, inline="always")
def _expand_chunk(kept, lt, vx, vy, valid, out, lo, hi, i):
    """``out[lo:hi]``: the kept events' columns from index ``i`` on, no estimate elsewhere."""
    for k in range(lo, hi):
        o = out[k]
        if kept[k]:
            o.lifetime_us = lt[i]
            o.vx_px_s = vx[i]
            o.vy_px_s = vy[i]
            o.valid = valid[i]
            i += 1
        else:
            o.lifetime_us = np.nan
            o.vx_px_s = np.nan
            o.vy_px_s = np.nan
            o.valid = False


@njit(cache=True, inline="always")
def _columns_chunk(events, cols, lo, hi):
    """Events ``[lo, hi)``'s x, y, t, p into ``cols[:, lo:hi]``."""
    for k in range(lo, hi):
        e = events[k]
        cols[0, k] = e.x
        cols[1, k] = e.y
        cols[2, k] = e.t
        cols[3, k] = 1 if e.p else 0


@njit(cache=True)
def _record_columns_into(events, cols):
    """The events' x, y, t, p into ``cols`` ((4, n) int64: its rows are the estimator's columns), in one pass."""
    _columns_chunk(events, cols, 0, events.shape[0])


@njit(parallel=True, cache=True)
def _record_columns_par_into(events, cols):
    """:func:`_record_columns_into` over chunks of events in parallel: the same array."""
    n = events.shape[0]
    for c in prange(n_chunks(n)):
        lo, hi = chunk_bounds(c, n)
        _columns_chunk(events, cols, lo, hi)


@njit(cache=True, inline="always")
def _lifetime_chunk(lifetimes, cols, valid, lo, hi):
    """Lifetimes ``[lo, hi)``'s lifetime, vx, vy into ``cols[:, lo:hi]`` and valid into ``valid[lo:hi]``."""
    for k in range(lo, hi):
        o = lifetimes[k]
        cols[0, k] = o.lifetime_us
        cols[1, k] = o.vx_px_s
        cols[2, k] = o.vy_px_s
        valid[k] = o.valid


@njit(cache=True)
def _lifetime_columns_into(lifetimes, cols, valid):
    """A LIFETIME_DTYPE array's lifetime, vx, vy into ``cols`` ((3, n) float64) and valid into ``valid``."""
    _lifetime_chunk(lifetimes, cols, valid, 0, lifetimes.shape[0])


@njit(parallel=True, cache=True)
def _lifetime_columns_par_into(lifetimes, cols, valid):
    """:func:`_lifetime_columns_into` over chunks in parallel: the same arrays."""
    n = lifetimes.shape[0]
    for c in prange(n_chunks(n)):
        lo, hi = chunk_bounds(c, n)
        _lifetime_chunk(lifetimes, cols, valid, lo, hi)


@njit(cache=True)
def _kept_columns(events, kept):
    """The kept events' x, y, t, p as a (4, m) int64 array (its rows: the estimator's columns), in one pass."""
    m = 0
    for k in range(kept.shape[0]):
        if kept[k]:
            m += 1
    cols = np.empty((4, m), np.int64)
    _kept_chunk(events, kept, cols, 0, kept.shape[0], 0)
    return cols


@njit(cache=True)
def _kept_columns_into(events, kept, cols):
    """:func:`_kept_columns` written into ``cols`` ((4, m) int64, m the count of kept events)."""
    _kept_chunk(events, kept, cols, 0, kept.shape[0], 0)


@njit(cache=True)
def _expand_lifetimes(kept, lt, vx, vy, valid, out):
    """``out`` (LIFETIME_DTYPE, aligned with all events): the kept events' columns, no estimate elsewhere."""
    _expand_chunk(kept, lt, vx, vy, valid, out, 0, kept.shape[0], 0)


@njit(cache=True)
def _expand_columns(kept, lt, vx, vy, valid, out_lt, out_vx, out_vy, out_valid):
    """:func:`_expand_lifetimes` into four plain columns (aligned with all events) instead of records."""
    i = 0
    for k in range(kept.shape[0]):
        if kept[k]:
            out_lt[k] = lt[i]
            out_vx[k] = vx[i]
            out_vy[k] = vy[i]
            out_valid[k] = valid[i]
            i += 1
        else:
            out_lt[k] = np.nan
            out_vx[k] = np.nan
            out_vy[k] = np.nan
            out_valid[k] = False


@njit(parallel=True, cache=True)
def _kept_offsets(kept):
    """Where each chunk's kept events start among the kept ones (length chunks + 1: the total last)."""
    nc = n_chunks(kept.shape[0])
    cnt = np.zeros(nc + 1, np.int64)
    for c in prange(nc):
        m = 0
        lo, hi = chunk_bounds(c, kept.shape[0])
        for k in range(lo, hi):
            m += 1 if kept[k] else 0
        cnt[c + 1] = m
    return np.cumsum(cnt)


@njit(cache=True)
def _kept_columns_par(events, kept, off):
    """:func:`_kept_columns` over chunks in parallel (``off`` from :func:`_kept_offsets`): the same array."""
    cols = np.empty((4, off[-1]), np.int64)
    _kept_columns_par_into(events, kept, off, cols)
    return cols


@njit(parallel=True, cache=True)
def _kept_columns_par_into(events, kept, off, cols):
    """:func:`_kept_columns_par` written into ``cols`` ((4, off[-1]) int64)."""
    for c in prange(off.shape[0] - 1):
        lo, hi = chunk_bounds(c, kept.shape[0])
        _kept_chunk(events, kept, cols, lo, hi, off[c])


@njit(parallel=True, cache=True)
def _expand_lifetimes_par(kept, lt, vx, vy, valid, out, off):
    """:func:`_expand_lifetimes` over chunks in parallel (``off`` from :func:`_kept_offsets`): the same bytes."""
    for c in prange(off.shape[0] - 1):
        lo, hi = chunk_bounds(c, kept.shape[0])
        _expand_chunk(kept, lt, vx, vy, valid, out, lo, hi, off[c])
