"""CPU time per event of the one-shot event buffer (``filter_events``): the previous path against today's, one run.

The previous path (session 6, copied here as :func:`previous_filter`): ``check_events`` (range and order,
numpy passes over the strided fields), then the streaming kernel ``_buffer_scan`` (one forward pass that walks
each neighbour's chain of unsupported events, an int64 chain entry per event, 16 bytes of state per pixel).
Today's (:func:`evedge.detector.buffer.filter_events`): a forward pass with the checks fused in and a backward
pass, 8 bytes of state per pixel each, no per-event array but the mask (module notes of
:mod:`evedge.detector.buffer`).

Inputs: the real ``stripes.mat`` (DVS128, 340 k events) and the same repeated ``--copies`` times one after the
other (30: 10.2 M events, as ``bench_cli.py``'s file). For each option set (paper defaults, causal, the line rule
``line_params()``) it checks that both paths give the same bytes (and the strips, ``n_tiles=2``, too), then prints
ns/event of each (thread CPU time, least of ``--repeat`` calls after a warm-up: compilation excluded; each call
allocates its outputs, as a caller's would) and the ratio. Also the shares of today's path: the forward pass
(checks included), the backward pass. The load average is printed before and after.

Run: ``.venv/bin/python benchmarks/bench_buffer.py [--copies 30] [--repeat 5]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_detector import load_stripes  # noqa: E402

from evedge.detector._buffer_kernels import (_buffer_scan, _line_scan, _support_after, _support_before,  # noqa: E402
                                             empty_line_state, empty_state)
from evedge.detector._checks import check_events  # noqa: E402
from evedge.detector.buffer import BufferParams, filter_events, line_params  # noqa: E402


def previous_filter(events, size, params):
    """The one-shot buffer as it was before the two passes (serial path of ``_filter``, session 6)."""
    events = check_events(events, size)
    w, h = size.width, size.height
    n = events.shape[0]
    x, y, t, p = events["x"], events["y"], events["t"], events["p"]
    supported = np.empty(n, dtype=bool)
    _buffer_scan(x, y, t, p, np.empty(n, dtype=np.int64), supported, 0, 0, empty_state(w, h), w, h,
                 params.tau_min_us, params.mode == "causal")
    if params.line_window_us:
        _line_scan(x, y, t, p, supported, 0, 0, empty_line_state(w, h), w, h, params.line_window_us,
                   params.line_tolerance, params.line_quiet, params.line_count)
    return supported


def repeated(events, copies):
    """``events`` ``copies`` times one after the other, each shifted past the one before (as ``bench_cli.py``)."""
    span = int(events["t"][-1]) - int(events["t"][0]) + 1000
    parts = []
    for c in range(copies):
        e = events.copy()
        e["t"] += c * span
        parts.append(e)
    return np.concatenate(parts)


def least(fn, repeat):
    fn()
    best = np.inf
    for _ in range(repeat):
        c = time.thread_time()
        fn()
        best = min(best, time.thread_time() - c)
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--copies", type=int, default=30)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args(argv)
    data = load_stripes()
    if data is None:
        return 1
    ev, size = data
    big = repeated(ev, args.copies)
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs (thread CPU time, least of {args.repeat})")
    rules = [("paper defaults", BufferParams()), ("causal", BufferParams(mode="causal")), ("line_params()", line_params())]
    w, h = size.width, size.height
    for name, e in (("stripes.mat", ev), (f"{args.copies} x stripes.mat", big)):
        n = e.size
        for label, params in rules:
            want = previous_filter(e, size, params)
            got = filter_events(e, size, params)
            same = want.tobytes() == got.tobytes()
            same_strips = filter_events(e, size, params, n_tiles=2).tobytes() == want.tobytes()
            old = least(lambda: previous_filter(e, size, params), args.repeat)
            new = least(lambda: filter_events(e, size, params), args.repeat)
            print(f"{name:18s} {label:15s} previous {1e9 * old / n:5.1f}  today {1e9 * new / n:5.1f} ns/event  "
                  f"({old / new:.2f}x)  same bytes: serial {same}, strips {same_strips}  kept {100 * got.mean():.1f} %  "
                  f"({n:,} events)")
            if not (same and same_strips):
                raise SystemExit("different decisions")
        x, y, t, p = e["x"], e["y"], e["t"], e["p"]
        sup = np.empty(n, bool)
        fwd = least(lambda: _support_before(x, y, t, p, sup, w, h, 10_000), args.repeat)
        bwd = least(lambda: _support_after(x, y, t, p, sup, w, h, 10_000), args.repeat)
        chk = least(lambda: check_events(e, size), args.repeat)
        print(f"{name:18s} today's parts: forward pass with the checks {1e9 * fwd / n:.1f}, backward pass "
              f"{1e9 * bwd / n:.1f} ns/event; the previous path's check_events alone {1e9 * chk / n:.1f}")
    print(f"load average {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
