"""Where the estimator's per-event time goes: instrumented copies of the stream kernel, stopped at each stage.

A copy of :mod:`evedge.detector._intra_kernels` is generated (text; compiled
without cache) in which the stream kernel takes one more argument, ``stage``:

* ``record``: the real kernel, recording every fit's ``(ok, a, b)`` (per event
  and attempt);
* 0: no window gather and no fit; 1: gather (+ the int range and the random
  key); 2: + 2-means; 3: + compaction and the least-squares-first check (no
  trial, no refit); 4: the whole fit.

Stages 0-3 return the recorded fit results, so the burst bookkeeping and the SAE
evolve exactly as in the real run (the same windows at every stage). Printed:
CPU time (``time.process_time``) per kept event (the buffer's output) of each
stage, best of ``--repeat`` runs alternated, and the differences (the cost of
each stage), on stripes.mat and simulated shapes_translation (2 s).

Run: ``.venv/bin/python benchmarks/profile_stream.py [--repeat 15] [--limit 150000] [--base REV]``
(``--base``: the kernels of a git revision too, alternated with today's in the same
run; both must give the same bytes, checked).

Measured 2026-12-02 03:57 UTC (load 3.2, all kept events, best of 7; ``--base
52796c1 --limit 100000000 --repeat 7``), ns per kept event at the end of each stage,
before (52796c1) -> after the 2-means pass reductions:

==================  =====================  =====================
stage               shapes_translation     stripes.mat
==================  =====================  =====================
0 bookkeeping       52 -> 52               56 -> 55
1 + gather          134 -> 131 (+83/+79)   153 -> 145 (+97/+91)
2 + 2-means         189 -> 179 (+55/+47)   218 -> 201 (+65/+56)
3 + compact + LS    261 -> 258 (+71/+80)   289 -> 286 (+72/+85)
4 full fit          383 -> 376 (+123/+118) 753 -> 726 (+463/+439)
==================  =====================  =====================

Measured 2026-12-07 (load 1.0, first 150,000 kept events, best of 5; ``--repeat 5 --base 9d7b6b6``;
every event fitted: the kernel's burst reuse is off here), 9d7b6b6 -> today (the fit's scratch arrays
passed without reference counts, ``detector/_borrow.py``): shapes_translation 64 / 142 / 183 / 230 /
310 -> 45 / 112 / 166 / 215 / 293 ns per kept event at the end of stages 0-4, stripes.mat 67 / 151 /
196 / 260 / 631 -> 50 / 120 / 184 / 245 / 619 (the same bytes, checked).

No stage dominates on shapes: the fixed per-event work (stages 0-3, ~260 ns) is a
dozen short loops over the 5x5 window's ~10-20 points; RANSAC and the refit add
~120 ns there (82 % of the clusters skip the trials) and ~440 ns on stripes.mat.
Run-to-run noise at this load: +-10 ns per stage.
"""

from __future__ import annotations

import argparse
import inspect
import os
import re
import sys
import time
import types
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_detector import load_stripes, simulated_shapes  # noqa: E402

import evedge.detector._intra_kernels as K  # noqa: E402
from evedge.detector import filter_events  # noqa: E402
from evedge.detector.intra import IntraParams, noise_args  # noqa: E402

STAGES = (0, 1, 2, 3, 4)


def _instrumented(src=None):
    src = inspect.getsource(K) if src is None else src
    src = src.replace("cache=True", "cache=False")
    src = re.sub(r"from \.(\w+) import", r"from evedge.detector.\1 import", src)
    fit = src[src.index("@njit(cache=False)\ndef _fit_points("):src.index("@njit(cache=False)\ndef _event_on_plane")]
    full = fit.replace("def _fit_points(", "def _fit_full(")
    stage = fit.replace("def _fit_points(", "def _fit_stage(").replace("noise, ls_first):", "noise, ls_first, stage):")
    stage = stage.replace("    # ---- 2-means", "    if stage <= 1:\n        return False, np.nan, np.nan\n    # ---- 2-means")
    stage = stage.replace("    # an option passed as None (off)",
                          "    if stage <= 2:\n        return False, np.nan, np.nan\n    # an option passed as None (off)")
    stage = stage.replace("        k = 0\n        um = np.uint64(m)",
                          "        if stage <= 3:\n            return False, np.nan, np.nan\n        k = 0\n"
                          "        um = np.uint64(m)")
    assert stage.count("if stage <=") == 3
    wrap = '''
@njit(cache=False)
def _fit_points(wf, wi, n, exact, key, delta, thr_us, thr_rel, max_trials, stop_prob, log_fail, min_points,
                min_inliers, intercept, fallback, gap_ratio, on_plane, jump_check, noise, ls_first, rec, ri, stage):
    if stage < 0:
        r = _fit_full(wf, wi, n, exact, key, delta, thr_us, thr_rel, max_trials, stop_prob, log_fail, min_points,
                      min_inliers, intercept, fallback, gap_ratio, on_plane, jump_check, noise, ls_first)
        rec[ri, 0] = 1.0 if r[0] else 0.0
        rec[ri, 1] = r[1]
        rec[ri, 2] = r[2]
        return r
    if stage > 0:
        _fit_stage(wf, wi, n, exact, key, delta, thr_us, thr_rel, max_trials, stop_prob, log_fail, min_points,
                   min_inliers, intercept, fallback, gap_ratio, on_plane, jump_check, noise, ls_first, stage)
    return rec[ri, 0] == 1.0, rec[ri, 1], rec[ri, 2]


'''
    src = src.replace(fit, full + stage + wrap)
    a = src.index("@njit(cache=False)\ndef _intra_stream(")
    b = src.index("@njit(cache=False)\ndef _fit_windows(")
    st = src[a:b]
    # (the signature and the gather's radius as the kernel has had them: before the ring refit and after)
    if "out_valid, wf, wi, ls_first):" in st:
        st = st.replace("out_valid, wf, wi, ls_first):", "out_valid, wf, wi, ls_first, rec, stage):")
    else:  # optional arguments after ls_first (ring refit, burst reuse): rec and stage before them
        st = st.replace("wf, wi, ls_first, refine=None,", "wf, wi, ls_first, rec, stage, refine=None,")
    for radius in ("half", "fh"):
        call = f"_gather(sae, wf, wi, base, xk, yk, tk, width, rows, {radius}, oldest)"
        if "n, big = _gather(" in st:
            st = st.replace(f"= {call}", f"= {call} if stage != 0 else (0, 0)")
        else:  # before the gather returned (n, big)
            st = st.replace(f"= {call}", f"= {call} if stage != 0 else 0")
    st = st.replace("jump_check, noise, ls_first)", "jump_check, noise, ls_first, rec, 2 * k + attempt, stage)")
    assert "2 * k + attempt" in st and "if stage != 0" in st and "rec, stage" in st
    src = src[:a] + st
    mod = types.ModuleType("_intra_kernels_profiled")
    exec(compile(src, "<profiled _intra_kernels>", "exec"), mod.__dict__)
    return mod


def run(mod, events, size, pr, rec, stage):
    x, y, t, p = (np.ascontiguousarray(events[c]).astype(np.int64) for c in ("x", "y", "t", "p"))
    n = x.size
    w, h = size.width, size.height
    planes = 2 if pr.per_polarity else 1
    sae = np.full(planes * w * h, K._NEVER, np.int64)
    prev_t = np.zeros(sae.size, np.int64)
    prev_lt = np.full(sae.size, np.nan)
    prev_pol = np.full(sae.size, -1, np.int8)
    wf, wi = K.scratch_arrays(pr.window_size**2)
    lt, vx, vy, valid = np.empty(n), np.empty(n), np.empty(n), np.empty(n, np.bool_)
    c = time.process_time()
    mod._intra_stream(x, y, t, p, np.arange(n), 0, 0, sae, prev_t, prev_lt, prev_pol, pr.burst_lifetimes, w, h, 0,
                      h, 0, h, np.empty(0, np.int8), np.empty(0), pr.per_polarity, pr.window_size // 2, pr.delta_px,
                      pr.inlier_threshold_us, pr.inlier_threshold_rel, pr.max_trials, pr.stop_probability,
                      pr.min_points, pr.min_inliers, pr.refit_intercept, pr.fallback_all_points, pr.seed,
                      K.off_as_none(pr.split_gap_ratio), K.off_as_none(pr.event_on_plane), pr.burst_startup,
                      pr.border_px, pr.split_jump_check, pr.stale_fraction, K._NEVER, 0.0, noise_args(pr), lt, vx, vy,
                      valid, wf, wi, pr.ls_first, rec, stage)
    return time.process_time() - c, lt


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--base", help="also the kernels of this git revision, alternated with today's (one run)")
    ap.add_argument("--stages", default="0,1,2,3,4")
    ap.add_argument("--limit", type=int, default=150_000, help="first kept events timed (short runs, many repeats)")
    args = ap.parse_args(argv)
    stages = tuple(int(v) for v in args.stages.split(","))
    pr = IntraParams()
    mods = {"today": _instrumented()}
    if args.base:
        import subprocess

        old = subprocess.run(["git", "show", f"{args.base}:detector/_intra_kernels.py"], check=True,
                             capture_output=True, text=True, cwd=Path(__file__).resolve().parents[1]).stdout
        mods = {args.base: _instrumented(old), **mods}
    data = {}
    shapes = simulated_shapes()
    if shapes is not None:
        data["shapes_translation"] = shapes
    real = load_stripes()
    if real is not None:
        data["stripes.mat"] = real
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs; CPU ns per kept event, "
          f"best of {args.repeat}")
    names = ["0 bookkeeping", "1 +gather", "2 +2-means", "3 +compact+LS", "4 full fit"]
    for name, (ev, size) in data.items():
        sub = ev[filter_events(ev, size)][: args.limit]
        rec = np.zeros((2 * sub.size, 3))
        lt_ref = None
        for mod in mods.values():
            run(mod, sub[:2000], size, pr, rec, -1)  # compile
            _, lt = run(mod, sub, size, pr, rec, -1)
            assert lt_ref is None or np.array_equal(lt, lt_ref, equal_nan=True), "revisions differ"
            lt_ref = lt
        best = {(v, s): np.inf for v in mods for s in stages}
        for _ in range(args.repeat):
            for s in stages:
                for v, mod in mods.items():
                    dt, lt = run(mod, sub, size, pr, rec, s)
                    assert np.array_equal(lt, lt_ref, equal_nan=True)
                    best[v, s] = min(best[v, s], dt)
        print(f"{name} ({sub.size} kept events)" + "".join(f"{v:>22s}" for v in mods))
        prev = {v: 0.0 for v in mods}
        for s in stages:
            row = f"  {names[s]:16s}"
            for v in mods:
                ns = best[v, s] / sub.size * 1e9
                row += f" {ns:6.0f} ns (+{ns - prev[v]:5.0f})"
                prev[v] = ns
            print(row)
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
