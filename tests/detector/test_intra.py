"""Intra-pixel-area RANSAC: kernels against slow references, analytic edges, streaming, errors."""

import math

import numpy as np
import pytest

from evedge.detector.intra import IntraParams, IntraPixelLifetime, estimate_lifetimes, fit_window, fit_windows
from evedge.detector.result import LIFETIME_DTYPE
from evedge.events import EVENT_DTYPE, SensorSize, make_events

M64 = (1 << 64) - 1


# ---- slow references -------------------------------------------------------------------------


def mix(z):
    z = (z + 0x9E3779B97F4A7C15) & M64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & M64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & M64
    return z ^ (z >> 31)


def draw(seed, g, counter):
    key = mix(seed ^ mix(g))
    return mix((key + counter) & M64)


def ref_two_means(dts):
    """Labels (True = the current event's cluster) of the past points ``dts``; current = 0."""
    c0 = min([0.0] + list(dts))
    c1 = 0.0
    if c0 == c1:
        return [True] * len(dts)
    labels = [None] * len(dts)
    cur = None
    for _ in range(100):
        lc = 1 if abs(0.0 - c1) <= abs(0.0 - c0) else 0
        changed = lc != cur
        cur = lc
        groups = {0: [], 1: []}
        groups[lc].append(0.0)
        for i, v in enumerate(dts):
            li = 1 if abs(v - c1) <= abs(v - c0) else 0
            changed |= li != labels[i]
            labels[i] = li
            groups[li].append(v)
        if not changed:
            break
        if groups[0]:
            c0 = sum(groups[0]) / len(groups[0])  # same summation order as the kernel
        if groups[1]:
            c1 = sum(groups[1]) / len(groups[1])
    return [lab == cur for lab in labels]


def ref_fit(points, p: IntraParams, seed, g, delta):
    """points: list of (dx, dy, dt). Returns (ok, a, b, inlier flags of the points)."""
    kept = ref_two_means([q[2] for q in points])
    res = ref_ransac(points, kept, p, seed, g, delta)
    if res == "degenerate" and p.fallback_all_points:
        res = ref_ransac(points, [True] * len(points), p, seed, g, delta)
    if isinstance(res, str):
        return False, math.nan, math.nan, [False] * len(points)
    return res


def ref_ransac(points, kept, p, seed, g, delta):
    idx = [i for i, k in enumerate(kept) if k]
    m = len(idx)
    if m < 2 or m + 1 < p.min_points:
        return "degenerate"
    best = None  # (count, cost, a, b, flags)
    trials = p.max_trials
    k = 0
    while k < trials:
        pi = draw(seed, g, 2 * k) % m
        pj = draw(seed, g, 2 * k + 1) % (m - 1)
        if pj >= pi:
            pj += 1
        k += 1
        (xi, yi, ti), (xj, yj, tj) = points[idx[pi]], points[idx[pj]]
        det = xi * yj - xj * yi
        if det == 0:
            continue
        a = (ti * yj - tj * yi) / det
        b = (xi * tj - xj * ti) / det
        thr = p.inlier_threshold_us + p.inlier_threshold_rel * math.sqrt(a * a + b * b)
        flags = [False] * len(points)
        cnt, cost = 1, 0.0
        for u in idx:
            x, y, t = points[u]
            r = max(0.0, abs(t - (a * x + b * y)) - delta * (abs(a) + abs(b)))
            if r <= thr:
                flags[u] = True
                cnt += 1
                cost += r
        if best is None or cnt > best[0] or (cnt == best[0] and cost < best[1]):
            best = (cnt, cost, a, b, flags)
            if p.stop_probability < 1.0:
                w = (cnt - 1) / m
                if w >= 1.0:
                    trials = k
                elif 1.0 - w * w < 1.0:
                    trials = min(trials, math.ceil(math.log(1.0 - p.stop_probability) / math.log(1.0 - w * w)))
    if best is None:
        return "degenerate"
    if best[0] < p.min_inliers:
        return "few inliers"
    cnt, _, a, b, flags = best
    pts = [(0.0, 0.0, 0.0)] + [points[u] for u in idx if flags[u]]
    X = np.array([[q[0], q[1]] for q in pts], float)
    T = np.array([q[2] for q in pts], float)
    if p.refit_intercept:
        X = X - X.mean(0)
        T = T - T.mean()
    sol, *_ = np.linalg.lstsq(X, T, rcond=None)
    a, b = sol
    if a * a + b * b == 0:
        return "flat"
    return True, float(a), float(b), flags


def ref_stream(events, size, p: IntraParams):
    """Whole estimator on a list of events with a dict SAE."""
    sae = {}
    prev = {}  # (plane, x, y) -> (time, lifetime or nan, polarity) of the pixel's previous event
    half = p.window_size // 2
    out = []
    for g, e in enumerate(events):
        x, y, t, pol = int(e["x"]), int(e["y"]), int(e["t"]), bool(e["p"])
        plane = pol if p.per_polarity else 0
        t_ev = t
        pt, plt, ppol = prev.get((plane, x, y), (0, math.nan, None))
        if p.burst_lifetimes > 0 and ppol == pol and t - pt <= p.burst_lifetimes * plt:
            t = sae[(plane, x, y)]  # same burst: fitted at the burst's first time
        else:
            sae[(plane, x, y)] = t
        pts = []
        for oy in range(-half, half + 1):
            for ox in range(-half, half + 1):
                q = (plane, x + ox, y + oy)
                if (ox or oy) and 0 <= x + ox < size.width and 0 <= y + oy < size.height and q in sae:
                    pts.append((float(ox), float(oy), float(sae[q] - t)))
        ok, a, b, _ = ref_fit(pts, p, p.seed, g, p.delta_px)
        if ok:
            g2 = a * a + b * b
            out.append((math.sqrt(g2), a / g2 * 1e6, b / g2 * 1e6, True))
        else:
            out.append((math.nan, math.nan, math.nan, False))
        prev[(plane, x, y)] = (t_ev, out[-1][0], pol)
    return np.array(out, dtype=LIFETIME_DTYPE)


def assert_lifetimes_close(got, want):
    np.testing.assert_array_equal(got["valid"], want["valid"])
    for name in ("lifetime_us", "vx_px_s", "vy_px_s"):
        np.testing.assert_allclose(got[name], want[name], rtol=1e-9, atol=1e-9, equal_nan=True)


def random_windows(n, side, rng):
    """Noisy planes with outliers, never-fired pixels and tied (integer) timestamps."""
    rng = np.random.default_rng(rng)
    out = np.empty((n, side, side))
    h = side // 2
    ys, xs = np.mgrid[-h : h + 1, -h : h + 1]
    for k in range(n):
        a, b = rng.normal(0, 1000, 2)
        w = a * xs + b * ys + rng.normal(0, rng.choice([1, 50, 300]), xs.shape)
        w[rng.random(xs.shape) < 0.15] -= rng.uniform(0, 20_000)
        w = np.round(w / rng.choice([1, 100])) * rng.choice([1, 100])
        w[rng.random(xs.shape) < 0.2] = np.nan
        w[h, h] = np.nanmax(w) if rng.random() < 0.8 else 0.0
        out[k] = w
    out[0] = np.nan  # too few points
    out[0, h, h], out[0, h, h - 1], out[0, h - 1, h] = 5.0, 3.0, 2.0
    out[1] = 7.0  # all tied: flat plane
    return out


# ---- kernels against references --------------------------------------------------------------


@pytest.mark.parametrize("side", [3, 5, 7])
@pytest.mark.parametrize(
    "params",
    [IntraParams(), IntraParams(stop_probability=1.0, max_trials=7, min_inliers=3, min_points=3,
                                fallback_all_points=False),
     IntraParams(refit_intercept=False, inlier_threshold_rel=0.0, inlier_threshold_us=200.0)],
)
def test_fit_windows_matches_reference(side, params):
    if params.min_inliers > side * side:
        pytest.skip("window too small")
    windows = random_windows(150, side, rng=side)
    for use_intra in (True, False):
        a, b, ok, inl = fit_windows(windows, params, use_intra=use_intra, seed=11)
        n_ok = 0
        for k, w in enumerate(windows):
            h = side // 2
            cells = [(yy, xx) for yy in range(side) for xx in range(side) if (yy, xx) != (h, h) and not np.isnan(w[yy, xx])]
            pts = [(float(xx - h), float(yy - h), float(w[yy, xx] - w[h, h])) for yy, xx in cells]
            rok, ra, rb, flags = ref_fit(pts, params, 11, k, params.delta_px if use_intra else 0.0)
            assert ok[k] == rok, k
            if rok:
                n_ok += 1
                np.testing.assert_allclose([a[k], b[k]], [ra, rb], rtol=1e-9, atol=1e-6)
                want = np.zeros((side, side), bool)
                want[h, h] = True
                for (yy, xx), f in zip(cells, flags):
                    want[yy, xx] = f
                np.testing.assert_array_equal(inl[k], want)
            else:
                assert not inl[k].any() and np.isnan(a[k])
        assert 0 < n_ok < len(windows)


def test_two_means_reference_properties():
    # an old cluster is separated from the current one; ties join the current cluster
    assert ref_two_means([-10_000.0, -9_900.0, -100.0, -50.0]) == [False, False, True, True]
    assert ref_two_means([-10.0, -5.0]) == [False, True]  # -5 is equidistant from -10 and 0 initially
    assert ref_two_means([0.0, 0.0]) == [True, True]


@pytest.mark.parametrize("per_polarity", [True, False])
def test_stream_matches_reference(random_events, per_polarity):
    size = SensorSize(9, 7)
    ev = random_events(400, size.width, size.height, duration_us=30_000, rng=3)
    params = IntraParams(per_polarity=per_polarity, min_inliers=4, min_points=4, seed=5)
    got = estimate_lifetimes(ev, size, params)
    want = ref_stream(ev, size, params)
    assert_lifetimes_close(got, want)
    assert 0 < want["valid"].sum() < want.size


def test_stream_matches_reference_on_noisy_edge(edge_events):
    size = SensorSize(10, 10)
    ev, _ = edge_events(10, 10, 300, 0.4, n_edges=2, spacing_px=6, jitter_frac=0.1, subpixel_px=0.25, rng=2)
    params = IntraParams()
    assert_lifetimes_close(estimate_lifetimes(ev, size, params), ref_stream(ev, size, params))


def burst_edge(edge_events, size, speed, angle, n_burst=3, **kw):
    """An edge whose pixels fire ``n_burst`` events each, at sub-pixel edge positions
    ``(k + 0.5) / n - 0.5`` px from their centre (as a multi-threshold edge does)."""
    ev, tau = edge_events(size.width, size.height, speed, angle, **kw)
    parts = []
    for k in range(n_burst):
        e = ev.copy()
        e["t"] += int(round(((k + 0.5) / n_burst - 0.5) * tau + tau))
        parts.append(e)
    ev = np.concatenate(parts)
    return ev[np.argsort(ev["t"], kind="stable")], tau


@pytest.mark.parametrize("per_polarity", [True, False])
def test_stream_matches_reference_on_bursts(edge_events, per_polarity):
    size = SensorSize(10, 9)
    ev, _ = burst_edge(edge_events, size, 400, 0.3, n_edges=2, spacing_px=5, jitter_frac=0.05, rng=4)
    # a few flipped polarities: a burst only continues with its own polarity
    ev["p"] = np.random.default_rng(1).random(ev.size) < 0.9
    params = IntraParams(per_polarity=per_polarity, min_inliers=4, min_points=4)
    got = estimate_lifetimes(ev, size, params)
    assert_lifetimes_close(got, ref_stream(ev, size, params))
    # burst grouping changed some estimates (both branches of the kernel ran)
    plain = estimate_lifetimes(ev, size, IntraParams(per_polarity=per_polarity, min_inliers=4, min_points=4,
                                                     burst_lifetimes=0.0))
    assert_lifetimes_close(plain, ref_stream(ev, size, IntraParams(per_polarity=per_polarity, min_inliers=4,
                                                                    min_points=4, burst_lifetimes=0.0)))
    assert got.tobytes() != plain.tobytes()
    # the burst state carries across chunks
    est = IntraPixelLifetime(size, params)
    chunked = np.concatenate([est.process(c) for c in np.array_split(ev, 7)])
    assert chunked.tobytes() == got.tobytes()


# ---- analytic cases --------------------------------------------------------------------------


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 45.0])
def test_burst_edge_lifetime(edge_events, angle_deg):
    # 3 events per pixel per edge: the SAE of the paper holds each pixel's last event, so
    # the front of the edge (pixels mid-burst) is early against its past neighbours and
    # the slope comes out ~20 % short; burst grouping restores the exact lifetime
    size = SensorSize(20, 20)
    ev, tau = burst_edge(edge_events, size, 200.0, np.deg2rad(angle_deg))
    inner = (ev["x"] >= 2) & (ev["x"] < 18) & (ev["y"] >= 2) & (ev["y"] < 18)
    r = estimate_lifetimes(ev, size)
    v = r["valid"] & inner
    assert v.sum() > 0.95 * inner.sum()
    np.testing.assert_allclose(np.median(r["lifetime_us"][v]), tau, rtol=5e-3)
    # all but the first columns the edge crosses (whose bursts start without any estimate
    # to group them, so their pixels hold their last events)
    assert np.mean(np.abs(r["lifetime_us"][v] / tau - 1) < 0.02) > 0.8
    r0 = estimate_lifetimes(ev, size, IntraParams(burst_lifetimes=0.0))
    assert np.median(r0["lifetime_us"][r0["valid"] & inner]) < 0.9 * tau




@pytest.mark.parametrize("speed", [50.0, 400.0, 3000.0])
@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 45.0, 100.0, 225.0])
def test_straight_edge_lifetime_and_flow(edge_events, speed, angle_deg):
    size = SensorSize(20, 20)
    ang = np.deg2rad(angle_deg)
    ev, tau = edge_events(20, 20, speed, ang)
    r = estimate_lifetimes(ev, size)
    inner = (ev["x"] >= 2) & (ev["x"] < 18) & (ev["y"] >= 2) & (ev["y"] < 18)
    v = r["valid"] & inner
    assert v.sum() > 0.95 * inner.sum()
    # timestamps are rounded to 1 us: allow that much
    np.testing.assert_allclose(r["lifetime_us"][v], tau, rtol=2e-3 + 2.0 / tau)
    np.testing.assert_allclose(r["vx_px_s"][v], speed * np.cos(ang), atol=5e-3 * speed)
    np.testing.assert_allclose(r["vy_px_s"][v], speed * np.sin(ang), atol=5e-3 * speed)


def test_noisy_edge_median_error_is_small(edge_events):
    size = SensorSize(30, 30)
    ev, tau = edge_events(30, 30, 500, 0.5, n_edges=2, jitter_frac=0.02, subpixel_px=0.25, rng=1)
    r = estimate_lifetimes(ev, size)
    rel = np.abs(r["lifetime_us"][r["valid"]] / tau - 1)
    assert r["valid"].mean() > 0.9
    assert np.median(rel) < 0.08
    # the intra-pixel area helps here (more estimates within 10 %)
    r0 = estimate_lifetimes(ev, size, IntraParams(delta_px=0.0))
    good = lambda res: np.mean(res["valid"] & (np.abs(res["lifetime_us"] / tau - 1) < 0.1))  # noqa: E731
    assert good(r) > good(r0)


def test_fit_window_exact_plane_and_ties():
    ys, xs = np.mgrid[-2:3, -2:3]
    w = 1000.0 * xs + 500.0 * ys
    w[w > 0] = np.nan  # pixels the edge has not reached
    w[2, 2] = 0.0
    fit = fit_window(w)
    assert fit.ok and fit.a_us_per_px == pytest.approx(1000) and fit.b_us_per_px == pytest.approx(500)
    assert fit.lifetime_us == pytest.approx(math.hypot(1000, 500))
    # every point of the kept 2-means cluster is an inlier; the oldest cluster is not used
    fired = ~np.isnan(w)
    fired[2, 2] = False
    kept = ref_two_means(list(w[fired]))
    want = np.zeros((5, 5), bool)
    want[fired] = kept
    want[2, 2] = True
    np.testing.assert_array_equal(fit.inliers, want)
    assert 5 <= want.sum() < (~np.isnan(w)).sum()
    # a gross outlier is rejected; old timestamps fall in the other 2-means cluster
    w2 = w.copy()
    w2[0, 0] = -100_000.0
    w2[0, 1] = -2500.0 + 900.0
    fit2 = fit_window(w2, use_intra=False)
    assert fit2.ok and not fit2.inliers[0, 0] and not fit2.inliers[0, 1]
    assert fit2.a_us_per_px == pytest.approx(1000) and fit2.b_us_per_px == pytest.approx(500)
    # all timestamps tied with the current event: flat plane, no estimate
    flat = np.zeros((5, 5))
    assert not fit_window(flat).ok
    # too few points
    few = np.full((5, 5), np.nan)
    few[2, 2], few[2, 1], few[1, 2] = 0.0, -1.0, -1.0
    res = fit_window(few)
    assert not res.ok and math.isnan(res.lifetime_us) and not res.inliers.any()


def test_chunked_equals_one_shot_and_seeds(random_events):
    size = SensorSize(16, 12)
    ev = random_events(3000, size.width, size.height, duration_us=100_000, rng=9)
    want = estimate_lifetimes(ev, size)
    est = IntraPixelLifetime(size)
    got = np.concatenate([est.process(c) for c in np.array_split(ev, 13)])
    assert got.tobytes() == want.tobytes()
    est.reset()
    assert est.process(ev).tobytes() == want.tobytes()
    other = estimate_lifetimes(ev, size, IntraParams(seed=1))
    assert other.tobytes() != want.tobytes()
    assert estimate_lifetimes(ev, size, IntraParams(seed=1)).tobytes() == other.tobytes()


def test_never_fired_is_not_zero_time():
    # an event at t = 0 next to pixels that never fired: a 0 sentinel would create points
    size = SensorSize(7, 7)
    ev = make_events([3, 4, 3, 4, 2], [3, 3, 4, 4, 2], [0, 0, 0, 0, 0], [True] * 5)
    r = estimate_lifetimes(ev, size, IntraParams(min_inliers=3, min_points=3))
    assert not r["valid"].any()


@pytest.mark.parametrize(
    "kwargs, exc, field",
    [
        (dict(window_size=4), ValueError, "window_size"),
        (dict(window_size=1), ValueError, "window_size"),
        (dict(window_size=5.5), TypeError, "window_size"),
        (dict(delta_px=-0.1), ValueError, "delta_px"),
        (dict(delta_px=0.51), ValueError, "delta_px"),
        (dict(inlier_threshold_us=0), ValueError, "inlier_threshold_us"),
        (dict(inlier_threshold_us=float("nan")), ValueError, "inlier_threshold_us"),
        (dict(inlier_threshold_rel=-1), ValueError, "inlier_threshold_rel"),
        (dict(max_trials=0), ValueError, "max_trials"),
        (dict(stop_probability=0), ValueError, "stop_probability"),
        (dict(stop_probability=1.5), ValueError, "stop_probability"),
        (dict(min_points=2), ValueError, "min_points"),
        (dict(min_inliers=26), ValueError, "min_inliers"),
        (dict(seed=-1), ValueError, "seed"),
        (dict(burst_lifetimes=-0.5), ValueError, "burst_lifetimes"),
        (dict(burst_lifetimes=float("inf")), ValueError, "burst_lifetimes"),
        (dict(per_polarity=1), TypeError, "per_polarity"),
        (dict(fallback_all_points=None), TypeError, "fallback_all_points"),
    ],
)
def test_bad_params(kwargs, exc, field):
    with pytest.raises(exc, match=f"IntraParams.{field}"):
        IntraParams(**kwargs)


def test_bad_inputs():
    size = SensorSize(8, 8)
    ev = make_events([1, 2], [1, 1], [0, 5], [True, True])
    with pytest.raises(TypeError, match="events"):
        estimate_lifetimes(ev.astype([("x", "f4"), ("y", "i4"), ("t", "i8"), ("p", "?")]), size)
    with pytest.raises(ValueError, match="outside the sensor"):
        estimate_lifetimes(make_events([8], [0], [0], [True]), size)
    with pytest.raises(ValueError, match="not sorted"):
        estimate_lifetimes(ev[::-1].copy(), size)
    with pytest.raises(TypeError, match="params"):
        estimate_lifetimes(ev, size, params=5)
    est = IntraPixelLifetime(size)
    est.process(ev)
    with pytest.raises(ValueError, match="previous chunk"):
        est.process(make_events([1], [1], [1], [True]))
    assert estimate_lifetimes(np.empty(0, EVENT_DTYPE), size).dtype == LIFETIME_DTYPE
    with pytest.raises(ValueError, match="centre"):
        fit_window(np.full((5, 5), np.nan))
    with pytest.raises(ValueError, match="odd"):
        fit_window(np.zeros((4, 4)))
    with pytest.raises(ValueError, match="shape"):
        fit_window(np.zeros((5, 3)))
    with pytest.raises(ValueError, match="infinite"):
        w = np.zeros((5, 5))
        w[0, 0] = -np.inf
        fit_window(w)


def test_seed_range_is_a_clear_error_everywhere():
    """Regression: a seed beyond float range escaped as numpy's isfinite TypeError, and fit_windows
    accepted seeds in [2**63, 2**64) that IntraParams refuses."""
    w = np.add.outer(np.arange(5.0) * 100, np.arange(5.0) * 50)
    for seed in (2**63, 2**64, 2**70):
        with pytest.raises(ValueError, match=r"IntraParams.seed must be < 2\*\*63"):
            IntraParams(seed=seed)
        with pytest.raises(ValueError, match=r"fit_windows.seed must be < 2\*\*63"):
            fit_window(w, seed=seed)
    assert fit_window(w, seed=2**63 - 1).ok
    with pytest.raises(TypeError, match="window_t_us: expected numbers"):
        fit_window([["a", "b", "c"]] * 3)
    with pytest.raises(TypeError, match="windows: expected numbers"):
        fit_windows([[["a"] * 3] * 3])
