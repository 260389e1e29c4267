"""The event buffer's line rule (``BufferParams.line_window_us``, off by default): known answers, the kernel
against its plain-Python definition (``_buffer_reference.line_reference_mask``), chunked = one-shot, strips."""

import sys
from pathlib import Path

import numpy as np
import pytest

from evedge.detector._buffer_kernels import _buffer_scan, _line_scan, empty_line_state, new_line_state, new_state
from evedge.detector.buffer import BufferParams, EventBuffer, filter_events
from evedge.events import SensorSize, make_events

sys.path.insert(0, str(Path(__file__).parent))
from _buffer_reference import line_reference_mask, reference_mask  # noqa: E402

S = SensorSize(12, 9)
SLOW = 30_000  # us between neighbours: three times the 10 ms window


def _row(times, xs=(2, 3, 4), y=4, p=True):
    """Events at pixels ``xs[i]`` of row ``y`` at ``times[i]`` (the first ``len(times)``), in time order."""
    xs = np.asarray(xs)[:len(times)]
    order = np.argsort(times, kind="stable")
    return make_events(xs[order], [y] * len(xs), np.asarray(times)[order], [p] * len(xs))


def test_off_by_default_and_paper_window_drops_a_slow_edge():
    ev = _row([0, SLOW, 2 * SLOW])
    assert BufferParams().line_window_us == 0
    assert not filter_events(ev, S).any()


def test_the_middle_of_a_slow_line_is_kept():
    ev = _row([0, SLOW, 2 * SLOW])  # pixels 2, 3, 4 of row 4 in turn
    got = filter_events(ev, S, BufferParams(line_window_us=SLOW))
    assert got.tolist() == [False, True, False]
    # a window shorter than either delay: nothing
    assert not filter_events(ev, S, BufferParams(line_window_us=SLOW - 1)).any()
    # diagonal and vertical lines too; other polarity at the far end does not count
    for xs, ys in (((2, 3, 4), (1, 2, 3)), ((5, 5, 5), (2, 3, 4)), ((6, 5, 4), (1, 2, 3))):
        ev = make_events(xs, ys, [0, SLOW, 2 * SLOW], [True] * 3)
        assert filter_events(ev, S, BufferParams(line_window_us=SLOW)).tolist() == [False, True, False]
        ev["p"][2] = False
        assert not filter_events(ev, S, BufferParams(line_window_us=SLOW)).any()


def test_not_in_line_or_not_midway_is_dropped():
    # an L shape: the two neighbours are not opposite
    ev = make_events([2, 3, 3], [4, 4, 5], [0, SLOW, 2 * SLOW], [True] * 3)
    assert not filter_events(ev, S, BufferParams(line_window_us=SLOW)).any()
    # delays 30 and 20 ms: |d1 - d2| = 10 ms = tolerance x 30 ms at tolerance 1/3
    ev = _row([0, SLOW, SLOW + 20_000])
    assert filter_events(ev, S, BufferParams(line_window_us=SLOW, line_tolerance=1 / 3)).tolist() == [False, True,
                                                                                                        False]
    assert not filter_events(ev, S, BufferParams(line_window_us=SLOW, line_tolerance=0.33)).any()


def test_an_active_middle_pixel_is_not_kept():
    # the middle pixel fired 80 ms before: quiet for 80 ms < 2 x the 60 ms span
    ev = make_events([3, 2, 3, 4], [4, 4, 4, 4], [50_000, 100_000, 100_000 + SLOW, 100_000 + 2 * SLOW], [True] * 4)
    assert not filter_events(ev, S, BufferParams(line_window_us=SLOW)).any()
    got = filter_events(ev, S, BufferParams(line_window_us=SLOW, line_quiet=80_000 / (2 * SLOW)))
    assert got.tolist() == [False, False, True, False]
    assert filter_events(ev, S, BufferParams(line_window_us=SLOW, line_quiet=0)).tolist() == [False, False, True,
                                                                                              False]


def test_two_lines_through_the_event():
    # an edge at 20 degrees, 10 px/s, crossing a 3 x 3 block: each pixel fires when the edge reaches its centre
    a = np.radians(20)
    ys, xs = np.mgrid[3:6, 3:6]
    t = np.round((xs * np.cos(a) + ys * np.sin(a)) * 100_000).astype(np.int64).ravel()
    order = np.argsort(t, kind="stable")
    ev = make_events(xs.ravel()[order], ys.ravel()[order], t[order], [True] * 9)
    centre = (ev["x"] == 4) & (ev["y"] == 4)
    for count in (1, 2):
        got = filter_events(ev, S, BufferParams(line_window_us=100_000, line_count=count))
        assert got[centre].all()
    # along (0, 1) and (1, -1) the centre is midway (34 and 60 ms); along (1, 0) 94 ms: a window of 70 ms sees two
    # lines, 40 ms one
    assert filter_events(ev, S, BufferParams(line_window_us=70_000, line_count=2))[centre].all()
    assert filter_events(ev, S, BufferParams(line_window_us=40_000, line_count=1))[centre].all()
    assert not filter_events(ev, S, BufferParams(line_window_us=40_000, line_count=2))[centre].any()


def test_the_rule_uses_the_latest_events_only():
    # pixel 4 fires again before the middle: its latest is after t_c, so no line that way round
    ev = make_events([2, 4, 3, 4], [4, 4, 4, 4], [0, 5_000, SLOW, 2 * SLOW], [True] * 4)
    want = line_reference_mask(ev, S, SLOW, 0.5, 2.0)
    assert want.tolist() == [False, False, True, False]
    np.testing.assert_array_equal(filter_events(ev, S, BufferParams(line_window_us=SLOW)),
                                  want | reference_mask(ev, S, 10_000, False))


def test_latency_is_the_longer_window():
    buf = EventBuffer(S, BufferParams(line_window_us=SLOW))
    assert buf.params.hold_us == SLOW
    assert buf.process(_row([0, SLOW])).size == 0 and buf.n_pending == 2
    assert buf.advance_to(2 * SLOW).size == 0 and buf.n_pending == 1  # the first is dropped, the middle waits
    out = buf.process(make_events([4], [4], [2 * SLOW], [True]))
    assert out["t"].tolist() == [SLOW]
    assert buf.flush().size == 0


@pytest.mark.parametrize("kwargs, exc", [
    (dict(line_window_us=-1), ValueError), (dict(line_window_us=2.5), TypeError),
    (dict(line_window_us=True), TypeError), (dict(line_tolerance=1.5), ValueError),
    (dict(line_tolerance=-0.1), ValueError), (dict(line_quiet=-1), ValueError),
    (dict(line_quiet=float("inf")), ValueError), (dict(line_count=3), ValueError), (dict(line_count=True), ValueError), (dict(line_window_us=1000, mode="causal"), ValueError),
])
def test_bad_params(kwargs, exc):
    with pytest.raises(exc, match="BufferParams"):
        BufferParams(**kwargs)


def _slow_edges_and_noise(size, seed):
    """Straight edges at random angles and 5-40 px/s (the line rule's case), one event per pixel and passage with
    time jitter, skipped passages, and background noise; many events at equal times."""
    g = np.random.default_rng(seed)
    ys, xs = np.mgrid[0:size.height, 0:size.width]
    parts = []
    for _ in range(3):
        a = g.uniform(0, np.pi)
        speed = g.uniform(5, 40)
        s = xs * np.cos(a) + ys * np.sin(a)
        t = (s - s.min()) / speed * 1e6 + g.uniform(0, 2e5)
        t = t + g.normal(0, 0.1 * 1e6 / speed, t.shape)
        keep = g.random(t.shape) < 0.85
        parts.append(make_events(xs[keep], ys[keep], np.round(t[keep] / 500) * 500, np.full(keep.sum(), g.random() < 0.5)))
    t_end = max(int(p["t"].max()) for p in parts)
    n = size.width * size.height
    parts.append(make_events(g.integers(0, size.width, n), g.integers(0, size.height, n),
                             np.round(g.integers(0, t_end, n) / 500) * 500, g.random(n) < 0.5))
    ev = np.concatenate(parts)
    return ev[np.argsort(ev["t"], kind="stable")]


def _strips_mask(ev, size, params, cuts):
    """The strips' form (as ``detector._tiles._buffer_tiles``): each strip's events plus a one-row halo, run with
    both kernels on the strip's own state; an owned event's decision taken from its strip."""
    x, y, t, p = (np.ascontiguousarray(ev[f], dtype=np.int64) for f in "xytp")
    out = np.zeros(ev.size, bool)
    edges = [0, *cuts, size.height]
    for lo_own, hi_own in zip(edges[:-1], edges[1:]):
        lo, hi = max(lo_own - 1, 0), min(hi_own + 1, size.height)
        sel = np.flatnonzero((y >= lo) & (y < hi))
        n = sel.size
        sup = np.empty(n, bool)
        xs, ys, ts, ps = x[sel].copy(), y[sel] - lo, t[sel].copy(), p[sel].copy()
        _buffer_scan(xs, ys, ts, ps, np.empty(n, np.int64), sup, 0, 0, new_state(size.width, hi - lo), size.width,
                     hi - lo, params.tau_min_us, False)
        _line_scan(xs, ys, ts, ps, sup, 0, 0, new_line_state(size.width, hi - lo), size.width, hi - lo,
                   params.line_window_us, params.line_tolerance, params.line_quiet, params.line_count)
        own = (y[sel] >= lo_own) & (y[sel] < hi_own)
        out[sel[own]] = sup[own]
    return out


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("tol, quiet, count", [(0.5, 2.0, 1), (0.3, 0.0, 1), (1.0, 4.0, 1), (0.5, 2.0, 2),
                                               (1.0, 0.0, 2)])
def test_kernel_equals_definition_chunked_and_strips(seed, tol, quiet, count):
    size = SensorSize(24, 18)
    ev = _slow_edges_and_noise(size, seed)
    params = BufferParams(line_window_us=60_000, line_tolerance=tol, line_quiet=quiet, line_count=count)
    short = reference_mask(ev, size, params.tau_min_us, False)
    line = line_reference_mask(ev, size, 60_000, tol, quiet, count)
    assert (line & ~short).sum() > 10 and (~(line | short)).sum() > 20, "the case must discriminate"
    want = short | line
    np.testing.assert_array_equal(filter_events(ev, size, params), want)
    for n_tiles in (2, 3, 5):  # the real strips (numba threads, one-row halo)
        np.testing.assert_array_equal(filter_events(ev, size, params, n_tiles=n_tiles), want)
    g = np.random.default_rng(seed)
    for cuts in ([9], [1, 2, 10], sorted(g.choice(np.arange(1, 18), 5, replace=False).tolist())):
        np.testing.assert_array_equal(_strips_mask(ev, size, params, cuts), want)
    # streaming in chunks, with advance_to between them, equals one-shot
    buf = EventBuffer(size, params)
    chunks = np.split(ev, np.sort(g.integers(0, ev.size, 25)))
    out = []
    for i, c in enumerate(chunks):
        out.append(buf.process(c))
        nxt = next((int(d["t"][0]) for d in chunks[i + 1:] if d.size), None)
        if nxt is not None and c.size:
            out.append(buf.advance_to(int(g.integers(int(c["t"][-1]), nxt + 1))))
    out.append(buf.flush())
    np.testing.assert_array_equal(np.concatenate(out), ev[want])


def test_line_state_in_numpy_equals_the_kernels():
    for w, h in ((1, 1), (3, 7), (64, 48)):
        a, b = empty_line_state(w, h), new_line_state(w, h)
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes()
