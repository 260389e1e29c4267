"""A tight numba kernel doing the intra-pixel-area estimator's per-event work: the speed bound.

Same steps, parameters, random draws and adaptive trial count as
:func:`evedge.detector._intra_kernels._intra_stream` (SAE update with burst
grouping, 5x5 window gather, 2-means, RANSAC with the intra-pixel residual and
the skimage-style stopping rule, fallback to all points, least-squares refit
with a free offset; least squares first, ``ls_first``, as the project's default),
written as one function with none of the project's
constraints:

* no byte-exactness: float sums are free to be reordered (the tie-breaking cost
  sum is fused into the vectorised inlier count, 2-means sums in float64
  vectorised), so its outputs agree with the project's only up to rounding
  (the share of identical estimates is printed by the benchmark);
* no input checks, no structured-array columns, no reusable scratch layout:
  one-dimensional local arrays, the window gathered over clipped ranges
  (no per-cell bounds tests).

It is the "what a careful hand-written kernel costs" figure the project's
kernel is compared against (``bench_detector.py`` prints project / bound).
It does not implement the options added later and off by default, nor the
start-up rule (``burst_startup``, on by default since 2026-12-01: a second fit
for the second event of a pixel's first burst), so it does slightly less work
than the project on the defaults; its estimates then equal the project's for
~90 % of the events (99.2-99.7 % before that rule).
"""

import math

import numpy as np
from numba import njit

from evedge._splitmix import _splitmix64

_NEVER = np.iinfo(np.int64).min


@njit(cache=True, fastmath=False)
def bound_stream(x, y, t, p, sae, prev_t, prev_lt, width, height, half, delta, thr_us, thr_rel, max_trials,
                 stop_prob, min_points, min_inliers, burst, seed, out_lt, out_valid, ls_first):
    """Lifetimes of time-sorted events (per-polarity SAE ``sae``, burst state ``prev_t/prev_lt``)."""
    nn = (2 * half + 1) ** 2
    dx = np.empty(nn)
    dy = np.empty(nn)
    dt = np.empty(nn)
    kx = np.empty(nn)
    ky = np.empty(nn)
    kt = np.empty(nn)
    lab = np.empty(nn, np.bool_)
    log_fail = math.log(1.0 - stop_prob) if stop_prob < 1.0 else 0.0
    for k in range(x.shape[0]):
        xk = x[k]
        yk = y[k]
        tk = t[k]
        base = p[k] * height * width
        si = base + yk * width + xk
        t_ev = tk
        if burst > 0.0 and tk - prev_t[si] <= burst * prev_lt[si]:
            tk = sae[si]
        else:
            sae[si] = tk
        # ---- gather over clipped ranges
        y0 = max(yk - half, 0)
        y1 = min(yk + half, height - 1)
        x0 = max(xk - half, 0)
        x1 = min(xk + half, width - 1)
        n = 0
        tmin = 0.0
        for yy in range(y0, y1 + 1):
            row = base + yy * width
            for xx in range(x0, x1 + 1):
                v = sae[row + xx]
                if v == _NEVER or (xx == xk and yy == yk):
                    continue
                d = float(v - tk)
                dx[n] = xx - xk
                dy[n] = yy - yk
                dt[n] = d
                tmin = min(tmin, d)
                n += 1
        # ---- 2-means (centroids: window minimum, current time)
        c0 = tmin
        c1 = 0.0
        if c0 == c1:
            for i in range(n):
                lab[i] = True
        else:
            for _ in range(100):
                s0 = 0.0
                s1 = 0.0
                n1 = 1
                for i in range(n):
                    v = dt[i]
                    near1 = abs(v - c1) <= abs(v - c0)
                    lab[i] = near1
                    s1 += v if near1 else 0.0
                    s0 += 0.0 if near1 else v
                    n1 += 1 if near1 else 0
                n0 = n + 1 - n1
                nc0 = s0 / n0 if n0 > 0 else c0
                nc1 = s1 / n1
                if nc0 == c0 and nc1 == c1:
                    break
                c0 = nc0
                c1 = nc1
        key = _splitmix64(np.uint64(seed) ^ _splitmix64(np.uint64(k)))
        ok = False
        a_out = 0.0
        b_out = 0.0
        for attempt in range(2):
            m = 0
            for i in range(n):
                kx[m] = dx[i]
                ky[m] = dy[i]
                kt[m] = dt[i]
                m += 1 if (lab[i] or attempt == 1) else 0
            if m < 2 or m + 1 < min_points:
                continue
            best_n = 0
            best_cost = np.inf
            best_a = 0.0
            best_b = 0.0
            best_s = 0.0
            best_thr = 0.0
            trials = max_trials
            # ---- least squares first (ls_first): the sums over the whole cluster, the plane through
            # the event; every residual within ls_first thresholds: the refit on all points, no trial
            full = False
            s1 = 1.0 + m
            sx = 0.0
            sy = 0.0
            st = 0.0
            sxx = 0.0
            sxy = 0.0
            syy = 0.0
            sxt = 0.0
            syt = 0.0
            if ls_first > 0.0:
                for q in range(m):
                    sx += kx[q]
                    sy += ky[q]
                    st += kt[q]
                    sxx += kx[q] * kx[q]
                    sxy += kx[q] * ky[q]
                    syy += ky[q] * ky[q]
                    sxt += kx[q] * kt[q]
                    syt += ky[q] * kt[q]
                det = sxx * syy - sxy * sxy
                if det > 1e-9 * (sxx * syy):
                    a = (sxt * syy - syt * sxy) / det
                    b = (syt * sxx - sxt * sxy) / det
                    slack = delta * (abs(a) + abs(b))
                    tight = ls_first * (thr_us + thr_rel * math.sqrt(a * a + b * b))
                    worst = 0.0
                    for q in range(m):
                        worst = max(worst, abs(kt[q] - a * kx[q] - b * ky[q]) - slack)
                    if worst <= tight and math.isfinite(a) and math.isfinite(b):
                        full = True
                        best_n = m + 1
                        best_a = a
                        best_b = b
                        trials = 0
            um = np.uint64(m)
            um1 = np.uint64(m - 1)
            kk = 0
            while kk < trials:
                pi = np.int64(_splitmix64(key + np.uint64(2 * kk)) % um)
                pj = np.int64(_splitmix64(key + np.uint64(2 * kk + 1)) % um1)
                if pj >= pi:
                    pj += 1
                det = kx[pi] * ky[pj] - kx[pj] * ky[pi]
                if det != 0.0:
                    a = (kt[pi] * ky[pj] - kt[pj] * ky[pi]) / det
                    b = (kx[pi] * kt[pj] - kx[pj] * kt[pi]) / det
                    slack = delta * (abs(a) + abs(b))
                    thr = thr_us + thr_rel * math.sqrt(a * a + b * b)
                    cnt = 1
                    cost = 0.0
                    for q in range(m):  # count and cost fused (reordered sum: vectorises)
                        r = max(abs(kt[q] - a * kx[q] - b * ky[q]) - slack, 0.0)
                        inl = r <= thr
                        cnt += 1 if inl else 0
                        cost += r if inl else 0.0
                    if cnt > best_n or (cnt == best_n and cost < best_cost):
                        best_n = cnt
                        best_cost = cost
                        best_a = a
                        best_b = b
                        best_s = slack
                        best_thr = thr
                        if stop_prob < 1.0:
                            w = (cnt - 1) / m
                            if w >= 1.0:
                                trials = kk + 1
                            elif w > 0.0:
                                need = math.ceil(log_fail / math.log(1.0 - w * w))
                                trials = min(trials, need)
                kk += 1
            if best_n == 0:
                continue
            if best_n < min_inliers:
                break
            # ---- refit with a free offset on the inliers (current event included; all: the sums above)
            if not full:
                s1 = 1.0
                sx = 0.0
                sy = 0.0
                st = 0.0
                sxx = 0.0
                sxy = 0.0
                syy = 0.0
                sxt = 0.0
                syt = 0.0
                for q in range(m):
                    r = max(abs(kt[q] - best_a * kx[q] - best_b * ky[q]) - best_s, 0.0)
                    wq = 1.0 if r <= best_thr else 0.0
                    xq = kx[q] * wq
                    yq = ky[q] * wq
                    s1 += wq
                    sx += xq
                    sy += yq
                    st += kt[q] * wq
                    sxx += xq * kx[q]
                    sxy += xq * ky[q]
                    syy += yq * ky[q]
                    sxt += xq * kt[q]
                    syt += yq * kt[q]
            sxx -= sx * sx / s1
            sxy -= sx * sy / s1
            syy -= sy * sy / s1
            sxt -= sx * st / s1
            syt -= sy * st / s1
            det = sxx * syy - sxy * sxy
            a = best_a
            b = best_b
            if det > 1e-9 * (sxx * syy):
                a = (sxt * syy - syt * sxy) / det
                b = (syt * sxx - sxt * sxy) / det
            if a * a + b * b > 0.0 and math.isfinite(a) and math.isfinite(b):
                ok = True
                a_out = a
                b_out = b
            break
        if ok:
            out_lt[k] = math.sqrt(a_out * a_out + b_out * b_out)
            out_valid[k] = True
        else:
            out_lt[k] = np.nan
            out_valid[k] = False
        prev_t[si] = t_ev
        prev_lt[si] = out_lt[k]


def bound_lifetimes(events, width, height, half=2, delta=0.25, thr_us=50.0, thr_rel=0.2, max_trials=20,
                    stop_prob=0.999, min_points=5, min_inliers=5, burst=1.0, seed=0, ls_first=None):
    """``(lifetime_us, valid)`` of ``events`` by :func:`bound_stream` (fresh state; the IntraParams defaults)."""
    if ls_first is None:
        from evedge.detector.intra import IntraParams

        ls_first = IntraParams().ls_first
    x = np.ascontiguousarray(events["x"], dtype=np.int64)
    y = np.ascontiguousarray(events["y"], dtype=np.int64)
    t = np.ascontiguousarray(events["t"], dtype=np.int64)
    p = np.ascontiguousarray(events["p"], dtype=np.int64)
    n = x.shape[0]
    cells = 2 * width * height
    sae = np.full(cells, _NEVER, np.int64)
    prev_t = np.zeros(cells, np.int64)
    prev_lt = np.full(cells, np.nan)
    lt = np.empty(n)
    valid = np.empty(n, np.bool_)
    bound_stream(x, y, t, p, sae, prev_t, prev_lt, width, height, half, delta, thr_us, thr_rel, max_trials,
                 stop_prob, min_points, min_inliers, burst, seed, lt, valid, float(ls_first))
    return lt, valid
