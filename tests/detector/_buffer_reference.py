"""The event buffer's previous kernel (before the padded-state rewrite), kept as the tests' reference.

Same decisions by construction of the tests: ``tests/detector/test_buffer_kernel.py``
compares the keep masks of :func:`evedge.detector.buffer.filter_events` (and its
streaming and strip forms) against :func:`reference_mask`, built on this kernel,
which itself is checked against the O(n^2) definition in ``test_buffer.py``.
"""

import numpy as np
from numba import njit

from evedge.events import SensorSize

_NEVER = np.iinfo(np.int64).min


@njit(cache=True)
def buffer_scan_reference(x, y, t, p, prev, supported, n_old, base_g, last_t, head_g, covered_g, width, height, tau_us,
                 causal):
    """Mark support for events ``n_old..`` of the arrays (events ``0..n_old`` are carried over).

    Arrays ``x, y, t, p, prev, supported`` hold the unreleased events, the first of which
    has global index ``base_g``. ``last_t`` and ``head_g`` are per pixel and polarity
    (index ``(p * height + y) * width + x``): the latest timestamp and the global index of
    the latest event there. ``prev`` chains the events of one pixel and polarity.
    ``covered_g`` (per pixel and polarity, -1 = none) is the global index of the newest
    event of that pixel reached by an earlier backward walk: that walk marked every
    event of the pixel up to it no older than its own ``t - tau``, which is no later
    than the present walk's (time-sorted stream), so the present walk stops there
    (the marks are the same; on dense edges most of the walking is saved).
    Returns nothing; updates ``supported``, ``prev``, ``last_t``, ``head_g``, ``covered_g`` in place.
    """
    n = x.shape[0]
    for k in range(n_old, n):
        xk = x[k]
        yk = y[k]
        tk = t[k]
        plane = p[k] * height
        lo = tk - tau_us
        n_support = 0
        x0 = max(xk - 1, 0)
        x1 = min(xk + 1, width - 1)
        # the 3x3 neighbourhood over clipped ranges; the support test is branch-free
        # (whether a neighbour fired within tau is unpredictable), the walk is not
        for yy in range(max(yk - 1, 0), min(yk + 1, height - 1) + 1):
            row = (plane + yy) * width
            for xx in range(x0, x1 + 1):
                q = row + xx
                lt = last_t[q]
                # a neighbour (not the pixel itself) fired within tau before (or at) this event
                near = (lt >= lo) & (lt != _NEVER) & ((xx != xk) | (yy != yk))
                n_support += near
                if near and not causal:
                    # ...and this event supports every unreleased event of that
                    # neighbour within tau before it
                    g = head_g[q]
                    stop = max(covered_g[q], base_g - 1)
                    covered_g[q] = g
                    while g > stop:
                        j = g - base_g
                        if t[j] < lo:
                            break
                        supported[j] = True
                        g = prev[j]
        if n_support > 0:
            supported[k] = True
        pix = (plane + yk) * width + xk
        prev[k] = head_g[pix]
        head_g[pix] = base_g + k
        last_t[pix] = tk


def reference_mask(events, sensor_size: SensorSize, tau_us: int, causal: bool) -> np.ndarray:
    """Keep mask of the previous kernel (one shot)."""
    w, h = sensor_size.width, sensor_size.height
    n = events.shape[0]
    cols = [np.ascontiguousarray(events[f], dtype=np.int64) for f in ("x", "y", "t", "p")]
    supported = np.zeros(n, dtype=bool)
    buffer_scan_reference(*cols, np.full(n, -1, dtype=np.int64), supported, 0, 0,
                          np.full(2 * w * h, _NEVER, dtype=np.int64), np.full(2 * w * h, -1, dtype=np.int64),
                          np.full(2 * w * h, -1, dtype=np.int64), w, h, tau_us, causal)
    return supported


def _midway(t1, tc, t2, line_us, line_tol):
    if t1 is None or t2 is None:
        return False
    lo, hi = min(t1, t2), max(t1, t2)
    d1, d2 = hi - tc, tc - lo
    return d1 >= 0 and d2 >= 0 and d1 <= line_us and d2 <= line_us and abs(d1 - d2) <= line_tol * max(d1, d2)


def line_reference_mask(events, sensor_size: SensorSize, line_us: int, line_tol: float, line_quiet: float,
                        line_count: int = 1) -> np.ndarray:
    """The line rule alone (:class:`~evedge.detector.buffer.BufferParams` ``line_window_us``), straight from its
    definition, in plain Python: for each event ``k`` at ``u`` and each direction ``a``, the latest events before
    ``k`` (stream order) at ``c = u + a`` and ``e = u + 2a`` of ``k``'s polarity, and ``c``'s event before that;
    ``c``'s latest event is kept when it lies midway in time between the two, ``c`` was quiet before, and (with
    ``line_count = 2``) another pair of ``c``'s opposite neighbours is midway too (see ``_line_scan``)."""

    def latest(q):
        if not (0 <= q[0] < w and 0 <= q[1] < h) or not history.get(q):
            return None
        return history[q][-1][0]

    w, h = sensor_size.width, sensor_size.height
    xs, ys = events["x"].astype(int), events["y"].astype(int)
    ts, ps = events["t"].astype(int), events["p"].astype(int)
    history: dict = {}  # (x, y, p) -> list of (t, index), stream order
    keep = np.zeros(events.size, bool)
    for k in range(events.size):
        u = (int(xs[k]), int(ys[k]), int(ps[k]))
        tk = int(ts[k])
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dx == 0 and dy == 0:
                    continue
                c = (u[0] + dx, u[1] + dy, u[2])
                e = (u[0] + 2 * dx, u[1] + 2 * dy, u[2])
                if not (0 <= c[0] < w and 0 <= c[1] < h) or not history.get(c):
                    continue
                if not (0 <= e[0] < w and 0 <= e[1] < h) or not history.get(e):
                    continue
                tc, gc = history[c][-1]
                te = history[e][-1][0]
                d1, d2 = tk - tc, tc - te
                if not (0 <= d2 and d1 <= line_us and d2 <= line_us):
                    continue
                if abs(d1 - d2) > line_tol * max(d1, d2):
                    continue
                if len(history[c]) >= 2 and tc - history[c][-2][0] < line_quiet * (d1 + d2):
                    continue
                if line_count >= 2:
                    others = [(bx, by) for bx, by in ((1, 0), (0, 1), (1, 1), (1, -1))
                              if (bx, by) not in ((dx, dy), (-dx, -dy))]
                    if not any(_midway(latest((c[0] + bx, c[1] + by, c[2])), tc,
                                       latest((c[0] - bx, c[1] - by, c[2])), line_us, line_tol)
                               for bx, by in others):
                        continue
                keep[gc] = True
        history.setdefault(u, []).append((tk, k))
    return keep
