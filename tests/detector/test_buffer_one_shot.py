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

from evedge.detector._buffer_kernels import _buffer_scan, _support_after, _support_before, empty_state, one_shot_exact
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


def _two_pass_mask(ev, size, tau, causal):
    n = ev.size
    sup = np.empty(n, bool)
    assert _support_before(ev["x"], ev["y"], ev["t"], ev["p"], sup, size.width, size.height, tau) == -1
    if not causal:
        _support_after(ev["x"], ev["y"], ev["t"], ev["p"], sup, size.width, size.height, tau)
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
    assert _two_pass_mask(ev, size, tau, causal).tobytes() == want.tobytes()
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
    """Streams starting (ending) within tau of int64's min (max) take the chain kernel; one more us, the passes."""
    size = SensorSize(6, 5)
    tau = 50
    base = _random(size, 600, 2_000, 3)
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
