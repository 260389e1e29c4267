"""Event buffer: numba kernel against a slow reference, analytic cases, streaming, errors."""

import numpy as np
import pytest

from evedge.detector.buffer import BufferParams, EventBuffer, filter_events
from evedge.events import EVENT_DTYPE, SensorSize, make_events

S = SensorSize(12, 9)


def reference_mask(events, tau_us, causal):
    """O(n^2) definition: a same-polarity event at a strict 8-neighbour within tau."""
    n = events.shape[0]
    keep = np.zeros(n, bool)
    for i in range(n):
        for j in range(n):
            if j == i or events["p"][j] != events["p"][i]:
                continue
            cheb = max(abs(int(events["x"][j]) - int(events["x"][i])), abs(int(events["y"][j]) - int(events["y"][i])))
            if cheb != 1:
                continue
            dt = int(events["t"][i]) - int(events["t"][j])
            if causal:
                if j < i and 0 <= dt <= tau_us:
                    keep[i] = True
            elif abs(dt) <= tau_us:
                keep[i] = True
    return keep


@pytest.mark.parametrize("mode", ["buffered", "causal"])
@pytest.mark.parametrize("seed", range(4))
def test_matches_reference(random_events, mode, seed):
    ev = random_events(300, S.width, S.height, duration_us=40_000, rng=seed)
    params = BufferParams(tau_min_us=3_000, mode=mode)
    got = filter_events(ev, S, params)
    want = reference_mask(ev, 3_000, mode == "causal")
    np.testing.assert_array_equal(got, want)
    assert 0 < want.sum() < want.size  # the case discriminates


@pytest.mark.parametrize("mode", ["buffered", "causal"])
def test_chunked_equals_one_shot(random_events, mode):
    ev = random_events(2000, S.width, S.height, duration_us=200_000, rng=7)
    params = BufferParams(tau_min_us=2_000, mode=mode)
    want = ev[filter_events(ev, S, params)]
    rng = np.random.default_rng(0)
    for _ in range(3):
        cuts = np.sort(rng.integers(0, ev.size, 15))
        buf = EventBuffer(S, params)
        out = [buf.process(c) for c in np.split(ev, cuts)] + [buf.flush()]
        got = np.concatenate(out)
        np.testing.assert_array_equal(got, want)
        assert np.all(np.diff(got["t"]) >= 0)


def test_first_event_of_an_edge_kept_only_when_buffered():
    # a vertical edge moving right: column x fires at 1000 x us; plus one isolated event
    xs, ys = np.meshgrid(np.arange(5), np.arange(3))
    t = (xs.ravel() * 1000).astype(np.int64)
    order = np.argsort(t, kind="stable")
    x, y, t = xs.ravel()[order], ys.ravel()[order], t[order]
    x = np.append(x, 10)
    y = np.append(y, 8)
    t = np.append(t, 4500)
    ev = make_events(x, y, t, np.ones(x.size, bool))
    # within a column all pixels fire together: they support each other at dt = 0
    buffered = filter_events(ev, S)
    assert buffered[:-1].all() and not buffered[-1]
    # causal: the first column has support only from its own column (stream order)
    causal = filter_events(ev, S, BufferParams(mode="causal"))
    first_col = ev["x"] == 0
    assert not causal[np.flatnonzero(first_col)[0]]
    assert not causal[-1]


def test_single_leading_event_is_kept_after_its_neighbour_fires():
    ev = make_events([3, 4], [3, 3], [100, 100 + 9_999], [True, True])
    np.testing.assert_array_equal(filter_events(ev, S), [True, True])
    np.testing.assert_array_equal(filter_events(ev, S, BufferParams(mode="causal")), [False, True])
    late = make_events([3, 4], [3, 3], [100, 100 + 10_001], [True, True])
    np.testing.assert_array_equal(filter_events(late, S), [False, False])


def test_same_pixel_and_other_polarity_do_not_support():
    ev = make_events([3, 3, 4], [3, 3, 3], [0, 10, 20], [True, True, False])
    assert not filter_events(ev, S).any()


def test_release_latency_is_bounded_by_tau():
    buf = EventBuffer(S, BufferParams(tau_min_us=1_000))
    first = make_events([3], [3], [0], [True])
    assert buf.process(first).size == 0 and buf.n_pending == 1
    # a supporting neighbour arrives: both are released at once
    out = buf.process(make_events([4], [3], [900], [True]))
    assert out["t"].tolist() == [0, 900]
    # an unsupported event is dropped as soon as an event later than t + tau arrives
    assert buf.process(make_events([9], [8], [5_000], [True])).size == 0
    assert buf.n_pending == 1
    assert buf.process(make_events([0], [0], [6_001], [True])).size == 0
    assert buf.n_pending == 1  # only the newest waits
    assert buf.flush().size == 0


def test_advance_to_bounds_latency_without_new_events():
    buf = EventBuffer(S, BufferParams(tau_min_us=1_000))
    ev = make_events([3, 4, 9], [3, 3, 8], [0, 500, 600], [True, True, True])
    assert buf.process(ev)["t"].tolist() == [0, 500]  # supported: released at once
    assert buf.n_pending == 1
    assert buf.advance_to(1_600).size == 0 and buf.n_pending == 1  # t + tau = 1600 not yet passed
    assert buf.advance_to(1_601).size == 0 and buf.n_pending == 0  # dropped
    with pytest.raises(ValueError, match="before the newest"):
        buf.advance_to(1_000)
    with pytest.raises(ValueError, match="previous chunk"):
        buf.process(make_events([1], [1], [1_500], [True]))
    # chunked + advance_to == one-shot
    rnd = np.random.default_rng(0)
    t = np.sort(rnd.integers(0, 50_000, 400))
    evs = make_events(rnd.integers(0, S.width, 400), rnd.integers(0, S.height, 400), t, rnd.random(400) < 0.5)
    want = evs[filter_events(evs, S, BufferParams(tau_min_us=1_000))]
    buf.reset()
    out = []
    for chunk in np.array_split(evs, 9):
        out.append(buf.process(chunk))
        out.append(buf.advance_to(int(chunk["t"][-1]) + 1))
    out.append(buf.flush())
    np.testing.assert_array_equal(np.concatenate(out), want)


def test_reset_forgets():
    buf = EventBuffer(S)
    buf.process(make_events([3], [3], [0], [True]))
    buf.reset()
    assert buf.n_pending == 0
    assert buf.process(make_events([4], [3], [10], [True])).size == 0
    assert buf.flush().size == 0


@pytest.mark.parametrize(
    "kwargs, exc",
    [
        (dict(tau_min_us=0), ValueError),
        (dict(tau_min_us=-5), ValueError),
        (dict(tau_min_us=1.5), TypeError),
        (dict(tau_min_us="10"), TypeError),
        (dict(mode="both"), ValueError),
    ],
)
def test_bad_params(kwargs, exc):
    with pytest.raises(exc, match="BufferParams"):
        BufferParams(**kwargs)


def test_bad_inputs():
    good = make_events([1, 2], [1, 1], [0, 5], [True, True])
    with pytest.raises(TypeError, match="events"):
        filter_events(np.zeros(3), S)
    with pytest.raises(ValueError, match="outside the sensor"):
        filter_events(make_events([12], [0], [0], [True]), S)
    with pytest.raises(ValueError, match="not sorted"):
        filter_events(good[::-1].copy(), S)
    with pytest.raises(TypeError, match="params"):
        filter_events(good, S, params={"tau_min_us": 5})
    with pytest.raises(TypeError, match="sensor_size"):
        filter_events(good, 12)
    buf = EventBuffer(S)
    buf.process(good)
    with pytest.raises(ValueError, match="previous chunk"):
        buf.process(make_events([1], [1], [1], [True]))
    assert filter_events(np.empty(0, EVENT_DTYPE), S).shape == (0,)


def test_empty_state_in_numpy_equals_the_kernels():
    """The serial buffer's initial state (numpy, no compilation) has the bytes of the strips' (numba)."""
    from evedge.detector._buffer_kernels import empty_state, new_state

    for w, h in ((1, 1), (3, 7), (128, 128), (240, 180)):
        a, b = empty_state(w, h), new_state(w, h)
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes()
