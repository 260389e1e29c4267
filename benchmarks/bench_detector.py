"""Events per second of each detector stage, on stripes.mat and simulated 240x180 sequences.

Sequences: ``stripes.mat`` (DVS128, Mueggler et al.'s recording), the simulator's
``scenes/shapes_translation.toml`` (240x180, 2 s; :mod:`evedge.sim`, about 2.5 s to
simulate) and, with ``--synthetic``, straight moving edges plus 5 % noise
(``_synthetic_edges``). Stages: event buffer (``filter_events``), SAE + 2-means + RANSAC
(``estimate_lifetimes`` on the kept events), edge frames at 100 fps
(``edge_frames``), the full pipeline (``detect``: buffer + estimator) and the
full pipeline with edge frames; Mueggler et al.'s baseline beside them when
present. One core (``n_tiles=1``); best of ``--repeat`` runs after a warm-up run
(compilation excluded), as CPU time of the process (robust when other jobs
share the machine) and as wall-clock time.

Beside them, in the same run:

* the bound: ``_bound_kernel.bound_stream``, a tight hand-written numba kernel
  doing the estimator's per-event work (same steps, draws and trial counts, no
  byte-exactness constraint); printed as project / bound (CPU);
* the strips (``n_tiles``): buffer + estimator on 1 and on ``--tiles`` strips
  (default 2; the strips are shared by numba's threads), alternated ``--repeat``
  times, wall and CPU; wall speedup = wall(1) / wall(N): on this shared machine
  it measures the load more than the strips. Beside it, figures that do not
  depend on the load: the simulated schedule of the strips' rules on idle
  workers (``_strip_schedule.py``, one unit per fit), the workers' own thread
  CPU clocks (in turns that ran events / waiting), the strips' extra CPU per
  event against the serial estimator (thread CPU, alternated), the share of
  events deferred, and from these the speedup expected on idle cores (Amdahl:
  ``detect``'s bookkeeping, the check serial, the columns and the expansion on the
  threads; the buffer with its two passes at once; the estimator's strips);
* the projection to a Prophesee Gen4 sensor (1280x720, 20 M events/s): cores
  needed = 20e6 x the measured CPU time per event of the full pipeline (buffer +
  estimator + edge image) / the strips' efficiency on 8 cores (simulated 8-strip
  speedup / 8 / the strips' extra CPU), and with detect's bookkeeping left on one
  core; last, the whole of it on a Gen4-sized input (``tiled_stripes_gen4``:
  ``stripes.mat`` tiled 10x6 on 1280x720, 0.1 s, ~1.6 M events; ``--only gen4``), from an
  empty state, and the estimator in steady state (:func:`gen4_steady`: the tiles' next 0.1 s
  after the first, with the per-core figure and the projection at that cost);
* the edge frames run on the strips too (``edge_frames(..., n_tiles)``): the wall
  speedup is printed for detect, for the edge frames and for both;
* the machine's load (1-minute load average before and after, CPU count): the
  machine is shared, wall-clock figures depend on it.

Run: ``.venv/bin/python benchmarks/bench_detector.py [--repeat 3] [--tiles 2] [--synthetic] [--no-gen4]
[--only stripes|shapes|gen4] [--preset defaults|robust|noise] [--intra KEY=VALUE ...]``; ``--preset`` and
``--intra`` (as in ``robustness_grid.py``, module ``_intra_options``) choose the estimator's
:class:`~evedge.detector.intra.IntraParams` for every stage (default: ``IntraParams()``), e.g.
``--intra burst_reuse=0``; the bound fits every event (its ratio is taken against the estimator with
``burst_reuse=0``, timed in the same run, and the reuse's own speedup is printed beside it) and does the
defaults' work for every other option (printed).

What limits the speed (2026-12-01, CPU time, best of 3, load average ~8 on the
2 CPUs): the intra-pixel estimator, ~0.52 us per kept event on stripes.mat and
~0.33 us on shapes_translation. Its per-event work is already at the bound:
the tight reference kernel (``_bound_kernel``) costs the same (project / bound
0.94 and 1.18). With one RANSAC trial the estimator still costs ~0.24 us per
event (window gather ~0.07, 2-means ~0.05-0.10, compaction, one trial, refit);
each further trial ~0.025 us, and stripes.mat runs ~10.2 trials per event
(shapes ~3.8) under the adaptive rule at stop_probability 0.999, so the trial
count, not the code, is what is left to gain on one core. The event buffer costs
~0.03 us per event (28-30 ns at load ~3, after its kernel's rewrite; was ~0.05; ~18 ns since its
one-shot two passes, 2026-12-03, ``bench_buffer.py``),
``detect``'s own bookkeeping (checks, boolean indexing) ~0.03 us.

On the Gen4-sized input (2026-12-07) a third of the estimator's time per kept event was
waiting for memory: its 1280x720 state misses the caches at nearly every event. The
stream kernel and the buffer's passes now ask for the next events' cache lines ahead
(:mod:`evedge.detector._prefetch`): 947 -> 681 ns per kept event, the buffer 53 -> 35
ns/event; the rest of the gap to ``stripes.mat`` is work (more events fitted from an empty
state: see the steady-state line this benchmark prints).

Profile of the estimator by stages (2026-12-01, engineer i12: copies of the
kernel returning after each stage, start-up rule off so that every event is
fitted once, CPU time in one run, load ~3; stripes.mat / shapes_translation, ns
per kept event): window gather with the per-event state ~62 / 63; 2-means
~64 / 58 (2.2 passes over ~21 points); compaction of the kept cluster ~44 / 35
(~13 points); RANSAC and refit the rest (516 / 330 in all; with one trial
267 / 250), i.e. ~26-30 ns per further trial at 10.4 / 3.9 trials per fit, 4.1
/ 1.9 tie-breaking cost sums per fit. Tried, same bytes, no gain beyond the
+-3 % noise: the inlier counts of the 4 candidates of a batch in one pass over
the points (4 independent lanes), counting in fixed blocks of 4 on padded
points, the tie-breaking cost only computed for a tie (and for the best so
far then), no inlier bookkeeping for the stream (1.00-1.03x). The 64-bit
modulo of the draws is ~3 ns per trial (a multiply-shift in its place, which
changes the draws: 1.05x). So the kernel is latency-bound per event (dependent
chains, unpredictable branches on the counts) rather than by any one loop, and
3.5 M events/s per core (~286 ns per event for all stages) would need about
half of today's estimator work per event: not reached.

Since 2026-12-03 the defaults reuse burst planes (``IntraParams.burst_reuse = 2``,
measured neutral on the simulator's truth; module notes of ``detector/intra.py``):
a burst's continuing events are refitted warm from the stored plane, then take it.
In one run (load 0.7-1.5) that made the estimator 1.38x cheaper on ``stripes.mat``
(864 -> 635 ns per kept event) and 1.83x on shapes_translation (461 -> 252); what is
left on ``stripes.mat`` is mostly the full fits of the bursts' first events (~55 %
of the kept events). The bound is compared with the estimator at ``burst_reuse = 0``
(the same work).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _synthetic_edges import edge_events  # noqa: E402

from _bound_kernel import bound_lifetimes  # noqa: E402
from _intra_options import PRESETS, _parse_intra  # noqa: E402

from evedge.detector import detect, edge_frames, estimate_lifetimes, filter_events  # noqa: E402
from evedge.detector.intra import IntraParams  # noqa: E402
from evedge.events import SensorSize, make_events  # noqa: E402

STRIPES = Path(__file__).resolve().parents[1] / ".." / "shared" / "realdata" / "rpg_event_lifetime" / "stripes.mat"


def load_stripes():
    if not STRIPES.exists():
        print(f"stripes.mat absent ({STRIPES}): skipped")
        return None
    from scipy.io import loadmat

    e = loadmat(str(STRIPES))["events"]
    return make_events(e[:, 0], e[:, 1], e[:, 3], e[:, 2]), SensorSize(128, 128)


def tiled_stripes_gen4(stripes, duration_s=0.1):
    """A Gen4-sized input: ``stripes.mat`` tiled 10 x 6 over 1280x720 (rows past 720 dropped).

    Each tile is the recording shifted circularly in time by its own offset
    (golden-ratio steps of the span), so the tiles show different phases of the
    motion; the first ``duration_s`` seconds: about 16 M events/s (Gen4's 20 M),
    ~1.6 M events at 0.1 s.
    """
    events, _ = stripes
    t0 = int(events["t"][0])
    span = int(events["t"][-1]) - t0 + 1
    rel = events["t"].astype(np.int64) - t0
    cols = {"x": [], "y": [], "t": [], "p": []}
    for i in range(6):
        for j in range(10):
            tile = i * 10 + j
            tt = (rel + int(span * ((tile * 0.6180339887) % 1.0))) % span
            keep = (tt < duration_s * 1e6) & (events["y"].astype(np.int64) + 128 * i < 720)
            cols["x"].append(events["x"][keep].astype(np.int64) + 128 * j)
            cols["y"].append(events["y"][keep].astype(np.int64) + 128 * i)
            cols["t"].append(tt[keep] + t0)
            cols["p"].append(events["p"][keep])
    c = {k: np.concatenate(v) for k, v in cols.items()}
    order = np.argsort(c["t"], kind="stable")
    ev = make_events(c["x"][order], c["y"][order], c["t"][order], c["p"][order])
    return ev, SensorSize(1280, 720)


def simulated_shapes(duration_s=2.0):
    """``scenes/shapes_translation.toml`` (240x180) simulated by :mod:`evedge.sim` (seeded: same events each run)."""
    from evedge.sim import simulate

    scene = Path(__file__).resolve().parents[1] / "scenes" / "shapes_translation.toml"
    if not scene.exists():
        print(f"scene absent ({scene}): skipped")
        return None
    rec = simulate(str(scene), duration_s=duration_s, progress=False)
    return rec.events, rec.sensor_size


def synthetic_240x180(rng=0):
    """Four families of moving edges (different speeds and angles) plus 5 % uniform noise events."""
    size = SensorSize(240, 180)
    parts = []
    for i, (speed, ang) in enumerate(((300, 0.2), (800, 1.9), (1500, 3.6), (2500, 5.0))):
        ev, _ = edge_events(240, 180, speed, ang, n_edges=3, spacing_px=20, jitter_frac=0.05,
                            subpixel_px=0.25, rng=rng + i)
        parts.append(ev)
    ev = np.concatenate(parts)
    ev = ev[np.argsort(ev["t"], kind="stable")]
    g = np.random.default_rng(rng + 99)
    n_noise = ev.size // 20
    noise = make_events(g.integers(0, 240, n_noise), g.integers(0, 180, n_noise),
                        np.sort(g.integers(int(ev["t"][0]), int(ev["t"][-1]), n_noise)), g.random(n_noise) < 0.5)
    ev = np.concatenate([ev, noise])
    ev["p"] = g.random(ev.size) < 0.5  # mixed polarities
    return ev[np.argsort(ev["t"], kind="stable")], size


def best_time(fn, repeat):
    """Best wall-clock and best CPU (process) time; CPU time is robust to a shared machine."""
    fn()  # warm-up: numba compilation or cache load
    wall, cpu = [], []
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    return min(wall), min(cpu)


def load_line():
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min) / {five:.2f} (5 min) on {os.cpu_count()} CPUs"


def bench(name, events, size, repeat, tiles, params, gen4=False):
    n = events.size
    span_s = (int(events["t"][-1]) - int(events["t"][0])) / 1e6
    print(f"\n== {name}: {n:,} events, {size.width}x{size.height}, {span_s:.2f} s of recording ==")
    print(f"before: {load_line()}")
    kept = filter_events(events, size)
    sub = events[kept]
    lifetimes = estimate_lifetimes(sub, size, params)
    frame_t = np.arange(int(events["t"][0]), int(events["t"][-1]), 10_000)
    plain = dataclasses.replace(params, burst_reuse=0)  # the bound's work: every event fitted
    one_trial = dataclasses.replace(params, max_trials=1)  # the least RANSAC work a fit can do
    rows = [
        ("buffer (filter_events)", n, lambda: filter_events(events, size)),
        ("SAE + 2-means + RANSAC (kept events)", sub.size, lambda: estimate_lifetimes(sub, size, params)),
        ("  bound: tight reference kernel (kept events)", sub.size, lambda: bound_lifetimes(sub, size.width,
                                                                                          size.height)),
        ("  the estimator with burst_reuse=0 (kept events)", sub.size, lambda: estimate_lifetimes(sub, size, plain)),
        ("  the estimator with max_trials=1 (kept events)", sub.size,
         lambda: estimate_lifetimes(sub, size, one_trial)),
    ] if not gen4 else [
        ("buffer (filter_events)", n, lambda: filter_events(events, size)),
        ("SAE + 2-means + RANSAC (kept events)", sub.size, lambda: estimate_lifetimes(sub, size, params)),
        ("  (bound and Mueggler baseline: skipped on the Gen4-sized input)", 1, None),
    ]
    rows += [
        (f"edge frames ({frame_t.size} frames at 100 fps)", sub.size,
         lambda: edge_frames(sub, lifetimes, size, frame_t)),
        ("full pipeline: detect (buffer + estimator)", n, lambda: detect(events, size, params=params)),
        ("full pipeline + edge frames", n, lambda: full_pipeline(events, size, frame_t, 1, params)),
    ]
    try:
        from evedge.detector.mueggler import estimate_lifetimes_mueggler

        if not gen4:
            rows.append(("Mueggler 2015 baseline (all events)", n, lambda: estimate_lifetimes_mueggler(events, size)))
    except ImportError:
        print("Mueggler baseline absent: skipped")
    print(f"{'stage (one core)':48s} {'events':>10s}   {'CPU ms':>8s} {'M ev/s':>7s} {'ns/ev':>6s}   "
          f"{'wall ms':>8s} {'M ev/s':>7s}")
    rate = {}
    for label, count, fn in rows:
        if fn is None:
            print(label)
            continue
        wall, cpu = best_time(fn, repeat)
        rate[label] = count / cpu
        print(f"{label:48s} {count:>10,}   {cpu * 1e3:8.1f} {count / cpu / 1e6:7.2f} {cpu / count * 1e9:6.0f}   "
              f"{wall * 1e3:8.1f} {count / wall / 1e6:7.2f}")
    label = {key: next(r[0] for r in rows if r[0].startswith(prefix)) for key, prefix in (
        ("buffer", "buffer"), ("est", "SAE"), ("edges", "edge frames"), ("detect", "full pipeline: detect"),
        ("full", "full pipeline + edge frames"))}
    est, full = label["est"], label["full"]
    if not gen4:
        bound, plain_row = rows[2][0], rows[3][0]
        print(f"project / bound (estimator with every event fitted, burst_reuse=0, as the bound; CPU time per "
              f"event): {rate[bound] / rate[plain_row]:.2f}  (target <= 1.5); burst reuse "
              f"(burst_reuse={params.burst_reuse}) makes the estimator {rate[est] / rate[plain_row]:.2f}x faster "
              f"(same run)")
        lt_b, valid_b = bound_lifetimes(sub, size.width, size.height)
        plain_lt = estimate_lifetimes(sub, size, plain)
        same = (valid_b == plain_lt["valid"]) & (~valid_b | (np.abs(lt_b - plain_lt["lifetime_us"]) <= 1e-9 * lt_b))
        print(f"  the bound's estimates equal the project's (burst_reuse=0; validity, lifetime to 1e-9) for "
              f"{same.mean():.4f} of the events")
    base = rows[-1][0]
    if base.startswith("Mueggler"):
        print(f"full pipeline / Mueggler baseline (CPU, events/s): {rate[label['detect']] / rate[base]:.2f}")
    print(f"kept by buffer {kept.mean():.3f}; with estimate (of kept) {lifetimes['valid'].mean():.3f}")
    print(f"per core, full pipeline + edge image: {rate[full] / 1e6:.2f} M events/s (CPU time); "
          f"target 3.5 M: ratio {rate[full] / 3.5e6:.2f}")
    if not gen4:
        # the least the estimator can cost with RANSAC at all (one trial per fit; estimates change): what is left of
        # a 3.5 M events/s budget per core after this run's buffer and edge frames, per kept event
        one = rows[4][0]
        rest_ns = 1e9 / rate[label["buffer"]] + kept.mean() * 1e9 / rate[label["edges"]]
        budget = (1e9 / 3.5e6 - rest_ns) / kept.mean()
        print(f"  one RANSAC trial per fit (max_trials=1): the estimator {1e9 / rate[one]:.0f} ns per kept event "
              f"(defaults {1e9 / rate[est]:.0f}); 3.5 M events/s per core leaves it {budget:.0f} ns per kept event "
              f"after this run's buffer and edge frames ({rest_ns:.0f} ns/event): one trial / budget "
              f"{1e9 / rate[one] / budget:.2f}")
    if tiles > 1:
        bench_tiles(events, size, repeat, tiles, sub, rate[full], sub.size / rate[label["edges"]] / n,
                    n / rate[label["buffer"]], frame_t, params)
    else:
        print(f"Gen4 (1280x720, 20 M events/s): {20e6 / rate[full]:.1f} cores at the measured per-core cost "
              f"({1e9 / rate[full]:.0f} ns/event), with no parallel loss")
    print(f"after: {load_line()}")
    return {"full_ns": 1e9 / rate[full], "est_ns": 1e9 / rate[est], "kept": float(kept.mean())}


def full_pipeline(events, size, frame_t, n_tiles, params):
    """detect (buffer + estimator) and the edge frames, all on ``n_tiles`` strips."""
    r = detect(events, size, params=params, n_tiles=n_tiles)
    # compress: boolean indexing of the records costs ~4x more
    return r, edge_frames(events.compress(r.kept), r.lifetimes.compress(r.kept), size, frame_t, n_tiles=n_tiles)


def _spy_intra_tiled(fn):
    """Run ``fn`` with the strips' counters captured: returns ``(fn(), [(stats, work) per call])``."""
    from evedge.detector import _tiles, intra

    calls = []
    real = _tiles.intra_tiled

    def spy(*a, **k):
        n_tiles = a[8]
        stats = np.zeros((n_tiles, 5), np.int64)  # fifth column: each strip's CPU time
        work = np.zeros((min(n_tiles, numba.get_num_threads()), 3), np.int64)
        calls.append((stats, work))
        return real(*a, stats=stats, work=work, **k)

    intra.intra_tiled = spy
    try:
        return fn(), calls
    finally:
        intra.intra_tiled = real


def bench_tiles(events, size, repeat, tiles, sub, full_rate, edge_s_per_event, buffer_s, frame_t, params):
    """Buffer + estimator (detect) and the edge frames on 1 and on ``tiles`` strips, alternated; the load-free
    proxies; the Gen4 projection.

    Prints, in one run: wall and CPU time of both, the wall speedups (limited by
    the machine's load); the strips' extra CPU: the workers' thread CPU in turns
    that ran events over the serial estimator's thread CPU, each pair run back
    to back (median of the pairs: the load drifts less within a pair), and each
    strip's own CPU time; the simulated schedule's speedup (``_strip_schedule``:
    the same rules on idle workers, one unit per fit: independent of the load);
    the speedup expected on idle cores from these (Amdahl); and the Gen4
    projection from the per-core cost measured in this run.
    """
    from _strip_schedule import simulate_strips

    from evedge.detector._tiles import balanced_strips

    threads = numba.get_num_threads()
    if threads < 2:
        print("strips: numba has a single thread; skipped")
        return
    one, f_one = full_pipeline(events, size, frame_t, 1, params)
    many, f_many = full_pipeline(events, size, frame_t, tiles, params)
    assert many.lifetimes.tobytes() == one.lifetimes.tobytes() and np.array_equal(many.kept, one.kept)
    assert f_many.tobytes() == f_one.tobytes()
    wall = {k: {"detect": [], "edges": [], "all": []} for k in (1, tiles)}
    cpu = {1: [], tiles: []}
    for _ in range(repeat):
        for k in (1, tiles):
            w0, c0 = time.perf_counter(), time.process_time()
            r = detect(events, size, params=params, n_tiles=k)
            w1 = time.perf_counter()
            edge_frames(events.compress(r.kept), r.lifetimes.compress(r.kept), size, frame_t, n_tiles=k)
            w2 = time.perf_counter()
            cpu[k].append(time.process_time() - c0)
            wall[k]["detect"].append(w1 - w0)
            wall[k]["edges"].append(w2 - w1)
            wall[k]["all"].append(w2 - w0)
    n = events.size
    w1, wk = min(wall[1]["all"]), min(wall[tiles]["all"])
    sp = {st: min(wall[1][st]) / min(wall[tiles][st]) for st in ("detect", "edges", "all")}
    print(f"strips (detect + edge frames, same bytes checked): 1 strip wall {n / w1 / 1e6:.2f} M ev/s "
          f"(CPU {n / min(cpu[1]) / 1e6:.2f}); {tiles} strips on {min(tiles, threads)} threads wall "
          f"{n / wk / 1e6:.2f} M ev/s (CPU {n / min(cpu[tiles]) / 1e6:.2f}); MEASURED WALL SPEEDUP {sp['all']:.2f}x "
          f"(detect {sp['detect']:.2f}x, edge frames {sp['edges']:.2f}x; best of {repeat}, alternated; target >= 1.8 "
          f"on idle cores)  [{load_line()}]")
    # the strips' extra CPU: thread clocks, each strip run right after a serial run (pairs)
    ser, busy, wait, ratios = [], [], [], []
    for _ in range(max(repeat, 5)):
        c0 = time.thread_time()
        estimate_lifetimes(sub, size, params)
        ser.append(time.thread_time() - c0)
        _, calls = _spy_intra_tiled(lambda: estimate_lifetimes(sub, size, params, n_tiles=tiles))
        stats, work = calls[0]
        busy.append(work[:, 0].sum() / 1e9)
        wait.append(work[:, 1].sum() / 1e9)
        ratios.append(busy[-1] / ser[-1])
    overhead = float(np.median(ratios))
    own = balanced_strips(sub["y"], size.height, tiles)
    owned = [np.count_nonzero((sub["y"] >= a) & (sub["y"] < b)) for a, b in own]
    print(f"  EXTRA CPU RATIO of the estimator's strips: {overhead:.3f}x the serial thread CPU (median of "
          f"{len(ratios)} back-to-back pairs: {', '.join(f'{v:.3f}' for v in ratios)}; best/best "
          f"{min(busy) / min(ser):.3f}; target <= ~1.05); serial {min(ser) * 1e3:.1f} ms; workers waiting "
          f"{min(wait) * 1e3:.1f} ms; deferred {stats[:, 1].sum() / sub.size:.2f} of the events (last run)")
    print("  per strip (last run): " + "; ".join(
        f"strip {s} rows {a}-{b}: {owned[s]:,} owned events, thread CPU {stats[s, 4] / 1e6:.1f} ms "
        f"({stats[s, 4] / max(owned[s], 1):.0f} ns/owned event), {stats[s, 0]:,} batches, {stats[s, 2]} turns"
        for s, (a, b) in enumerate(own)) + f"; events per worker {', '.join(f'{v:,}' for v in work[:, 2])}")
    # the load-free proxy: the simulated schedule on idle workers
    half = max(params.window_size, params.refine_window) // 2  # the radius the events read (the strips' halo)
    serial_valid = estimate_lifetimes(sub, size, params)["valid"]
    sims = {}
    for k in sorted({tiles, 8}):
        sims[k] = simulate_strips(sub, size, k, half=half, valid=serial_valid)
    print("  load-free proxy: simulated schedule (the strips' rules, idle workers, one unit per fit) "
          + "; ".join(f"{k} strips {v[0]:.2f}x (workers busy {v[1]:.2f}, deferred {v[2]:.2f})"
                      for k, v in sims.items())
          + f"; / the extra CPU ({overhead:.3f}x) -> estimator on {tiles} idle cores {sims[tiles][0] / overhead:.2f}x")
    # detect + edges = bookkeeping + the buffer (with n_tiles > 1 its two passes at once on two threads) +
    # estimator strips + edge strips
    per_strip = [np.count_nonzero((events["y"] >= a) & (events["y"] < b))
                 for a, b in balanced_strips(events["y"], size.height, tiles)]
    edge_speedup = events.size / max(per_strip) if tiles <= threads else threads
    edge_s = edge_s_per_event * n
    est1 = min(ser)
    # detect's and the edge frames' own bookkeeping, timed directly (the difference of totals is the load's noise):
    # the O(n) check, the kept events' columns, the expansion to all events, the compresses for the frames; the
    # columns and the expansion serially (CPU) and as detect runs them on strips (chunks in parallel, wall)
    from evedge.detector._checks import check_events
    from evedge.detector._stream_kernels import (_expand_lifetimes, _expand_lifetimes_par, _kept_columns,
                                                 _kept_columns_par, _kept_offsets)

    kept = one.kept
    est = one.lifetimes.compress(kept)
    est_cols = [np.ascontiguousarray(est[f]) for f in est.dtype.names]
    out = np.empty_like(one.lifetimes)
    serial_part = sum(best_time(f, repeat)[1] for f in (lambda: check_events(events, size),
                                                         lambda: events.compress(kept),
                                                         lambda: one.lifetimes.compress(kept)))
    columns_1 = sum(best_time(f, repeat)[1] for f in (lambda: _kept_columns(events, kept),
                                                      lambda: _expand_lifetimes(kept, *est_cols, out)))
    off = _kept_offsets(kept)
    columns_k = sum(best_time(f, repeat)[0] for f in (lambda: _kept_columns_par(events, kept, _kept_offsets(kept)),
                                                      lambda: _expand_lifetimes_par(kept, *est_cols, out, off)))
    rest = serial_part + columns_1
    buffer_k = best_time(lambda: filter_events(events, size, n_tiles=tiles), repeat)[0]
    cpu1 = est1 + buffer_s + edge_s + rest
    # the edge frames' strips on one thread (all strips in turn) against the serial frames: their extra CPU
    esub, elt = events.compress(kept), one.lifetimes.compress(kept)
    e_ratio = []
    numba.set_num_threads(1)
    try:
        for _ in range(max(repeat, 3)):
            c0 = time.thread_time()
            edge_frames(esub, elt, size, frame_t)
            c1 = time.thread_time()
            edge_frames(esub, elt, size, frame_t, n_tiles=tiles)
            e_ratio.append((time.thread_time() - c1) / (c1 - c0))
    finally:
        numba.set_num_threads(threads)
    edge_extra = float(np.median(e_ratio))
    print(f"  edge frames on {tiles} strips: thread CPU {edge_extra:.2f}x the serial frames (all strips on one "
          f"thread, median of {len(e_ratio)} pairs: each strip gathers its events' 8 columns and has its own state)")
    expect = cpu1 / (serial_part + columns_k + buffer_k + est1 * overhead / sims[tiles][0]
                     + edge_s * edge_extra / edge_speedup)
    print(f"  detect + edge frames on {tiles} idle cores, EXPECTED (Amdahl) {expect:.2f}x (serial bookkeeping "
          f"{serial_part * 1e3:.1f} ms, columns and expansion {columns_1 * 1e3:.1f} ms CPU -> {columns_k * 1e3:.1f} "
          f"ms wall on the threads, buffer {buffer_s * 1e3:.1f} ms CPU -> {buffer_k * 1e3:.1f} ms wall with its "
          f"passes at once, edge frames "
          f"{edge_s * 1e3:.1f} ms at {edge_speedup:.2f}x / {edge_extra:.2f}, estimator {est1 * 1e3:.1f} ms at "
          f"{sims[tiles][0]:.2f}x / {overhead:.3f}; target >= 1.8)")
    eff8 = sims[8][0] / 8 / overhead
    # s per event of what detect runs on one core: the check and the compresses, and half the buffer (its two
    # passes at once, no more); the columns and the expansion spread over the cores as the strips
    serial_s = (serial_part + buffer_s / 2) / n
    par = 1 / full_rate - serial_s  # s per event of the stages on strips
    serial_share = 20e6 * serial_s  # cores' worth of the serial part at Gen4's rate
    with_serial = (f"{20e6 * par / eff8 / (1 - serial_share):.1f}" if serial_share < 1
                   else "never (the serial part alone exceeds one core)")
    print(f"GEN4 PROJECTION (1280x720, 20 M events/s) from this run's per-core cost ({1e9 / full_rate:.0f} ns/event: "
          f"edge image {edge_s_per_event * 1e9:.0f}, bookkeeping {rest / n * 1e9:.0f}): {20e6 / full_rate:.1f} cores "
          f"with no parallel loss; {20e6 / full_rate / eff8:.1f} cores at the strips' 8-strip efficiency "
          f"(simulated 8-strip speedup / 8 / extra CPU = {eff8:.2f}), every stage spread over the cores; "
          f"{with_serial} with detect's serial part (the check, the compresses and a buffer pass: "
          f"{serial_share:.2f} core "
          f"at 20 M ev/s) left on one core (target <= 8)")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--synthetic", action="store_true", help="also the synthetic moving edges")
    ap.add_argument("--tiles", type=int, default=2,
                    help="strips for the parallel measurement, shared by numba's threads (1 = skip)")
    ap.add_argument("--no-gen4", action="store_true", help="skip the Gen4-sized input (tiled stripes, 1280x720)")
    ap.add_argument("--only", choices=("stripes", "shapes", "gen4"), help="run one input only")
    ap.add_argument("--preset", choices=sorted(PRESETS), default="defaults",
                    help="where the estimator's parameters start (default: IntraParams())")
    ap.add_argument("--intra", action="append", default=[], metavar="KEY=VALUE",
                    help="an IntraParams field on top of the preset (repeatable), e.g. burst_reuse=0")
    args = ap.parse_args(argv)
    params = _parse_intra(args.intra, PRESETS[args.preset]())
    changed = {f.name: getattr(params, f.name) for f in dataclasses.fields(params)
               if getattr(params, f.name) != getattr(IntraParams(), f.name)}
    print(f"estimator: IntraParams({', '.join(f'{k}={v!r}' for k, v in changed.items())})"
          + ("" if set(changed) <= {"burst_reuse"} else
             "; the bound kernel does the defaults' work only (plus burst_reuse): project / bound is not like "
             "for like"))
    run = (lambda name: args.only in (None, name))
    stripes = load_stripes() if run("stripes") or run("gen4") else None
    if stripes is not None and run("stripes"):
        bench("stripes.mat (DVS128)", *stripes, args.repeat, args.tiles, params)
    shapes = simulated_shapes() if run("shapes") else None
    if shapes is not None:
        bench("simulated shapes_translation (evedge.sim)", *shapes, args.repeat, args.tiles, params)
    if args.synthetic:
        bench("synthetic moving edges", *synthetic_240x180(), args.repeat, args.tiles, params)
    if stripes is not None and run("gen4") and not args.no_gen4:
        cold = bench("Gen4-sized: stripes.mat tiled 10x6 on 1280x720, 0.1 s", *tiled_stripes_gen4(stripes),
                     args.repeat, args.tiles, params, gen4=True)
        gen4_steady(stripes, args.repeat, params, cold)


def gen4_steady(stripes, repeat, params, cold):
    """The estimator on the Gen4-sized input in steady state: the tiles' second 0.1 s, after the first.

    The rows above start from an empty state (each tile's pixels have no history, so
    fewer events continue a burst and more are fitted); a running sensor is past that.
    The streaming estimator is fed the kept events of the first 0.1 s, untimed, then a
    copy of it (per repeat) the next 0.1 s (CPU, best of ``repeat``). The buffer runs on
    the whole 0.2 s once.
    """
    import copy

    from evedge.detector.intra import IntraPixelLifetime

    events, size = tiled_stripes_gen4(stripes, duration_s=0.2)
    kept = filter_events(events, size)
    half = int(np.searchsorted(events["t"], int(events["t"][0]) + 100_000))
    warm, timed = events[:half][kept[:half]], events[half:][kept[half:]]
    est = IntraPixelLifetime(size, params)
    est.process(warm)
    best = math.inf
    valid = None
    for _ in range(repeat):
        e = copy.deepcopy(est)
        c0 = time.process_time()
        out = e.process(timed)
        best = min(best, time.process_time() - c0)
        valid = out["valid"]
    first = estimate_lifetimes(events[:half][kept[:half]], size, params)["valid"].mean()
    ns = best / timed.size * 1e9
    full_ns = cold["full_ns"] + cold["kept"] * (ns - cold["est_ns"])  # the cold run's stages, this estimator
    print(f"\n== Gen4-sized in steady state: the estimator on the tiles' second 0.1 s ({timed.size:,} kept events) "
          f"after the first ({warm.size:,}, untimed) ==")
    print(f"SAE + 2-means + RANSAC, steady state: {best / timed.size * 1e9:.0f} ns per kept event (CPU, best of "
          f"{repeat}); with estimate {valid.mean():.3f} of the kept (the first 0.1 s from an empty state: "
          f"{first:.3f})  [{load_line()}]")
    print(f"per core, full pipeline + edge image with this estimator cost (the other stages as the cold run above): "
          f"{1e3 / full_ns:.2f} M events/s; Gen4 (20 M events/s): {20e6 * full_ns / 1e9:.1f} cores with no "
          f"parallel loss")


if __name__ == "__main__":
    main()
