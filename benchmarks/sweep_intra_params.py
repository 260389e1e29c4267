"""Sweep the parameters the paper leaves open (inlier threshold, trials, minimum inliers).

Ground truth: straight edges (``_synthetic_edges.edge_events``) on a 48x48 sensor,
8 speeds from 20 to 5000 px/s (lifetimes 50 ms .. 200 us) x 6 angles, under two
noise conditions: "mild" (sub-pixel position error +-0.25 px, jitter 2 % of
the lifetime), "severe" (+-0.25 px, jitter 5 %, 10 % scattered outliers) and
"burst" (3 events per pixel per edge at sub-pixel edge positions -1/3, 0, +1/3 px,
each +-0.1 px, jitter 2 %: the multi-event edges of a real sensor).
Events within 2 px of the border are not scored. Score: share of the scored
events with an estimate within 10 % of the true lifetime (``good``), beside the
share with an estimate (``valid``) and the median relative error of the
estimates (``med``); the overall score is the mean over the conditions.

Run: ``.venv/bin/python benchmarks/sweep_intra_params.py``.
"""

from __future__ import annotations

import itertools
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _synthetic_edges import edge_events  # noqa: E402

from evedge.detector.intra import IntraParams, estimate_lifetimes  # noqa: E402
from evedge.events import SensorSize  # noqa: E402

SIZE = SensorSize(48, 48)
SPEEDS = (20, 50, 100, 200, 500, 1000, 2000, 5000)
ANGLES = np.deg2rad((0, 15, 30, 45, 60, 80))
NOISE = {
    "mild": dict(subpixel_px=0.25, jitter_frac=0.02, outlier_frac=0.0),
    "severe": dict(subpixel_px=0.25, jitter_frac=0.05, outlier_frac=0.10),
    "burst": dict(subpixel_px=0.1, jitter_frac=0.02, outlier_frac=0.0, events_per_edge=3),
}


def scenarios():
    out = {}
    for name, noise in NOISE.items():
        rows = []
        for i, (v, a) in enumerate(itertools.product(SPEEDS, ANGLES)):
            ev, tau = edge_events(SIZE.width, SIZE.height, v, a, rng=1000 + i, **noise)
            inner = (ev["x"] >= 2) & (ev["x"] < SIZE.width - 2) & (ev["y"] >= 2) & (ev["y"] < SIZE.height - 2)
            rows.append((ev, tau, inner))
        out[name] = rows
    return out


def score(rows, params):
    n = good = valid = 0
    errs = []
    for ev, tau, inner in rows:
        r = estimate_lifetimes(ev, SIZE, params)[inner]
        rel = np.abs(r["lifetime_us"][r["valid"]] / tau - 1.0)
        n += inner.sum()
        valid += r["valid"].sum()
        good += (rel < 0.10).sum()
        errs.append(rel)
    errs = np.concatenate(errs)
    return good / n, valid / n, float(np.median(errs)) if errs.size else float("nan")


def report(data, params, label):
    parts = []
    total = 0.0
    for name, rows in data.items():
        g, v, m = score(rows, params)
        total += g
        parts.append(f"{name}: good {g:.3f} valid {v:.3f} med {m:.3f}")
    print(f"{label:55s} mean good {total / len(data):.3f} | " + " | ".join(parts), flush=True)
    return total / len(data)


def main():
    t0 = time.perf_counter()
    data = scenarios()
    base = IntraParams()
    print("== defaults and delta ==")
    report(data, base, "defaults")
    report(data, IntraParams(delta_px=0.0), "delta_px=0 (no intra-pixel area)")
    report(data, IntraParams(delta_px=0.5), "delta_px=0.5")
    report(data, IntraParams(refit_intercept=False), "refit through the current event")
    report(data, IntraParams(fallback_all_points=False), "no fallback to all points")
    for bl in (0.0, 0.5, 2.0):
        report(data, IntraParams(burst_lifetimes=bl), f"burst_lifetimes={bl:g}" + (" (paper's SAE)" if bl == 0 else ""))
    print("== inlier threshold (abs us, rel) ==")
    best = None
    for thr_us, thr_rel in itertools.product((10.0, 50.0, 200.0, 1000.0), (0.0, 0.05, 0.1, 0.2, 0.4)):
        p = IntraParams(inlier_threshold_us=thr_us, inlier_threshold_rel=thr_rel)
        s = report(data, p, f"thr_us={thr_us:g} thr_rel={thr_rel:g}")
        if best is None or s > best[0]:
            best = (s, thr_us, thr_rel)
    print("best threshold:", best)
    print("== trials / minimum inliers / min points (at default threshold) ==")
    for trials, stop in ((5, 1.0), (10, 1.0), (20, 1.0), (40, 1.0), (20, 0.99), (20, 0.999), (40, 0.999)):
        report(data, IntraParams(max_trials=trials, stop_probability=stop), f"max_trials={trials} stop_probability={stop}")
    for mi in (3, 4, 5, 6, 8, 10):
        report(data, IntraParams(min_inliers=mi, min_points=min(mi, 5)), f"min_inliers={mi} min_points={min(mi, 5)}")
    print("== accuracy of the defaults per speed (all angles; median |relative error|, share with estimate) ==")
    conditions = {"noise-free": dict(), **NOISE}
    print(f"{'speed px/s':>10s} " + " ".join(f"{c:>22s}" for c in conditions))
    for i_v, v in enumerate(SPEEDS):
        cells = []
        for noise in conditions.values():
            errs, valid, n = [], 0, 0
            for i_a, a in enumerate(ANGLES):
                ev, tau = edge_events(SIZE.width, SIZE.height, v, a, rng=5000 + 10 * i_v + i_a, **noise)
                inner = (ev["x"] >= 2) & (ev["x"] < SIZE.width - 2) & (ev["y"] >= 2) & (ev["y"] < SIZE.height - 2)
                r = estimate_lifetimes(ev, SIZE, base)[inner]
                errs.append(np.abs(r["lifetime_us"][r["valid"]] / tau - 1))
                valid += r["valid"].sum()
                n += inner.sum()
            cells.append(f"{np.median(np.concatenate(errs)) * 100:8.2f} % {valid / n * 100:6.1f} %")
        print(f"{v:>10d} " + " ".join(f"{c:>22s}" for c in cells))
    print(f"sweep took {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
