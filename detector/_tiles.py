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
    that event kept its pixel's burst time depends on the lifetime kept for
    the pixel's previous event, whose window reaches ``2 h`` rows out, and so
    on: the dependence has no finite radius, so no fixed halo is enough by
    itself. Instead the strip that owns an event near its edges publishes the
    lifetime it keeps for the event's pixel (and its burst decision), and the
    strips whose halo holds the pixel replay its events with the same burst
    rule (SAE and burst state, no fit, :func:`_halo_event`): a halo event
    needs only the lifetime of its pixel's *previous* event, one same-pixel
    gap older (the start-up rule's trial, after an event without estimate,
    needs the owner's decision of the event itself). An event that cannot run
    yet is deferred, and so is every later event within the window radius of
    a deferred one; the others run ahead, out of time order, because events
    farther apart read and write disjoint state (:func:`_run_strip`). By
    induction every event runs after all earlier events of its window, with
    the serial SAE and burst state: every strip gives exactly the serial
    result (:func:`intra_tiled`). No strip waits forever: the earliest event
    not yet run anywhere is always ready.

Random draws are keyed by the event's global index, so they do not depend on
the strip either. Both cut the rows at the quantiles of the events' rows
(:func:`balanced_strips`: about as many events each). The buffer runs one strip
per ``prange`` iteration; the estimator's strips are shared by
numba's threads (:func:`_intra_parallel`): a worker runs any free strip until
nothing in it can run, then moves to another.

Edge image (halo 1 row)
    A pixel's edge state changes only by its own events and by the clearing of
    an 8-neighbour's event (``clear_behind``), which depends on that event alone;
    a strip replaying its rows' events and one row on each side has the serial
    state in its owned rows (:func:`edge_frames_tiled`).

Cache lines: counters a strip updates often are kept in locals and added once
per turn (the strips' ``stats`` rows share lines), and the owners publish their
decisions in one of two arrays by the strip's parity, so that neighbouring
strips never write the same line of ``dec`` / ``dec_lt``.

Speed (``benchmarks/bench_detector.py --tiles 2``): the simulated schedule of
these rules on idle workers (``benchmarks/_strip_schedule.py``, one unit per
fit) gives 1.91x on ``stripes.mat`` and 2.00x on shapes_translation with 2
strips, 7.1x / 6.1x with 8, 2.00x / 7.89x on the Gen4-sized input (stripes
tiled on 1280x720); the strips' extra CPU per event (halo replays, deferral
checks) is measured beside it: 1.04-1.11x on ``stripes.mat`` under load, 0.91x
on the Gen4-sized input (a strip's state is smaller than the sensor's and
fits the caches better).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

from ._atomic import _claim, _clock_ns, _load_acquire, _sched_yield, _store_release
from ._checks import NEVER_US
from ._chunks import chunk_bounds, n_chunks
from ._buffer_kernels import (_buffer_scan, _line_scan, _two_passes, narrow_state, new_line_state, new_state,
                              one_shot_exact)
from ._edges_kernels import _DX, _DY, _edge_update
from ._intra_kernels import _FIT_STRIDE, _intra_stream, _scratch
from ._noise_kernels import _AGREE, _BURST_SPAN
from ._workspace import WORKSPACE


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


def balanced_strips(y: np.ndarray, height: int, n_tiles: int) -> np.ndarray:
    """Owned rows of each strip, ``(n_tiles, 2)`` int64 ``[lo, hi)``: about as many events each.

    Cuts at the quantiles of the events' rows (each strip keeps at least one
    row); where the strips are cut changes no result, only how evenly the work
    is shared.
    """
    return _balanced(_chunk_rows(np.asarray(y), height).sum(axis=0) if height else np.zeros(0, np.int64),
                     height, n_tiles)


def _balanced(counts: np.ndarray, height: int, n_tiles: int) -> np.ndarray:
    """:func:`balanced_strips` from the events per row."""
    cum = np.cumsum(counts)
    edges = np.zeros(n_tiles + 1, np.int64)
    edges[-1] = height
    total = cum[-1] if cum.size else 0
    for i in range(1, n_tiles):
        c = int(np.searchsorted(cum, total * i / n_tiles, side="left")) + 1 if total else (height * i) // n_tiles
        edges[i] = min(max(c, edges[i - 1] + 1), height - (n_tiles - i))
    return np.stack([edges[:-1], edges[1:]], axis=1)


def strip_layout(y: np.ndarray, height: int, n_tiles: int, halo: int, own: np.ndarray | None = None):
    """The strips of the events with rows ``y``: their owned rows (:func:`balanced_strips`, or ``own`` when
    given), with ``halo`` rows on each side, and their events (:func:`_strip_index`), from one pass of row counts
    per chunk of events.

    Returns ``(own, lo, hi, idx, starts, off)``: ``own`` ``(n_tiles, 2)``, the rows
    ``[lo, hi)`` each strip holds, and :func:`_strip_index`'s three arrays.
    """
    part = _chunk_rows(y, height)
    if own is None:
        own = _balanced(part.sum(axis=0), height, n_tiles)
    lo = np.maximum(own[:, 0] - halo, 0)
    hi = np.minimum(own[:, 1] + halo, height)
    idx, starts, off = _strip_index(y, lo, hi, part)
    return own, lo, hi, idx, starts, off


@njit(parallel=True, cache=True)
def _chunk_rows(y, height):
    """Events per row of each chunk of events: ``(chunks, height)`` (rows outside ``[0, height)`` ignored)."""
    nc = n_chunks(y.shape[0])
    part = np.zeros((nc, height), np.int64)
    for c in prange(nc):
        row = np.zeros(height, np.int64)  # the chunk's own counts, written once (no shared cache lines)
        lo, hi = chunk_bounds(c, y.shape[0])
        for k in range(lo, hi):
            r = y[k]
            if 0 <= r < height:
                row[r] += 1
        part[c] = row
    return part


# ---------------------------------------------------------------- event buffer


@njit(cache=True)
def _strip_events(x, y, t, p, sel, row0):
    """The events ``sel`` of a strip as int64 columns, rows relative to the strip's first row ``row0``."""
    n = sel.shape[0]
    xs = np.empty(n, np.int64)
    ys = np.empty(n, np.int64)
    ts = np.empty(n, np.int64)
    ps = np.empty(n, np.int64)
    for j in range(n):
        k = sel[j]
        xs[j] = x[k]
        ys[j] = y[k] - row0
        ts[j] = t[k]
        ps[j] = p[k]
    return xs, ys, ts, ps


@njit(parallel=True, cache=True)
def _buffer_tiles(x, y, t, p, idx, starts, lo, rows, own_lo, own_hi, width, tau_us, causal, exact, narrow,
                  supported, line_us=0, line_tol=0.5, line_quiet=2.0, line_count=1):
    for s in prange(lo.shape[0]):
        sel = idx[starts[s]:starts[s + 1]]
        n = sel.shape[0]
        xs, ys, ts, ps = _strip_events(x, y, t, p, sel, lo[s])
        sup = np.empty(n, np.bool_)
        # the serial one-shot kernels (:func:`evedge.detector.buffer.filter_events`)
        _two_passes(xs, ys, ts, ps, sup, width, rows[s], tau_us, causal or not exact, narrow)
        if not (causal or exact):
            _buffer_scan(xs, ys, ts, ps, np.empty(n, np.int64), sup, 0, 0, new_state(width, rows[s]), width, rows[s],
                         tau_us, False)
        if line_us > 0:  # the line rule reads only pixels within one of the event it supports: the halo suffices
            _line_scan(xs, ys, ts, ps, sup, 0, 0, new_line_state(width, rows[s]), width, rows[s], line_us, line_tol,
                       line_quiet, line_count)
        for j in range(n):
            k = sel[j]
            if own_lo[s] <= y[k] < own_hi[s]:
                supported[k] = sup[j]


def filter_tiled(x, y, t, p, width: int, height: int, tau_us: int, causal: bool, n_tiles: int, line_us: int = 0,
                 line_tol: float = 0.5, line_quiet: float = 2.0, line_count: int = 1) -> np.ndarray:
    """The event buffer's decisions over ``n_tiles`` strips in parallel (halo one row): the serial ones.

    The strips are cut where they hold about as many events (:func:`balanced_strips`).
    """
    own, lo, hi, idx, starts, _ = strip_layout(y, height, n_tiles, 1)
    supported = np.zeros(x.shape[0], bool)
    exact = x.shape[0] > 0 and one_shot_exact(t[0], t[-1], tau_us)
    narrow = x.shape[0] > 0 and narrow_state(t[0], t[-1], tau_us, width, height)
    _buffer_tiles(x, y, t, p, idx, starts, lo, hi - lo, own[:, 0].copy(), own[:, 1].copy(), width, tau_us, causal,
                  exact, narrow, supported, line_us, line_tol, line_quiet, line_count)
    return supported


# ---------------------------------------------------------------- edge image


@njit(parallel=True, cache=True)
def _edge_tiles(x, y, t, lt, vx, vy, valid, p, idx, starts, lo, rows, own_lo, own_hi, width, clear_behind,
                invalid_clears, burst, times, order, out, soff, last_ts, expiries, start_ts, prev_lts, prev_pols):
    """Edge frames of every strip (one per ``prange`` iteration) at the sorted instants ``times``.

    A strip replays the events of its rows and of one row on each side
    (:func:`~evedge.detector._edges_kernels._edge_update`, read through its index
    into the shared columns, on its own state: cells ``soff[s]:soff[s + 1]`` of
    the five state arrays, set here) and writes its owned rows of frame
    ``order[i]`` at ``times[i]``.
    """
    flat = out.reshape(out.shape[0], -1)
    for s in prange(lo.shape[0]):
        sel = idx[starts[s]:starts[s + 1]]
        n = sel.shape[0]
        row0 = lo[s]
        last_t = last_ts[soff[s]:soff[s + 1]]
        expiry = expiries[soff[s]:soff[s + 1]]
        start_t = start_ts[soff[s]:soff[s + 1]]
        prev_lt = prev_lts[soff[s]:soff[s + 1]]
        prev_pol = prev_pols[soff[s]:soff[s + 1]]
        last_t[:] = NEVER_US
        expiry[:] = -np.inf
        start_t[:] = NEVER_US
        prev_lt[:] = np.nan
        prev_pol[:] = -1
        a = 0
        q0 = (own_lo[s] - row0) * width  # the owned rows: state cells q0 .. q0 + m, frame cells g0 .. g0 + m
        m = (own_hi[s] - own_lo[s]) * width
        g0 = own_lo[s] * width
        for i in range(times.shape[0]):
            tt = times[i]
            b = a
            while b < n and t[sel[b]] <= tt:
                b += 1
            if b > a:
                _edge_update(x, y, t, lt, vx, vy, valid, last_t, expiry, width, rows[s], clear_behind, invalid_clears,
                             _DX, _DY, p, burst, start_t, prev_lt, prev_pol, sel, a, b, row0)
                a = b
            # the owned rows as flat slices (one loop the compiler vectorises: both comparisons, no short circuit)
            o = flat[order[i], g0:g0 + m]
            lt_s = last_t[q0:q0 + m]
            ex_s = expiry[q0:q0 + m]
            for c in range(m):
                o[c] = (lt_s[c] <= tt) & (tt < ex_s[c])


def edge_frames_tiled(x, y, t, lt, vx, vy, valid, p, width: int, height: int, clear_behind: bool,
                      invalid_clears: bool, burst: float, times: np.ndarray, order: np.ndarray, n_tiles: int,
                      out: np.ndarray) -> None:
    """Edge frames over ``n_tiles`` strips in parallel (halo one row): the serial frames, written into ``out``.

    A pixel's state changes only by its own events and by the clearing of an
    8-neighbour's event (``clear_behind``), which depends on that event alone
    (its time, flow and validity), not on the neighbour pixel's state: a strip
    that replays its rows' events and those of one row on each side has the
    serial state in its owned rows. ``times`` are the instants sorted
    (``times[i]`` is frame ``order[i]``); cut where the strips hold about as many
    events (:func:`balanced_strips`).
    """
    own, lo, hi, idx, starts, _ = strip_layout(y, height, n_tiles, 1)
    soff = np.zeros(n_tiles + 1, np.int64)
    soff[1:] = np.cumsum((hi - lo) * width)
    with WORKSPACE.scope() as take:  # the strips' state, kept mapped between calls (:mod:`._workspace`)
        state = [take.empty(soff[-1], d) for d in (np.int64, np.float64, np.int64, np.float64, np.int8)]
        _edge_tiles(x, y, t, lt, vx, vy, valid, p, idx, starts, lo, hi - lo, own[:, 0].copy(), own[:, 1].copy(),
                    width, clear_behind, invalid_clears, burst, times, order, out, soff, *state)


# ---------------------------------------------------------------- intra-pixel estimator

#: Events handed to the stream kernel per call (decided ready before the call).
_BATCH_EVENTS = 64

#: Events a worker runs on one strip before moving on, when there are more strips than workers.
_TURN_EVENTS = 2048

#: ``clock_gettime``'s clock of the calling thread's CPU time (Linux).
_THREAD_CPU = 3

#: Deferred events a strip may hold (beyond that it waits); rounded up to a power of two.
_QUEUE_MAX = 4096

#: Events run before a strip looks again at a queue front that was not ready.
_RECHECK_EVENTS = 8


@njit(cache=True, inline="always")
def _queued_near(qrow, qcnt, prow, r, xk, rows, width, half):
    """Whether a deferred event of the plane whose rows start at ``prow`` lies within ``half`` px of ``(r, xk)``."""
    for rr in range(max(r - half, 0), min(r + half, rows - 1) + 1):
        if qrow[prow + rr] != 0:
            row = (prow + rr) * width
            for xx in range(max(xk - half, 0), min(xk + half, width - 1) + 1):
                if qcnt[row + xx] != 0:
                    return True
    return False


@njit(cache=True)
def _noise_halo(noise):
    """``(lifetime_agreement, burst_span_lifetimes)`` from the noise rules' array (None: both off)."""
    if noise is None:
        return 0.0, 0.0
    return noise[_AGREE], noise[_BURST_SPAN]


@njit(cache=True, inline="always")
def _halo_event(k, si, tk, pk, sae, prev_t, prev_lt, prev_pol, dec, dec_lt, burst, startup, agree, span, apply):
    """Replay halo event ``k`` at local pixel ``si`` (SAE and burst state, no fit); False when it cannot be yet.

    When the owner has published the event, its decision and kept lifetime are
    taken as they are. Otherwise the decision follows from the pixel's state
    with the burst rules of :func:`_intra_stream` (same expressions: the gap
    rule, then the noise rule ``burst_span_lifetimes``), once the lifetime its
    owner kept for the pixel's previous event is known: ``prev_lt`` of a halo
    pixel holds ``-(k' + 1)`` after a replayed event ``k'`` (lifetimes are
    positive or NaN) until ``dec_lt[k']`` is published. The start-up rule's
    trial (the previous event without estimate) needs the owner's decision of
    the event itself, and so does every event under the noise rule
    ``lifetime_agreement`` (owned events read their neighbours' ``prev_lt``: a
    halo pixel's must hold the value itself, never the pending marker). So a
    halo event mostly waits for an event one same-pixel gap older, not for its
    own copy. ``agree`` and ``span`` are ``lifetime_agreement`` and
    ``burst_span_lifetimes`` (0 = off, :func:`_noise_halo`). With ``apply``
    False, only whether it can.

    The other rules of :func:`_intra_stream` (``stale_fraction``,
    ``split_jump_check``, ``startup_reach``, ``newer_share_max``, the border)
    change only the fit, hence the kept lifetime, which the owner publishes;
    they read the event's own (owned) pixel and the window's SAE, which the
    halo replay keeps exact. A rule added to the burst decision in
    :func:`_intra_stream` must be added here too (``tests/detector/test_tiles.py``
    fails otherwise); a rule that makes owned events read their neighbours'
    ``prev_lt`` must wait for the owner's value instead (return False while
    ``dec[k]`` is 0).
    """
    d = _load_acquire(dec, k)
    if d == 0 and agree > 0.0:
        return False  # owned events read this pixel's prev_lt: the owner's value, not the pending marker
    if d != 0:
        cont = d == 2
        lt_after = dec_lt[k]
    elif burst <= 0.0:
        cont = False  # no burst grouping: every event takes its pixel's time; no rule reads a halo's prev_lt
        lt_after = np.nan
    else:
        lt = prev_lt[si]
        if lt < 0.0:
            kp = np.int64(-lt) - 1
            if _load_acquire(dec, kp) == 0:
                return False
            lt = dec_lt[kp]
        cont = prev_pol[si] == pk and tk - prev_t[si] <= burst * lt
        # noise rule burst_span_lifetimes: a burst lasts at most span lifetimes from its first event
        cont = cont and (span <= 0.0 or tk - sae[si] <= span * lt)
        if startup and not cont and prev_pol[si] == pk and math.isnan(lt):
            return False  # the trial's fit decides: the owner's
        lt_after = -np.float64(k + 1)
    if apply:
        if not cont:
            sae[si] = tk
        prev_t[si] = tk
        prev_pol[si] = pk
        prev_lt[si] = lt_after
    return True


@njit(cache=True)
def _flush(x, y, t, p, g0, seg, sae, prev_t, prev_lt, prev_pol, fits, row0, rows, own_lo, own_hi, dec, dec_lt,
           width, height, kargs, out_lt, out_vx, out_vy, out_valid, wf, wi, bpos, bidx, bl, bvx, bvy, bvalid, m):
    """Run the batch ``bpos[:m]`` (owned events, positions in ``seg``) through :func:`_intra_stream`."""
    if m == 0:
        return
    for i in range(m):
        bidx[i] = seg[bpos[i]]
    _intra_stream(x, y, t, p, bidx[:m], 0, g0, sae, prev_t, prev_lt, prev_pol, kargs[0], width, height, row0, rows,
                  own_lo, own_hi, dec, dec_lt, kargs[1], kargs[2], *kargs[3:22], bl[:m], bvx[:m], bvy[:m],
                  bvalid[:m], wf, wi, *kargs[22:27], fits, kargs[27], kargs[28])
    for i in range(m):
        jp = bpos[i]
        out_lt[jp] = bl[i]
        out_vx[jp] = bvx[i]
        out_vy[jp] = bvy[i]
        out_valid[jp] = bvalid[i]


@njit(cache=True)
def _run_strip(budget, x, y, t, p, g0, seg, sae, prev_t, prev_lt, prev_pol, fits, qcnt, qrow, queue, st, row0, rows,
               own_lo, own_hi, dec, dec_lt, width, height, kargs, out_lt, out_vx, out_vy, out_valid, wf, wi, bpos,
               bidx, bl, bvx, bvy, bvalid, stats, par, me):
    """Run one strip for up to ``budget`` events, out of time order where that is provably the same.

    The strip's events are taken in time order from ``st[0]`` (cursor). An event
    is *deferred* (appended to the strip's queue: ``st[1]`` head, ``st[2]``
    tail) when it is a halo event that cannot be replayed yet
    (:func:`_halo_event`), or when a deferred event of its SAE plane lies within
    the window radius ``half`` of it (it may read that event's pixel, or that
    event may read its pixel: the window is symmetric); otherwise it runs now.
    The queue's front runs first, in time order, whenever it is ready. Two
    events of different planes, or more than ``half`` px apart, read and write
    disjoint state (window, pixel, burst state), so they commute; every event
    still runs after all earlier events within its window: the SAE, burst state
    and fit of each event are the serial ones. Owned events go to
    :func:`_intra_stream` in batches; a halo event is replayed at once (after the
    batch when the batch holds events within ``half`` rows of it, which read its
    pixel). Returns the events run; ``stats[1]`` counts the deferred ones.

    ``dec, dec_lt`` are ``(2, events)``: a strip publishes in row ``me`` (its index's
    parity) and reads an event's decision in row ``par[y]`` (its owner's parity):
    neighbouring strips write different arrays, so their writes of events close
    in time do not share cache lines.
    """
    burst = kargs[0]
    per_pol = kargs[1]
    half = kargs[2]
    startup = kargs[15]
    agree, span = _noise_halo(kargs[21])  # the noise rules the halo replay applies
    n = seg.shape[0]
    mask = queue.shape[0] - 1  # a power of two
    nb = bpos.shape[0]
    cur = st[0]
    head = st[1]
    tail = st[2]
    done = 0
    m = 0  # events in the batch
    near_lo = 0  # of which within half rows of the strip's first / last owned row
    near_hi = 0
    recheck = 0
    n_batches = 0  # counted here, added to stats once: the strips' stats rows share cache lines
    n_deferred = 0
    while done < budget:
        jp = -1
        looked = head < tail and done >= recheck
        if looked:  # the queue's front, when ready
            k = seg[queue[head & mask]]
            pr = ((1 if p[k] else 0) if per_pol else 0) * rows + y[k] - row0
            if own_lo <= y[k] < own_hi or _halo_event(k, pr * width + x[k], t[k], np.int8(1 if p[k] else 0), sae,
                                                      prev_t, prev_lt, prev_pol, dec[par[y[k]]],
                                                      dec_lt[par[y[k]]], burst, startup, agree, span, False):
                jp = queue[head & mask]
                head += 1
                qrow[pr] -= 1
                qcnt[pr * width + x[k]] -= 1
            else:
                recheck = done + _RECHECK_EVENTS  # its neighbour is behind: run others a while
        while jp < 0 and cur < n:  # else the next new event that can run, deferring the others
            k = seg[cur]
            pl = ((1 if p[k] else 0) if per_pol else 0) * rows
            r = y[k] - row0
            later = head < tail and _queued_near(qrow, qcnt, pl, r, x[k], rows, width, half)
            if not later and not own_lo <= y[k] < own_hi:
                later = not _halo_event(k, (pl + r) * width + x[k], t[k], np.int8(1 if p[k] else 0), sae, prev_t,
                                        prev_lt, prev_pol, dec[par[y[k]]], dec_lt[par[y[k]]], burst, startup, agree,
                                        span, False)
            if not later:
                jp = cur
            elif tail - head > mask:
                break  # the queue is full: wait for its front
            else:
                queue[tail & mask] = cur
                tail += 1
                qrow[pl + r] += 1
                qcnt[(pl + r) * width + x[k]] += 1
                n_deferred += 1
            cur += 1
        if jp < 0:
            if head < tail and not looked:
                recheck = done  # nothing else can run: look at the front again
                continue
            break  # nothing can run before a neighbour publishes
        k = seg[jp]
        if own_lo <= y[k] < own_hi:
            if m == nb:
                _flush(x, y, t, p, g0, seg, sae, prev_t, prev_lt, prev_pol, fits, row0, rows, own_lo, own_hi, dec[me],
                       dec_lt[me], width, height, kargs, out_lt, out_vx, out_vy, out_valid, wf, wi, bpos, bidx, bl,
                       bvx, bvy, bvalid, m)
                n_batches += 1
                m = near_lo = near_hi = 0
            bpos[m] = jp
            m += 1
            near_lo += 1 if y[k] < own_lo + half else 0
            near_hi += 1 if y[k] >= own_hi - half else 0
        else:
            if (near_lo > 0 and y[k] < own_lo) or (near_hi > 0 and y[k] >= own_hi):
                _flush(x, y, t, p, g0, seg, sae, prev_t, prev_lt, prev_pol, fits, row0, rows, own_lo, own_hi, dec[me],
                       dec_lt[me], width, height, kargs, out_lt, out_vx, out_vy, out_valid, wf, wi, bpos, bidx, bl,
                       bvx, bvy, bvalid, m)
                n_batches += 1
                m = near_lo = near_hi = 0
            pl = ((1 if p[k] else 0) if per_pol else 0) * rows
            _halo_event(k, (pl + y[k] - row0) * width + x[k], t[k], np.int8(1 if p[k] else 0), sae, prev_t, prev_lt,
                        prev_pol, dec[par[y[k]]], dec_lt[par[y[k]]], burst, startup, agree, span, True)
        done += 1
    _flush(x, y, t, p, g0, seg, sae, prev_t, prev_lt, prev_pol, fits, row0, rows, own_lo, own_hi, dec[me], dec_lt[me],
           width, height, kargs, out_lt, out_vx, out_vy, out_valid, wf, wi, bpos, bidx, bl, bvx, bvy, bvalid, m)
    n_batches += 1 if m > 0 else 0
    stats[0] += n_batches
    stats[1] += n_deferred
    st[0] = cur
    st[1] = head
    st[2] = tail
    return done


@njit(parallel=True, cache=True)
def _intra_parallel(n_threads, turn, x, y, t, p, g0, idx, starts, off, sae, prev_t, prev_lt, prev_pol, fits, qcnt, roff,
                    qrow, queue, qoff, lo, rows, own_lo, own_hi, dec, dec_lt, width, height, kargs, out_lt, out_vx,
                    out_vy, out_valid, stats, work, par):
    """``n_threads`` workers share the strips: each takes any free strip, runs it (:func:`_run_strip`) for
    ``turn`` events or until it must wait, gives it back, and moves on.

    A strip is run by one worker at a time (``busy``, taken by compare-and-swap;
    its state is handed over by the release / acquire of that flag). Some strip
    can always run, whatever the number of workers and however the system
    schedules them: the earliest event not yet run anywhere is at its strip's
    queue front, or next with an empty queue, and needs no decision not yet
    taken (for a halo copy: of earlier events, or its owner's copy, which is as
    early and ready). ``stats[s]``: batches, deferred events, turns, turns that
    ran nothing, and (with a fifth column) the CPU time (ns) of its turns that
    ran events, per strip; ``work[th]``: the worker's CPU time (ns) in turns that
    ran events, in the others, and its events.
    """
    half = kargs[2]
    n_tiles = lo.shape[0]
    fo = _FIT_STRIDE if fits.shape[0] > 0 else 0  # burst reuse: _FIT_STRIDE values per cell (empty: off)
    busy = np.zeros(n_tiles, np.int64)
    fin = np.zeros(n_tiles, np.int64)
    state = np.zeros((n_tiles, 3), np.int64)
    for th in prange(n_threads):
        c_start = _clock_ns(_THREAD_CPU)
        wf, wi = _scratch((2 * half + 1) ** 2)  # the worker's own, reused by every strip it runs
        bpos = np.empty(_BATCH_EVENTS, np.int64)
        bidx = np.empty(_BATCH_EVENTS, np.int64)
        bl = np.empty(_BATCH_EVENTS)
        bvx = np.empty(_BATCH_EVENTS)
        bvy = np.empty(_BATCH_EVENTS)
        bvalid = np.empty(_BATCH_EVENTS, np.bool_)
        s = th % n_tiles
        idle = 0
        while True:
            finished = 0
            progressed = False
            for _ in range(n_tiles):
                if _load_acquire(fin, s) == 1:
                    finished += 1
                elif _claim(busy, s):
                    a = starts[s]
                    b = starts[s + 1]
                    o0 = off[s]
                    o1 = off[s + 1]
                    c0 = _clock_ns(_THREAD_CPU)
                    done = _run_strip(turn, x, y, t, p, g0, idx[a:b], sae[o0:o1], prev_t[o0:o1], prev_lt[o0:o1],
                                      prev_pol[o0:o1], fits[fo * o0:fo * o1], qcnt[o0:o1], qrow[roff[s]:roff[s + 1]],
                                      queue[qoff[s]:qoff[s + 1]], state[s], lo[s], rows[s], own_lo[s], own_hi[s],
                                      dec, dec_lt, width, height, kargs, out_lt[a:b], out_vx[a:b], out_vy[a:b],
                                      out_valid[a:b], wf, wi, bpos, bidx, bl, bvx, bvy, bvalid, stats[s], par, s % 2)
                    if done > 0:
                        dt = _clock_ns(_THREAD_CPU) - c0
                        work[th, 0] += dt
                        if stats.shape[1] > 4:
                            stats[s, 4] += dt
                    work[th, 2] += done
                    stats[s, 2] += 1
                    stats[s, 3] += 1 if done == 0 else 0
                    if state[s, 0] == b - a and state[s, 1] == state[s, 2]:
                        _store_release(fin, s, 1)
                    _store_release(busy, s, 0)
                    progressed = progressed or done > 0
                s = (s + 1) % n_tiles
            if finished == n_tiles:
                break
            idle = 0 if progressed else idle + 1
            if idle > 0:  # no strip could run: give the core away
                _sched_yield()
        work[th, 1] = _clock_ns(_THREAD_CPU) - c_start - work[th, 0]


@njit(cache=True)
def _row_strips(lo, hi):
    """Per row: the first and the last strip whose rows ``[lo, hi)`` hold it (strips sorted, overlapping
    only in their halos: the strips holding a row are a contiguous range)."""
    n_tiles = lo.shape[0]
    height = hi[-1]
    first = np.full(height, n_tiles, np.int64)
    last = np.full(height, -1, np.int64)
    for s in range(n_tiles):
        for r in range(lo[s], hi[s]):
            first[r] = min(first[r], s)
            last[r] = max(last[r], s)
    return first, last


@njit(parallel=True, cache=True)
def _strip_index(y, lo, hi, part):
    """The events of every strip's rows ``[lo, hi)`` in time order, concatenated, the strips' offsets, and
    where each chunk's events of each strip begin.

    ``part``: :func:`_chunk_rows` of ``y``. Returns ``(idx, starts, off)``: strip
    ``s`` holds ``idx[starts[s]:starts[s + 1]]``; the events of chunk ``c`` (events
    ``c * CHUNK_EVENTS`` on, :mod:`._chunks`) in strip ``s`` start at ``idx[off[c, s]]``. The chunks'
    counts per strip come from their row counts, then one pass over chunks in
    parallel fills each at its offsets: the serial order for any number of threads.
    """
    n_tiles = lo.shape[0]
    first, last = _row_strips(lo, hi)
    n = y.shape[0]
    nc = part.shape[0]
    starts = np.zeros(n_tiles + 1, np.int64)
    off = np.zeros((nc, n_tiles), np.int64)
    for s in range(n_tiles):
        acc = starts[s]
        for c in range(nc):
            off[c, s] = acc
            for r in range(lo[s], hi[s]):
                acc += part[c, r]
        starts[s + 1] = acc
    idx = np.empty(starts[-1], np.int64)
    for c in prange(nc):
        fill = off[c].copy()
        c0, c1 = chunk_bounds(c, n)
        for k in range(c0, c1):
            for s in range(first[y[k]], last[y[k]] + 1):
                idx[fill[s]] = k
                fill[s] += 1
    return idx, starts, off


@njit(parallel=True, cache=True)
def _put_owned(y, lo, hi, own_lo, own_hi, off, slot_lt, slot_vx, slot_vy, slot_valid, lt, vx, vy, valid):
    """Each strip's outputs of its owned events (slots aligned with :func:`_strip_index`'s ``idx``) into the
    per-event arrays; a gather in parallel over chunks of events (``off`` from :func:`_strip_index`)."""
    n_tiles = lo.shape[0]
    first, last = _row_strips(lo, hi)
    owner = np.empty(hi[-1], np.int64)
    for s in range(n_tiles):
        owner[own_lo[s]:own_hi[s]] = s
    for c in prange(off.shape[0]):
        fill = off[c].copy()  # slot of the chunk's next event in each strip
        c0, c1 = chunk_bounds(c, y.shape[0])
        for k in range(c0, c1):
            r = y[k]
            j = fill[owner[r]]
            lt[k] = slot_lt[j]
            vx[k] = slot_vx[j]
            vy[k] = slot_vy[j]
            valid[k] = slot_valid[j]
            for s in range(first[r], last[r] + 1):
                fill[s] += 1


@njit(parallel=True, cache=True)
def _state_to_strips(g, local, lo, hi, off):
    """Each strip's rows ``[lo, hi)`` of the state ``g`` (planes, height, cells per row) into ``local[off[s]:]``,
    the strips in parallel."""
    for s in prange(lo.shape[0]):
        dst = local[off[s]:off[s + 1]].reshape(g.shape[0], hi[s] - lo[s], g.shape[2])
        dst[:, :, :] = g[:, lo[s]:hi[s], :]


@njit(parallel=True, cache=True)
def _strips_to_state(g, local, lo, hi, own_lo, own_hi, off):
    """Each strip's owned rows back from ``local`` into the state ``g``, the strips in parallel (disjoint rows)."""
    for s in prange(lo.shape[0]):
        src = local[off[s]:off[s + 1]].reshape(g.shape[0], hi[s] - lo[s], g.shape[2])
        g[:, own_lo[s]:own_hi[s], :] = src[:, own_lo[s] - lo[s]:own_hi[s] - lo[s], :]


@njit(cache=True)
def _halos_from_owners(local, lo, hi, own_lo, own_hi, off, planes, rowlen):
    """Each strip's halo rows in ``local`` (laid out as :func:`_state_to_strips` does) from the strip owning them."""
    for s in range(lo.shape[0]):
        dst = local[off[s]:off[s + 1]].reshape(planes, hi[s] - lo[s], rowlen)
        for r in range(lo[s], hi[s]):
            if own_lo[s] <= r < own_hi[s]:
                continue
            o = 0
            while not (own_lo[o] <= r < own_hi[o]):
                o += 1
            src = local[off[o]:off[o + 1]].reshape(planes, hi[o] - lo[o], rowlen)
            dst[:, r - lo[s], :] = src[:, r - lo[o], :]


#: The initial value of each state array (SAE, previous time, lifetime, polarity, burst reuse's planes; a
#: burst's count of fits, the third of each cell's three, starts at 0), as :class:`~evedge.detector.intra.
#: IntraPixelLifetime` sets them.
_INITIAL = (NEVER_US, 0, np.nan, -1, np.nan)


class StripStates:
    """The strips' own state, kept between the calls of a stream (:class:`~evedge.detector.intra.IntraPixelLifetime`).

    Without it, every call of :func:`intra_tiled` copies the whole state into the
    strips and their owned rows back: O(sensor) per call, which on a 1280 x 720
    sensor and 1 ms chunks costs more than the events. With it, the first call
    fixes the cut (any cut gives the same bytes) and loads the strips; a later
    call only refreshes each strip's halo rows from the strips owning them (what
    the full copy would have put there), and the caller's state arrays are
    brought up to date by :meth:`store` when someone reads them.
    """

    def __init__(self) -> None:
        self.own: np.ndarray | None = None  # the fixed cut, after the first call
        self.local: list[np.ndarray] | None = None
        self._layout = None  # (lo, hi, own_lo, own_hi, off) of the first call
        self.stale = False  # the caller's arrays lack the strips' latest owned rows
        self.qcnt: np.ndarray | None = None  # deferred events per cell and per row (zero between calls)
        self.qrow: np.ndarray | None = None

    def store(self, state, fits: np.ndarray) -> None:
        """The strips' owned rows into ``state`` and ``fits`` (as :func:`intra_tiled` takes them)."""
        if self.stale:
            lo, hi, own_lo, own_hi, off = self._layout
            width = state[0].shape[2]
            for g, l in zip(_with_fits(state, fits), self.local):
                _strips_to_state(g, l, lo, hi, own_lo, own_hi, off * (g.shape[2] // width))
            self.stale = False


def _with_fits(state, fits):
    """``state`` and, with burst reuse (``fits`` not empty), ``fits`` as a fifth ``(planes, height, cells)`` array."""
    if fits is None or fits.size == 0:
        return tuple(state)
    planes, height, width = state[0].shape
    return (*state, fits.reshape(planes, height, _FIT_STRIDE * width))


def intra_tiled(x, y, t, p, g0: int, state, width: int, height: int, n_tiles: int, kernel_args: tuple, outs: tuple,
                strips: StripStates, stats: np.ndarray | None = None, work: np.ndarray | None = None,
                fits: np.ndarray | None = None, initial: bool = False):
    """The intra-pixel estimator over ``n_tiles`` strips; the serial result (module notes).

    ``state`` is ``(sae, prev_t, prev_lt, prev_pol)``, each ``(planes, height, width)``,
    updated in place; ``kernel_args`` are :func:`_intra_stream`'s arguments from
    ``burst`` to ``noise``, without the geometry (``burst, per_pol, half, delta,
    thr_us, thr_rel, max_trials, stop_prob, min_points, min_inliers, intercept,
    fallback, seed, gap_ratio, on_plane, startup, border, jump_check, stale_frac,
    t_start, reach_px, noise``: :func:`_run_strip` reads ``burst, per_pol, half``,
    ``startup`` and ``noise`` by position); ``outs`` is ``(lt, vx, vy, valid)``. The
    strips are cut where they hold about as many events (:func:`balanced_strips`) and shared by
    ``min(n_tiles, numba threads)`` workers (:func:`_intra_parallel`). ``stats`` (int64
    ``(n_tiles, 4)``, or 5 for the strips' CPU time)
    and ``work`` (int64 ``(workers, 3)``), when given, receive :func:`_intra_parallel`'s counters.
    ``fits`` (burst reuse, :func:`_intra_stream`; flat, ``_FIT_STRIDE`` per SAE cell; None or empty: off) is
    updated in place as ``state``; only owned pixels read or write it (halo events are not fitted).
    ``strips`` (the stream's :class:`StripStates`) keeps the strips' state between calls: ``state`` and ``fits``
    are read on its first call only and written by :meth:`StripStates.store`. With ``initial`` the strips start
    from the initial values (:data:`_INITIAL`) and ``state`` and ``fits`` only give shapes and types (zero-stride
    views will do).
    """
    half = kernel_args[2]
    planes = state[0].shape[0]
    own, lo, hi, idx, starts, chunk_off = strip_layout(y, height, n_tiles, half, strips.own)
    own_lo = own[:, 0].copy()
    own_hi = own[:, 1].copy()
    rows = hi - lo
    off = np.zeros(n_tiles + 1, np.int64)
    off[1:] = np.cumsum(planes * rows * width)
    roff = np.zeros(n_tiles + 1, np.int64)
    roff[1:] = np.cumsum(planes * rows)
    qoff = np.zeros(n_tiles + 1, np.int64)
    qoff[1:] = np.cumsum(np.full(n_tiles, 1 << max(int(_QUEUE_MAX) - 1, 1).bit_length()))
    state = _with_fits(state, fits)
    reuse = len(state) == 5
    par = np.zeros(height, np.int64)
    for s in range(n_tiles):
        par[own_lo[s]:own_hi[s]] = s % 2
    threads = min(n_tiles, numba.get_num_threads())
    if stats is None:
        stats = np.zeros((n_tiles, 4), np.int64)
    if work is None:
        work = np.zeros((threads, 3), np.int64)
    # the strips' state lives as long as ``strips``, the per-event scratch as long as this block; both lent by
    # the workspace, which keeps them mapped between calls (:mod:`._workspace`)
    if strips.local is None:  # the strips' own state from now on: loaded from the caller's arrays once
        strips.own, strips._layout = own, (lo, hi, own_lo, own_hi, off)
        strips.local = [WORKSPACE.lease(off[-1] * (g.shape[2] // width), g.dtype, strips) for g in state]
        for g, l, v in zip(state, strips.local, _INITIAL):
            if initial:
                l.fill(v)
            else:
                _state_to_strips(g, l, lo, hi, off * (g.shape[2] // width))
        if initial and reuse:
            strips.local[4][2::_FIT_STRIDE] = 0.0  # each burst's count of fits (every strip's cells start at 3k)
        # the deferred events' counts per cell and row: zero before a call and, every queue drained, after it
        strips.qcnt = WORKSPACE.lease(off[-1], np.int32, strips)
        strips.qcnt.fill(0)
        strips.qrow = np.zeros(roff[-1], np.int32)
    else:  # a later chunk: only the halo rows, from the strips owning them (what a full copy would put there)
        for g, l in zip(state, strips.local):
            _halos_from_owners(l, lo, hi, own_lo, own_hi, off * (g.shape[2] // width), planes, g.shape[2])
    local = strips.local if reuse else [*strips.local, np.empty(0)]
    with WORKSPACE.scope() as take:
        dec = take.zeros((2, x.shape[0]), np.int8)  # by the owner's parity (:func:`_run_strip`)
        # outputs per slot (each strip writes its own memory), then put in place
        slot_outs = [take.empty(idx.size, o.dtype) for o in outs]
        _intra_parallel(threads, np.iinfo(np.int64).max if threads == n_tiles else _TURN_EVENTS, x, y, t, p, g0,
                        idx, starts, off, *local, strips.qcnt, roff, strips.qrow, np.empty(qoff[-1], np.int64), qoff,
                        lo, rows, own_lo, own_hi, dec, take.empty((2, x.shape[0]), np.float64), width, height,
                        tuple(kernel_args), *slot_outs, stats, work, par)
        _put_owned(y, lo, hi, own_lo, own_hi, chunk_off, *slot_outs, *outs)
    strips.stale = True
