"""The event buffer's kernel against its previous form (``_buffer_reference.py``): same keep masks.

Inputs: the real stripes.mat (when present), simulated edges with noise, random streams
with many ties in time and events on the sensor border; one shot, streaming in random
chunks (with ``advance_to``) and parallel strips, buffered and causal.
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from evedge.detector.buffer import BufferParams, EventBuffer, filter_events
from evedge.events import SensorSize, make_events

sys.path.insert(0, str(Path(__file__).parent))
from _buffer_reference import reference_mask  # noqa: E402

MODES = ["buffered", "causal"]




def _check_all_forms(events, size, tau_us, mode, rng):
    params = BufferParams(tau_min_us=tau_us, mode=mode)
    want = reference_mask(events, size, tau_us, mode == "causal")
    assert 0 < want.sum() < want.size, "the case must discriminate"
    np.testing.assert_array_equal(filter_events(events, size, params), want)
    for n_tiles in (2, 3):
        np.testing.assert_array_equal(filter_events(events, size, params, n_tiles=n_tiles), want)
    # streaming in chunks equals one-shot
    buf = EventBuffer(size, params)
    cuts = np.sort(rng.integers(0, events.size, 30))
    got = np.concatenate([buf.process(c) for c in np.split(events, cuts)] + [buf.flush()])
    np.testing.assert_array_equal(got, events[want])
    # with advance_to between chunks (never past the next chunk's first event)
    buf.reset()
    out = []
    chunks = np.split(events, cuts)
    for i, c in enumerate(chunks):
        out.append(buf.process(c))
        nxt = next((int(d["t"][0]) for d in chunks[i + 1:] if d.size), None)
        if nxt is not None and c.size:
            out.append(buf.advance_to(int(rng.integers(int(c["t"][-1]), nxt + 1))))
    out.append(buf.flush())
    np.testing.assert_array_equal(np.concatenate(out), events[want])


@pytest.mark.parametrize("mode", MODES)
def test_stripes_same_decisions(stripes_events, mode):
    size = SensorSize(128, 128)
    ev = stripes_events[:120_000]
    _check_all_forms(ev, size, 10_000, mode, np.random.default_rng(1))


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("seed", range(3))
def test_simulated_edges_and_noise_same_decisions(edge_events, mode, seed):
    size = SensorSize(40, 30)
    edges, _ = edge_events(size.width, size.height, 400.0, 0.3 + seed, n_edges=3, jitter_frac=0.3, rng=seed)
    g = np.random.default_rng(seed + 10)
    n_noise = edges.size // 4
    noise = make_events(g.integers(0, size.width, n_noise), g.integers(0, size.height, n_noise),
                        g.integers(int(edges["t"][0]), int(edges["t"][-1]), n_noise), g.random(n_noise) < 0.5)
    ev = np.concatenate([edges, noise])
    ev["p"] = g.random(ev.size) < 0.7
    ev = ev[np.argsort(ev["t"], kind="stable")]
    _check_all_forms(ev, size, 2_000, mode, g)


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("seed", range(4))
def test_random_ties_and_border_same_decisions(mode, seed):
    size = SensorSize(7 + seed, 5 + 2 * seed)
    g = np.random.default_rng(seed)
    n = 3000
    # few distinct timestamps (many ties), half of the events on the border rows and columns
    t = np.sort(g.integers(0, 400, n)) * 25
    x = g.integers(0, size.width, n)
    y = g.integers(0, size.height, n)
    border = g.random(n) < 0.5
    x[border] = np.where(g.random(border.sum()) < 0.5, 0, size.width - 1)
    y[border & (g.random(n) < 0.5)] = size.height - 1
    ev = make_events(x, y, t, g.random(n) < 0.5)
    _check_all_forms(ev, size, int(g.integers(1, 4)) * 25, mode, g)


@pytest.mark.parametrize("mode", MODES)
def test_one_pixel_wide_sensors(mode):
    g = np.random.default_rng(5)
    for size in (SensorSize(1, 20), SensorSize(20, 1)):
        n = 400
        ev = make_events(g.integers(0, size.width, n), g.integers(0, size.height, n), np.sort(g.integers(0, 4000, n)),
                         g.random(n) < 0.5)
        want = reference_mask(ev, size, 30, mode == "causal")
        np.testing.assert_array_equal(filter_events(ev, size, BufferParams(tau_min_us=30, mode=mode)), want)


@pytest.mark.parametrize("mode", MODES)
def test_times_at_the_int64_floor(mode):
    # the "never fired" sentinel is int64 min: a window starting exactly there must not count it
    size = SensorSize(4, 4)
    tau = 10
    t0 = np.iinfo(np.int64).min
    t = np.array([t0, t0, t0 + 3, t0 + tau, t0 + tau, t0 + 2 * tau + 1, t0 + 2 * tau + 1], np.int64)
    ev = make_events([1, 2, 0, 1, 3, 2, 2], [1, 1, 0, 2, 3, 2, 3], t, np.ones(t.size, bool))
    want = reference_mask(ev, size, tau, mode == "causal")
    np.testing.assert_array_equal(filter_events(ev, size, BufferParams(tau_min_us=tau, mode=mode)), want)
