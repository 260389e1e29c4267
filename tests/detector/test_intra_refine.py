"""The ring refit (``IntraParams.refine_window``): slow reference, known answers, strips, chunks, errors."""

from dataclasses import replace

import numpy as np
import pytest

from evedge.detector.intra import IntraParams, IntraPixelLifetime, estimate_lifetimes, noise_params, robust_params
from evedge.events import SensorSize

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
    plain = ref_stream(ev, size, replace(ring_p, refine_window=0))  # the reference: no new kernel variant
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
    p = noise_params(refine_window=9)
    want = estimate_lifetimes(ev, size, p)
    assert want["valid"].sum() > 100
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
