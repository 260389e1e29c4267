"""Edge images: kernel against a slow reference, analytic cases, streaming == one-shot, errors."""

import math

import numpy as np
import pytest

from evedge.detector.edges import EdgeImage, edge_frames
from evedge.detector.result import LIFETIME_DTYPE, empty_lifetimes
from evedge.events import SensorSize, make_events

S = SensorSize(10, 8)


def random_lifetimes(n, rng):
    rng = np.random.default_rng(rng)
    out = empty_lifetimes(n)
    valid = rng.random(n) < 0.8
    speed = rng.uniform(100, 5000, n)
    ang = rng.uniform(-np.pi, np.pi, n)
    out["valid"] = valid
    out["lifetime_us"][valid] = (1e6 / speed)[valid]
    out["vx_px_s"][valid] = (speed * np.cos(ang))[valid]
    out["vy_px_s"][valid] = (speed * np.sin(ang))[valid]
    return out


def reference_frame(events, lifetimes, size, T, clear_behind, invalid, burst=0.0):
    """Replay every event with t <= T in pure Python."""
    last = {}
    expiry = {}
    burst_state = {}  # pix -> (start, lifetime, polarity) of the newest valid event
    dirs = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)]
    for e, r in zip(events, lifetimes):
        t = int(e["t"])
        if t > T:
            break
        pix = (int(e["x"]), int(e["y"]))
        if not r["valid"]:
            if invalid == "clear":
                last[pix], expiry[pix] = t, float(t)
            continue
        start = t
        if burst > 0:
            b_start, b_lt, b_pol = burst_state.get(pix, (None, math.nan, None))
            if b_pol == bool(e["p"]) and t - last[pix] <= burst * b_lt:
                start = b_start
            burst_state[pix] = (start, float(r["lifetime_us"]), bool(e["p"]))
        last[pix], expiry[pix] = t, start + float(r["lifetime_us"])
        if clear_behind:
            d = int(math.floor(math.atan2(-r["vy_px_s"], -r["vx_px_s"]) / (math.pi / 4) + 0.5)) % 8
            q = (pix[0] + dirs[d][0], pix[1] + dirs[d][1])
            if 0 <= q[0] < size.width and 0 <= q[1] < size.height and expiry.get(q, -math.inf) > t:
                expiry[q] = float(t)
    img = np.zeros(size.shape, bool)
    for (x, y), t in last.items():
        img[y, x] = t <= T < expiry[(x, y)]
    return img


@pytest.mark.parametrize("clear_behind", [False, True])
@pytest.mark.parametrize("invalid", ["ignore", "clear"])
@pytest.mark.parametrize("burst", [0.0, 1.0, 3.0])
def test_matches_reference(random_events, clear_behind, invalid, burst):
    ev = random_events(500, S.width, S.height, duration_us=20_000, rng=4)
    lt = random_lifetimes(ev.size, 5)
    times = np.array([15_000, 0, 5_000, 19_999, 7_777, int(ev["t"][100]), 30_000])
    frames = edge_frames(ev, lt, S, times, clear_behind=clear_behind, invalid=invalid, burst_lifetimes=burst)
    assert frames.shape == (times.size, *S.shape)
    for f, T in zip(frames, times):
        np.testing.assert_array_equal(f, reference_frame(ev, lt, S, T, clear_behind, invalid, burst))
    assert frames.any() and not frames.all()


def test_streaming_equals_one_shot(random_events):
    ev = random_events(800, S.width, S.height, duration_us=40_000, rng=1)
    lt = random_lifetimes(ev.size, 2)
    times = np.arange(1_000, 40_000, 2_500)
    want = edge_frames(ev, lt, S, times, clear_behind=True)
    img = EdgeImage(S, clear_behind=True)
    start = 0
    for i, T in enumerate(times):
        end = np.searchsorted(ev["t"], T, side="right")
        # feed in two uneven pieces
        mid = (start + end) // 3 + start // 2
        mid = min(max(mid, start), end)
        img.process(ev[start:mid], lt[start:mid])
        img.process(ev[mid:end], lt[mid:end])
        start = end
        np.testing.assert_array_equal(img.image_at(T), want[i])


def test_pixel_alive_for_its_lifetime_only():
    ev = make_events([2, 5], [3, 3], [1000, 1500], [True, False])
    lt = empty_lifetimes(2)
    lt["valid"] = [True, False]
    lt["lifetime_us"][0] = 400.0
    lt["vx_px_s"][0], lt["vy_px_s"][0] = 2500.0, 0.0
    f = edge_frames(ev, lt, S, [999, 1000, 1399, 1400])
    assert [bool(x[3, 2]) for x in f] == [False, True, True, False]
    assert not f[:, 3, 5].any()  # the invalid event makes no edge


def test_clear_behind_and_invalid_clear():
    # pixel (4, 3) alive, then an event at (5, 3) moving right (+x) clears it
    ev = make_events([4, 5], [3, 3], [0, 100], [True, True])
    lt = empty_lifetimes(2)
    lt["valid"] = True
    lt["lifetime_us"] = 1000.0
    lt["vx_px_s"], lt["vy_px_s"] = 1000.0, 0.0
    keep = edge_frames(ev, lt, S, [150])[0]
    cleared = edge_frames(ev, lt, S, [150], clear_behind=True)[0]
    assert keep[3, 4] and keep[3, 5]
    assert not cleared[3, 4] and cleared[3, 5]
    # an invalid event on a live pixel: ignored, or ends its life
    ev2 = make_events([4, 4], [3, 3], [0, 100], [True, True])
    lt2 = lt.copy()
    lt2["valid"][1] = False
    assert edge_frames(ev2, lt2, S, [150])[0][3, 4]
    assert not edge_frames(ev2, lt2, S, [150], invalid="clear")[0][3, 4]


def test_errors():
    ev = make_events([1, 2], [1, 1], [0, 5], [True, True])
    lt = empty_lifetimes(2)
    with pytest.raises(ValueError, match="lifetimes"):
        edge_frames(ev, empty_lifetimes(3), S, [0])
    with pytest.raises(TypeError, match="lifetimes"):
        edge_frames(ev, np.zeros(2), S, [0])
    with pytest.raises(ValueError, match="times_us"):
        edge_frames(ev, lt, S, [[0, 1]])
    with pytest.raises(ValueError, match="invalid"):
        EdgeImage(S, invalid="dead")
    img = EdgeImage(S)
    img.process(ev, lt)
    with pytest.raises(ValueError, match="before the newest"):
        img.image_at(4)
    assert img.image_at(5).dtype == bool
    with pytest.raises(ValueError, match="previous chunk"):
        img.process(ev[:1], lt[:1])
    assert lt.dtype == LIFETIME_DTYPE


def test_image_at_refuses_non_finite_instants():
    """Regression: image_at(nan) passed the 'not before' check (nan < t is False) and returned an empty map."""
    img = EdgeImage(SensorSize(4, 3))
    ev = make_events([1], [1], [100], [True])
    lt = empty_lifetimes(1)
    lt["lifetime_us"], lt["valid"] = 50.0, True
    img.process(ev, lt)
    assert img.image_at(120)[1, 1]
    for bad in (float("nan"), np.float64("inf"), -np.inf):
        with pytest.raises(ValueError, match="t_us must be finite"):
            img.image_at(bad)


def test_burst_aware_expiry_counts_from_the_burst_s_first_event():
    """A pixel fires a burst of 3 events 100 us apart (lifetime 1000 us each), then a new burst 5000 us later.
    Paper display: alive until 200 + 1000; burst-aware: until 0 + 1000; the later burst starts afresh."""
    ev = make_events([2] * 5, [3] * 5, [0, 100, 200, 5000, 5300], [True] * 5)
    lt = empty_lifetimes(5)
    lt["valid"] = True
    lt["lifetime_us"] = 1000.0
    lt["vx_px_s"], lt["vy_px_s"] = 1000.0, 0.0
    times = [999, 1000, 1199, 1200, 5999, 6000, 6299, 6300]
    paper = edge_frames(ev, lt, S, times)[:, 3, 2]
    burst = edge_frames(ev, lt, S, times, burst_lifetimes=1.0)[:, 3, 2]
    assert paper.tolist() == [True, True, True, False, True, True, True, False]
    assert burst.tolist() == [True, False, False, False, True, False, False, False]
    # an event of the other polarity starts a burst (at 100 us) that the third event continues
    ev["p"][1:3] = False
    other = edge_frames(ev, lt, S, [1099, 1100], burst_lifetimes=1.0)[:, 3, 2]
    assert other.tolist() == [True, False]


def test_burst_lifetimes_refuses_a_negative_value():
    with pytest.raises(ValueError, match="burst_lifetimes"):
        EdgeImage(S, burst_lifetimes=-1)


@pytest.mark.parametrize("clear_behind", [False, True])
@pytest.mark.parametrize("invalid", ["ignore", "clear"])
@pytest.mark.parametrize("burst", [0.0, 1.0])
def test_strips_give_the_serial_frames(random_events, clear_behind, invalid, burst):
    """Row strips in parallel (n_tiles, halo one row: a neighbour's events clear across the cut) == serial, bytes;
    instants unsorted, repeated, between and beyond the events, float and int."""
    size = SensorSize(24, 20)
    ev = random_events(6000, size.width, size.height, duration_us=40_000, rng=7)
    lts = random_lifetimes(ev.size, 8)
    lts["lifetime_us"] *= 20  # lives of a few ms: pixels alive across many frames and many clearings
    for times in (np.r_[np.arange(0, 45_000, 700)[::-1], 300, 300, -5], np.linspace(-10.0, 41_000.5, 37)):
        serial = edge_frames(ev, lts, size, times, clear_behind=clear_behind, invalid=invalid, burst_lifetimes=burst)
        assert serial.any(axis=(1, 2)).sum() > times.size // 2  # most frames show edges
        for n in (2, 3, 5, 20):
            tiled = edge_frames(ev, lts, size, times, clear_behind=clear_behind, invalid=invalid,
                                burst_lifetimes=burst, n_tiles=n)
            assert tiled.tobytes() == serial.tobytes(), n


def test_strips_on_real_lifetimes(stripes_events):
    """The estimator's lifetimes on the real recording (fast edges, the clearing crosses the strips' cuts)."""
    from evedge.detector import estimate_lifetimes

    size = SensorSize(128, 128)
    ev = stripes_events[:40_000]
    lts = estimate_lifetimes(ev, size)
    times = np.arange(int(ev["t"][0]), int(ev["t"][-1]) + 5000, 2500)
    for display in ("predecessor", "lifetime_only"):
        serial = edge_frames(ev, lts, size, times, display=display)
        for n in (2, 7):
            assert edge_frames(ev, lts, size, times, display=display, n_tiles=n).tobytes() == serial.tobytes(), n


def test_strips_errors_and_empty():
    ev = make_events([1, 2], [3, 4], [10, 20], [True, False])
    lts = random_lifetimes(2, 0)
    with pytest.raises(ValueError, match="n_tiles"):
        edge_frames(ev, lts, S, [15], n_tiles=9)
    with pytest.raises(TypeError, match="n_tiles"):
        edge_frames(ev, lts, S, [15], n_tiles=2.0)
    assert edge_frames(ev[:0], lts[:0], S, [5, 6], n_tiles=3).shape == (2, 8, 10)
    assert edge_frames(ev, lts, S, [], n_tiles=3).shape == (0, 8, 10)
