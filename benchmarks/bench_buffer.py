"""CPU time per event of the one-shot event buffer (``filter_events``): the previous path against today's, one run.

The previous path (session 6, :func:`previous_filter`: its chain kernel, still the streaming buffer's, and a
copy of its line-rule kernel as it was): ``check_events`` (range
and order, numpy passes over the strided fields), then the chain kernel ``_buffer_scan`` (one forward pass that
walks each neighbour's chain of unsupported events, an int64 chain entry per event, 16 bytes of state per
pixel), then, with the line rule, its kernel ``_line_scan`` as it was.
Today's (:func:`evedge.detector.buffer.filter_events`): a forward pass with the checks fused in and a backward
pass, one time per pixel (int64, or int32 on large sensors), no per-event array but the mask (module notes of
:mod:`evedge.detector.buffer`).

Inputs: the real ``stripes.mat`` (DVS128, 340 k events) and the same repeated ``--copies`` times one after the
other (30: 10.2 M events, as ``bench_cli.py``'s file); with ``--gen4`` also ``bench_detector.py``'s Gen4-sized
input (``stripes.mat`` tiled over 1280x720, 0.1 s, 1.6 M events). For each option set (paper defaults, causal,
the line rule ``line_params()``) it checks that both paths give the same bytes (and the strips, ``n_tiles=2``,
too), then prints ns/event of each (thread CPU time, least of ``--repeat`` calls after a warm-up: compilation
excluded; each call allocates its outputs, as a caller's would) and the ratio. Also today's two passes alone,
with the state ``filter_events`` uses and with the other: both passes, the forward pass alone (checks
included); and the streaming buffer (:class:`~evedge.detector.buffer.EventBuffer`, the chain kernel) fed in
chunks of 100 k and 10 k events. The load average is printed before and after.

Run: ``.venv/bin/python benchmarks/bench_buffer.py [--copies 30] [--repeat 5] [--gen4]``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_buffer_rules import _best as least  # noqa: E402
from bench_cli import repeated  # noqa: E402
from bench_detector import load_stripes, tiled_stripes_gen4  # noqa: E402

from numba import njit  # noqa: E402

from evedge.detector._buffer_kernels import (LINE_FIELDS, NEVER, empty_line_state, empty_state,  # noqa: E402
                                             narrow_state, run_passes)
from evedge.detector._buffer_kernels import _buffer_scan as buffer_scan_prev  # noqa: E402
from evedge.detector._checks import check_events  # noqa: E402
from evedge.detector.buffer import BufferParams, EventBuffer, filter_events, line_params  # noqa: E402


# ---------------------------------------------------------------- the previous kernels, the reference of the
# timings: the chain kernel is the streaming buffer's, unchanged (imported); the line rule's as it was at
# 2a1c4b7 (a copy: its kernel has changed since)

@njit(cache=True, inline="always")
def _midway_prev(t1, tc, t2, line_us, line_tol):
    """Whether ``tc`` lies between ``t1`` and ``t2`` (either order), each at most ``line_us`` away, and about midway."""
    if t1 == NEVER or t2 == NEVER:
        return False
    if t1 > t2:
        t1, t2 = t2, t1
    if t1 > tc or tc > t2:
        return False
    d1 = t2 - tc
    d2 = tc - t1
    return d1 <= line_us and d2 <= line_us and abs(d1 - d2) <= line_tol * max(d1, d2)


@njit(cache=True)
def line_scan_prev(x, y, t, p, supported, n_old, base_g, state, width, height, line_us, line_tol, line_quiet,
               line_count):
    """The line rule for events ``n_old..`` (after :func:`_buffer_scan` on the same arrays): or-s into ``supported``.

    When event ``k`` (pixel ``u``) arrives, for each of the 8 directions ``a``, let
    ``c = u + a`` and ``e = u + 2a`` (same polarity), with their latest events
    before ``k`` at ``t_c`` and ``t_e``, and ``c``'s event before its latest at
    ``t_c0``. The event at ``c`` is supported when ``t_e <= t_c <= t_k``,
    ``d1 = t_k - t_c <= line_us``, ``d2 = t_c - t_e <= line_us``,
    ``|d1 - d2| <= line_tol * max(d1, d2)`` (:func:`_midway`),
    ``t_c - t_c0 >= line_quiet * (d1 + d2)`` (never fired before counts as quiet)
    and, with ``line_count = 2``, one of the three other pairs of opposite
    neighbours of ``c`` is midway too (their latest events before ``k``, either
    order): ``c``'s event lies midway in time between neighbours on opposite
    sides, as on an edge crossing the three pixels at a steady speed, however
    slowly, and its own pixel was quiet for longer than that edge took to cross
    the three (on an active pixel a chance midpoint is likely). Every pixel read
    is within one of ``c``, the supported one, so a one-row halo keeps strips
    exact. Only events still held are marked (the caller holds an unsupported
    event ``line_us`` long).
    """
    row = LINE_FIELDS * (width + 4)
    plane = (height + 4) * row
    n = x.shape[0]
    for k in range(n_old, n):
        tk = t[k]
        lo = tk - line_us
        lo_n = lo + (lo == NEVER)
        u = p[k] * plane + (y[k] + 2) * row + LINE_FIELDS * (x[k] + 2)
        for dy in range(-1, 2):
            for dx in range(-1, 2):
                if dx == 0 and dy == 0:
                    continue
                step = dy * row + LINE_FIELDS * dx
                c = u + step
                tc = state[c]
                if tc < lo_n:
                    continue
                gc = state[c + 1]
                if gc < base_g or supported[gc - base_g]:
                    continue
                te = state[c + step]
                if not _midway_prev(te, tc, tk, line_us, line_tol):
                    continue
                tc0 = state[c + 2]
                if tc0 != NEVER and tc - tc0 < line_quiet * (tk - te):
                    continue
                if line_count >= 2:
                    found = False
                    for b in range(4):  # the pairs (1, 0), (0, 1), (1, 1), (1, -1), but the one along a
                        bx = 1 if b != 1 else 0
                        by = 0 if b == 0 else (1 if b != 3 else -1)
                        if (bx == dx and by == dy) or (bx == -dx and by == -dy):
                            continue
                        sb = by * row + LINE_FIELDS * bx
                        if _midway_prev(state[c + sb], tc, state[c - sb], line_us, line_tol):
                            found = True
                            break
                    if not found:
                        continue
                supported[gc - base_g] = True
        state[u + 2] = state[u]
        state[u] = tk
        state[u + 1] = base_g + k


# ----------------------------------------------------------------


def previous_filter(events, size, params):
    """The one-shot buffer as it was before the two passes (serial path of ``_filter``, session 6)."""
    events = check_events(events, size)
    w, h = size.width, size.height
    n = events.shape[0]
    x, y, t, p = events["x"], events["y"], events["t"], events["p"]
    supported = np.empty(n, dtype=bool)
    buffer_scan_prev(x, y, t, p, np.empty(n, dtype=np.int64), supported, 0, 0, empty_state(w, h), w, h,
                     params.tau_min_us, params.mode == "causal")
    if params.line_window_us:
        line_scan_prev(x, y, t, p, supported, 0, 0, empty_line_state(w, h), w, h, params.line_window_us,
                       params.line_tolerance, params.line_quiet, params.line_count)
    return supported


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--copies", type=int, default=30)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--gen4", action="store_true", help="also stripes.mat tiled over 1280x720 (bench_detector's)")
    args = ap.parse_args(argv)
    data = load_stripes()
    if data is None:
        return 1
    ev, size = data
    big = repeated(ev, args.copies)
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs (thread CPU time, least of {args.repeat})")
    rules = [("paper defaults", BufferParams()), ("causal", BufferParams(mode="causal")),
             ("line_params()", line_params())]
    inputs = [("stripes.mat", ev, size), (f"{args.copies} x stripes.mat", big, size)]
    if args.gen4:
        inputs.append(("Gen4-sized", *tiled_stripes_gen4((ev, size))))
    for name, e, size in inputs:
        n = e.size
        w, h = size.width, size.height
        for label, params in rules:
            want = previous_filter(e, size, params)
            got = filter_events(e, size, params)
            same = want.tobytes() == got.tobytes()
            same_strips = filter_events(e, size, params, n_tiles=2).tobytes() == want.tobytes()
            old = least(lambda: previous_filter(e, size, params), args.repeat)
            new = least(lambda: filter_events(e, size, params), args.repeat)
            print(f"{name:18s} {label:15s} previous {1e9 * old / n:5.1f}  today {1e9 * new / n:5.1f} ns/event  "
                  f"({old / new:.2f}x)  same bytes: serial {same}, strips {same_strips}  "
                  f"kept {100 * got.mean():.1f} %  "
                  f"({n:,} events)")
            if not (same and same_strips):
                raise SystemExit("different decisions")
        x, y, t, p = e["x"], e["y"], e["t"], e["p"]
        sup = np.empty(n, bool)
        narrow = narrow_state(t[0], t[-1], 10_000, w, h)
        parts = []
        for nar in (narrow, not narrow):
            fwd = least(lambda: run_passes(x, y, t, p, sup, w, h, 10_000, True, nar), args.repeat)
            both = least(lambda: run_passes(x, y, t, p, sup, w, h, 10_000, False, nar), args.repeat)
            parts.append(f"{'int32' if nar else 'int64'} state{' (used)' if nar == narrow else ''}: "
                         f"both {1e9 * both / n:.1f}, forward with the checks {1e9 * fwd / n:.1f}")
        for chunk in (100_000, 10_000):  # the streaming buffer (the chain kernel), as a live caller feeds it
            def stream(chunk=chunk):
                buf = EventBuffer(size)
                out = [buf.process(e[i:i + chunk]) for i in range(0, n, chunk)]
                return out + [buf.flush()]
            same = np.concatenate(stream()).tobytes() == e[filter_events(e, size)].tobytes()
            print(f"{name:18s} EventBuffer, chunks of {chunk:,}: {1e9 * least(stream, args.repeat) / n:.1f} ns/event "
                  f"(paper defaults; same events as filter_events: {same})")
            if not same:
                raise SystemExit("different decisions")
        chk = least(lambda: check_events(e, size), args.repeat)
        print(f"{name:18s} today's passes, ns/event: {'; '.join(parts)}; the previous path's check_events alone "
              f"{1e9 * chk / n:.1f}")
    print(f"load average {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
