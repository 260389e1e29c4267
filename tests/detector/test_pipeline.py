"""Pipeline: buffer + estimator aligned with the input; streaming detector == one-shot."""

import importlib.util

import numpy as np
import pytest

from evedge.detector import (BufferParams, Detector, EdgeImage, IntraParams, detect, edge_frames, estimate_lifetimes,
                             filter_events)
from evedge.events import SensorSize, make_events


def _noisy_edges(edge_events, random_events):
    ev, _ = edge_events(24, 20, 800, 0.3, n_edges=3, spacing_px=8, jitter_frac=0.05, rng=3)
    noise = random_events(300, 24, 20, duration_us=int(ev["t"][-1]), rng=4)
    allev = np.concatenate([ev, noise])
    return allev[np.argsort(allev["t"], kind="stable")]


def test_detect_aligns_with_input(edge_events, random_events):
    size = SensorSize(24, 20)
    ev = _noisy_edges(edge_events, random_events)
    res = detect(ev, size)
    kept = filter_events(ev, size)
    np.testing.assert_array_equal(res.kept, kept)
    assert 0 < (~kept).sum() < 0.2 * kept.size
    assert not res.lifetimes["valid"][~kept].any()
    assert np.isnan(res.lifetimes["lifetime_us"][~kept]).all()
    assert res.lifetimes[kept].tobytes() == estimate_lifetimes(ev[kept], size).tobytes()
    raw = detect(ev, size, use_buffer=False)
    assert raw.kept.all()
    assert raw.lifetimes.tobytes() == estimate_lifetimes(ev, size).tobytes()


def test_detect_when_the_buffer_keeps_nothing():
    # isolated events (no neighbour ever fires): the buffer drops all, and detect gives no estimate at all
    from evedge.events import make_events

    size = SensorSize(40, 40)
    ev = make_events(np.array([2, 20, 37]), np.array([3, 30, 11]), np.array([0, 50_000, 100_000]),
                     np.array([True, False, True]))
    res = detect(ev, size)
    assert not res.kept.any() and not res.lifetimes["valid"].any()
    assert np.isnan(res.lifetimes["lifetime_us"]).all() and np.isnan(res.lifetimes["vx_px_s"]).all()
    empty = detect(ev[:0], size)
    assert empty.lifetimes.shape == (0,) and empty.kept.shape == (0,)


@pytest.mark.parametrize("n_tiles", [1, 3])
def test_streaming_detector_equals_one_shot(edge_events, random_events, n_tiles):
    """Chunked through the streaming detector (its estimator on 1 or 3 strips that keep their state) == detect."""
    size = SensorSize(24, 20)
    ev = _noisy_edges(edge_events, random_events)
    bp = BufferParams(tau_min_us=3_000)
    res = detect(ev, size, buffer_params=bp)
    det = Detector(size, buffer_params=bp, n_tiles=n_tiles)
    assert det.estimator.n_tiles == n_tiles
    outs = []
    for c in np.array_split(ev, 11):
        outs.append(det.process(c))
        outs.append(det.advance_to(int(c["t"][-1])))
    outs.append(det.flush())
    got_ev = np.concatenate([o[0] for o in outs])
    got_lt = np.concatenate([o[1] for o in outs])
    np.testing.assert_array_equal(got_ev, ev[res.kept])
    assert got_lt.tobytes() == res.lifetimes[res.kept].tobytes()
    T = int(ev["t"][-1]) + 1
    want = edge_frames(ev[res.kept], res.lifetimes[res.kept], size, [T])[0]
    np.testing.assert_array_equal(det.image_at(T), want)


def test_streaming_detector_until_us_equals_advance_to(edge_events, random_events):
    """process(chunk, until_us=t) = process(chunk) then advance_to(t): same events, lifetimes and image."""
    size = SensorSize(24, 20)
    ev = _noisy_edges(edge_events, random_events)
    bp = BufferParams(tau_min_us=3_000)
    res = detect(ev, size, buffer_params=bp)
    two, one = Detector(size, buffer_params=bp), Detector(size, buffer_params=bp)
    outs_two, outs_one = [], []
    t = ev["t"]
    ends = np.arange(int(t[0]) + 700, int(t[-1]) + 700, 700)  # 0.7 ms chunks: some release nothing
    cuts = np.searchsorted(t, ends)
    start = 0
    for end, cut in zip(ends, cuts):
        c = ev[start:cut]
        outs_two += [two.process(c), two.advance_to(int(end))]
        outs_one.append(one.process(c, until_us=int(end)))
        start = cut
        np.testing.assert_array_equal(one.image_at(int(end)), two.image_at(int(end)))
    outs_two.append(two.flush())
    outs_one.append(one.flush())
    assert any(o[0].size == 0 for o in outs_one)  # the no-event path is taken
    for outs in (outs_two, outs_one):
        np.testing.assert_array_equal(np.concatenate([o[0] for o in outs]), ev[res.kept])
        assert np.concatenate([o[1] for o in outs]).tobytes() == res.lifetimes[res.kept].tobytes()
    with pytest.raises(ValueError, match="before the newest"):
        one.process(ev[:0], until_us=int(t[0]))


def test_method_and_param_errors(edge_events):
    size = SensorSize(8, 8)
    ev, _ = edge_events(8, 8, 500, 0.2)
    with pytest.raises(ValueError, match="method"):
        detect(ev, size, method="canny")
    with pytest.raises(TypeError, match="IntraParams"):
        detect(ev, size, params=BufferParams())
    with pytest.raises(TypeError, match="use_buffer"):
        detect(ev, size, use_buffer="yes")
    res = detect(ev, size, params=IntraParams(window_size=3, min_points=3, min_inliers=3))
    assert res.lifetimes["valid"].any()


@pytest.mark.skipif(importlib.util.find_spec("evedge.detector.mueggler") is None, reason="baseline absent")
def test_mueggler_method_runs(edge_events, random_events):
    from evedge.detector.mueggler import MuegglerParams, estimate_lifetimes_mueggler

    size = SensorSize(24, 20)
    ev = _noisy_edges(edge_events, random_events)
    res = detect(ev, size, method="mueggler")
    assert res.kept.all()  # no buffer by default for the baseline
    assert res.lifetimes["valid"].any()
    assert res.lifetimes.tobytes() == estimate_lifetimes_mueggler(ev, size).tobytes()
    # with the buffer: the baseline sees only the kept events, filtered ones have no estimate
    params = MuegglerParams(seed=5)
    buf = detect(ev, size, method="mueggler", use_buffer=True, params=params)
    np.testing.assert_array_equal(buf.kept, filter_events(ev, size))
    assert 0 < (~buf.kept).sum()
    assert not buf.lifetimes["valid"][~buf.kept].any()
    assert buf.lifetimes[buf.kept].tobytes() == estimate_lifetimes_mueggler(ev[buf.kept], size, params).tobytes()


def test_detector_streams_any_registered_estimator(edge_events, random_events):
    """The streaming Detector composes mueggler (no filter by default) as it does intra."""
    from evedge.detector.mueggler import estimate_lifetimes_mueggler

    size = SensorSize(24, 20)
    ev = _noisy_edges(edge_events, random_events)
    det = Detector(size, method="mueggler", display="lifetime_only")
    assert det.buffer is None
    outs = [det.process(c) for c in np.array_split(ev, 7)] + [det.flush()]
    got = np.concatenate([o[1] for o in outs])
    assert got.tobytes() == estimate_lifetimes_mueggler(ev, size).tobytes()
    T = int(ev["t"][-1]) + 1
    np.testing.assert_array_equal(det.image_at(T), edge_frames(ev, got, size, [T])[0])
    with pytest.raises(ValueError, match="is of kind 'edges', not 'estimator'"):
        Detector(size, method="time")
    with pytest.raises(ValueError, match="unknown method 'nope'"):
        Detector(size, method="nope")


def test_keep_mask_of_a_streaming_only_filter(edge_events, random_events):
    """A filter without a one-shot mask: the mask is rebuilt from what it releases (here: the buffer itself)."""
    from evedge.detector.buffer import EventBuffer
    from evedge.detector.pipeline import keep_mask
    from evedge.detector.protocols import METHODS, NoiseFilter

    class StreamOnly:
        kind = "filter"

        def __init__(self, sensor_size, **params):
            self.inner = EventBuffer(sensor_size, BufferParams(**params))

        def process(self, events):
            return self.inner.process(events)

        def flush(self):
            return self.inner.flush()

        def reset(self):
            self.inner.reset()

    size = SensorSize(24, 20)
    ev = _noisy_edges(edge_events, random_events)
    name = "tests.stream_only_filter"
    if name not in METHODS:
        METHODS.register(name, StreamOnly, kind="filter", source="test")
    assert isinstance(StreamOnly(size), NoiseFilter)
    want = filter_events(ev, size, BufferParams(tau_min_us=4000))
    np.testing.assert_array_equal(keep_mask(name, ev, size, {"tau_min_us": 4000}), want)
    res = detect(ev, size, filter=name, buffer_params={"tau_min_us": 4000})
    np.testing.assert_array_equal(res.kept, want)


def test_edge_frames_of_a_streaming_edge_detector(edge_events):
    """An edge detector without one-shot frames is streamed and asked image_at: same as the one-shot form."""
    from evedge.detector.accumulate import TimeWindowAccumulator, accumulate_time
    from evedge.detector.pipeline import edge_frames_of
    from evedge.detector.protocols import METHODS, EdgeDetector

    class Streamed(TimeWindowAccumulator):
        kind = "edges"

        def __init__(self, sensor_size, window_us=2000):
            super().__init__(sensor_size, window_us)

    name = "tests.streamed_time_window"
    if name not in METHODS:
        METHODS.register(name, Streamed, kind="edges", source="test")
    size = SensorSize(16, 12)
    ev, _ = edge_events(16, 12, 800, 0.3, n_edges=2, spacing_px=6)
    times = [int(ev["t"][-1]), 3000, int(ev["t"][ev.size // 2])]  # any order
    assert isinstance(Streamed(size), EdgeDetector)
    got = edge_frames_of(name, ev, size, times, {"window_us": 2000})
    order = np.argsort(times)
    want = np.zeros_like(got)
    want[order] = accumulate_time(ev, size, np.asarray(times)[order], 2000) > 0
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(edge_frames_of("time", ev, size, times, {"window_us": 2000}), got)


def _chunkings(ev):
    """(name, list of (chunk, until_us or None, advance_to or None)) covering the streaming calls."""
    t = ev["t"]
    rng = np.random.default_rng(7)
    cuts = np.sort(rng.integers(0, ev.size, 25))
    ends = np.arange(int(t[0]) + 1000, int(t[-1]) + 1000, 1000)
    ms = np.searchsorted(t, ends)
    return {
        "one event, until its time": [(ev[i:i + 1], int(t[i]), None) for i in range(ev.size)],
        "1 ms, until its end": [(ev[a:b], int(e), None) for a, b, e in zip(np.r_[0, ms[:-1]], ms, ends)],
        "random sizes, advance_to": [(c, None, int(c["t"][-1]) if c.size else None)
                                     for c in np.split(ev, cuts)],
        "random sizes, no clock": [(c, None, None) for c in np.split(ev, cuts)],
    }


@pytest.mark.parametrize("case", ["default", "burst_reuse, predecessor", "line rule, lifetime_only", "causal"])
def test_streamed_bytes_equal_one_shot_for_any_chunking(edge_events, random_events, case):
    """Every chunking: released events, lifetimes and the edge image's state = the one-shot stages' bytes.

    And each call's output = that of the stages called one by one (the generic path: checks, record
    arrays, one call per stage), so passing the columns between the built-in stages changes nothing.
    """
    from evedge.detector.buffer import line_params

    size = SensorSize(24, 20)
    ev = _noisy_edges(edge_events, random_events)
    kw = {"buffer_params": BufferParams(tau_min_us=3_000)}
    display = None
    if case.startswith("burst_reuse"):
        kw["params"] = IntraParams(burst_reuse=2)
        display = "predecessor"  # clears behind each event: the flow counts
    if case.startswith("line"):
        kw["buffer_params"] = line_params(line_window_us=20_000)
        display = "lifetime_only"
    if case.startswith("causal"):
        kw["buffer_params"] = BufferParams(tau_min_us=3_000, mode="causal")
    res = detect(ev, size, **kw)
    kept, lts = ev[res.kept], res.lifetimes[res.kept]
    ref = EdgeImage(size, display=display)
    ref.process(kept, lts)
    T = int(ev["t"][-1]) + 1
    for name, calls in _chunkings(ev).items():
        fast, slow = Detector(size, display=display, **kw), Detector(size, display=display, **kw)
        assert fast._columns
        slow._columns = False
        outs = []
        for chunk, until, adv in calls:
            got = [fast.process(chunk, until_us=until)] + ([fast.advance_to(adv)] if adv is not None else [])
            want = [slow.process(chunk, until_us=until)] + ([slow.advance_to(adv)] if adv is not None else [])
            for (ge, gl), (we, wl) in zip(got, want):
                assert ge.dtype == we.dtype and gl.dtype == wl.dtype and ge.shape == we.shape == gl.shape, name
                assert ge.tobytes() == we.tobytes() and gl.tobytes() == wl.tobytes(), name
            outs += got
        outs.append(fast.flush())
        assert np.concatenate([o[0] for o in outs]).tobytes() == kept.tobytes(), name
        assert np.concatenate([o[1] for o in outs]).tobytes() == lts.tobytes(), name
        for attr in ("_last_t", "_expiry", "_start_t", "_prev_lt", "_prev_pol"):
            assert getattr(fast.edges, attr).tobytes() == getattr(ref, attr).tobytes(), (name, attr)
        np.testing.assert_array_equal(fast.image_at(T), edge_frames(kept, lts, size, [T], display=display)[0])


def test_streaming_detector_chunk_checks(edge_events):
    """The one-pass chunk check: the full checks' messages on failure, conversions and read-only chunks accepted."""
    size = SensorSize(8, 8)
    ev, _ = edge_events(8, 8, 500, 0.2)
    det = Detector(size)
    bad = ev[:5].copy()
    bad["x"][3] = 8
    with pytest.raises(ValueError, match=r"chunk: event 3 has x=8 outside the sensor \(8x8\)"):
        det.process(bad)
    bad = ev[:5].copy()
    bad["y"][1] = -1
    with pytest.raises(ValueError, match="chunk: event 1 has y=-1 outside"):
        det.process(bad)
    bad = ev[:5].copy()
    bad["t"][2] = bad["t"][1] - 1
    with pytest.raises(ValueError, match="chunk: timestamps are not sorted: event 2"):
        det.process(bad)
    ro = ev[:40].copy()
    ro.flags.writeable = False  # a read-only chunk (e.g. a memory map): its own compiled check
    det.process(ro, until_us=int(ro["t"][-1]))
    with pytest.raises(ValueError, match="chunk starts at t="):
        det.process(ev[:5])
    # another dtype is converted (as_events), then checked as before
    wide = np.zeros(3, dtype=[("x", "<i4"), ("y", "<i4"), ("t", "<i8"), ("p", "?")])
    for f in "xytp":
        wide[f] = ev[40:43][f]
    det.process(wide)
    # an until_us before the chunk's last event: refused before anything changes
    ref = Detector(size)
    ref.process(ro, until_us=int(ro["t"][-1]))
    ref.process(wide)
    with pytest.raises(ValueError, match="before the newest processed event"):
        det.process(ev[43:60], until_us=int(ev["t"][50]))
    with pytest.raises(TypeError, match="t_us must be an integer"):
        det.process(ev[43:60], until_us=1.5)
    a, b = det.process(ev[43:], until_us=int(ev["t"][-1])), ref.process(ev[43:], until_us=int(ev["t"][-1]))
    assert a[0].tobytes() == b[0].tobytes() and a[1].tobytes() == b[1].tobytes()
    assert det.flush()[1].tobytes() == ref.flush()[1].tobytes()


def test_kept_columns_and_expansion_in_parallel_chunks():
    """detect's bookkeeping with n_tiles > 1 (chunks of events in parallel, at offsets counted first) gives the
    serial arrays: masks keeping all, none, or some, over more than one chunk and a partial last one."""
    from evedge.detector._chunks import CHUNK_EVENTS as _CHUNK
    from evedge.detector._stream_kernels import (_expand_lifetimes, _expand_lifetimes_par, _kept_columns,
                                                 _kept_columns_par, _kept_offsets, _lifetime_columns_into,
                                                 _lifetime_columns_par_into, _record_columns_into,
                                                 _record_columns_par_into)
    from evedge.detector.result import LIFETIME_DTYPE

    rng = np.random.default_rng(4)
    n = 3 * _CHUNK + 11
    ev = make_events(rng.integers(0, 50, n), rng.integers(0, 40, n), np.sort(rng.integers(0, 10**6, n)),
                     rng.random(n) < 0.5)
    for e in (ev, ev[::3]):  # all the events' columns (the estimator's process), also of a strided view
        want = np.stack([e[f].astype(np.int64) for f in ("x", "y", "t", "p")])
        serial, par = np.empty((4, e.size), np.int64), np.empty((4, e.size), np.int64)
        _record_columns_into(e, serial)
        _record_columns_par_into(e, par)
        assert np.array_equal(serial, want) and np.array_equal(par, want)
    for kept in (rng.random(n) < 0.3, np.ones(n, bool), np.zeros(n, bool), np.arange(n) >= n - 7):
        off = _kept_offsets(kept)
        assert off.shape == (4 + 1,) and off[-1] == kept.sum()
        cols = _kept_columns(ev, kept)
        assert np.array_equal(_kept_columns_par(ev, kept, off), cols)
        assert np.array_equal(cols, np.stack([ev[f][kept].astype(np.int64) for f in ("x", "y", "t", "p")]))
        m = int(kept.sum())
        lt, vx, vy = rng.random(m), rng.random(m), rng.random(m)
        valid = rng.random(m) < 0.5
        a = np.empty(n, LIFETIME_DTYPE)
        b = np.empty(n, LIFETIME_DTYPE)
        _expand_lifetimes(kept, lt, vx, vy, valid, a)
        _expand_lifetimes_par(kept, lt, vx, vy, valid, b, off)
        assert a.tobytes() == b.tobytes()
        assert np.array_equal(a["lifetime_us"][kept], lt) and np.isnan(a["lifetime_us"][~kept]).all()
        for into in (_lifetime_columns_into, _lifetime_columns_par_into):  # and back to columns (the edge frames)
            cols, got_valid = np.empty((3, n)), np.empty(n, bool)
            into(a, cols, got_valid)
            assert np.array_equal(cols, np.stack([a[f] for f in ("lifetime_us", "vx_px_s", "vy_px_s")]),
                                  equal_nan=True)
            assert np.array_equal(got_valid, a["valid"])
