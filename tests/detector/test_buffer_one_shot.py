"""The one-shot buffer's two passes (``_support_before`` / ``_support_after``): same bytes as the chain kernel.

The one-shot path decides with a forward and a backward pass and checks the events inside the
forward pass; the streaming path (``EventBuffer``) and the times near the int64 range's ends keep
the chain kernel ``_buffer_scan``. Compared here: the two against each other and against the
previous kernel (``_buffer_reference.py``), at the boundary where the one-shot path switches
kernels, and the errors of the fused checks against ``check_events``'.
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from evedge.detector._buffer_kernels import (I32_MAX, _buffer_scan, _two_passes, empty_state, narrow_exact,
                                             narrow_state, one_shot_exact, run_passes)
from evedge.detector._checks import check_events, validated
from evedge.detector.buffer import BufferParams, EventBuffer, filter_events, line_params
from evedge.events import SensorSize, make_events

sys.path.insert(0, str(Path(__file__).parent))
from _buffer_reference import reference_mask  # noqa: E402

MODES = ["buffered", "causal"]
I64 = np.iinfo(np.int64)


def _chain_mask(ev, size, tau, causal):
    """The chain kernel on the whole stream at once (the previous one-shot path)."""
    n = ev.size
    sup = np.empty(n, bool)
    _buffer_scan(ev["x"], ev["y"], ev["t"], ev["p"], np.empty(n, np.int64), sup, 0, 0, empty_state(size.width,
                 size.height), size.width, size.height, tau, causal)
    return sup


def _two_pass_mask(ev, size, tau, causal, narrow):
    """The passes with the state asked for, as the strips run them (numba) and as filter_events does (numpy state)."""
    sup = np.empty(ev.size, bool)
    assert _two_passes(ev["x"], ev["y"], ev["t"], ev["p"], sup, size.width, size.height, tau, causal, narrow) == -1
    sup2 = np.empty(ev.size, bool)
    assert run_passes(ev["x"], ev["y"], ev["t"], ev["p"], sup2, size.width, size.height, tau, causal, narrow) == -1
    assert sup.tobytes() == sup2.tobytes()
    return sup


def _random(size, n, span, seed):
    g = np.random.default_rng(seed)
    return make_events(g.integers(0, size.width, n), g.integers(0, size.height, n), np.sort(g.integers(0, span, n)),
                       g.random(n) < 0.5)


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("seed", range(6))
def test_two_passes_equal_the_chain_kernel(mode, seed):
    size = SensorSize(5 + 3 * seed, 4 + 2 * seed)
    tau = [1, 20, 300][seed % 3]
    # about half the events supported; many ties in time at tau = 1 (4000 events over ~2400 us)
    ev = _random(size, 4000, 12 * 4000 * tau // (size.width * size.height), seed)
    causal = mode == "causal"
    want = _chain_mask(ev, size, tau, causal)
    assert 0 < want.sum() < want.size
    for narrow in (False, True):
        assert _two_pass_mask(ev, size, tau, causal, narrow).tobytes() == want.tobytes()
    assert filter_events(ev, size, BufferParams(tau_min_us=tau, mode=mode)).tobytes() == want.tobytes()


@pytest.mark.parametrize("mode", MODES)
def test_stripes_two_passes_equal_the_chain_kernel(stripes_events, mode):
    size = SensorSize(128, 128)
    for tau in (1_000, 10_000, 100_000):
        want = _chain_mask(stripes_events, size, tau, mode == "causal")
        params = BufferParams(tau_min_us=tau, mode=mode)
        assert filter_events(stripes_events, size, params).tobytes() == want.tobytes()
        assert filter_events(stripes_events, size, params, n_tiles=4).tobytes() == want.tobytes()


def test_line_rule_on_top_of_the_two_passes(stripes_events):
    """The line rule or-s into the buffer's mask: the same bytes whichever kernel made it."""
    from evedge.detector._buffer_kernels import _line_scan, empty_line_state

    size = SensorSize(128, 128)
    ev = stripes_events[:150_000]
    for params in (line_params(), line_params(line_count=1, line_quiet=0.0), line_params(tau_min_us=2_000)):
        want = _chain_mask(ev, size, params.tau_min_us, False)
        _line_scan(ev["x"], ev["y"], ev["t"], ev["p"], want, 0, 0, empty_line_state(128, 128), 128, 128,
                   params.line_window_us, params.line_tolerance, params.line_quiet, params.line_count)
        assert filter_events(ev, size, params).tobytes() == want.tobytes()
        assert filter_events(ev, size, params, n_tiles=3).tobytes() == want.tobytes()


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("end", ["floor", "ceiling"])
def test_at_the_kernel_switch(mode, end):
    """Streams starting (ending) within tau of int64's min (max) take the chain kernel; one more us, the passes
    (int64 state: the span is too long for the narrow one)."""
    size = SensorSize(6, 5)
    tau = 50
    base = _random(size, 600, 2_000, 3)
    base["t"][300:] += 2**40  # a long gap: the int64 state
    rel = base["t"] - base["t"][0]
    for margin in (tau - 1, tau, tau + 1, tau + 2):
        ev = base.copy()
        if end == "floor":
            ev["t"] = I64.min + margin + rel
            exact = one_shot_exact(ev["t"][0], ev["t"][-1], tau)
        else:
            ev["t"] = I64.max - margin - (rel[-1] - rel)
            exact = one_shot_exact(ev["t"][0], ev["t"][-1], tau)
        assert exact == (margin > tau)
        assert not narrow_exact(ev["t"][0], ev["t"][-1], tau)
        want = reference_mask(ev, size, tau, mode == "causal")
        params = BufferParams(tau_min_us=tau, mode=mode)
        assert filter_events(ev, size, params).tobytes() == want.tobytes()
        assert filter_events(ev, size, params, n_tiles=2).tobytes() == want.tobytes()
        buf = EventBuffer(size, params)
        got = np.concatenate([buf.process(c) for c in np.array_split(ev, 7)] + [buf.flush()])
        assert got.tobytes() == ev[want].tobytes()


def test_read_only_and_validated_events():
    size = SensorSize(9, 7)
    ev = _random(size, 3000, 30_000, 8)
    want = filter_events(ev, size)
    with validated(ev, size):
        assert filter_events(ev, size).tobytes() == want.tobytes()
        assert filter_events(ev[100:], size).tobytes() == filter_events(ev[100:].copy(), size).tobytes()
    ro = ev.copy()
    ro.flags.writeable = False
    assert filter_events(ro, size).tobytes() == want.tobytes()


def _message(fn):
    with pytest.raises(ValueError) as info:
        fn()
    return str(info.value)


@pytest.mark.parametrize("mode", MODES)
def test_fused_checks_raise_check_events_errors(mode):
    size = SensorSize(9, 7)
    params = BufferParams(tau_min_us=500, mode=mode)
    good = _random(size, 2000, 20_000, 9)
    cases = []
    for field, value in (("x", 9), ("x", -1), ("y", 7), ("y", -3)):
        e = good.copy()
        e[field][1500] = value
        cases.append(e)
    e = good.copy()
    e["t"][1200] = e["t"][1199] - 1  # a decrease in time
    cases.append(e)
    e = e.copy()
    e["x"][1700] = 20  # and a later coordinate out of range: check_events names the coordinate first
    cases.append(e)
    e = good.copy()
    e["x"][0] = 100  # the very first event
    cases.append(e)
    for e in cases:
        want = _message(lambda: check_events(e, size))
        assert _message(lambda: filter_events(e, size, params)) == want
        assert _message(lambda: filter_events(e, size, params, n_tiles=2)) == want
    # the events' error comes before a bad n_tiles, as before the checks were fused
    assert _message(lambda: filter_events(cases[0], size, params, n_tiles=0)) == _message(
        lambda: check_events(cases[0], size))
    with pytest.raises(ValueError, match="n_tiles"):
        filter_events(good, size, params, n_tiles=0)
    with pytest.raises(TypeError, match="n_tiles"):
        filter_events(good, size, params, n_tiles=1.5)


def test_other_dtypes_are_converted_first():
    size = SensorSize(9, 7)
    ev = _random(size, 500, 5_000, 4)
    other = np.zeros(ev.size, dtype=[("t", "<u8"), ("x", "<u2"), ("y", "<u2"), ("on", "?")])
    for a, b in (("t", "t"), ("x", "x"), ("y", "y"), ("on", "p")):
        other[a] = ev[b]
    assert filter_events(other, size).tobytes() == filter_events(ev, size).tobytes()
    assert filter_events(ev[:0], size).shape == (0,)
    assert filter_events(ev[:1], size).tolist() == [False]


@pytest.mark.parametrize("mode", MODES)
def test_narrow_state_up_to_its_limit(mode):
    """int32 times relative to the first event while span + tau < 2**31 - 1: the same bytes; at the limit the
    backward pass's sentinel would count as an event (so narrow_exact refuses it)."""
    size = SensorSize(6, 5)
    tau = 1000
    causal = mode == "causal"
    ev = _random(size, 800, 20_000, 6)
    ev["x"][-1], ev["y"][-1] = 0, 0  # the last event alone, far from the others in time
    ev["t"][400:-1] += 2**30  # a gap of about 18 min in the middle
    for span in (None, 2**31 - 2 - tau, 2**31 - 1 - tau):  # None: without the lone event (span ~2**30)
        e = ev[:-1].copy() if span is None else ev.copy()
        if span is not None:
            e["t"][-1] = e["t"][0] + span
        e["t"] += 10**15
        span = int(e["t"][-1] - e["t"][0])
        want = _chain_mask(e, size, tau, causal)
        assert _two_pass_mask(e, size, tau, causal, False).tobytes() == want.tobytes()
        ok = narrow_exact(e["t"][0], e["t"][-1], tau)
        assert ok == (span + tau < I32_MAX)
        params = BufferParams(tau_min_us=tau, mode=mode)
        assert filter_events(e, size, params).tobytes() == want.tobytes()
        assert filter_events(e, size, params, n_tiles=2).tobytes() == want.tobytes()
        narrow = _two_pass_mask(e, size, tau, causal, True)
        if ok or causal:
            assert narrow.tobytes() == want.tobytes()
        else:  # the lone last event: the sentinel I32_MAX is within its window
            assert not want[-1] and narrow[-1]
            assert narrow[:-1].tobytes() == want[:-1].tobytes()


@pytest.mark.parametrize("mode", MODES)
def test_large_sensor_takes_the_narrow_state(stripes_events, mode):
    """On a sensor whose int64 state would not fit L2, filter_events takes the int32 state: the same bytes."""
    size = SensorSize(400, 300)
    g = np.random.default_rng(11)
    ev = stripes_events[:60_000].copy()
    ev["x"] += g.integers(0, 3) * 128  # the stripes somewhere on the larger sensor, plus uniform noise
    ev["y"] += 100
    noise = make_events(g.integers(0, 400, 20_000), g.integers(0, 300, 20_000),
                        g.integers(int(ev["t"][0]), int(ev["t"][-1]), 20_000), g.random(20_000) < 0.5)
    ev = np.concatenate([ev, noise])
    ev = ev[np.argsort(ev["t"], kind="stable")]
    ev["t"] += 10**12  # relative times fit int32, absolute ones do not
    assert narrow_state(ev["t"][0], ev["t"][-1], 10_000, 400, 300)
    assert not narrow_state(ev["t"][0], ev["t"][-1], 10_000, 128, 128)  # a DVS128's state fits: int64
    want = _chain_mask(ev, size, 10_000, mode == "causal")
    assert 0 < want.sum() < want.size
    params = BufferParams(mode=mode)
    assert filter_events(ev, size, params).tobytes() == want.tobytes()
    assert filter_events(ev, size, params, n_tiles=3).tobytes() == want.tobytes()


@pytest.mark.parametrize("mode", MODES)
def test_streaming_strided_and_read_only_chunks(mode):
    """The streaming buffer copies each chunk's records as raw bytes: strided and read-only chunks too."""
    size = SensorSize(10, 8)
    params = BufferParams(tau_min_us=700, mode=mode)
    ev = _random(size, 6000, 150_000, 12)
    sub = ev[::2]  # a strided view
    assert not sub.flags.c_contiguous
    ro = sub.copy()
    ro.flags.writeable = False
    want = sub[filter_events(sub.copy(), size, params)]
    assert 0 < want.size < sub.size
    for stream in (sub, ro):
        buf = EventBuffer(size, params)
        chunks = np.array_split(stream, 13)
        got = np.concatenate([buf.process(c) for c in chunks] + [buf.flush()])
        assert got.dtype == want.dtype and got.tobytes() == want.tobytes()


@pytest.mark.parametrize("mode", MODES)
def test_both_passes_at_once_equal_the_serial_passes(mode):
    """n_tiles > 1, buffered: the forward and backward passes on two threads (_passes_both), each with its own
    state, then or-ed: the serial bytes, with the int32 state of a large sensor and the int64 one; a bad
    coordinate met first by the backward pass (the last event) still gives check_events' error, no crash."""
    from evedge.detector import detect
    from evedge.detector._buffer_kernels import narrow_state

    for size, n in ((SensorSize(640, 480), 60_000), (SensorSize(16, 12), 5_000)):
        ev = _random(size, n, 40 * n, 7)
        tau = 2_000
        params = BufferParams(tau_min_us=tau, mode=mode)
        want = _chain_mask(ev, size, tau, mode == "causal")
        assert 0 < want.sum() < want.size
        assert narrow_state(ev["t"][0], ev["t"][-1], tau, size.width, size.height) == (size.width == 640)
        for n_tiles in (2, 3):
            assert filter_events(ev, size, params, n_tiles=n_tiles).tobytes() == want.tobytes()
        for field, value in (("x", size.width), ("y", -1)):
            bad = ev.copy()
            bad[field][-1] = value
            want_msg = _message(lambda: check_events(bad, size))
            assert _message(lambda: filter_events(bad, size, params, n_tiles=2)) == want_msg
            assert _message(lambda: detect(bad, size, n_tiles=2)) == want_msg
