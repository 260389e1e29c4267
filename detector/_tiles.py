"""Spatial tiles: the one place where the sensor is cut into row strips run in parallel.

Both the event buffer and the intra-pixel estimator decide an event from its
neighbourhood's history, so a strip of rows with a halo gives exactly the
serial result:

Event buffer (radius 1)
    A strip processes its events and those of one row on each side (halo);
    an owned event's support comes only from events within one row, all seen
    by the strip, so its decision is the serial one (:func:`filter_tiled`).
Intra-pixel estimator (window radius ``h``)
    An owned event's window reads the SAE up to ``h`` rows outside the strip
    (the halo). An SAE value there is written by a halo event, and whether
    that event kept its pixel's burst time depends on the lifetime estimated
    for the pixel's previous event, whose window reaches ``2 h`` rows out, and
    so on: the dependence has no finite radius, so no fixed halo is enough by
    itself. Instead the strip that owns an event publishes its burst decision
    (new burst / continues the burst; an atomic int8 per event), and the
    strips whose halo holds the event replay it with that decision (the SAE
    update only, no fit), waiting for it when it is not published yet. By
    induction over time the SAE every owned event reads is the serial one, so
    every strip gives exactly the serial result (:func:`intra_tiled`). No
    strip waits forever: the one holding the earliest unprocessed event needs
    only decisions of earlier events, already taken.

Random draws are keyed by the event's global index, so they do not depend on
the strip either. Strips are as even as possible in rows. The buffer's strips
run one per ``prange`` iteration; the estimator's are shared by numba's
threads (:func:`_intra_parallel`): a worker runs any free strip until it needs
a decision not yet published, then moves to another. Several narrow strips per
thread keep the threads busy when the events move across the sensor: with 2
row strips, an edge sweeping the rows of ``stripes.mat`` feeds one strip at a
time (at most 1.49x on 2 threads, from the events per strip per ms); with 8
strips shared by 2 threads, at most 1.84x (shapes_translation: 1.86 / 1.81x).
"""

from __future__ import annotations

import numba
import numpy as np
from numba import njit, prange

from ._atomic import _claim, _load_acquire, _sched_yield, _store_release
from ._buffer_kernels import _buffer_scan, new_state
from ._intra_kernels import _intra_stream, _scratch

_DEBUG = False
_HALO = 6


def check_n_tiles(n_tiles, height: int) -> int:
    """``n_tiles`` as an int in ``[1, height]`` (a clear error otherwise)."""
    if isinstance(n_tiles, bool) or not isinstance(n_tiles, (int, np.integer)):
        raise TypeError(f"n_tiles must be an integer >= 1, got {n_tiles!r}")
    if not 1 <= n_tiles <= height:
        raise ValueError(f"n_tiles must be in [1, {height}] (one row per strip at most), got {n_tiles}")
    return int(n_tiles)


def strips(height: int, n_tiles: int) -> np.ndarray:
    """Owned rows of each strip: ``(n_tiles, 2)`` int64 ``[lo, hi)``, as even as possible."""
    edges = (np.arange(n_tiles + 1) * height) // n_tiles
    return np.stack([edges[:-1], edges[1:]], axis=1).astype(np.int64)


def _strip_events(y: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Indices of the events of every strip's rows ``[lo, hi)``: concatenated, with offsets."""
    parts = [np.flatnonzero((y >= a) & (y < b)) for a, b in zip(lo, hi)]
    starts = np.zeros(len(parts) + 1, np.int64)
    starts[1:] = np.cumsum([q.size for q in parts])
    return np.concatenate(parts).astype(np.int64), starts


# ---------------------------------------------------------------- event buffer


@njit(parallel=True, cache=True)
def _buffer_tiles(x, y, t, p, idx, starts, lo, rows, own_lo, own_hi, width, tau_us, causal, supported):
    for s in prange(lo.shape[0]):
        sel = idx[starts[s]:starts[s + 1]]
        n = sel.shape[0]
        xs = np.empty(n, np.int64)
        ys = np.empty(n, np.int64)
        ts = np.empty(n, np.int64)
        ps = np.empty(n, np.int64)
        for j in range(n):
            k = sel[j]
            xs[j] = x[k]
            ys[j] = y[k] - lo[s]
            ts[j] = t[k]
            ps[j] = p[k]
        sup = np.empty(n, np.bool_)
        _buffer_scan(xs, ys, ts, ps, np.empty(n, np.int64), sup, 0, 0, new_state(width, rows[s]), width, rows[s],
                     tau_us, causal)
        for j in range(n):
            k = sel[j]
            if own_lo[s] <= y[k] < own_hi[s]:
                supported[k] = sup[j]


def filter_tiled(x, y, t, p, width: int, height: int, tau_us: int, causal: bool, n_tiles: int) -> np.ndarray:
    """The event buffer's decisions over ``n_tiles`` strips in parallel (halo one row): the serial ones."""
    own = strips(height, n_tiles)
    lo = np.maximum(own[:, 0] - 1, 0)
    hi = np.minimum(own[:, 1] + 1, height)
    idx, starts = _strip_events(y, lo, hi)
    supported = np.zeros(x.shape[0], bool)
    _buffer_tiles(x, y, t, p, idx, starts, lo, hi - lo, own[:, 0].copy(), own[:, 1].copy(), width, tau_us, causal,
                  supported)
    return supported


# ---------------------------------------------------------------- intra-pixel estimator


@njit(parallel=True, cache=True)
def _intra_parallel(n_threads, x, y, t, p, g0, idx, starts, off, sae, prev_t, prev_lt, prev_pol, lo, rows, own_lo,
                    own_hi, dec, dec_lt, burst, width, height, per_pol, half, delta, thr_us, thr_rel, max_trials,
                    stop_prob, min_points, min_inliers, intercept, fallback, seed, gap_ratio, on_plane, startup, border,
                    jump_check, stale_frac, t_start, reach_px, noise, out_lt, out_vx, out_vy, out_valid):
    """``n_threads`` workers share the strips: each takes any free strip, runs it until it needs a
    decision not yet taken (or to its end), gives it back, and moves on.

    A strip is run by one worker at a time (``busy``, taken by compare-and-swap).
    The strip holding the earliest unprocessed event never waits (a decision it
    needs is of an earlier event, already taken), so some strip always
    progresses, whatever the number of workers and however the system schedules
    them; many narrow strips keep the workers busy when the events move across
    the sensor (an edge sweeping the rows feeds one strip at a time).
    """
    n_tiles = lo.shape[0]
    busy = np.zeros(n_tiles, np.int64)
    cursor = np.zeros(n_tiles, np.int64)
    for th in prange(n_threads):
        wf, wi = _scratch((2 * half + 1) ** 2)  # the worker's own, reused by every strip it runs
        s = th % n_tiles
        idle = 0
        while True:
            finished = 0
            progressed = False
            for _ in range(n_tiles):
                seg = idx[starts[s]:starts[s + 1]]
                if _load_acquire(cursor, s) == seg.shape[0]:
                    finished += 1
                elif _claim(busy, s):
                    j0 = cursor[s]
                    o0 = off[s]
                    o1 = off[s + 1]
                    a = starts[s]
                    b = starts[s + 1]
                    j = _intra_stream(x, y, t, p, seg, j0, g0, sae[o0:o1], prev_t[o0:o1], prev_lt[o0:o1],
                                      prev_pol[o0:o1], burst, width, height, lo[s], rows[s], own_lo[s], own_hi[s],
                                      dec, dec_lt, False, per_pol, half, delta, thr_us, thr_rel, max_trials, stop_prob,
                                      min_points, min_inliers, intercept, fallback, seed, gap_ratio, on_plane,
                                      startup, border, jump_check, stale_frac, t_start, reach_px, noise,
                                      out_lt[a:b], out_vx[a:b], out_vy[a:b], out_valid[a:b], wf, wi)
                    _store_release(cursor, s, j)
                    _store_release(busy, s, 0)
                    progressed = progressed or j > j0
                s = (s + 1) % n_tiles
            if finished == n_tiles:
                break
            idle = 0 if progressed else idle + 1
            if idle > 0:  # every strip waited _SPINS reads in vain: give the core away
                _sched_yield()


def intra_tiled(x, y, t, p, g0: int, state, width: int, height: int, n_tiles: int, kernel_args: tuple, outs: tuple):
    """The intra-pixel estimator over ``n_tiles`` strips; the serial result (module notes).

    ``state`` is ``(sae, prev_t, prev_lt, prev_pol)``, each ``(planes, height, width)``,
    updated in place; ``kernel_args`` are :func:`_intra_stream`'s arguments from
    ``burst`` to ``noise`` without the geometry (``burst, per_pol, half, delta,
    thr_us, thr_rel, max_trials, stop_prob, min_points, min_inliers, intercept,
    fallback, seed, gap_ratio, on_plane, startup, border, jump_check, stale_frac, t_start,
    reach_px, noise``); ``outs`` is ``(lt, vx, vy, valid)``. The strips are
    shared by ``min(n_tiles, numba threads)`` workers (:func:`_intra_parallel`).
    """
    half = kernel_args[2]
    planes = state[0].shape[0]
    own = strips(height, n_tiles)
    own_lo = own[:, 0].copy()
    own_hi = own[:, 1].copy()
    lo = np.maximum(own_lo - half, 0)
    hi = np.minimum(own_hi + half, height)
    rows = hi - lo
    idx, starts = _strip_events(y, lo, hi)
    off = np.zeros(n_tiles + 1, np.int64)
    off[1:] = np.cumsum(planes * rows * width)
    local = [np.empty(off[-1], a.dtype) for a in state]
    for s in range(n_tiles):
        for g, l in zip(state, local):
            l[off[s]:off[s + 1]] = g[:, lo[s]:hi[s], :].reshape(-1)
    # outputs per slot (each strip writes its own memory), then put in place
    slot_outs = [np.empty(idx.size, o.dtype) for o in outs]
    _intra_parallel(min(n_tiles, numba.get_num_threads()), x, y, t, p, g0, idx, starts, off, *local, lo, rows,
                    own_lo, own_hi, np.zeros(x.shape[0], np.int8), np.empty(x.shape[0]), kernel_args[0], width, height, *kernel_args[1:],
                    *slot_outs)
    ys = y[idx]
    tile_of = np.repeat(np.arange(n_tiles), np.diff(starts))
    owned = (ys >= own_lo[tile_of]) & (ys < own_hi[tile_of])
    for o, so in zip(outs, slot_outs):
        o[idx[owned]] = so[owned]
    for s in range(n_tiles):
        a, b = own_lo[s], own_hi[s]
        for g, l in zip(state, local):
            g[:, a:b, :] = l[off[s]:off[s + 1]].reshape(planes, rows[s], width)[:, a - lo[s]:b - lo[s], :]
