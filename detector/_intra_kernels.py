"""numba kernels of the intra-pixel-area lifetime estimator (see :mod:`evedge.detector.intra`).

Points of a window are past events in coordinates local to the current event:
``dx, dy`` (pixel offsets) and ``dt`` (time minus the current time, us). The
current event itself is the origin and is not stored among them.

Least squares first (``ls_first > 0``, the one speed change that changes results, see
:mod:`evedge.detector.intra`, "schedule"): before the trials, the least-squares plane
through the current event on the compacted cluster; every residual within
``ls_first`` thresholds: the refit on all points from the same sums, no trial. A
window that fails the check runs the trials below unchanged (same bytes as at 0).

Speed (the per-event work of the stream kernel; results are unchanged by all of it):

* the per-event fit (2-means + RANSAC + refit) is one function, :func:`_fit_points`,
  on two scratch arrays: every array handed to a numba function costs an atomic
  increment and decrement of its reference count per call, which with a dozen
  scratch arrays and three nested calls per event took about a third of the time;
* RANSAC first only counts a candidate's inliers (a loop without a serial float
  sum, which vectorises); the summed residual, the tie-breaker, is computed only
  for a candidate with at least as many inliers as the best, in the same order;
  the winner's inliers are recomputed once at the end with the same expression;
* on the stream, timestamps are integers: 2-means sums them in int64, exact and so
  equal to the float64 sums (guarded: only when ``n * max|dt| < 2**53``);
* RANSAC computes the candidate planes of 4 trials together (each is a chain of
  dependent operations: draw, 64-bit modulo, division, square root; the chains
  overlap), then scores them in trial order;
* 2-means takes the window minimum and the integer total in one pass, gives the labels
  no initial value (the first iteration always runs) and skips the relabelling pass when
  the current event's cluster already has label 1 (the usual case): ~8-17 ns per kept
  event (``benchmarks/profile_stream.py``, which also shows where the rest goes);
* the adaptive trial bound's ``log(1 - stop_probability)`` is computed once per call,
  and ``log(1 - w**2)`` comes from a table built once per call with the same expression.
"""

import math

import numpy as np
from numba import njit

from evedge._splitmix import _splitmix64

from ._atomic import _store_release
from ._borrow import _borrowed
from ._prefetch import _prefetch
from ._noise_kernels import _AGREE, _BURST_SPAN, _NEWER, _PASSAGE_GAP, _lifetime_agrees, _newer_count

_NEVER = np.iinfo(np.int64).min


@njit(cache=True)
def _event_key(seed, g):
    """Random stream key of the event with global index ``g``: independent of chunking."""
    return _splitmix64(np.uint64(seed) ^ _splitmix64(np.uint64(g)))


@njit(cache=True)
def _draw(key, counter):
    """The ``counter``-th uint64 of the stream ``key``."""
    return _splitmix64(key + np.uint64(counter))


# rows of the float scratch array ``wf`` (see :func:`_scratch`) ...
_DX = 0  # window points: pixel offsets and time (us) relative to the current event
_DY = 1
_DT = 2
_KX = 3  # the points of the cluster RANSAC runs on, compacted
_KY = 4
_KT = 5
_CA = 6  # a batch of candidate planes: slopes, intra-pixel slack, inlier threshold
_CB = 7
_CS = 8
_CT = 9
_LOG = 10  # row _LOG + m, column c: log(1 - ((c - 1) / m)**2), the adaptive trial bound's
# ... and of the int64 scratch array ``wi``
_IT = 0  # integer dt (stream only)
_LAB = 1  # 2-means label: 1 = the current event's cluster
_IDX = 2  # window index of the k-th compacted point
_KIN = 3  # the winner's inliers among the compacted points
_INL = 4  # the winner's inliers among the window points
_CV = 5  # 1 when the batch's candidate is a plane (its sample is not collinear with the event)

#: Largest window (cells) with a precomputed table of the trial bound's logarithms.
_LOG_TABLE_MAX = 121

#: Candidate planes computed together (their chains of dependent operations overlap).
_BATCH = 4
_FB = _BATCH  # wi[_CV, _FB] (after the batch's slots): 1 when the last fit ran the fallback on all points
_FIT_STRIDE = 3  # burst reuse: per SAE cell a, b of the burst's stored plane and the burst's count of fits

#: Largest ``n * max|dt|`` for which int64 sums of the window's times equal float64 sums.
_EXACT_SUM = 2**53

#: The stream kernel asks for the state of the event this many places ahead (:mod:`._prefetch`).
_AHEAD = 4


@njit(cache=True)
def _scratch(nn):
    """Scratch arrays ``(wf, wi)`` for windows of ``nn`` cells (allocated once per kernel call).

    ``wf`` also holds the table of ``log(1 - w**2)``, ``w = (c - 1) / m``, for every
    cluster size ``m <= nn`` and inlier count ``1 < c <= m`` (computed with the same
    expression as a direct call would, so the same bits).
    """
    rows = _LOG + nn + 1 if nn <= _LOG_TABLE_MAX else _LOG  # no table for huge windows
    wf = np.full((rows, nn + 2), np.nan)
    for m in range(1, rows - _LOG):
        for c in range(2, m + 1):
            w = (c - 1) / m
            wf[_LOG + m, c] = math.log(1.0 - w * w)
    return wf, np.zeros((6, nn), np.int64)


def scratch_arrays(nn):
    """:func:`_scratch` in plain numpy, for callers outside numba (the same bytes, no compilation).

    The table's logarithms come from Python's ``math.log``, the same C library
    function a numba kernel calls (``tests/detector/test_intra.py`` compares the bytes).
    """
    rows = _LOG + nn + 1 if nn <= _LOG_TABLE_MAX else _LOG
    wf = np.full((rows, nn + 2), np.nan)
    for m in range(1, rows - _LOG):
        for c in range(2, m + 1):
            w = (c - 1) / m
            wf[_LOG + m, c] = math.log(1.0 - w * w)
    return wf, np.zeros((6, nn), np.int64)


@njit(cache=True)
def _degenerate(wf, n, lo, hi, min_points):
    """Whether the window points with ``lo <= dt <= hi`` and the current event fix no plane through it.

    Degenerate: fewer than ``min_points`` points (current event included), or
    all points on one line through the current event (the origin).
    """
    m = 1
    ux = 0.0
    uy = 0.0
    spread = False
    for i in range(n):
        v = wf[_DT, i]
        if lo <= v <= hi:
            m += 1
            x = wf[_DX, i]
            y = wf[_DY, i]
            if ux == 0.0 and uy == 0.0:
                ux = x
                uy = y
            elif ux * y - uy * x != 0.0:
                spread = True
    return m < min_points or not spread


@njit(cache=True)
def _linkage_split(wf, wi, n, gap_ratio, min_gap_us, min_points, jump_check):
    """The current event's cluster by single linkage in time (``split_gap_ratio > 0``), replacing 2-means.

    The paper's 2-means (initial centroids: the window minimum and the current
    time) has two failure modes on a real SAE. With *stale levels* (pixels that
    skipped the current edge passage keep the time of one or two passages
    before) the middle stale level lies nearer the current centroid than the
    oldest one and joins the current cluster. On a clean *ramp* (levels 0, -L,
    -2L behind an axis-aligned edge) the middle level sits on the centroids'
    midpoint and timing jitter cuts it in two. Both come from a split that
    ignores where the time gaps are. Here the cluster grows from the current
    event (``dt = 0``) one window time at a time, always taking the nearest time
    not yet in it (older or newer), while that gap is at most ``gap_ratio``
    times the largest gap taken so far (gaps up to ``min_gap_us``, timing noise,
    are always taken). One edge passage makes a chain of gaps of at most about
    one lifetime; the gap to a stale level is the time between passages less
    the window's span, many lifetimes. While the cluster is degenerate (see
    :func:`_degenerate`: e.g. only the current event's own column of an
    axis-aligned edge, whose pixels fire together) the next time is taken
    whatever its gap: the cluster grows by the fewest time levels that fix a
    plane (this replaces ``fallback_all_points``). The kept cluster is an
    interval ``lo <= dt <= hi``; ``wi[_LAB, i]`` gets 1 inside.
    """
    lo = 0.0
    hi = 0.0
    big = min_gap_us  # largest gap taken so far (at least the timing noise)
    g1 = 0.0  # the largest and second-largest gaps taken, and whether the largest was forced
    g2 = 0.0
    f1 = False
    for _ in range(n):
        below = -np.inf
        above = np.inf
        for i in range(n):
            v = wf[_DT, i]
            if v < lo and v > below:
                below = v
            elif v > hi and v < above:
                above = v
        g_below = lo - below
        g_above = above - hi
        g = min(g_below, g_above)
        if not math.isfinite(g):
            break
        forced = not g <= gap_ratio * big
        if forced and not _degenerate(wf, n, lo, hi, min_points):
            break
        if g > g1:
            g2 = g1
            g1 = g
            f1 = forced
        elif g > g2:
            g2 = g
        big = max(big, g)
        if g_below <= g_above:
            lo = below
        else:
            hi = above
    for i in range(n):
        v = wf[_DT, i]
        wi[_LAB, i] = 1 if lo <= v <= hi else 0
    return _jump_ok(g1, g2, f1, gap_ratio, jump_check)


@njit(cache=True)
def _jump_ok(g1, g2, forced, gap_ratio, jump_check):
    """Whether a linkage cluster is kept: its largest gap ``g1``, if forced, is at most ``gap_ratio g2``.

    ``g2`` is the second-largest gap taken. A forced gap (taken only because the
    cluster fixed no plane yet) is legitimate when it is one step of the edge's
    ramp (the current event's own column, then the next column behind it, about
    one lifetime away) and other steps of that size follow; a forced jump many
    times larger than every other gap is the jump to a stale level (pixels that
    skipped the current passage keep the time of the one before), and a plane
    through it is fitted on the wrong passage. ``jump_check`` False keeps every
    cluster (as before the check).
    """
    return not (jump_check and forced and g1 > gap_ratio * g2)


@njit(cache=True)
def _fit_points(wf, wi, n, exact, key, delta, thr_us, thr_rel, max_trials, stop_prob, log_fail, min_points,
                min_inliers, intercept, fallback, gap_ratio, on_plane, jump_check, noise, ls_first):
    """2-means, then RANSAC on the current event's cluster, then a least-squares refit.

    The ``n`` window points are ``wf[_DX/_DY/_DT, :n]`` (and ``wi[_IT, :n]`` when
    ``exact``, see below). Returns ``(ok, a, b)``; ``wi[_INL, :n]`` marks the
    winner's inlier points.

    **2-means** of the points' ``dt`` and the current event (``dt = 0``). Initial
    centroids: the window minimum and the current time. A point at equal distance
    from both centroids joins the current event's cluster; a window whose
    timestamps all equal the current one is one cluster. With ``exact`` the cluster
    sums are taken over the integers ``wi[_IT]`` (equal to the float64 sums,
    whatever the order, when ``n * max|dt| < 2**53``).

    **RANSAC** plane ``dt = a dx + b dy`` through the current event: candidates pass
    through the current event and two distinct past points of the kept cluster,
    drawn with :func:`_draw` (counters 2k, 2k+1 at trial k); samples collinear with
    the current event are skipped (they still use up a trial). Residual of a point:
    ``max(0, |dt - a dx - b dy| - delta (|a| + |b|))`` (closest point of its
    intra-pixel square); inlier when ``<= thr_us + thr_rel * sqrt(a^2 + b^2)``.
    Most inliers wins, ties go to the smaller sum of inlier residuals, then to the
    earlier trial. With ``stop_prob < 1`` the number of trials shrinks adaptively
    as in scikit-image's ``ransac`` (``log_fail = log(1 - stop_prob)``). The kept
    cluster is degenerate when it has fewer than ``min_points`` points (current
    event included) or fewer than 3, or when every sample is collinear with the
    current event; with ``fallback`` RANSAC then runs once more, with the same
    random stream, on all the window's points (this happens on a clean ramp whose
    middle row of timestamps 2-means gives to the old cluster: an axis-aligned
    edge, whose kept pixels all lie on the current event's row or column).

    **Refit** by least squares on the winner's inliers (current event included when
    fewer than ``min_inliers`` there is no estimate): through the current event, or
    with ``intercept`` with a free time offset (the plane's slopes are what we
    need; the offset only absorbs the current event's own timing noise). A flat
    plane (``a = b = 0``) or a non-finite one is no estimate.

    **Least squares first** (``ls_first > 0``): before the trials, the least-squares
    plane through the current event on the whole cluster; when every point's residual
    is within ``ls_first`` times its inlier threshold the trials are skipped and the
    refit runs on all points (the same sums, same order, as the refit of a winner
    with every point an inlier).

    ``wi[_CV, _FB]`` is 1 when the result comes from the fallback on all points, else 0.

    ``gap_ratio`` and ``on_plane`` may be None, the same as 0 (off): numba then
    prunes their branches when it compiles, so a run without these options
    never compiles :func:`_linkage_split` and :func:`_event_on_plane`
    (:func:`off_as_none`; about a quarter of the estimator's compilation).
    """
    # ---- 2-means; labels: 1 = the current event's cluster
    # the window minimum and (exact) the integer total in one pass; the labels need no initial
    # value: the first iteration always runs on (its centroid test differs from cur = -1)
    c0 = 0.0
    total = 0
    if exact:
        for i in range(n):
            c0 = min(c0, wf[_DT, i])
            total += wi[_IT, i]
    else:
        for i in range(n):
            if wf[_DT, i] < c0:
                c0 = wf[_DT, i]
    c1 = 0.0
    if c0 == c1:
        # every timestamp equals the current one: a single cluster
        for i in range(n):
            wi[_LAB, i] = 1
    else:
        cur = -1
        for _ in range(100):
            lc = 1 if abs(0.0 - c1) <= abs(0.0 - c0) else 0
            changed = lc != cur
            cur = lc
            n1 = 1 if lc == 1 else 0
            nchg = 0
            if exact:
                si1 = 0
                for i in range(n):
                    v = wf[_DT, i]
                    near1 = abs(v - c1) <= abs(v - c0)
                    li = 1 if near1 else 0
                    nchg += 1 if li != wi[_LAB, i] else 0
                    wi[_LAB, i] = li
                    si1 += wi[_IT, i] if near1 else 0
                    n1 += li
                s1 = float(si1)
                s0 = float(total - si1)
            else:
                # branch-free accumulation (labels are unpredictable; adding 0.0 changes no sum)
                s1 = 0.0
                s0 = 0.0
                for i in range(n):
                    v = wf[_DT, i]
                    near1 = abs(v - c1) <= abs(v - c0)
                    li = 1 if near1 else 0
                    nchg += 1 if li != wi[_LAB, i] else 0
                    wi[_LAB, i] = li
                    s1 += v if near1 else 0.0
                    s0 += 0.0 if near1 else v
                    n1 += li
            n0 = n + 1 - n1  # the current event and the past points not in cluster 1
            if not changed and nchg == 0:
                break
            if n0 > 0:
                c0 = s0 / n0
            if n1 > 0:
                c1 = s1 / n1
        if cur != 1:  # the current event's cluster is label 0: swap (labels are 1 = its cluster)
            for i in range(n):
                wi[_LAB, i] = 1 if wi[_LAB, i] == cur else 0
    # an option passed as None (off) is pruned when the kernel compiles: its code is then never compiled
    if gap_ratio is not None:
        if gap_ratio > 0.0:
            if not _linkage_split(wf, wi, n, gap_ratio, thr_us, min_points, jump_check):
                for i in range(n):
                    wi[_INL, i] = 0
                return False, np.nan, np.nan  # a forced jump to a stale level: no estimate

    # ---- RANSAC on the kept cluster; a second attempt on all points when it is degenerate
    nin = -1
    wi[_CV, _FB] = 0
    for attempt in range(2):
        if attempt == 1:
            if nin >= 0 or not fallback:
                break
            wi[_CV, _FB] = 1  # burst reuse stores no fallback fit (:func:`_intra_stream`)
            for i in range(n):
                wi[_LAB, i] = 1
        m = 0
        for i in range(n):
            wi[_INL, i] = 0
            # branch-free compaction into contiguous copies of the kept points (the
            # trial loop reads them directly); a slot is overwritten unless kept
            wi[_IDX, m] = i
            wf[_KX, m] = wf[_DX, i]
            wf[_KY, m] = wf[_DY, i]
            wf[_KT, m] = wf[_DT, i]
            m += 1 if wi[_LAB, i] == 1 else 0
        if m < 2 or m + 1 < min_points:
            nin = -1
            continue
        best_n = 0
        best_cost = np.inf
        best_a = np.nan
        best_b = np.nan
        best_slack = 0.0
        best_thr = 0.0
        trials = max_trials
        # least-squares sums over the whole cluster; the current event (origin) adds 1 to the count only
        s1 = 1.0
        sx = 0.0
        sy = 0.0
        st = 0.0
        sxx = 0.0
        sxy = 0.0
        syy = 0.0
        sxt = 0.0
        syt = 0.0
        full = False
        if ls_first > 0.0:
            # least squares first: the plane through the current event fitted to the whole cluster;
            # when every point is its inlier (within ls_first times the threshold) no hypothesis can
            # have more, and the refit on all points is the result: no trial (same sums, same
            # order as the refit below)
            for q in range(m):
                xq = wf[_KX, q]
                yq = wf[_KY, q]
                tq = wf[_KT, q]
                s1 += 1.0
                sx += xq
                sy += yq
                st += tq
                sxx += xq * xq
                sxy += xq * yq
                syy += yq * yq
                sxt += xq * tq
                syt += yq * tq
            det0 = sxx * syy - sxy * sxy
            if det0 > 1e-9 * (sxx * syy):
                a = (sxt * syy - syt * sxy) / det0
                b = (syt * sxx - sxt * sxy) / det0
                slack = delta * (abs(a) + abs(b))
                thr = thr_us + thr_rel * math.sqrt(a * a + b * b)
                tight = ls_first * thr
                cnt = 1
                for q in range(m):
                    r = abs(wf[_KT, q] - (a * wf[_KX, q] + b * wf[_KY, q])) - slack
                    r = max(r, 0.0)
                    cnt += 1 if r <= tight else 0
                if cnt == m + 1 and math.isfinite(a) and math.isfinite(b):
                    full = True
                    best_n = cnt
                    best_cost = 0.0
                    best_a = a
                    best_b = b
                    best_slack = slack
                    best_thr = thr
                    trials = 0
        k = 0
        um = np.uint64(m)
        um1 = np.uint64(m - 1)
        while k < trials:
            # the candidates of the next trials first, together: each is a chain of
            # dependent operations (draw, 64-bit modulo, division, sqrt) and the
            # chains overlap; a candidate past the final trial count is never used
            kb = min(k + _BATCH, trials)
            for kk in range(k, kb):
                pi = np.int64(_draw(key, 2 * kk) % um)
                pj = np.int64(_draw(key, 2 * kk + 1) % um1)
                if pj >= pi:
                    pj += 1
                xi = wf[_KX, pi]
                yi = wf[_KY, pi]
                ti = wf[_KT, pi]
                xj = wf[_KX, pj]
                yj = wf[_KY, pj]
                tj = wf[_KT, pj]
                det = xi * yj - xj * yi
                plane = det != 0.0
                # a sample collinear with the current event is no plane (divide by 1, unused)
                det = det if plane else 1.0
                a = (ti * yj - tj * yi) / det
                b = (xi * tj - xj * ti) / det
                s = kk - k
                wf[_CA, s] = a
                wf[_CB, s] = b
                wf[_CS, s] = delta * (abs(a) + abs(b))
                wf[_CT, s] = thr_us + thr_rel * math.sqrt(a * a + b * b)
                wi[_CV, s] = 1 if plane else 0
            for kk in range(k, kb):
                if kk >= trials:
                    break
                s = kk - k
                if wi[_CV, s] == 0:
                    continue
                a = wf[_CA, s]
                b = wf[_CB, s]
                slack = wf[_CS, s]
                thr = wf[_CT, s]
                # count first: no serial float sum, so the loop vectorises
                cnt = 1
                for q in range(m):
                    r = abs(wf[_KT, q] - (a * wf[_KX, q] + b * wf[_KY, q])) - slack
                    r = max(r, 0.0)
                    cnt += 1 if r <= thr else 0
                if cnt < best_n:
                    continue
                # the summed residual only breaks ties, so it is summed only for a tie: a new best's own sum
                # waits (NaN) until a tie needs it; the candidate's partial sum, which never decreases,
                # stops once it reaches the best's (it cannot be smaller). The same sums, in the same order.
                cost = np.nan
                if cnt == best_n:
                    if math.isnan(best_cost):
                        best_cost = 0.0
                        for q in range(m):
                            r = abs(wf[_KT, q] - (best_a * wf[_KX, q] + best_b * wf[_KY, q])) - best_slack
                            r = max(r, 0.0)
                            best_cost += r if r <= best_thr else 0.0
                    cost = 0.0
                    for q in range(m):
                        r = abs(wf[_KT, q] - (a * wf[_KX, q] + b * wf[_KY, q])) - slack
                        r = max(r, 0.0)
                        cost += r if r <= thr else 0.0
                        if cost >= best_cost:
                            break
                if cnt > best_n or cost < best_cost:
                    best_n = cnt
                    best_cost = cost
                    best_a = a
                    best_b = b
                    best_slack = slack
                    best_thr = thr
                    if stop_prob < 1.0:
                        w = (cnt - 1) / m
                        if w >= 1.0:
                            trials = kk + 1
                        else:
                            denom = 1.0 - w * w
                            if denom < 1.0:
                                lg = wf[_LOG + m, cnt] if wf.shape[0] > _LOG else math.log(denom)
                                need = math.ceil(log_fail / lg)
                                if need < trials:
                                    trials = need
            k = kb
        if best_n == 0:
            # every sample was collinear with the current event: no plane at all
            nin = -1
            continue
        nin = best_n
        if full:
            # every point is an inlier; the sums above are the refit's
            for q in range(m):
                wi[_KIN, q] = 1
                wi[_INL, wi[_IDX, q]] = 1
        else:
            # the winner's inliers, recomputed exactly as in its trial
            for q in range(m):
                r = abs(wf[_KT, q] - (best_a * wf[_KX, q] + best_b * wf[_KY, q])) - best_slack
                r = max(r, 0.0)
                inl = 1 if r <= best_thr else 0
                wi[_KIN, q] = inl
                wi[_INL, wi[_IDX, q]] = inl
        if best_n < min_inliers:
            return False, np.nan, np.nan
        if not full:
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
                wq = 1.0 if wi[_KIN, q] == 1 else 0.0
                xq = wf[_KX, q] * wq
                yq = wf[_KY, q] * wq
                tq = wf[_KT, q] * wq
                s1 += wq
                sx += xq
                sy += yq
                st += tq
                sxx += xq * wf[_KX, q]
                sxy += xq * wf[_KY, q]
                syy += yq * wf[_KY, q]
                sxt += xq * wf[_KT, q]
                syt += yq * wf[_KT, q]
        on = True
        if on_plane is not None:
            on = not (on_plane > 0.0 and intercept) or _event_on_plane(s1, sx, sy, st, sxx, sxy, syy, sxt, syt,
                                                                      delta, thr_us, thr_rel, on_plane)
        solved, a, b = _ls_slopes(s1, sx, sy, st, sxx, sxy, syy, sxt, syt, intercept)
        if not solved:
            a = best_a
            b = best_b
        if not (a * a + b * b > 0.0) or not math.isfinite(a) or not math.isfinite(b):
            # a flat plane (all inliers at the current time): no finite lifetime
            return False, np.nan, np.nan
        if not on:
            return False, np.nan, np.nan
        if noise is not None:
            # noise rule (module _noise_kernels): the plane must not leave many recent points above it
            newer = noise[_NEWER]
            if newer < 1.0:
                c = _newer_count(wf, _DX, _DY, _DT, n, a, b, delta, thr_us, thr_rel)
                if c > newer * (c + best_n - 1):
                    return False, np.nan, np.nan
        return True, a, b
    return False, np.nan, np.nan


@njit(cache=True, inline="always")
def _ls_slopes(s1, sx, sy, st, sxx, sxy, syy, sxt, syt, intercept):
    """Least-squares slopes ``(solved, a, b)`` of ``dt = a dx + b dy (+ c)`` from the raw sums over the points.

    With ``intercept`` the sums are centred first: a free time offset ``c`` (the
    current event becomes one point among the others instead of a fixed anchor).
    ``solved`` is False (and ``a, b`` NaN) when the points fix no plane (the
    determinant is not above ``1e-9`` of its scale: all on one line). The one
    place of this arithmetic for :func:`_fit_points`, :func:`_refine` and
    :func:`_burst_refit` (same operations in the same order: the same bytes).
    """
    if intercept:
        sxx -= sx * sx / s1
        sxy -= sx * sy / s1
        syy -= sy * sy / s1
        sxt -= sx * st / s1
        syt -= sy * st / s1
    det = sxx * syy - sxy * sxy
    if not det > 1e-9 * (sxx * syy):
        return False, np.nan, np.nan
    return True, (sxt * syy - syt * sxy) / det, (syt * sxx - sxt * sxy) / det


@njit(cache=True)
def _event_on_plane(s1, sx, sy, st, sxx, sxy, syy, sxt, syt, delta, thr_us, thr_rel, tol):
    """Whether the current event (the origin) lies on the plane of its past inliers (``event_on_plane``).

    ``s*`` are the raw (uncentred) least-squares sums over the winner's inliers,
    the current event included (it adds 1 to ``s1`` and 0 to the others). The
    plane ``dt = a dx + b dy + c`` is fitted on the *past* inliers alone (leave the
    current event out: a fit that includes it is pulled towards it); the event is
    on it when its intra-pixel residual ``max(0, |c| - delta (|a| + |b|))`` is
    within ``tol`` times the inlier threshold of that plane. False when the past inliers
    alone fix no plane (all on one line). A background-activity event fired
    after an edge passed its pixel (or before it arrives) is off that plane by
    the time between them: no estimate.
    """
    n = s1 - 1.0
    if n < 3.0:
        return False
    cxx = sxx - sx * sx / n
    cxy = sxy - sx * sy / n
    cyy = syy - sy * sy / n
    cxt = sxt - sx * st / n
    cyt = syt - sy * st / n
    det = cxx * cyy - cxy * cxy
    if not det > 1e-9 * (cxx * cyy) or not det > 0.0:
        return False
    a = (cxt * cyy - cyt * cxy) / det
    b = (cyt * cxx - cxt * cxy) / det
    c = (st - a * sx - b * sy) / n
    r = max(0.0, abs(c) - delta * (abs(a) + abs(b)))
    return r <= tol * (thr_us + thr_rel * math.sqrt(a * a + b * b))


def off_as_none(value: float):
    """An option of the kernels at 0 (off) as None: numba then compiles none of its code (:func:`_fit_points`)."""
    return None if value == 0.0 else value


@njit(cache=True)
def _log_fail(stop_prob):
    """``log(1 - stop_prob)`` for the adaptive trial bound (unused at ``stop_prob = 1``)."""
    return math.log(1.0 - stop_prob) if stop_prob < 1.0 else 0.0


@njit(cache=True)
def _stale_cutoff(tk, prev, prev_lt, frac, half):
    """Oldest SAE time still a window point of a new burst at ``tk`` (``stale_fraction``; ``_NEVER``: all are).

    ``prev`` is the time of the pixel's previous event of the same polarity: the
    same edge cannot pass the pixel twice in between, so a neighbour's time older
    than ``frac`` of that interval before ``tk`` (the midpoint at 0.5) is from an
    earlier passage (a stale level of a pixel that skipped this one).
    """
    if not frac > 0.0:
        return _NEVER
    gap = frac * float(tk - prev)
    if gap <= 2.0 * half * prev_lt:  # False when prev_lt is NaN (no estimate)
        return _NEVER
    return tk - np.int64(gap)


@njit(cache=True)
def _history_short(tk, a, b, reach_px, t_start):
    """Whether the plane ``dt = a dx + b dy`` through ``(0, 0, tk)`` reaches before ``t_start``.

    ``reach_px`` is ``startup_reach`` times the window's half-size: the oldest
    window cell of the plane is ``half (|a| + |b|)`` before ``tk``. When that is
    before the stream's first event (``t_start``; ``_NEVER`` = no start-up
    rule) the pixels there could not hold the plane's times yet (they never
    fired, or fired at the start with whatever phase the edge had reached), and
    the fit rests on a truncated history: on the simulated scenes such estimates
    are short by 30-80 %, so the reach of the (short) estimate itself is scaled.
    """
    return float(tk) - reach_px * (abs(a) + abs(b)) < float(t_start)


@njit(cache=True)
def _gather(sae, wf, wi, base, xk, yk, tk, width, height, half, oldest):
    """The window points around pixel ``(xk, yk)`` of the SAE plane at ``base``, relative to time ``tk``.

    Fills ``wf[_DX/_DY/_DT]`` and ``wi[_IT]``; never-fired pixels and pixels outside
    the sensor (rows ``0 .. height - 1`` of the plane) are not points, nor is the
    centre. Returns the number of points.
    """
    n = 0
    # clipped ranges: the same cells in the same order as testing each against the sensor
    for yy in range(max(yk - half, 0), min(yk + half, height - 1) + 1):
        row = base + yy * width
        oy = yy - yk
        for xx in range(max(xk - half, 0), min(xk + half, width - 1) + 1):
            v = sae[row + xx]
            if v == _NEVER or v < oldest or (xx == xk and oy == 0):
                continue
            d = v - tk
            wf[_DX, n] = xx - xk
            wf[_DY, n] = oy
            wf[_DT, n] = float(d)
            wi[_IT, n] = d
            n += 1
    return n


@njit(cache=True)
def _refine(sae, wf, wi, n, base, xk, yk, tk, width, height, fh, half, oldest, a, b, delta, thr_us, thr_rel,
            intercept, curv=None):
    """The fit ``dt = a dx + b dy`` refitted on its inliers and on the outer ring's points on its plane.

    The fit saw the ``n`` points of the window of half-size ``fh`` (``wi[_INL]``
    marks its inliers); the ring is the cells of the window of half-size
    ``half > fh`` outside it, read from the SAE plane at ``base`` (never-fired
    cells, cells older than ``oldest`` and rows outside ``0 .. height - 1`` are no
    points, as in :func:`_gather`). A ring point joins when its residual to the
    fit's plane (with the inliers' least-squares offset when ``intercept``, else
    through the current event), less the intra-pixel slack, is within the inlier
    threshold. Least squares on the inliers, the joined points and the current
    event, as the fit's own refit. Returns ``(a, b, pa, pb)``: the slopes, and the
    plane's (the same unless the quadratic below is taken); ``(a, b)`` unchanged when
    no ring point joins or the refit is flat, singular or not finite.

    Curvature (``curv``, None = off, pruned when compiled): on the same points, the
    quadratic ``dt = a dx + b dy + c dx^2 + d dx dy + e dy^2`` (``+ t0`` with
    ``intercept``) too, by least squares (:func:`_quad_solve`); its slopes at the
    current event, ``(a, b)``, replace the plane's when the F statistic of the three
    curvature terms exceeds ``curv`` (:func:`_prefers_quadratic`); ``pa, pb`` are then
    the plane's on the same points (the start-up rule judges the window's history
    with it, as it was measured). Tried also when no ring point joins.
    """
    s1 = 1.0
    sx = 0.0
    sy = 0.0
    st = 0.0
    sxx = 0.0
    sxy = 0.0
    syy = 0.0
    sxt = 0.0
    syt = 0.0
    mom = _NO_MOMENTS  # curvature: the points' higher moments (:func:`_moments_add`)
    for i in range(n):
        if wi[_INL, i] == 1:
            xq = wf[_DX, i]
            yq = wf[_DY, i]
            tq = wf[_DT, i]
            if curv is not None:
                mom = _moments_add(mom, xq, yq, tq)
            s1 += 1.0
            sx += xq
            sy += yq
            st += tq
            sxx += xq * xq
            sxy += xq * yq
            syy += yq * yq
            sxt += xq * tq
            syt += yq * tq
    c = (st - a * sx - b * sy) / s1 if intercept else 0.0
    slack = delta * (abs(a) + abs(b))
    thr = thr_us + thr_rel * math.sqrt(a * a + b * b)
    joined = 0
    for yy in range(max(yk - half, 0), min(yk + half, height - 1) + 1):
        row = base + yy * width
        oy = yy - yk
        for xx in range(max(xk - half, 0), min(xk + half, width - 1) + 1):
            ox = xx - xk
            if abs(ox) <= fh and abs(oy) <= fh:
                continue
            v = sae[row + xx]
            if v == _NEVER or v < oldest:
                continue
            xq = float(ox)
            yq = float(oy)
            tq = float(v - tk)
            if abs(tq - (a * xq + b * yq + c)) - slack > thr:
                continue
            if curv is not None:
                mom = _moments_add(mom, xq, yq, tq)
            joined += 1
            s1 += 1.0
            sx += xq
            sy += yq
            st += tq
            sxx += xq * xq
            sxy += xq * yq
            syy += yq * yq
            sxt += xq * tq
            syt += yq * tq
    if joined == 0 and curv is None:
        return a, b, a, b
    solved, a2, b2 = _ls_slopes(s1, sx, sy, st, sxx, sxy, syy, sxt, syt, intercept)
    if not solved:
        return a, b, a, b
    if not (a2 * a2 + b2 * b2 > 0.0) or not math.isfinite(a2) or not math.isfinite(b2):
        return a, b, a, b
    if curv is not None:
        # the quadratic's residual degrees of freedom: the current event is an observation with an
        # intercept; through it, it fixes nothing
        dof = (s1 - 6.0) if intercept else (s1 - 1.0 - 5.0)
        if dof >= 3.0:
            s30, s21, s12, s03, s40, s31, s22, s13, s04, s20t, s11t, s02t, stt = mom
            # the plane's residual sum of squares from the same sums (least squares: sum r^2 = sum r t)
            c2 = (st - a2 * sx - b2 * sy) / s1 if intercept else 0.0
            rss_plane = stt - a2 * sxt - b2 * syt - c2 * st
            _quad_fill(wf, s1, sx, sy, sxx, sxy, syy, s30, s21, s12, s03, s40, s31, s22, s13, s04, st, sxt, syt,
                       s20t, s11t, s02t)
            ok, qa, qb, rss_quad = _quad_solve(wf, intercept, stt)
            if ok and _prefers_quadratic(rss_plane, rss_quad, dof, curv):
                if qa * qa + qb * qb > 0.0 and math.isfinite(qa) and math.isfinite(qb):
                    return qa, qb, a2, b2
        if joined == 0:
            return a, b, a, b
    return a2, b2, a2, b2


#: Curvature (:func:`_refine`): the quadratic's normal equations, 6 x 7 augmented, flat in row ``_CA`` of ``wf``
#: (:func:`_quad_fill`).
_QN = 6
_QW = _QN + 1
#: Least window cells of a scratch whose row ``_CA`` holds the quadratic's equations (``_QN * _QW`` values).
QUAD_SCRATCH = _QN * _QW


#: No point yet: :func:`_moments_add`'s thirteen sums.
_NO_MOMENTS = (0.0,) * 13


@njit(cache=True, inline="always")
def _moments_add(m, xq, yq, tq):
    """The point ``(xq, yq, tq)`` added to the moments ``m`` the quadratic needs beyond the plane's: the sums of
    ``dx^3, dx^2 dy, dx dy^2, dy^3, dx^4, dx^3 dy, dx^2 dy^2, dx dy^3, dy^4, dx^2 dt, dx dy dt, dy^2 dt, dt^2``."""
    xx = xq * xq
    xy = xq * yq
    yy = yq * yq
    return (m[0] + xx * xq, m[1] + xx * yq, m[2] + xq * yy, m[3] + yy * yq, m[4] + xx * xx, m[5] + xx * xy,
            m[6] + xx * yy, m[7] + xy * yy, m[8] + yy * yy, m[9] + xx * tq, m[10] + xy * tq, m[11] + yy * tq,
            m[12] + tq * tq)


@njit(cache=True, inline="always")
def _quad_fill(wf, s1, sx, sy, sxx, sxy, syy, s30, s21, s12, s03, s40, s31, s22, s13, s04, st, sxt, syt, s20t, s11t,
               s02t):
    """The quadratic's normal equations (basis ``1, dx, dy, dx^2, dx dy, dy^2``) from the points' moments, 6 x 7
    augmented, flat in row ``_CA`` of ``wf`` (``s1`` counts the current event, the origin)."""
    g = (s1, sx, sy, sxx, sxy, syy, st,
         sx, sxx, sxy, s30, s21, s12, sxt,
         sy, sxy, syy, s21, s12, s03, syt,
         sxx, s30, s21, s40, s31, s22, s20t,
         sxy, s21, s12, s31, s22, s13, s11t,
         syy, s12, s03, s22, s13, s04, s02t)
    for i in range(_QN * _QW):
        wf[_CA, i] = g[i]


@njit(cache=True)
def _quad_solve(wf, intercept, stt):
    """Solve the normal equations :func:`_quad_fill` wrote (symmetric: ``L D L^T``, in place).

    Without ``intercept`` the basis is ``dx, dy, dx^2, dx dy, dy^2`` (through the current
    event). Returns ``(solved, a, b, rss)``: the slopes at the current event and the
    residual sum of squares ``stt - beta . rhs``; ``solved`` is False when a pivot
    ``D[j]`` is not above ``1e-9`` of the largest diagonal term (the points fix no
    quadratic). ``L`` (unit, below the diagonal) and ``D`` (on it) overwrite the
    matrix; the solution overwrites the right-hand side (column ``_QN``).
    """
    q0 = 0 if intercept else 1
    scale = 0.0
    for i in range(q0, _QN):
        scale = max(scale, wf[_CA, i * _QW + i])
    for j in range(q0, _QN):
        d = wf[_CA, j * _QW + j]
        for k in range(q0, j):
            lk = wf[_CA, j * _QW + k]
            d -= lk * lk * wf[_CA, k * _QW + k]
        if not d > 1e-9 * scale:
            return False, np.nan, np.nan, np.nan
        wf[_CA, j * _QW + j] = d
        for i in range(j + 1, _QN):
            v = wf[_CA, i * _QW + j]
            for k in range(q0, j):
                v -= wf[_CA, i * _QW + k] * wf[_CA, j * _QW + k] * wf[_CA, k * _QW + k]
            wf[_CA, i * _QW + j] = v / d
    rss = stt
    for i in range(q0, _QN):  # L z = rhs; beta^T rhs = sum z_i^2 / D_i, the residual sum's decrease
        v = wf[_CA, i * _QW + _QN]
        for k in range(q0, i):
            v -= wf[_CA, i * _QW + k] * wf[_CA, k * _QW + _QN]
        wf[_CA, i * _QW + _QN] = v
        rss -= v * v / wf[_CA, i * _QW + i]
    for i in range(_QN - 1, q0 - 1, -1):  # D L^T beta = z
        v = wf[_CA, i * _QW + _QN] / wf[_CA, i * _QW + i]
        for k in range(i + 1, _QN):
            v -= wf[_CA, k * _QW + i] * wf[_CA, k * _QW + _QN]
        wf[_CA, i * _QW + _QN] = v
    return True, wf[_CA, 1 * _QW + _QN], wf[_CA, 2 * _QW + _QN], rss


@njit(cache=True, inline="always")
def _prefers_quadratic(rss_plane, rss_quad, dof, f_min):
    """The F test of the quadratic's three curvature terms against the plane: ``F > f_min`` with ``dof`` residual
    degrees of freedom of the quadratic (the caller asks for at least 3), written without a division."""
    return (rss_plane - rss_quad) * dof > f_min * 3.0 * max(rss_quad, 0.0)


@njit(cache=True)
def _burst_refit(wf, wi, n, a0, b0, delta, thr_us, thr_rel, min_inliers, intercept, on_plane, noise):
    """Burst reuse's warm refit: the stored plane ``dt = a0 dx + b0 dy``'s inliers among the window, least squares.

    The ``n`` window points are ``wf[_DX/_DY/_DT, :n]`` (as for :func:`_fit_points`,
    no 2-means, no trial). A point is an inlier of the stored plane as of a RANSAC
    candidate (residual less the intra-pixel slack within the inlier threshold;
    ``wi[_INL]`` marks them); with at least ``min_inliers`` (current event
    included) the least-squares refit on them and the current event, as
    :func:`_fit_points`' refit (``intercept``), and its rules (flat or non-finite
    plane, ``on_plane``, the noise rule's newer points). Returns ``(ok, a, b,
    inliers)`` (the current event included); not ok: the caller fits the window
    as usual.
    """
    slack = delta * (abs(a0) + abs(b0))
    thr = thr_us + thr_rel * math.sqrt(a0 * a0 + b0 * b0)
    s1 = 1.0
    sx = 0.0
    sy = 0.0
    st = 0.0
    sxx = 0.0
    sxy = 0.0
    syy = 0.0
    sxt = 0.0
    syt = 0.0
    cnt = 1
    for i in range(n):
        r = abs(wf[_DT, i] - (a0 * wf[_DX, i] + b0 * wf[_DY, i])) - slack
        r = max(r, 0.0)
        inl = 1 if r <= thr else 0
        wi[_INL, i] = inl
        cnt += inl
        # branch-free: a weight of 0 or 1 (adding 0.0 changes no sum)
        wq = float(inl)
        xq = wf[_DX, i] * wq
        yq = wf[_DY, i] * wq
        tq = wf[_DT, i] * wq
        s1 += wq
        sx += xq
        sy += yq
        st += tq
        sxx += xq * wf[_DX, i]
        sxy += xq * wf[_DY, i]
        syy += yq * wf[_DY, i]
        sxt += xq * wf[_DT, i]
        syt += yq * wf[_DT, i]
    if cnt < min_inliers or cnt < 3:
        return False, np.nan, np.nan, cnt
    on = True
    if on_plane is not None:
        on = not (on_plane > 0.0 and intercept) or _event_on_plane(s1, sx, sy, st, sxx, sxy, syy, sxt, syt,
                                                                  delta, thr_us, thr_rel, on_plane)
    solved, a, b = _ls_slopes(s1, sx, sy, st, sxx, sxy, syy, sxt, syt, intercept)
    if not solved:
        return False, np.nan, np.nan, cnt
    if not (a * a + b * b > 0.0) or not math.isfinite(a) or not math.isfinite(b) or not on:
        return False, np.nan, np.nan, cnt
    if noise is not None:
        newer = noise[_NEWER]
        if newer < 1.0:
            c = _newer_count(wf, _DX, _DY, _DT, n, a, b, delta, thr_us, thr_rel)
            if c > newer * (c + cnt - 1):
                return False, np.nan, np.nan, cnt
    return True, a, b, cnt


@njit(cache=True)
def _intra_stream(x, y, t, p, idx, j0, g0, sae, prev_t, prev_lt, prev_pol, burst, width, height, row0, rows, own_lo,
                  own_hi, dec, dec_lt, per_pol, half, delta, thr_us, thr_rel, max_trials, stop_prob, min_points,
                  min_inliers, intercept, fallback, seed, gap_ratio, on_plane, startup, border, jump_check, stale_frac,
                  t_start, reach_px, noise, out_lt, out_vx, out_vy, out_valid, wf, wi, ls_first, refine=None,
                  reuse=0, reuse_warm=True, reuse_inliers=0, fits=None, ring_tol=1.0, curv=None):
    """SAE update, window gathering, 2-means and RANSAC for the events ``idx[j0:]`` in order.

    ``wf, wi`` are the scratch arrays of :func:`_scratch` for the window's cells
    (made once by the caller: a strip may be resumed many times).

    The state covers sensor rows ``row0 .. row0 + rows - 1`` of the ``width x height``
    sensor (all of it, or a strip and its halo, see :mod:`evedge.detector._tiles`):
    ``sae`` is the flat SAE (``(plane * rows + y - row0) * width + x``), updated in
    place; rows outside it are treated as outside the sensor. Event ``k = idx[j]``
    has global index ``g0 + k`` (it seeds its random stream) and writes
    ``out_*[j]`` (flow in px/s; aligned with ``idx``, so a strip's outputs are its
    own memory, not interleaved with its neighbours') when it lies in the owned
    rows ``own_lo <= y < own_hi``. Returns the index ``j`` where it stopped
    (``idx.size`` at the end).

    Strips (:mod:`evedge.detector._tiles`): every event of ``idx`` must lie in the
    owned rows; the caller replays the halo's events itself. An event within
    ``half`` rows of the owned rows' edges (a neighbour's halo reads it) publishes,
    for event ``k``, its pixel's ``prev_lt`` after it in ``dec_lt[k]``, then its burst
    decision in ``dec[k]`` (int8, atomic release: ``1`` new burst, ``2`` continues
    its pixel's burst). ``dec`` is empty without strips. The noise rule
    ``lifetime_agreement`` reads the inlier pixels' ``prev_lt``, the halo's
    included: the halo replay then takes the owner's published value.

    Burst grouping (``burst > 0``): ``prev_lt`` (float, NaN = none) and ``prev_pol``
    (int8, -1 = none), laid out as ``sae`` and updated in place, hold the lifetime
    estimated for the previous event of each pixel and its polarity. An event of
    the same polarity as its pixel's previous event, with an estimate ``L``, and at
    most ``burst * L`` after the time the pixel holds, continues that burst: the
    pixel keeps the burst's first time and the event is fitted at that time (its
    points are ``dt = t_window - t_burst_start``). Otherwise the pixel takes the
    event's time (the paper's SAE).

    Start-up rule (``startup``, with ``burst > 0``): when the pixel's previous
    event has the same polarity but no estimate (always so for the second event
    of a pixel's first burst: nothing had history before it), the event is first
    fitted as a continuation of the burst, and kept so when that fit gives a
    lifetime ``L`` with the gap to the previous event at most ``burst * L``;
    otherwise it is fitted again as a new burst. An event without estimate
    inside a burst leaves the burst's lifetime in ``prev_lt`` (the next events
    still continue the burst).

    Border rule (``border > 0``): an event closer than ``border`` px to the sensor
    edge (its window is clipped) is reported without estimate; its fit still
    sets the burst state of its pixel, as any other event's. The start-up rule
    (``t_start``, the stream's first event time; ``_NEVER`` = off) does the same
    for a fit whose plane reaches before ``t_start`` in the window
    (:func:`_history_short`).

    Stale cutoff (``stale_frac > 0``): an event that starts a burst ignores the
    window times older than :func:`_stale_cutoff`.

    Ring refit (``refine``, None = off, pruned when compiled): the fit (gather,
    2-means, RANSAC, the rules) sees the window of half-size ``refine``, and
    :func:`_refine` refits its plane with the points of the window of half-size
    ``half`` on it (``half`` is then the radius the event reads, for the strips)
    whose residual is within ``ring_tol`` times the fit's inlier threshold; with
    ``curv`` (None = off) it takes a quadratic's slopes where the points prefer one.

    Burst reuse (``reuse = k > 0``; ``fits``, float64 of :data:`_FIT_STRIDE` per SAE
    cell: ``a, b`` of the plane stored for the pixel's current burst, NaN = none,
    and the count of fits the burst has stored): an event that continues its
    pixel's burst, whose burst holds a plane, is refitted while the burst has
    stored fewer than ``k`` fits, and from the ``k``-th on takes the stored plane
    (its lifetime and flow) with no fit and no fit rule; the reporting rules
    (border, start-up) run as always. The refit is warm with ``reuse_warm``
    (:func:`_burst_refit` on the window at the burst's first time, then the ring
    refit and ``lifetime_agreement`` as after a fit; when it gives none, the
    usual fit on the same gathered window), else the usual fit. An event that
    starts a burst, or whose burst holds no plane, is fitted as usual. Every fit
    or warm refit with an estimate stores its plane and counts (the count
    restarts with a new burst), except a fit of the fallback on all points
    (``wi[_CV, _FB]``) and one with fewer than ``reuse_inliers`` inliers (current
    event included; the fit's window, the ring aside), which, as a fit without
    estimate, clear the plane: the burst's next event is fitted again.
    ``reuse = 0`` (or empty ``fits``): off, the same bytes as without.
    """
    log_fail = _log_fail(stop_prob)
    # the scratch arrays go to a non-inlined fit per event: without reference counts (two locked
    # instructions per array and call, :mod:`._borrow`); the caller keeps them alive
    wf = _borrowed(wf)
    wi = _borrowed(wi)
    use_fits = False
    if fits is not None:
        use_fits = reuse > 0 and fits.shape[0] > 0
    fh = half  # the fit's window half-size
    ring_us = thr_us  # the ring refit's inlier threshold (refine_tolerance times the fit's)
    ring_rel = thr_rel
    if refine is not None:
        fh = refine
        ring_us = thr_us * ring_tol
        ring_rel = thr_rel * ring_tol
    publish = dec.shape[0] > 0
    for j in range(j0, idx.shape[0]):
        if j + _AHEAD < idx.shape[0]:
            # a hint (no value changes): the state the event _AHEAD places on will read, on a large
            # sensor far from this one's and out of the caches (:mod:`._prefetch`)
            k2 = idx[j + _AHEAD]
            x2 = x[k2]
            y2 = y[k2] - row0
            b2 = (p[k2] if per_pol else 0) * rows * width  # its SAE plane
            s2 = b2 + y2 * width + x2
            _prefetch(prev_t, s2)
            _prefetch(prev_lt, s2)
            _prefetch(prev_pol, s2)
            if use_fits:
                _prefetch(fits, _FIT_STRIDE * s2)
            for yy in range(max(y2 - half, 0), min(y2 + half, rows - 1) + 1):  # each window row's two ends
                _prefetch(sae, b2 + yy * width + max(x2 - half, 0))
                _prefetch(sae, b2 + yy * width + min(x2 + half, width - 1))
        k = idx[j]
        xk = x[k]
        yk = y[k] - row0
        tk = t[k]
        base = (p[k] if per_pol else 0) * rows * width
        si = base + yk * width + xk
        pk = np.int8(1) if p[k] else np.int8(0)
        # prev_lt is NaN when the previous event had no estimate: the comparison is False
        cont = burst > 0.0 and prev_pol[si] == pk and tk - prev_t[si] <= burst * prev_lt[si]
        # noise rule (module _noise_kernels): a burst lasts at most span lifetimes from its first event
        span = 0.0
        if noise is not None:
            span = noise[_BURST_SPAN]
            cont = cont and (span <= 0.0 or tk - sae[si] <= span * prev_lt[si])
        # start-up rule: the previous event of the burst has no estimate yet; try the continuation first
        trial = startup and burst > 0.0 and not cont and prev_pol[si] == pk and math.isnan(prev_lt[si])
        t_ev = tk
        ok = False
        a = np.nan
        b = np.nan
        n = 0
        fresh = not cont  # the event does not continue its pixel's burst by the rule above (a trial may make it)
        fs = _FIT_STRIDE * si
        reused = False  # burst reuse: the stored plane taken, no fit
        warm = False  # burst reuse: the warm refit gave the estimate
        n_inl = 0  # burst reuse: the warm refit's inliers (current event included)
        gathered = False  # the window at the burst's first time is in wf, wi already
        refined = False  # the ring refit ran: ra, rb are its plane's slopes (the start-up rule's)
        ra = np.nan
        rb = np.nan
        if use_fits and cont and not math.isnan(fits[fs]):
            tk = sae[si]  # the burst's first time, as a continuing event's fit
            if fits[fs + 2] >= reuse:
                reused = True
                ok = True
                a = fits[fs]
                b = fits[fs + 1]
            elif reuse_warm:
                oldest = np.int64(_NEVER)  # typed as the fit's below: one specialisation of _gather and _refine
                n = _gather(sae, wf, wi, base, xk, yk, tk, width, rows, fh, oldest)
                gathered = True
                ok, a, b, n_inl = _burst_refit(wf, wi, n, fits[fs], fits[fs + 1], delta, thr_us, thr_rel,
                                               min_inliers, intercept, on_plane, noise)
                warm = ok
                if refine is not None:
                    if ok:
                        a, b, ra, rb = _refine(sae, wf, wi, n, base, xk, yk, tk, width, rows, fh, half, oldest, a,
                                               b, delta, ring_us, ring_rel, intercept, curv)
                        refined = True
        for attempt in range(0 if ok else 2):
            if cont or trial:
                tk = sae[si]  # same burst: the pixel and the event keep the burst's first time
            else:
                tk = t_ev
                sae[si] = tk
            oldest = _NEVER
            if not (cont or trial) and prev_pol[si] == pk:
                oldest = _stale_cutoff(tk, prev_t[si], prev_lt[si], stale_frac, fh)
            if not gathered:  # (a failed warm refit gathered this window: continuing, no cutoff)
                n = _gather(sae, wf, wi, base, xk, yk, tk, width, rows, fh, oldest)
            gathered = False
            big = 0
            for i in range(n):
                big = max(big, abs(wi[_IT, i]))
            ok, a, b = _fit_points(wf, wi, n, n * big < _EXACT_SUM, _event_key(seed, g0 + k), delta, thr_us,
                                   thr_rel, max_trials, stop_prob, log_fail, min_points, min_inliers, intercept,
                                   fallback, gap_ratio, on_plane, jump_check, noise, ls_first)
            if refine is not None:
                if ok:
                    a, b, ra, rb = _refine(sae, wf, wi, n, base, xk, yk, tk, width, rows, fh, half, oldest, a, b,
                                           delta, ring_us, ring_rel, intercept, curv)
                    refined = True
            if not trial:
                break
            trial = False
            lt_fit = math.sqrt(a * a + b * b)
            if ok and t_ev - prev_t[si] <= burst * lt_fit and (span <= 0.0 or t_ev - tk <= span * lt_fit):
                cont = True  # the continuation fits and its own lifetime covers the gap: keep it
                break
        if noise is not None:
            # noise rule (module _noise_kernels): the lifetime agrees with the inlier pixels' own estimates
            agree = noise[_AGREE]
            if ok and agree > 0.0 and not reused:
                ok = _lifetime_agrees(wf, wi, n, _DX, _DY, _INL, _CA, prev_lt, base, xk, yk, width,
                                      math.sqrt(a * a + b * b), agree)
            # passage gap: a new burst's lifetime is below the time since the pixel's previous same-polarity event
            gap_k = noise[_PASSAGE_GAP]
            if ok and gap_k > 0.0 and fresh and prev_pol[si] == pk:
                ok = math.sqrt(a * a + b * b) <= gap_k * float(t_ev - prev_t[si])
        if use_fits and not reused:
            # burst reuse: an estimate stores its plane and counts, unless it is the fallback's or has
            # fewer than reuse_inliers inliers (current event included; the fit's window, the ring aside)
            keep_fit = ok and (warm or wi[_CV, _FB] == 0)
            if keep_fit and reuse_inliers > 0:
                if not warm:
                    n_inl = 1
                    for i in range(n):
                        n_inl += wi[_INL, i]
                keep_fit = n_inl >= reuse_inliers
            fits[fs] = a if keep_fit else np.nan
            fits[fs + 1] = b if keep_fit else np.nan
            if cont:
                fits[fs + 2] += 1.0 if keep_fit else 0.0
            else:
                fits[fs + 2] = 1.0 if keep_fit else 0.0
        # border rule: the fit still feeds the burst state below, but is not reported
        # start-up rule (t_start > _NEVER): likewise while the window's history is too short for the plane
        if ok and (xk < border or y[k] < border or xk >= width - border or y[k] >= height - border
                   or _history_short(tk, ra if refined else a, rb if refined else b, reach_px, t_start)):
            out_lt[j] = math.sqrt(a * a + b * b)
            out_vx[j] = np.nan
            out_vy[j] = np.nan
            out_valid[j] = False
        elif ok:
            g2 = a * a + b * b
            out_lt[j] = math.sqrt(g2)
            out_vx[j] = a / g2 * 1e6
            out_vy[j] = b / g2 * 1e6
            out_valid[j] = True
        else:
            out_lt[j] = np.nan
            out_vx[j] = np.nan
            out_vy[j] = np.nan
            out_valid[j] = False
        prev_t[si] = t_ev
        # start-up rule: an event without estimate inside a burst keeps the burst's lifetime
        if ok or not (startup and cont):
            prev_lt[si] = out_lt[j]
        if not out_valid[j]:
            out_lt[j] = np.nan  # a border event's lifetime was kept above only for its burst state
        prev_pol[si] = pk
        if publish and (y[k] < own_lo + half or y[k] >= own_hi - half):  # only neighbours' halos read it
            dec_lt[k] = prev_lt[si]
            _store_release(dec, k, 2 if cont else 1)
    return idx.shape[0]


@njit(cache=True)
def _fit_windows(win, side, seed, g0, delta, thr_us, thr_rel, max_trials, stop_prob, min_points,
                 min_inliers, intercept, fallback, out_a, out_b, out_ok, out_inl, gap_ratio, on_plane, jump_check,
                 noise, ls_first):
    """:func:`_fit_points` on flat windows ``win`` (k * side * side, NaN = never fired).

    Window ``w`` uses the random stream of global index ``g0 + w``. ``out_inl`` gets the
    inlier mask per window cell (the centre, the current event, is an inlier when ok).
    """
    nn = side * side
    c = nn // 2
    half = side // 2
    wf, wi = _scratch(nn)
    cell = np.empty(nn, np.int64)
    log_fail = _log_fail(stop_prob)
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
            wf[_DX, n] = q % side - half
            wf[_DY, n] = q // side - half
            wf[_DT, n] = v - tc
            cell[n] = q
            n += 1
        # float times: 2-means sums them in float64 (exact=False)
        ok, a, b = _fit_points(wf, wi, n, False, _event_key(seed, g0 + w), delta, thr_us, thr_rel,
                               max_trials, stop_prob, log_fail, min_points, min_inliers, intercept, fallback,
                               gap_ratio, on_plane, jump_check, noise, ls_first)
        out_ok[w] = ok
        out_a[w] = a
        out_b[w] = b
        for q in range(nn):
            out_inl[off + q] = False
        if ok:
            out_inl[off + c] = True
            for i in range(n):
                if wi[_INL, i] == 1:
                    out_inl[off + cell[i]] = True
