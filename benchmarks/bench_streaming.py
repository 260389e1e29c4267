"""Streaming latency of the detector: 1 ms chunks of a recording, fed at its recorded rate.

The streaming :class:`evedge.detector.Detector` (event buffer -> intra-pixel
estimator -> edge image, one core) gets the events of each 1 ms of the
recording as one chunk with ``until_us`` = the chunk's end (what a driver with
a clock does: the buffer also releases what it has decided by then, and the
released events go through the estimator and the edge image in one call each).
Per chunk we time the processing (wall clock and the thread's CPU time) and
print the p50 / p99 latencies, the sustained rate (events / total processing
time) and whether it keeps up: sustained rate above the input rate and p99
latency under the chunk length.

Beside them, in the same run, the same events through the same stages in one
call each (``detect`` + the edge image), alternated with the streamed passes
(``--passes``, medians): streamed / one-shot CPU is the cost of streaming
(per-chunk overhead: checks, copies, one call per stage, and the stages'
states evicting each other from the caches between chunks). Keeping up on the
CPU (sustained CPU rate above the input's, p99 CPU latency under the chunk,
each chunk's least CPU over the passes) is the figure an idle machine would
give. The fixed cost of a chunk (one-event chunks, median) and the per-event
rest are printed, with the p99 a pipeline at ``--target-ns`` per event would
give with today's fixed cost (issue 12 item 1's 3.5 M events/s per core by
default).

Input: ``stripes.mat`` (DVS128, ~0.28 M events/s) as recorded; the same
recording with its time axis divided so it arrives at 2 M events/s (the issue's
target rate per core) and divided by ``--copies`` (the same events on the
same 128x128 sensor at ``copies`` times the rate: ~2.5 M events/s for 9, the
figure the detector must keep up with on one core; the scene moves 9x faster,
so lifetimes are 9x shorter); and the recording tiled ``--copies`` times side
by side on a larger sensor (384x384 for 9; each copy shifted in time by a few
ms so they do not fire in lockstep): the same scene at the same speed and
``copies`` times the rate, with a per-pixel state 9x larger (it no longer fits
in the core's cache: the cost of a larger sensor). The first 50 chunks are
a warm-up (compilation, caches) and are not counted. The machine is shared:
the load average is printed with the figures, CPU latencies are the robust
ones, wall latencies include preemption by other jobs.

Also printed: the estimator alone, its own ``process`` (a fresh one, checks
and record packing included) on the very chunks the stream released, and its
share of the streamed CPU: what is left when the buffer, the edge image and
the glue cost nothing. ``--base REV`` runs the ``detector/`` of a git revision
beside this tree's in the same process (its files in a temporary package,
``evedge.detector`` renamed; the two alternate within every pass, so they see
the same load), one line each; ``--only`` picks inputs; ``--intra key=value``
sets IntraParams fields for both (e.g. ``burst_reuse=true``).

``--tiles N`` runs the estimator on N row strips (numba threads; the strips keep their state between
chunks): the CPU figures then count every thread (``time.process_time``), the wall latencies are the ones to
compare with one core's.

Run: ``.venv/bin/python benchmarks/bench_streaming.py [--copies 9] [--chunk-us 1000] [--passes 3]
[--target-ns 286] [--intra burst_reuse=true ...] [--base REV] [--only recorded 2M copies tiled] [--tiles 2]``
(``--intra``: IntraParams fields, as in ``robustness_grid.py``, module ``_intra_options``).

Measured 2026-12-03 09:22-09:29 UTC, ``--base 2a1c4b7 --passes 5`` then the same with
``--intra burst_reuse=true`` (load 4.7 -> 6.5 on 2 CPUs: four engineers), 2a1c4b7 -> this tree
(the built-in stages pass plain columns, session 7); CPU latencies: each chunk's least over 5 passes:

=======================  =============  ===============  ================  ===========================
input, estimator         p99 CPU (us)   sustained CPU    streamed /        the estimator's process
                                        (M ev/s)         one-shot          alone: % of streamed
=======================  =============  ===============  ================  ===========================
as recorded, defaults    583 -> 459     0.73 -> 0.98     1.43 -> 1.10      68 -> 94
2 M ev/s, defaults       3399 -> 3206   0.86 -> 0.94     1.03 -> 1.01      86 -> 88
time / 9, defaults       4566 -> 4408   0.87 -> 0.92     1.08 -> 0.95      79 -> 92
tiled x 9, defaults      4830 -> 4382   0.72 -> 0.84     1.05 -> 1.02      76 -> 85
as recorded, reuse       459 -> 329     0.92 -> 1.40     1.84 -> 1.14      55 -> 92
2 M ev/s, reuse          2627 -> 2354   1.21 -> 1.39     1.11 -> 0.95      77 -> 87
time / 9, reuse          2875 -> 2718   1.38 -> 1.50     1.01 -> 0.91      78 -> 87
tiled x 9, reuse         3413 -> 2909   1.13 -> 1.24     1.11 -> 0.95      67 -> 87
=======================  =============  ===============  ================  ===========================

The fixed cost of a chunk went from 46-47 to 13-14 us (one row 81 -> 26, a load spike). Keeping
up at 2 M events/s (p99 under 1 ms, i.e. ~400 ns per event for the p99 chunk's 2453 events) is
not met, with or without burst reuse: the estimator's own ``process`` on the same chunks is
85-94 % of the streamed CPU now (87-92 % with reuse), and streamed / one-shot is about 1 (below
it, presumably: the one-shot ``detect`` copies records and touches whole-stream arrays; not
measured), so what is left is the estimator's per-event work. Run-to-run noise at this load:
about +-10 % on a row (a run 09:09-09:16, load 3.4-5.1, before 3872d18, differed that much).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
import types
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_detector import load_stripes  # noqa: E402
from _intra_options import _parse_intra  # noqa: E402

from evedge.detector import Detector, EdgeImage, IntraParams, detect  # noqa: E402
from evedge.events import EVENT_DTYPE, SensorSize  # noqa: E402

WARMUP_CHUNKS = 50

#: This tree's stages (a namespace of ``Detector``, ``EdgeImage``, ``detect``, as :func:`base_detector`'s).
_THIS = types.SimpleNamespace(Detector=Detector, EdgeImage=EdgeImage, detect=detect)


def base_detector(rev: str) -> types.SimpleNamespace:
    """``Detector``, ``EdgeImage`` and ``detect`` of ``detector/`` at git revision ``rev``, beside this tree's.

    Its files are written to a temporary package (``evedge.detector`` renamed
    in their text, so its registry and imports stay its own; the rest of
    ``evedge`` is this tree's) and imported: the two run in one process, on
    the same load. Its numba kernels compile on first use (not counted: warm-up).
    """
    import importlib
    import subprocess
    import tempfile

    repo = Path(__file__).resolve().parent.parent
    sha = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short", rev], check=True, capture_output=True,
                         text=True).stdout.strip()
    name = f"evedge_base_{sha}"
    root = Path(tempfile.gettempdir()) / f"bench_streaming_{name}"
    pkg = root / name
    pkg.mkdir(parents=True, exist_ok=True)
    files = subprocess.run(["git", "-C", str(repo), "ls-tree", "--name-only", sha, "detector/"], check=True,
                           capture_output=True, text=True).stdout.split()
    for f in files:
        if f.endswith(".py"):
            text = subprocess.run(["git", "-C", str(repo), "show", f"{sha}:{f}"], check=True, capture_output=True,
                                  text=True).stdout
            target = pkg / Path(f).name
            new = text.replace("evedge.detector", name)
            if not target.exists() or target.read_text() != new:  # unchanged files keep their numba cache
                target.write_text(new)
    sys.path.insert(0, str(root))
    mod = importlib.import_module(name)
    return types.SimpleNamespace(Detector=mod.Detector, EdgeImage=mod.EdgeImage, detect=mod.detect)


def tiled(events: np.ndarray, size: SensorSize, copies: int, rng=0):
    """``copies`` copies of ``events`` on a grid of sensors, each shifted by up to 5 ms; time-sorted."""
    side = int(np.ceil(np.sqrt(copies)))
    g = np.random.default_rng(rng)
    parts = []
    for c in range(copies):
        e = events.copy()
        e["x"] += (c % side) * size.width
        e["y"] += (c // side) * size.height
        e["t"] += int(g.integers(0, 5000))
        parts.append(e)
    out = np.concatenate(parts)
    out = out[np.argsort(out["t"], kind="stable")]
    return out, SensorSize(side * size.width, side * size.height)


def compressed(events: np.ndarray, factor: float) -> np.ndarray:
    """The recording with its time axis divided by ``factor`` (floored to whole us: still time-sorted)."""
    fast = events.copy()
    t0 = int(events["t"][0])
    fast["t"] = t0 + np.floor((events["t"] - t0) / factor).astype(np.int64)
    return fast


#: Row strips of the estimator (``--tiles``): with more than one the CPU clock is the process's (all threads).
TILES = 1


def _cpu() -> float:
    """CPU seconds: the calling thread's (one core), or the process's with strips (their threads too)."""
    return time.thread_time() if TILES == 1 else time.process_time()


def _detector(impl, size: SensorSize, params):
    """A streaming ``Detector`` of ``impl`` (on ``TILES`` strips when more than one)."""
    return impl.Detector(size, params=params) if TILES == 1 else impl.Detector(size, params=params, n_tiles=TILES)


def stream(events: np.ndarray, size: SensorSize, chunk_us: int, params=None, impl=None):
    """Per-chunk latencies (wall, CPU) in seconds and the event counts, after the warm-up; total CPU; released chunks.

    Each chunk is one call, ``Detector.process(chunk, until_us=chunk end)`` (the
    filter releases what it has decided by the chunk's end: ``process`` then
    ``advance_to`` in one pass through the estimator and the edge image).
    """
    det = _detector(impl or _THIS, size, params)
    t = events["t"]
    t0 = int(t[0])
    edges = np.arange(t0, int(t[-1]) + chunk_us, chunk_us)
    cuts = np.searchsorted(t, edges)
    wall, cpu, counts, released = [], [], [], []
    c_all = _cpu()
    for i in range(len(edges) - 1):
        chunk = events[cuts[i]:cuts[i + 1]]
        w0, c0 = time.perf_counter(), _cpu()
        out = det.process(chunk, until_us=int(edges[i + 1]))
        w1, c1 = time.perf_counter(), _cpu()
        if out[0].size:
            released.append(out[0])
        if i >= WARMUP_CHUNKS:
            wall.append(w1 - w0)
            cpu.append(c1 - c0)
            counts.append(chunk.size)
    out = det.flush()
    c_all = _cpu() - c_all
    if out[0].size:
        released.append(out[0])
    return np.array(wall), np.array(cpu), np.array(counts), c_all, released


def one_shot_cpu(events: np.ndarray, size: SensorSize, params=None, impl=None) -> float:
    """CPU seconds of the same work in one call per stage: buffer + estimator (``detect``) + the edge image."""
    impl = impl or _THIS
    c0 = _cpu()
    res = impl.detect(events, size, params=params, n_tiles=TILES) if TILES > 1 else impl.detect(events, size, params=params)
    image = impl.EdgeImage(size)
    image.process(events[res.kept], res.lifetimes[res.kept])
    return _cpu() - c0


def estimator_cpu(released, size: SensorSize, params=None, impl=None) -> float:
    """CPU seconds of the estimator alone (its ``process``, a fresh one) on the chunks the stream released.

    The same calls on the same events as inside the streamed pass: the floor of
    any pipeline around today's estimator (the rest of the streamed CPU is the
    buffer, the edge image and the glue).
    """
    est = _detector(impl or _THIS, size, params).estimator
    cpu = 0.0
    for chunk in released:
        c0 = _cpu()
        est.process(chunk)
        cpu += _cpu() - c0
    return cpu


def fixed_cost(events: np.ndarray, size: SensorSize, n: int = 3000, params=None, impl=None) -> float:
    """Median CPU seconds of one ``Detector.process`` call on a one-event chunk (the per-chunk fixed cost).

    The events of the stream one by one (after 500 of warm-up), each with
    ``until_us`` just after it: the checks, allocations and one call per stage
    that every chunk pays, plus one event's work.
    """
    det = _detector(impl or _THIS, size, params)
    cpu = []
    for i in range(min(n + 500, events.size)):
        t = int(events["t"][i])
        c0 = _cpu()
        det.process(events[i:i + 1], until_us=t)
        c1 = _cpu()
        if i >= 500:
            cpu.append(c1 - c0)
    return float(np.median(cpu))


def report(label, events, size, chunk_us, passes, target_ns, params=None, impls=None):
    """One line per implementation: latencies, sustained rate, keeping up, streamed / one-shot, cost model, projection.

    ``passes`` streamed passes alternate with as many one-shot runs (same process,
    same load); the streamed / one-shot ratio is that of their medians (whole
    stream, warm-up included, the same events). Latencies: the first pass (wall,
    CPU) and, per chunk, the least CPU over the passes (the chunk's own cost
    without other jobs' cache pollution). Projection: each chunk's least CPU minus
    the fixed cost of a chunk (:func:`fixed_cost`) is its per-event work; scaled by
    ``target_ns`` / today's mean per-event cost (a uniformly faster pipeline) and
    the fixed cost added back, the p99 over the same chunks is what a pipeline
    at ``target_ns`` per event would give with today's per-chunk overhead.

    ``impls``: ``(name, namespace)`` pairs (a namespace has ``Detector``,
    ``EdgeImage``, ``detect``; default: this tree's), measured alternately
    within each pass, one line each; ``params`` a mapping of IntraParams fields.
    """
    impls = impls or [("", _THIS)]
    span_s = (int(events["t"][-1]) - int(events["t"][0])) / 1e6
    rate = events.size / span_s
    load = os.getloadavg()[0]
    runs = {name: [] for name, _ in impls}
    whole = {name: [] for name, _ in impls}
    alone = {name: [] for name, _ in impls}
    for _, impl in impls:  # compilation (a first use of each tree's kernels) and first touches: not counted
        stream(events[:20_000], size, chunk_us, params, impl)
        one_shot_cpu(events[:20_000], size, params, impl)
    for _ in range(passes):
        for name, impl in impls:
            *run, released = stream(events, size, chunk_us, params, impl)
            runs[name].append(run)
            alone[name].append(estimator_cpu(released, size, params, impl))
            whole[name].append(one_shot_cpu(events, size, params, impl))
    fixed = {name: fixed_cost(events, size, params=params, impl=impl) for name, impl in impls}
    load_end = os.getloadavg()[0]
    for name, _ in impls:
        _line(f"{label} {name}".rstrip(), size, rate, chunk_us, passes, target_ns, runs[name], whole[name],
              alone[name], fixed[name], events.size, f"{load:.2f}->{load_end:.2f}")


def _line(label, size, rate, chunk_us, passes, target_ns, runs, whole, alone, a, n_events, load):
    """Print :func:`report`'s line of one implementation from its passes."""
    wall, cpu, counts, _ = runs[0]
    streamed = np.median([r[3] for r in runs])
    cpu_min = np.min([r[1] for r in runs], axis=0)
    ratio = streamed / np.median(whole)
    n = counts.sum()
    chunk_s = chunk_us * 1e-6
    keeps = n / wall.sum() >= rate and np.quantile(wall, 0.99) < chunk_s
    keeps_cpu = n / cpu_min.sum() >= rate and np.quantile(cpu_min, 0.99) < chunk_s
    per_event = (cpu_min.sum() - a * cpu_min.size) / n
    proj = np.quantile(a + (cpu_min - a) * (target_ns * 1e-9 / per_event), 0.99)
    print(f"{label:40s} {size.width}x{size.height} {rate / 1e6:5.2f} M ev/s in, {counts.mean():5.0f} ev/chunk "
          f"(p99 {np.quantile(counts, 0.99):5.0f}) | latency wall p50 {np.median(wall) * 1e6:5.0f} p99 "
          f"{np.quantile(wall, 0.99) * 1e6:5.0f} us, CPU p50 {np.median(cpu) * 1e6:5.0f} p99 "
          f"{np.quantile(cpu, 0.99) * 1e6:5.0f} us, least of {passes} p50 {np.median(cpu_min) * 1e6:5.0f} p99 "
          f"{np.quantile(cpu_min, 0.99) * 1e6:5.0f} us (p99 / chunk {np.quantile(cpu_min, 0.99) / chunk_s:.2f}) | "
          f"sustained {n / wall.sum() / 1e6:5.2f} M ev/s wall, {n / cpu_min.sum() / 1e6:5.2f} CPU | keeps up: wall "
          f"{'yes' if keeps else 'no'}, CPU {'yes' if keeps_cpu else 'no'} | streamed / one-shot CPU {ratio:.2f} "
          f"({streamed / n_events * 1e9:.0f} / {np.median(whole) / n_events * 1e9:.0f} ns per input event; the "
          f"estimator alone on the released chunks {np.median(alone) / n_events * 1e9:.0f}, "
          f"{np.median(alone) / streamed * 100:.0f} % of streamed) | fixed {a * 1e6:.0f} us per chunk + "
          f"{per_event * 1e9:.0f} ns/event; at {target_ns:.0f} "
          f"ns/event p99 would be {proj * 1e6:.0f} us | load {load} on {os.cpu_count()} CPUs")


#: The inputs (``--only``): as recorded, at 2 M events/s, time / copies, tiled copies.
INPUTS = ("recorded", "2M", "copies", "tiled")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--copies", type=int, default=9, help="copies of stripes.mat side by side (rate x copies)")
    ap.add_argument("--chunk-us", type=int, default=1000)
    ap.add_argument("--passes", type=int, default=3, help="streamed passes (and one-shot runs), alternated")
    ap.add_argument("--target-ns", type=float, default=1e9 / 3.5e6,
                    help="per-event cost of the projection (default: issue 12's 3.5 M events/s per core)")
    ap.add_argument("--intra", nargs="*", default=[], metavar="KEY=VALUE",
                    help="IntraParams fields of the estimator, e.g. burst_reuse=true (default: the defaults)")
    ap.add_argument("--base", metavar="REV",
                    help="also the detector/ of git revision REV, alternated with this tree's in each pass")
    ap.add_argument("--only", nargs="*", choices=INPUTS, default=list(INPUTS), help="the inputs to run (default: all)")
    ap.add_argument("--tiles", type=int, default=1,
                    help="row strips of the estimator on numba's threads (CPU figures then count every thread)")
    args = ap.parse_args(argv)
    global TILES
    TILES = args.tiles
    params = _parse_intra(args.intra)
    changed = {k: v for k, v in dataclasses.asdict(params).items() if v != getattr(IntraParams(), k)}
    impls = [("", _THIS)]
    if args.base:
        impls = [(f"[{args.base}]", base_detector(args.base)), ("[this tree]", _THIS)]
    # the fields as a mapping: both trees' detectors take it (each its own IntraParams class)
    rep = dict(chunk_us=args.chunk_us, passes=args.passes, target_ns=args.target_ns, params=changed, impls=impls)
    data = load_stripes()
    if data is None:
        return
    events, size = data
    assert events.dtype == EVENT_DTYPE
    cores = "one core" if TILES == 1 else f"the estimator on {TILES} strips (CPU: all threads)"
    print(f"chunks of {args.chunk_us} us, {cores}, first {WARMUP_CHUNKS} chunks not counted, "
          f"intra params: {changed or 'defaults'}")
    span_s = (int(events["t"][-1]) - int(events["t"][0])) / 1e6
    factor = 2e6 / (events.size / span_s)  # the target rate: 2 M events/s on one core
    if "recorded" in args.only:
        report("stripes.mat as recorded", events, size, **rep)
    if "2M" in args.only:
        report(f"stripes.mat, time / {factor:.2f} (2 M ev/s)", compressed(events, factor), size, **rep)
    if "copies" in args.only:
        report(f"stripes.mat, time / {args.copies}", compressed(events, args.copies), size, **rep)
    if "tiled" in args.only:
        big, big_size = tiled(events, size, args.copies)
        report(f"stripes.mat x {args.copies} (tiled)", big, big_size, **rep)


if __name__ == "__main__":
    main()
