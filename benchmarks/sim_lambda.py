"""How much the sampling safety factor ``lambda`` moves the events, per shipped scene.

Run: ``.venv/bin/python benchmarks/sim_lambda.py [--quick]``. For each scene the
events at ``lambda = 0.5`` and ``0.25`` are compared per (pixel, polarity):
the change of the total count, the share of pairs with the same count, and
for those the |shift| of the matched sub-microsecond times (``truth.t_ns``):
median, 95th percentile and maximum, in us. Printed for the default exact
crossing times and for ESIM's linear interpolation (``crossing_times = "linear"``).
"""

from __future__ import annotations

import argparse
import os
import tomllib
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from evedge.sim import parse_scene, simulate  # noqa: E402

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def compare(a, b):
    def groups(rec):
        key = (rec.events["y"].astype(np.int64) * 40000 + rec.events["x"].astype(np.int64)) * 2 + rec.events["p"]
        order = np.lexsort((rec.truth["t_ns"], key))
        key, t = key[order], rec.truth["t_ns"][order]
        cut = np.flatnonzero(np.diff(key)) + 1
        return dict(zip(key[np.r_[0, cut]].tolist(), np.split(t, cut)))

    ga, gb = groups(a), groups(b)
    pairs = set(ga) | set(gb)
    same = [k for k in pairs if k in ga and k in gb and ga[k].shape == gb[k].shape]
    d = np.abs(np.concatenate([ga[k] - gb[k] for k in same])) / 1e3 if same else np.zeros(1)
    return (b.events.shape[0] / a.events.shape[0] - 1, len(same) / len(pairs), np.median(d), np.percentile(d, 95),
            d.max(), np.mean(d < 5))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="the first 0.3 s of each scene")
    args = ap.parse_args()
    print(f"{'scene':20s} {'times':7s} {'count':>8s} {'same':>7s} {'median':>8s} {'p95':>8s} {'max':>9s} {'<5us':>7s}")
    for name in ("stripes", "shapes_translation", "shapes_rotation"):
        for times in ("exact", "linear"):
            data = tomllib.loads((SCENES / f"{name}.toml").read_text())
            data.setdefault("events", {})["crossing_times"] = times
            scene = parse_scene(data, f"{name}.toml")
            dur = min(0.3, scene.duration_s) if args.quick else scene.duration_s
            a, b = (simulate(scene, duration_s=dur, frame_rate_hz=0, progress=False, lambda_=lam) for lam in (0.5, 0.25))
            dc, same, med, p95, mx, under5 = compare(a, b)
            print(f"{name:20s} {times:7s} {dc:+8.3%} {same:7.2%} {med:8.4f} {p95:8.4f} {mx:9.2f} {under5:7.2%}",
                  flush=True)


if __name__ == "__main__":
    main()
