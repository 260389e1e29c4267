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


#: (burst_reuse, burst_warm_refit, burst_reuse_inliers): plain reuse, warm refits without floor, the two neutral
#: settings of the module notes (full refits, warm refits, with the default floor)
SETTINGS = [(1, True, 0), (2, True, 0), (3, False, 8), (2, True, 8)]


def _reuse(k, warm, inliers):
    return dict(burst_reuse=k, burst_warm_refit=warm, burst_reuse_inliers=inliers)


def _startup_only(**kw):
    return IntraParams(burst_lifetimes=2.0, burst_startup=True, **kw)


@pytest.mark.parametrize("preset, setting", [(noise_params, s) for s in SETTINGS]
                         + [(_startup_only, s) for s in SETTINGS] + [(robust_params, SETTINGS[1])])
def test_reuse_matches_the_reference(edge_events, random_events, preset, setting):
    """Kernel = slow reference (dict SAE, dicts of burst planes and counts) on jittered edges with noise."""
    size = SensorSize(18, 14)
    p = preset(**_reuse(*setting), min_points=4, min_inliers=4, seed=3)
    ev, _ = _edge_with_noise(edge_events, random_events, size, 0.05, 300)
    got = estimate_lifetimes(ev, size, p)
    assert_lifetimes_close(got, ref_stream(ev, size, p))
    assert got["valid"].mean() > 0.3
    plain = estimate_lifetimes(ev, size, replace(p, burst_reuse=0))
    assert got.tobytes() != plain.tobytes()  # the events reuse reaches are many here


def _pairs_in_bursts(ev, size, lt):
    """Index pairs (earlier, next) of consecutive events of a pixel less than one estimated lifetime apart."""
    key = ev["y"].astype(np.int64) * size.width + ev["x"]
    order = np.lexsort((np.arange(ev.size), key))  # each pixel's events in time order
    same_pixel = key[order][1:] == key[order][:-1]
    first, then = order[:-1][same_pixel], order[1:][same_pixel]
    close = (ev["t"][then] - ev["t"][first]) < lt["lifetime_us"][first]  # inside the burst (1 lifetime)
    return first[close], then[close]


def test_continuing_events_take_the_bursts_plane(edge_events):
    """Known answer (``burst_reuse = 1``, no inlier floor): inside a burst the lifetime and flow are the burst's first fit's, bit for
    bit; without reuse they are refitted and differ."""
    size = SensorSize(30, 24)
    ev, _ = _bursty_edges(edge_events, size, 150.0, 0.04, rng=1)
    p = robust_params(burst_reuse=1, burst_reuse_inliers=0)
    on, off = estimate_lifetimes(ev, size, p), estimate_lifetimes(ev, size, replace(p, burst_reuse=0))
    first, then = _pairs_in_bursts(ev, size, on)
    both = on["valid"][first] & on["valid"][then]
    assert both.sum() > 50
    np.testing.assert_array_equal(on["lifetime_us"][then][both], on["lifetime_us"][first][both])
    np.testing.assert_array_equal(on["vx_px_s"][then][both], on["vx_px_s"][first][both])
    both_off = off["valid"][first] & off["valid"][then]
    assert np.mean(off["lifetime_us"][then][both_off] != off["lifetime_us"][first][both_off]) > 0.5


def test_warm_refits_then_reuse(edge_events):
    """Known answer (``burst_reuse = 2``, warm, no inlier floor): a burst's second event is refitted (its plane differs from the
    first's), the third takes the second's plane bit for bit."""
    size = SensorSize(30, 24)
    ev, _ = _bursty_edges(edge_events, size, 150.0, 0.04, rng=1)
    on = estimate_lifetimes(ev, size, robust_params(burst_reuse=2, burst_reuse_inliers=0))
    first, then = _pairs_in_bursts(ev, size, on)
    second = np.isin(first, then)  # pairs (second event, third event) of a burst
    pair = on["valid"][first] & on["valid"][then]
    take = pair & second
    assert take.sum() > 50 and (pair & ~second).sum() > 50
    np.testing.assert_array_equal(on["lifetime_us"][then][take], on["lifetime_us"][first][take])
    refit = pair & ~second  # (first event, second event): the warm refit moved the plane
    assert np.mean(on["lifetime_us"][then][refit] != on["lifetime_us"][first][refit]) > 0.5


def test_reuse_is_off_without_bursts(edge_events):
    """``burst_lifetimes = 0``: no event continues a burst, so reuse changes no byte."""
    size = SensorSize(20, 16)
    ev, _ = _bursty_edges(edge_events, size, 250.0, 0.03, rng=2)
    p = IntraParams(burst_lifetimes=0.0, min_inliers=4)
    for setting in SETTINGS:
        assert estimate_lifetimes(ev, size, replace(p, **_reuse(*setting))).tobytes() == \
            estimate_lifetimes(ev, size, p).tobytes()


def test_reuse_off_ignores_the_other_fields(edge_events, random_events):
    """``burst_reuse = 0``: ``burst_warm_refit`` and ``burst_reuse_inliers`` change no byte."""
    size = SensorSize(18, 14)
    ev, _ = _edge_with_noise(edge_events, random_events, size, 0.05, 300)
    p = noise_params(burst_reuse=0)
    want = estimate_lifetimes(ev, size, p).tobytes()
    assert estimate_lifetimes(ev, size, replace(p, burst_warm_refit=False, burst_reuse_inliers=3)).tobytes() == want


@pytest.mark.parametrize("n_tiles", [2, 3])
@pytest.mark.parametrize("setting", SETTINGS[2:])
def test_reuse_strips_and_chunks_equal_one_shot(edge_events, random_events, n_tiles, setting):
    """The burst planes are per-pixel state like the SAE: any strip count and any chunking give the serial bytes."""
    size = SensorSize(24, 20)
    ev, _ = _edge_with_noise(edge_events, random_events, size, 0.08, 1500, rng=2)
    p = noise_params(**_reuse(*setting))
    want = estimate_lifetimes(ev, size, p)
    assert want["valid"].sum() > 100
    np.testing.assert_array_equal(estimate_lifetimes(ev, size, p, n_tiles=n_tiles).view(np.uint8),
                                  want.view(np.uint8))
    est = IntraPixelLifetime(size, p, n_tiles=n_tiles)
    parts = [est.process(c) for c in np.array_split(ev, 7)]
    np.testing.assert_array_equal(np.concatenate(parts).view(np.uint8), want.view(np.uint8))
    est.reset()
    np.testing.assert_array_equal(est.process(ev).view(np.uint8), want.view(np.uint8))


@pytest.mark.parametrize("field, value, exc", [
    ("burst_reuse", True, TypeError), ("burst_reuse", 1.5, TypeError), ("burst_reuse", "2", TypeError),
    ("burst_reuse", None, TypeError), ("burst_reuse", -1, ValueError),
    ("burst_reuse_inliers", False, TypeError), ("burst_reuse_inliers", 2.0, TypeError),
    ("burst_reuse_inliers", -3, ValueError),
    ("burst_warm_refit", 1, TypeError), ("burst_warm_refit", "yes", TypeError),
])
def test_bad_reuse_fields_are_clear_errors(field, value, exc):
    with pytest.raises(exc, match=field):
        IntraParams(**{field: value})
