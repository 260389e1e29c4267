"""A simulated schedule of the estimator's strips: the parallel speedup without the machine's load.

:func:`simulate_strips` replays :func:`evedge.detector._tiles._run_strip`'s rules
(deferral queue, window conflicts, halo replays that wait for the owner's
published lifetime of the pixel's previous event, or for the owner's own
decision under the start-up rule's trial) on ``n_tiles`` workers, one per
strip, in virtual time: each owned event costs 1 (its fit), a halo replay or a
deferral ``halo_cost``, and a decision is published when its owner finishes
the event (no latency). The speedup is the serial work (one unit per event) over
the simulated makespan: what the strips give on idle cores, when the per-event
costs are alike. It depends only on the events and the rules, not on the load.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from evedge.detector._tiles import _QUEUE_MAX, strip_layout


@njit(cache=True)
def _near(qcnt, r, xk, plane, rows, width, half):
    for rr in range(max(r - half, 0), min(r + half, rows - 1) + 1):
        for xx in range(max(xk - half, 0), min(xk + half, width - 1) + 1):
            if qcnt[(plane * rows + rr) * width + xx] != 0:
                return True
    return False


@njit(cache=True)
def _schedule(x, y, p, prev_same, needs_own, idx, starts, lo, own_lo, own_hi, rows, width, half, per_pol, cap,
              halo_cost, start):
    n_tiles = lo.shape[0]
    pub = np.full(x.shape[0], np.inf)  # when each owned event's decision is published
    clock = start.copy()
    cursor = np.zeros(n_tiles, np.int64)
    head = np.zeros(n_tiles, np.int64)
    tail = np.zeros(n_tiles, np.int64)
    total_q = starts[-1]
    queue = np.empty(total_q, np.int64)
    planes = 2 if per_pol else 1
    qoff = np.zeros(n_tiles + 1, np.int64)
    for s in range(n_tiles):
        qoff[s + 1] = qoff[s] + planes * rows[s] * width
    qcnt = np.zeros(qoff[-1], np.int32)
    fin = np.zeros(n_tiles, np.bool_)
    waited = np.zeros(n_tiles)
    deferred = 0
    left = n_tiles
    while left > 0:
        s = -1
        for u in range(n_tiles):
            if not fin[u] and (s < 0 or clock[u] < clock[s]):
                s = u
        a = starts[s]
        n = starts[s + 1] - a
        qc = qcnt[qoff[s]:qoff[s + 1]]
        # 1. the queue's front
        acted = False
        need = np.inf
        if head[s] < tail[s]:
            k = idx[a + queue[a + head[s]]]
            own = own_lo[s] <= y[k] < own_hi[s]
            ready = own
            if not own:
                w = 0.0
                if prev_same[k] >= 0:
                    w = pub[prev_same[k]]
                if needs_own[k]:
                    w = max(w, pub[k])
                ready = w <= clock[s]
                need = w
            if ready:
                clock[s] += 1.0 if own else halo_cost
                if own:
                    pub[k] = clock[s]
                head[s] += 1
                pl = (1 if (per_pol and p[k]) else 0)
                qc[(pl * rows[s] + y[k] - lo[s]) * width + x[k]] -= 1
                acted = True
        # 2. the next new event
        if not acted and cursor[s] < n:
            k = idx[a + cursor[s]]
            own = own_lo[s] <= y[k] < own_hi[s]
            pl = (1 if (per_pol and p[k]) else 0)
            r = y[k] - lo[s]
            later = head[s] < tail[s] and _near(qc, r, x[k], pl, rows[s], width, half)
            if not later and not own:
                w = 0.0
                if prev_same[k] >= 0:
                    w = pub[prev_same[k]]
                if needs_own[k]:
                    w = max(w, pub[k])
                later = w > clock[s]
            if later and tail[s] - head[s] < cap:
                queue[a + tail[s]] = cursor[s]
                tail[s] += 1
                qc[(pl * rows[s] + r) * width + x[k]] += 1
                cursor[s] += 1
                clock[s] += halo_cost
                deferred += 1
                acted = True
            elif not later:
                clock[s] += 1.0 if own else halo_cost
                if own:
                    pub[k] = clock[s]
                cursor[s] += 1
                acted = True
        if not acted:
            if cursor[s] == n and head[s] == tail[s]:
                fin[s] = True
                left -= 1
                continue
            # blocked: until the awaited decision, or until another strip has moved on
            nxt = np.inf
            for u in range(n_tiles):
                if u != s and not fin[u] and clock[u] >= clock[s]:
                    nxt = min(nxt, clock[u])
            target = need if need < np.inf else nxt
            if not target < np.inf or target <= clock[s]:
                target = clock[s] + max(halo_cost, 1e-3)  # always some progress
            waited[s] += target - clock[s]
            clock[s] = target
    return clock, waited, deferred


def simulate_strips(events, sensor_size, n_tiles: int, half: int = 2, per_polarity: bool = True,
                    valid: np.ndarray | None = None, halo_cost: float = 0.05, queue_max: int = _QUEUE_MAX,
                    late: float = 0.0):
    """Simulated makespan of ``n_tiles`` strips on as many idle workers; returns ``(speedup, busy, deferred)``.

    ``valid`` (bool per event, the serial estimator's): a halo replay after an
    event without estimate at its pixel waits for the owner's own decision (the
    start-up rule's trial); without it, no replay does. ``busy`` is the share of the
    workers' time not spent waiting, ``deferred`` the share of the events
    deferred. ``late``: the odd-numbered workers start that
    many units late (a thread woken late, or descheduled at the start).
    """
    x = events["x"].astype(np.int64)
    y = events["y"].astype(np.int64)
    p = events["p"].astype(np.bool_)
    width, height = sensor_size.width, sensor_size.height
    plane = p.astype(np.int64) if per_polarity else np.zeros(x.size, np.int64)
    cell = (plane * height + y) * width + x
    order = np.argsort(cell, kind="stable")
    prev_same = np.full(x.size, -1, np.int64)
    same = cell[order[1:]] == cell[order[:-1]]
    prev_same[order[1:][same]] = order[:-1][same]
    # the start-up rule's trial (about): the pixel's previous event (same plane) had no estimate
    needs_own = np.zeros(x.size, bool)
    if valid is not None:
        needs_own = (prev_same >= 0) & ~np.asarray(valid, bool)[np.maximum(prev_same, 0)]
    own, lo, hi, idx, starts, _ = strip_layout(y, height, n_tiles, half)
    clock, waited, deferred = _schedule(x, y, p, prev_same, needs_own, idx, starts, lo,
                                        own[:, 0].copy(), own[:, 1].copy(), hi - lo, width, half, per_polarity,
                                        min(queue_max, x.size), halo_cost,
                                        np.where(np.arange(n_tiles) % 2 == 1, float(late), 0.0))
    makespan = clock.max()
    busy = 1.0 - (waited.sum() + late * (n_tiles // 2)) / (n_tiles * makespan)
    return x.size / makespan, busy, deferred / max(x.size, 1)
