"""The ring refit (``IntraParams.refine_window``): slow reference, known answers, strips, chunks, errors."""

from dataclasses import replace

import numpy as np
import pytest

from evedge.detector.intra import IntraParams, IntraPixelLifetime, estimate_lifetimes, noise_params, robust_params
from evedge.events import SensorSize, make_events

from .test_intra import assert_lifetimes_close, ref_stream


def _jittered_edge(edge_events, size, jitter_frac, rng=0):
    """A straight edge crossing ``size`` twice, timestamps jittered by ``jitter_frac`` lifetimes."""
    return edge_events(size.width, size.height, 400.0, 0.35, n_edges=2, spacing_px=20, jitter_frac=jitter_frac,
                       rng=rng)


@pytest.mark.parametrize("preset", [robust_params, noise_params])
@pytest.mark.parametrize("tolerance", [1.0, 0.3])
def test_ring_refit_matches_the_reference(edge_events, random_events, preset, tolerance):
    """Kernel = slow reference (dict SAE, numpy least squares) on a jittered edge and on random events,
    the ring's threshold the fit's (1) or a fraction of it (refine_tolerance)."""
    size = SensorSize(16, 12)
    p = preset(refine_window=7, min_points=4, min_inliers=4, seed=3, refine_tolerance=tolerance)
    ev, _ = _jittered_edge(edge_events, size, 0.05)
    got = estimate_lifetimes(ev, size, p)
    assert_lifetimes_close(got, ref_stream(ev, size, p))
    assert got["valid"].mean() > 0.5
    noise = random_events(500, 9, 7, duration_us=30_000, rng=4)
    assert_lifetimes_close(estimate_lifetimes(noise, SensorSize(9, 7), p), ref_stream(noise, SensorSize(9, 7), p))


def test_ring_refit_reduces_timing_noise_keeps_decisions(edge_events):
    """On a straight edge with timing jitter the ring's points lie on the same plane: the median lifetime
    error falls (here by more than a third). The ring itself makes or removes no estimate; the rules that
    read the lifetime (burst grouping, start-up reach) may decide a few events differently."""
    size = SensorSize(30, 24)
    ev, lifetime = _jittered_edge(edge_events, size, 0.06, rng=1)
    ring_p = robust_params()  # refine_window 9
    assert ring_p.refine_window == 9
    plain = ref_stream(ev, size, replace(ring_p, refine_window=0, curvature_f=0.0))  # the reference: no new kernel variant
    ring = estimate_lifetimes(ev, size, ring_p)
    err = {k: np.nanmedian(np.abs(r["lifetime_us"][r["valid"]] / lifetime - 1)) for k, r in (("5", plain),
                                                                                        ("9", ring))}
    assert err["9"] < 0.65 * err["5"], err
    assert np.mean(ring["valid"] == plain["valid"]) > 0.98


def test_ring_refit_exact_plane_is_unchanged(edge_events):
    """Without jitter every ring point is on the plane: the slopes are the fit's, to the timestamps'
    rounding to 1 us (relative 1.25e-4 of the 4 ms lifetime per point)."""
    size = SensorSize(30, 24)
    ev, lifetime = edge_events(size.width, size.height, 250.0, 0.3, n_edges=1)
    b = estimate_lifetimes(ev, size, robust_params(refine_window=7))
    a = ref_stream(ev, size, robust_params(refine_window=0))
    assert np.mean(a["valid"] == b["valid"]) > 0.99
    v = a["valid"] & b["valid"]
    assert v.sum() > 300
    np.testing.assert_allclose(b["lifetime_us"][v], a["lifetime_us"][v], rtol=2e-4)
    np.testing.assert_allclose(b["lifetime_us"][v], lifetime, rtol=3e-4)


@pytest.mark.parametrize("n_tiles", [2, 3])
def test_ring_refit_strips_and_chunks_equal_one_shot(edge_events, random_events, n_tiles):
    """The strips' halo is the ring's radius: any strip count and any chunking give the serial bytes."""
    size = SensorSize(24, 20)
    ev, _ = _jittered_edge(edge_events, size, 0.08, rng=2)
    noise = random_events(1500, size.width, size.height, duration_us=int(ev["t"][-1]), rng=5)
    ev = np.sort(np.concatenate([ev, noise]), order="t", kind="stable")
    assert_strips_and_chunks_equal(ev, size, noise_params(refine_window=9), (n_tiles,))


def assert_strips_and_chunks_equal(ev, size, p, tile_counts):
    """``n_tiles`` strips (each count) and 7 chunks give the one-shot bytes (with estimates to compare)."""
    want = estimate_lifetimes(ev, size, p)
    assert want["valid"].sum() > 100
    for n_tiles in tile_counts:
        np.testing.assert_array_equal(estimate_lifetimes(ev, size, p, n_tiles=n_tiles).view(np.uint8),
                                      want.view(np.uint8))
    est = IntraPixelLifetime(size, p)
    parts = [est.process(c) for c in np.array_split(ev, 7)]
    np.testing.assert_array_equal(np.concatenate(parts).view(np.uint8), want.view(np.uint8))


@pytest.mark.parametrize("value", [5, 3, 6, -1, 2.5])
def test_bad_refine_window_is_a_clear_error(value):
    with pytest.raises((ValueError, TypeError), match="refine_window"):
        IntraParams(refine_window=value)


def test_presets_keep_the_ring_around_a_larger_window():
    assert robust_params().refine_window == 9 and noise_params().refine_window == 9
    assert robust_params(window_size=7).refine_window == 11
    assert noise_params(window_size=3).refine_window == 7
    assert robust_params(window_size=7, refine_window=0).refine_window == 0
    with pytest.raises(ValueError, match="refine_window"):
        robust_params(refine_window=5)


def test_refine_tolerance_selects_ring_points(edge_events):
    """A tighter ring threshold changes the refits (fewer ring points join) and not the decisions; at 1 it
    is the option's absence; out of (0, 1] it is a clear error naming the field."""
    size = SensorSize(30, 24)
    ev, _ = _jittered_edge(edge_events, size, 0.06, rng=1)
    full = estimate_lifetimes(ev, size, robust_params())
    assert estimate_lifetimes(ev, size, robust_params(refine_tolerance=1.0)).tobytes() == full.tobytes()
    tight = estimate_lifetimes(ev, size, robust_params(refine_tolerance=0.2))
    both = full["valid"] & tight["valid"]
    assert both.mean() > 0.5 and not np.array_equal(full["lifetime_us"][both], tight["lifetime_us"][both])
    for bad in (0.0, -1.0, 1.5, float("nan")):
        with pytest.raises(ValueError, match="refine_tolerance"):
            IntraParams(refine_tolerance=bad)
    with pytest.raises(TypeError, match="refine_tolerance"):
        IntraParams(refine_tolerance="0.5")


# ---- curvature (IntraParams.curvature_f) ---------------------------------------------------------


def _curved_front(size, speed_px_s=500.0, k=0.02):
    """Every pixel fires once when the front ``x + k x y = speed t`` reaches it: a time surface
    ``t = (x + k x y) / speed`` whose gradient turns along the edge (as a rotating edge's does)."""
    yy, xx = np.mgrid[0:size.height, 0:size.width]
    t_us = np.round(1e6 * (xx + k * xx * yy) / speed_px_s).astype(np.int64) + 1000
    order = np.argsort(t_us.ravel(), kind="stable")
    ev = make_events(xx.ravel()[order], yy.ravel()[order], t_us.ravel()[order], np.ones(order.size, bool))
    gx = 1e6 * (1 + k * ev["y"]) / speed_px_s
    gy = 1e6 * k * ev["x"] / speed_px_s
    return ev, np.hypot(gx, gy)


@pytest.mark.parametrize("intercept", [True, False])
def test_curvature_matches_the_reference(edge_events, random_events, intercept):
    """Kernel = slow reference (numpy least squares of the quadratic, the same F test) on a curved front, a
    jittered edge and random events, with and without the refit's free offset."""
    size = SensorSize(16, 12)
    p = noise_params(refine_window=7, min_points=4, min_inliers=4, seed=3, curvature_f=2.0,
                     refit_intercept=intercept)
    for ev in (_curved_front(size)[0], _jittered_edge(edge_events, size, 0.05)[0]):
        got = estimate_lifetimes(ev, size, p)
        assert_lifetimes_close(got, ref_stream(ev, size, p))
        assert got["valid"].mean() > 0.3
    noise = random_events(500, 9, 7, duration_us=30_000, rng=4)
    assert_lifetimes_close(estimate_lifetimes(noise, SensorSize(9, 7), p), ref_stream(noise, SensorSize(9, 7), p))


def test_curvature_gives_the_slopes_at_the_event():
    """On a curved time surface the plane through the past points gives the slopes at their centroid, behind
    the event; the quadratic gives them at the event: the known gradient."""
    size = SensorSize(30, 24)
    ev, truth = _curved_front(size)
    p = robust_params(startup_reach=0.0, refit_intercept=False, curvature_f=4.0)  # the presets' kernel types
    quad = estimate_lifetimes(ev, size, p)
    plane = ref_stream(ev, size, replace(p, curvature_f=0.0))  # the reference: no new kernel variant
    inner = (ev["x"] >= 6) & (ev["x"] < size.width - 4) & (ev["y"] >= 4) & (ev["y"] < size.height - 4)
    v = inner & plane["valid"] & quad["valid"]
    assert v.sum() > 150
    err_plane = np.abs(plane["lifetime_us"][v] / truth[v] - 1)
    err_quad = np.abs(quad["lifetime_us"][v] / truth[v] - 1)
    # the timestamps 2000 x + 40 x y us are integers: exactly on the quadratic, whose slopes are then exact
    assert np.max(err_quad) < 1e-9 and np.median(err_plane) > 5e-3, (np.max(err_quad), np.median(err_plane))


def test_curvature_leaves_the_start_up_rule_to_the_plane():
    """The start-up rule judges the window's history with the plane on the refit's points, as it was measured:
    on a curved front (one event per pixel, no burst) the quadratic changes the lifetimes, not which events the
    rule lets through."""
    size = SensorSize(30, 24)
    ev, _ = _curved_front(size, speed_px_s=200.0)
    p = robust_params(curvature_f=4.0)
    assert p.startup_reach > 0
    quad = estimate_lifetimes(ev, size, p)
    plane = ref_stream(ev, size, replace(p, curvature_f=0.0))  # the reference: no new kernel variant
    np.testing.assert_array_equal(quad["valid"], plane["valid"])
    assert 0.2 < quad["valid"].mean() < 0.9  # the rule refuses the first columns' events, not all
    v = quad["valid"]
    assert not np.allclose(quad["lifetime_us"][v], plane["lifetime_us"][v], rtol=1e-3)


def test_curvature_keeps_a_plane_and_the_strips(edge_events, random_events):
    """A straight edge without jitter prefers no quadratic (the same slopes as without the option, to rounding);
    strips and chunks give the serial bytes with the option on."""
    size = SensorSize(30, 24)
    ev, lifetime = edge_events(size.width, size.height, 250.0, 0.3, n_edges=1)
    a = estimate_lifetimes(ev, size, robust_params())
    b = estimate_lifetimes(ev, size, robust_params(curvature_f=16.0))
    v = a["valid"] & b["valid"]
    assert v.sum() > 300 and np.mean(a["valid"] == b["valid"]) > 0.99
    np.testing.assert_allclose(b["lifetime_us"][v], lifetime, rtol=5e-4)
    size = SensorSize(24, 20)
    ev, _ = _jittered_edge(edge_events, size, 0.08, rng=2)
    noise = random_events(1500, size.width, size.height, duration_us=int(ev["t"][-1]), rng=5)
    ev = np.sort(np.concatenate([ev, noise]), order="t", kind="stable")
    assert_strips_and_chunks_equal(ev, size, noise_params(curvature_f=4.0), (2, 3))


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf")])
def test_bad_curvature_is_a_clear_error(bad):
    with pytest.raises(ValueError, match="curvature_f"):
        robust_params(curvature_f=bad)
    with pytest.raises(ValueError, match="curvature_f.*refine_window"):
        IntraParams(curvature_f=4.0)
    with pytest.raises(TypeError, match="curvature_f"):
        robust_params(curvature_f="4")
