"""Row strips in parallel (detector._tiles): the same bytes as the serial kernels, whatever the strip count."""

from pathlib import Path

import numpy as np
import pytest

from evedge.detector import detect, filter_events
from evedge.detector._tiles import check_n_tiles, strips
from evedge.detector.buffer import BufferParams
from evedge.detector.intra import IntraParams, IntraPixelLifetime, estimate_lifetimes, noise_params, robust_params
from evedge.events import EVENT_DTYPE, SensorSize

SCENES = Path(__file__).resolve().parents[2] / "scenes"


@pytest.fixture(scope="module")
def shapes():
    from evedge.sim import simulate

    rec = simulate(str(SCENES / "shapes_translation.toml"), duration_s=0.4, progress=False)
    return rec.events, rec.sensor_size


@pytest.fixture(scope="module")
def sim_stripes():
    from evedge.sim import simulate

    rec = simulate(str(SCENES / "stripes.toml"), duration_s=0.3, progress=False)
    return rec.events, rec.sensor_size


# the strips are shared by numba's threads (2 here): as many strips as threads, and more
TILES = (2, 3, 5, 16)


def test_strips_cover_the_rows_once():
    for h, n in ((180, 2), (128, 3), (7, 7), (100, 16)):
        s = strips(h, n)
        assert s[0, 0] == 0 and s[-1, 1] == h and np.all(s[1:, 0] == s[:-1, 1]) and np.all(s[:, 1] > s[:, 0])
        assert s[:, 1].max() - s[:, 0].min() == h and (s[:, 1] - s[:, 0]).max() - (s[:, 1] - s[:, 0]).min() <= 1


@pytest.mark.parametrize("scene", ["shapes", "sim_stripes"])
def test_estimator_strips_give_the_serial_bytes(request, scene):
    events, size = request.getfixturevalue(scene)
    sub = events[filter_events(events, size)]
    serial = estimate_lifetimes(sub, size)
    assert serial["valid"].mean() > 0.5  # a real workload, bursts included
    for n in TILES:
        assert estimate_lifetimes(sub, size, n_tiles=n).tobytes() == serial.tobytes(), n


def test_estimator_strips_on_the_real_recording(stripes_events):
    size = SensorSize(128, 128)
    sub = stripes_events[:60_000]
    serial = estimate_lifetimes(sub, size)
    for n in (2, 5):
        assert estimate_lifetimes(sub, size, n_tiles=n).tobytes() == serial.tobytes(), n


# options on only as the presets have them together (the rules that are a value, not None when off, alone too):
# numba compiles the strip kernels once per combination of the options off as None, ~10 s each cold
@pytest.mark.parametrize("params", [IntraParams(burst_lifetimes=0.0), IntraParams(window_size=7, per_polarity=False),
                                    IntraParams(burst_lifetimes=2.0, seed=5),
                                    robust_params(split_gap_ratio=1.5, split_jump_check=False, stale_fraction=0.0,
                                                  startup_reach=0.0, refine_window=9),
                                    IntraParams(burst_startup=True, border_px=2), robust_params(),
                                    noise_params(burst_span_lifetimes=1.5, refine_tolerance=0.5)])
def test_estimator_strips_other_parameters(shapes, params):
    events, size = shapes
    sub = events[:40_000]
    serial = estimate_lifetimes(sub, size, params)
    for n in (2, 7):
        assert estimate_lifetimes(sub, size, params, n_tiles=n).tobytes() == serial.tobytes(), n


def test_estimator_strips_streamed_in_chunks(shapes):
    """Strips carry the SAE and burst state across chunks: chunked with strips == one-shot serial."""
    events, size = shapes
    sub = events[:50_000]
    serial = estimate_lifetimes(sub, size)
    est = IntraPixelLifetime(size, n_tiles=3)
    cuts = [0, 1, 777, 20_000, 20_001, 50_000]
    out = np.concatenate([est.process(sub[a:b]) for a, b in zip(cuts[:-1], cuts[1:])])
    assert out.tobytes() == serial.tobytes()


def test_pipeline_strips(shapes):
    events, size = shapes
    serial = detect(events[:60_000], size)
    tiled = detect(events[:60_000], size, n_tiles=4)
    assert np.array_equal(tiled.kept, serial.kept) and tiled.lifetimes.tobytes() == serial.lifetimes.tobytes()


@pytest.mark.parametrize("mode", ["buffered", "causal"])
def test_buffer_strips_give_the_serial_decisions(shapes, random_events, mode):
    events, size = shapes
    noise = random_events(30_000, 240, 180, duration_us=200_000, rng=3)
    for ev in (events, noise):
        params = BufferParams(mode=mode)
        serial = filter_events(ev, size, params)
        for n in TILES:
            assert np.array_equal(filter_events(ev, size, params, n_tiles=n), serial), n


@pytest.mark.parametrize("bad, err", [(0, ValueError), (181, ValueError), (1.5, TypeError), (True, TypeError)])
def test_n_tiles_errors(bad, err):
    with pytest.raises(err, match="n_tiles"):
        check_n_tiles(bad, 180)
    with pytest.raises(err, match="n_tiles"):
        estimate_lifetimes(np.zeros(0, dtype=EVENT_DTYPE), (240, 180), n_tiles=bad)


def test_estimator_strips_on_a_single_worker(shapes):
    """With one numba thread, one worker runs all the strips in turn: still the serial bytes."""
    import numba

    events, size = shapes
    sub = events[:30_000]
    serial = estimate_lifetimes(sub, size)
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        tiled = estimate_lifetimes(sub, size, n_tiles=6)
    finally:
        numba.set_num_threads(before)
    assert tiled.tobytes() == serial.tobytes()


@pytest.fixture
def one_worker_small_turns(monkeypatch):
    """One numba thread, strips handed over every few events and tiny queues: the deferral paths run
    constantly (a strip far ahead of its neighbours defers, fills its queue, waits), deterministically."""
    import numba

    from evedge.detector import _tiles

    before = numba.get_num_threads()
    numba.set_num_threads(1)
    monkeypatch.setattr(_tiles, "_TURN_EVENTS", 400)
    monkeypatch.setattr(_tiles, "_QUEUE_MAX", 5)
    yield _tiles
    numba.set_num_threads(before)


# each noise rule alone is on top of the robust options (the noise preset's other option types)
@pytest.mark.parametrize("params", [IntraParams(), IntraParams(burst_startup=False),
                                    robust_params(split_gap_ratio=1.5, border_px=2),
                                    IntraParams(window_size=7, per_polarity=False, burst_lifetimes=2.0),
                                    robust_params(), IntraParams(stale_fraction=0.5), IntraParams(startup_reach=2.0),
                                    noise_params(newer_share_max=1.0, lifetime_agreement=0.0, burst_span_lifetimes=1.5),
                                    noise_params(newer_share_max=1.0, lifetime_agreement=1.3),
                                    noise_params(lifetime_agreement=0.0),
                                    noise_params(burst_span_lifetimes=1.5, refine_tolerance=0.5)])
def test_estimator_strips_with_constant_deferrals(shapes, one_worker_small_turns, params):
    """Out-of-order runs, full queues and halo replays waiting for a neighbour: still the serial bytes."""
    events, size = shapes
    sub = events[:30_000]
    serial = estimate_lifetimes(sub, size, params)
    deferred = waited = 0
    for n in (2, 5, 16):
        stats = np.zeros((n, 4), np.int64)
        real = one_worker_small_turns.intra_tiled

        def spy(*a, **k):
            return real(*a, stats=stats, **k)

        from evedge.detector import intra

        intra.intra_tiled = spy
        try:
            tiled = estimate_lifetimes(sub, size, params, n_tiles=n)
        finally:
            intra.intra_tiled = real
        deferred += stats[:, 1].sum()
        waited += stats[:, 3].sum()
        assert tiled.tobytes() == serial.tobytes(), n
    assert deferred > 1000 and waited > 5  # the paths under test did run (events deferred; turns with none ready)


@pytest.mark.parametrize("params", [IntraParams(), noise_params(burst_span_lifetimes=1.5, refine_tolerance=0.5)])
def test_estimator_strips_streamed_every_tile_count(sim_stripes, params):
    """Chunked through the streaming estimator with 2/3/5/16 strips (the halo state crosses chunks) == one shot;
    also with every rule of robust_params() and the noise rules on (startup_reach keeps the stream's start)."""
    events, size = sim_stripes
    sub = events[filter_events(events, size)][:40_000]
    serial = estimate_lifetimes(sub, size, params)
    cuts = [0, 5, 9_000, 9_001, 25_000, 40_000]
    for n in TILES:
        est = IntraPixelLifetime(size, params, n_tiles=n)
        out = np.concatenate([est.process(sub[a:b]) for a, b in zip(cuts[:-1], cuts[1:])])
        assert out.tobytes() == serial.tobytes(), n


def test_balanced_strips_follow_the_events():
    from evedge.detector._tiles import balanced_strips

    y = np.r_[np.full(900, 10), np.arange(100) % 50]  # nearly all events on row 10
    s = balanced_strips(y, 50, 3)
    assert s[0, 0] == 0 and s[-1, 1] == 50 and np.all(s[1:, 0] == s[:-1, 1]) and np.all(s[:, 1] > s[:, 0])
    assert s[0, 1] == 11  # the first cut right after the busy row
    even = balanced_strips(np.arange(90) % 90, 90, 3)
    assert np.array_equal(even[:, 1], [30, 60, 90])
    assert np.array_equal(balanced_strips(np.zeros(0, np.int64), 7, 7)[:, 0], np.arange(7))


def test_estimator_strips_carry_the_lifetimes_the_noise_rule_reads():
    """lifetime_agreement reads the inlier pixels' latest estimates, up to the window radius into a strip's halo:
    the owner publishes them with its burst decision. Narrow strips (3 rows, halo 2) and a strict ratio make most
    of those reads halo reads."""
    from evedge.bench.robustness import build
    from evedge.sim import parse_scene, simulate

    rec = simulate(parse_scene(build("stripes", 40, 30, 3, angle_deg=20, speed=300, r=3.0, noise_hz=5.0), "t"),
                   progress=False)
    params = noise_params(newer_share_max=1.0, lifetime_agreement=1.3)  # the rule alone on the robust options
    serial = estimate_lifetimes(rec.events, rec.sensor_size, params)
    assert 0 < serial["valid"].sum() < estimate_lifetimes(rec.events, rec.sensor_size, robust_params())["valid"].sum()
    assert estimate_lifetimes(rec.events, rec.sensor_size, params, n_tiles=10).tobytes() == serial.tobytes()


@pytest.mark.parametrize("halo", [0, 1, 2])
@pytest.mark.parametrize("n_tiles", [1, 2, 5])
def test_strip_index_and_gather_equal_the_naive_ones(halo, n_tiles):
    """The parallel chunked passes (row counts, strip index, owned-slot gather) against plain Python on more
    events than one chunk holds, rows skewed, with empty strips' halos and a last partial chunk."""
    from evedge.detector._chunks import CHUNK_EVENTS as _CHUNK_EVENTS
    from evedge.detector._tiles import _chunk_rows, _put_owned, _strip_index, balanced_strips, strip_layout

    rng = np.random.default_rng(halo * 10 + n_tiles)
    height = 37
    n = 3 * _CHUNK_EVENTS + 17
    y = np.minimum(rng.geometric(0.08, n) - 1, height - 1).astype(np.int64)
    part = _chunk_rows(y, height)
    assert part.shape == (4, height)
    for c in range(4):  # each chunk's row counts
        assert np.array_equal(part[c], np.bincount(y[c * _CHUNK_EVENTS:(c + 1) * _CHUNK_EVENTS], minlength=height))
    assert np.array_equal(_chunk_rows(y.astype(np.int16), height), part)
    own = balanced_strips(y, height, n_tiles)
    lo = np.maximum(own[:, 0] - halo, 0)
    hi = np.minimum(own[:, 1] + halo, height)
    idx, starts, off = _strip_index(y, lo, hi, part)
    layout = strip_layout(y, height, n_tiles, halo)  # the same, from one call
    for got, want in zip(layout, (own, lo, hi, idx, starts, off)):
        assert np.array_equal(got, want)
    for s in range(n_tiles):
        assert np.array_equal(idx[starts[s]:starts[s + 1]], np.flatnonzero((y >= lo[s]) & (y < hi[s])))
    # each strip's slots hold a value of (strip, event); the gather must pick the owner's slot of each event
    slots = np.empty(idx.size)
    for s in range(n_tiles):
        slots[starts[s]:starts[s + 1]] = s * 10 * n + idx[starts[s]:starts[s + 1]]
    outs = (np.empty(n), np.empty(n), np.empty(n), np.empty(n, bool))
    _put_owned(y, lo, hi, own[:, 0].copy(), own[:, 1].copy(), off, slots, slots * 2, slots * 3, slots % 2 == 0, *outs)
    owner = np.searchsorted(own[:, 1], y, side="right")
    expect = owner * 10 * n + np.arange(n)
    assert np.array_equal(outs[0], expect) and np.array_equal(outs[1], 2 * expect)
    assert np.array_equal(outs[2], 3 * expect) and np.array_equal(outs[3], expect % 2 == 0)
    empty = _strip_index(np.zeros(0, np.int64), lo, hi, _chunk_rows(np.zeros(0, np.int64), height))
    assert empty[0].size == 0 and np.all(empty[1] == 0) and empty[2].shape == (0, n_tiles)


def test_tiny_inputs_on_strips_equal_serial():
    """No event, one, two, a few: detect, the buffer, the estimator and the edge frames on 2, 3 and 6 strips (as
    many as the rows) give the serial bytes (the chunked passes, the buffer's two passes at once, empty strips)."""
    from evedge.detector import edge_frames
    from evedge.events import make_events

    size = SensorSize(8, 6)
    rng = np.random.default_rng(0)
    for n in (0, 1, 2, 5, 40):
        ev = make_events(rng.integers(0, 8, n), rng.integers(0, 6, n), np.sort(rng.integers(0, 10**5, n)),
                         rng.random(n) < 0.5)
        one = detect(ev, size)
        for n_tiles in (2, 3, 6):
            many = detect(ev, size, n_tiles=n_tiles)
            assert many.lifetimes.tobytes() == one.lifetimes.tobytes() and np.array_equal(many.kept, one.kept)
            assert np.array_equal(filter_events(ev, size, n_tiles=n_tiles), filter_events(ev, size))
            assert (estimate_lifetimes(ev, size, n_tiles=n_tiles).tobytes()
                    == estimate_lifetimes(ev, size).tobytes())
            times = [0, 50_000, 10**5]
            assert (edge_frames(ev, one.lifetimes, size, times, n_tiles=n_tiles).tobytes()
                    == edge_frames(ev, one.lifetimes, size, times).tobytes())


def test_streamed_strips_keep_their_state_and_show_it_when_read(sim_stripes):
    """A stream's strips keep their state between chunks (only the halos are refreshed) and the estimator's
    arrays are brought up to date when read: after every chunk the SAE and the burst state equal the serial
    stream's, reading them changes nothing that follows, and a reset starts over (a new cut)."""
    events, size = sim_stripes
    sub = events[filter_events(events, size)][:30_000]
    params = noise_params()
    cuts = [0, 3, 8_000, 8_001, 19_000, 30_000]
    serial = IntraPixelLifetime(size, params)
    est = IntraPixelLifetime(size, params, n_tiles=3)
    for a, b in zip(cuts[:-1], cuts[1:]):
        assert est.process(sub[a:b]).tobytes() == serial.process(sub[a:b]).tobytes()
        assert not est._strips.qcnt.any() and not est._strips.qrow.any()  # every deferral drained (kept)
        if b % 2:  # read after some chunks only: the next chunks must not depend on it
            assert np.array_equal(est.sae.times_us, serial.sae.times_us)
            for name in ("_prev_t", "_prev_lt", "_prev_pol", "_prev_fit"):
                assert getattr(est, name).tobytes() == getattr(serial, name).tobytes(), name
    assert est._strips.local is not None and est._strips.stale  # the last chunk's state not read yet
    assert np.array_equal(est.sae.times_us, serial.sae.times_us) and not est._strips.stale
    est.reset()
    serial.reset()
    assert est._strips.local is None and (est.sae.times_us == serial.sae.times_us).all()
    again = IntraPixelLifetime(size, params)
    assert est.process(sub[5_000:9_000]).tobytes() == again.process(sub[5_000:9_000]).tobytes()
