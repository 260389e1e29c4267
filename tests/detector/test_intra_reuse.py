"""Burst reuse (``IntraParams.burst_reuse``): slow reference, known answers, strips, chunks, errors."""

from dataclasses import replace

import numpy as np
import pytest

from evedge.detector.intra import IntraParams, IntraPixelLifetime, estimate_lifetimes, noise_params, robust_params
from evedge.events import SensorSize

from .test_intra import assert_lifetimes_close, ref_stream


def _bursty_edges(edge_events, size, speed_px_s, jitter_frac, *, n_passages=2, rng=0):
    """Straight edges whose every passage fires three events per pixel, 0.2 lifetimes apart (a burst)."""
    parts = []
    for k in range(n_passages):
        ev, lifetime = edge_events(size.width, size.height, speed_px_s, 0.3, n_edges=3, spacing_px=0.2,
                                   jitter_frac=jitter_frac, rng=rng + k)
        ev["t"] += int(k * 14 * lifetime)
        parts.append(ev)
    return np.sort(np.concatenate(parts), order="t", kind="stable"), lifetime


def _edge_with_noise(edge_events, random_events, size, jitter_frac, n_noise, rng=0):
    """Bursty jittered edges and uniform background events, in time order."""
    ev, lifetime = _bursty_edges(edge_events, size, 300.0, jitter_frac, rng=rng)
    noise = random_events(n_noise, size.width, size.height, duration_us=int(ev["t"][-1]), rng=rng + 7)
    return np.sort(np.concatenate([ev, noise]), order="t", kind="stable"), lifetime


@pytest.mark.parametrize("reuse", [1, 2, 3])
@pytest.mark.parametrize("preset", [robust_params, noise_params,
                                    lambda **kw: IntraParams(burst_lifetimes=2.0, burst_startup=True, **kw)])
def test_reuse_matches_the_reference(edge_events, random_events, preset, reuse):
    """Kernel = slow reference (dict SAE, dicts of burst planes and counts) on jittered edges with noise."""
    size = SensorSize(18, 14)
    p = preset(burst_reuse=reuse, min_points=4, min_inliers=4, seed=3)
    ev, _ = _edge_with_noise(edge_events, random_events, size, 0.05, 300)
    got = estimate_lifetimes(ev, size, p)
    assert_lifetimes_close(got, ref_stream(ev, size, p))
    assert got["valid"].mean() > 0.3
    plain = estimate_lifetimes(ev, size, replace(p, burst_reuse=0))
    assert got.tobytes() != plain.tobytes()  # the events reuse reaches are many here
