"""numba kernels of the intra-pixel-area lifetime estimator (see :mod:`evedge.detector.intra`).

Points of a window are past events in coordinates local to the current event:
``dx, dy`` (pixel offsets) and ``dt`` (time minus the current time, us). The
current event itself is the origin and is not stored among them.
"""

import math

import numpy as np
from numba import njit

from evedge._splitmix import _splitmix64

_NEVER = np.iinfo(np.int64).min


@njit(cache=True)
def _event_key(seed, g):
    """Random stream key of the event with global index ``g``: independent of chunking."""
    return _splitmix64(np.uint64(seed) ^ _splitmix64(np.uint64(g)))


@njit(cache=True)
def _draw(key, counter):
    """The ``counter``-th uint64 of the stream ``key``."""
    return _splitmix64(key + np.uint64(counter))


@njit(cache=True)
def _two_means(dt, n, label):
    """1-D 2-means of the past points and the current event (dt = 0).

    Initial centroids: the window minimum and the current time. A point at equal
    distance from both centroids joins the current event's cluster. On return
    ``label[i]`` is 1 for the points in the current event's cluster, else 0.
    """
    c0 = 0.0
    for i in range(n):
        if dt[i] < c0:
            c0 = dt[i]
    c1 = 0.0
    if c0 == c1:
        # every timestamp equals the current one: a single cluster
        for i in range(n):
            label[i] = 1
        return
    for i in range(n):
        label[i] = -1
    cur = -1
    for _ in range(100):
        changed = False
        s0 = 0.0
        s1 = 0.0
        n1 = 0
        lc = 1 if abs(0.0 - c1) <= abs(0.0 - c0) else 0
        if lc != cur:
            changed = True
            cur = lc
        if lc == 1:
            n1 += 1
        # branch-free accumulation (labels are unpredictable; adding 0.0 changes no sum)
        for i in range(n):
            v = dt[i]
            near1 = abs(v - c1) <= abs(v - c0)
            li = np.int8(1) if near1 else np.int8(0)
            changed |= li != label[i]
            label[i] = li
            s1 += v if near1 else 0.0
            s0 += 0.0 if near1 else v
            n1 += li
        n0 = n + 1 - n1  # the current event and the past points not in cluster 1
        if not changed:
            break
        if n0 > 0:
            c0 = s0 / n0
        if n1 > 0:
            c1 = s1 / n1
    for i in range(n):
        label[i] = 1 if label[i] == cur else 0


@njit(cache=True)
def _ransac(dx, dy, dt, label, n, key, delta, thr_us, thr_rel, max_trials, stop_prob,
            min_points, min_inliers, intercept, inl_best, inl_tmp, idx, kx, ky, kt):
    """RANSAC plane ``dt = a dx + b dy`` through the current event, then least squares.

    Candidates pass through the current event and two distinct past points of the
    kept cluster (``label == 1``), drawn with :func:`_draw` (counters 2k, 2k+1 at
    trial k); samples collinear with the current event are skipped (they still use
    up a trial). Residual of a point: ``max(0, |dt - a dx - b dy| - delta (|a| + |b|))``
    (closest point of its intra-pixel square); inlier when
    ``<= thr_us + thr_rel * sqrt(a^2 + b^2)``. Most inliers wins, ties go to the
    smaller sum of inlier residuals, then to the earlier trial. With
    ``stop_prob < 1`` the number of trials shrinks adaptively as in
    scikit-image's ``ransac``. The winner is refitted by least squares on its
    inliers: through the current event, or with ``intercept`` with a free time offset
    (the plane's slopes are what we need; the offset only absorbs the current event's
    own timing noise).

    Returns ``(ok, a, b, n_inliers)``; ``n_inliers`` counts the current event and is
    -1 when the kept cluster is degenerate (too few points, or no sample off the
    line through the current event).
    ``inl_best[i]`` marks the inlier past points.
    """
    m = 0
    for i in range(n):
        inl_best[i] = False
        # branch-free compaction into contiguous copies of the kept points (the
        # trial loop reads them directly); a slot is overwritten unless kept
        idx[m] = i
        kx[m] = dx[i]
        ky[m] = dy[i]
        kt[m] = dt[i]
        m += 1 if label[i] == 1 else 0
    if m < 2 or m + 1 < min_points:
        return False, np.nan, np.nan, -1
    best_n = 0
    best_cost = np.inf
    best_a = np.nan
    best_b = np.nan
    trials = max_trials
    k = 0
    um = np.uint64(m)
    um1 = np.uint64(m - 1)
    while k < trials:
        pi = np.int64(_draw(key, 2 * k) % um)
        pj = np.int64(_draw(key, 2 * k + 1) % um1)
        if pj >= pi:
            pj += 1
        k += 1
        i = idx[pi]
        j = idx[pj]
        det = dx[i] * dy[j] - dx[j] * dy[i]
        if det == 0.0:
            continue
        a = (dt[i] * dy[j] - dt[j] * dy[i]) / det
        b = (dx[i] * dt[j] - dx[j] * dt[i]) / det
        slack = delta * (abs(a) + abs(b))
        thr = thr_us + thr_rel * math.sqrt(a * a + b * b)
        cnt = 1
        cost = 0.0
        for q in range(m):
            r = abs(kt[q] - (a * kx[q] + b * ky[q])) - slack
            if r < 0.0:
                r = 0.0
            ok_q = r <= thr
            inl_tmp[q] = ok_q
            # branch-free: whether a point is an inlier is unpredictable
            cnt += 1 if ok_q else 0
            cost += r if ok_q else 0.0
        if cnt > best_n or (cnt == best_n and cost < best_cost):
            best_n = cnt
            best_cost = cost
            best_a = a
            best_b = b
            for q in range(m):
                inl_best[idx[q]] = inl_tmp[q]
            if stop_prob < 1.0:
                w = (cnt - 1) / m
                if w >= 1.0:
                    trials = k
                else:
                    denom = 1.0 - w * w
                    if denom < 1.0:
                        need = math.ceil(math.log(1.0 - stop_prob) / math.log(denom))
                        if need < trials:
                            trials = need
    if best_n == 0:
        # every sample was collinear with the current event: no plane at all
        return False, np.nan, np.nan, -1
    if best_n < min_inliers:
        return False, np.nan, np.nan, best_n
    # sums over the inliers; the current event (origin) adds 1 to the count only
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
        # branch-free: a weight of 0 or 1 (adding 0.0 changes no sum)
        wq = 1.0 if inl_best[idx[q]] else 0.0
        xq = kx[q] * wq
        yq = ky[q] * wq
        tq = kt[q] * wq
        s1 += wq
        sx += xq
        sy += yq
        st += tq
        sxx += xq * kx[q]
        sxy += xq * ky[q]
        syy += yq * ky[q]
        sxt += xq * kt[q]
        syt += yq * kt[q]
    if intercept:
        # centred sums: least squares with a free time offset (the current event
        # becomes one point among the inliers instead of a fixed anchor)
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
    if not (a * a + b * b > 0.0) or not math.isfinite(a) or not math.isfinite(b):
        # a flat plane (all inliers at the current time): no finite lifetime
        return False, np.nan, np.nan, best_n
    return True, a, b, best_n


@njit(cache=True)
def _fit_points(dx, dy, dt, label, n, key, delta, thr_us, thr_rel, max_trials, stop_prob, min_points,
                min_inliers, intercept, fallback, inl_best, inl_tmp, idx, kx, ky, kt):
    """2-means, then RANSAC on the current event's cluster; returns ``(ok, a, b)``.

    With ``fallback``, a degenerate cluster (see :func:`_ransac`) is replaced by
    all the window's points and RANSAC runs once more with the same random
    stream. This happens on a clean ramp whose middle row of timestamps 2-means
    gives to the old cluster (an axis-aligned edge: the kept pixels then all lie
    on the current event's row or column).
    """
    _two_means(dt, n, label)
    ok, a, b, nin = _ransac(dx, dy, dt, label, n, key, delta, thr_us, thr_rel, max_trials, stop_prob,
                            min_points, min_inliers, intercept, inl_best, inl_tmp, idx, kx, ky, kt)
    if nin < 0 and fallback:
        for i in range(n):
            label[i] = 1
        ok, a, b, nin = _ransac(dx, dy, dt, label, n, key, delta, thr_us, thr_rel, max_trials, stop_prob,
                                min_points, min_inliers, intercept, inl_best, inl_tmp, idx, kx, ky, kt)
    return ok, a, b


@njit(cache=True)
def _intra_stream(x, y, t, p, g0, sae, prev_t, prev_lt, prev_pol, burst, width, height, per_pol, half, delta,
                  thr_us, thr_rel, max_trials, stop_prob, min_points, min_inliers, intercept, fallback, seed,
                  out_lt, out_vx, out_vy, out_valid):
    """SAE update, window gathering, 2-means and RANSAC for each event in order.

    ``sae`` is the flat SAE (``(plane * height + y) * width + x``), updated in place;
    ``g0`` is the global index of the first event (seeds its random stream).
    Flow is written in px/s.

    Burst grouping (``burst > 0``): ``prev_lt`` (float, NaN = none) and ``prev_pol``
    (int8, -1 = none), laid out as ``sae`` and updated in place, hold the lifetime
    estimated for the previous event of each pixel and its polarity. An event of
    the same polarity as its pixel's previous event, with an estimate ``L``, and at
    most ``burst * L`` after the time the pixel holds, continues that burst: the
    pixel keeps the burst's first time and the event is fitted at that time (its
    points are ``dt = t_window - t_burst_start``). Otherwise the pixel takes the
    event's time (the paper's SAE).
    """
    side = 2 * half + 1
    nn = side * side
    dx = np.empty(nn)
    dy = np.empty(nn)
    dt = np.empty(nn)
    label = np.empty(nn, np.int8)
    inl_best = np.zeros(nn, np.bool_)
    inl_tmp = np.zeros(nn, np.bool_)
    idx = np.empty(nn, np.int64)
    kx = np.empty(nn)
    ky = np.empty(nn)
    kt = np.empty(nn)
    for k in range(x.shape[0]):
        xk = x[k]
        yk = y[k]
        tk = t[k]
        base = (p[k] if per_pol else 0) * height * width
        si = base + yk * width + xk
        pk = np.int8(1) if p[k] else np.int8(0)
        # prev_lt is NaN when the previous event had no estimate: the comparison is False
        if burst > 0.0 and prev_pol[si] == pk and tk - prev_t[si] <= burst * prev_lt[si]:
            t_ev = tk
            tk = sae[si]  # same burst: the pixel and the event keep the burst's first time
        else:
            t_ev = tk
            sae[si] = tk
        n = 0
        for oy in range(-half, half + 1):
            yy = yk + oy
            if yy < 0 or yy >= height:
                continue
            row = base + yy * width
            for ox in range(-half, half + 1):
                if ox == 0 and oy == 0:
                    continue
                xx = xk + ox
                if xx < 0 or xx >= width:
                    continue
                v = sae[row + xx]
                if v == _NEVER:
                    continue
                dx[n] = ox
                dy[n] = oy
                dt[n] = float(v - tk)
                n += 1
        ok, a, b = _fit_points(dx, dy, dt, label, n, _event_key(seed, g0 + k), delta, thr_us, thr_rel,
                               max_trials, stop_prob, min_points, min_inliers, intercept, fallback,
                               inl_best, inl_tmp, idx, kx, ky, kt)
        if ok:
            g2 = a * a + b * b
            out_lt[k] = math.sqrt(g2)
            out_vx[k] = a / g2 * 1e6
            out_vy[k] = b / g2 * 1e6
            out_valid[k] = True
        else:
            out_lt[k] = np.nan
            out_vx[k] = np.nan
            out_vy[k] = np.nan
            out_valid[k] = False
        prev_t[si] = t_ev
        prev_lt[si] = out_lt[k]
        prev_pol[si] = pk


@njit(cache=True)
def _fit_windows(win, side, seed, g0, delta, thr_us, thr_rel, max_trials, stop_prob, min_points,
                 min_inliers, intercept, fallback, out_a, out_b, out_ok, out_inl):
    """:func:`_ransac` on flat windows ``win`` (k * side * side, NaN = never fired).

    Window ``w`` uses the random stream of global index ``g0 + w``. ``out_inl`` gets the
    inlier mask per window cell (the centre, the current event, is an inlier when ok).
    """
    nn = side * side
    c = nn // 2
    half = side // 2
    dx = np.empty(nn)
    dy = np.empty(nn)
    dt = np.empty(nn)
    cell = np.empty(nn, np.int64)
    label = np.empty(nn, np.int8)
    inl_best = np.zeros(nn, np.bool_)
    inl_tmp = np.zeros(nn, np.bool_)
    idx = np.empty(nn, np.int64)
    kx = np.empty(nn)
    ky = np.empty(nn)
    kt = np.empty(nn)
    nw = win.shape[0] // nn
    for w in range(nw):
        off = w * nn
        tc = win[off + c]
        n = 0
        for q in range(nn):
            if q == c:
                continue
            v = win[off + q]
            if math.isnan(v):
                continue
            dx[n] = q % side - half
            dy[n] = q // side - half
            dt[n] = v - tc
            cell[n] = q
            n += 1
        ok, a, b = _fit_points(dx, dy, dt, label, n, _event_key(seed, g0 + w), delta, thr_us, thr_rel,
                               max_trials, stop_prob, min_points, min_inliers, intercept, fallback,
                               inl_best, inl_tmp, idx, kx, ky, kt)
        out_ok[w] = ok
        out_a[w] = a
        out_b[w] = b
        for q in range(nn):
            out_inl[off + q] = False
        if ok:
            out_inl[off + c] = True
            for i in range(n):
                if inl_best[i]:
                    out_inl[off + cell[i]] = True
