"""Events lost by the default sampling of the analytic shapes scenes, against dense steps.

Run: ``.venv/bin/python benchmarks/sim_completeness.py [--quick]``. For each
shapes scene (full duration; ``--quick``: the first 0.5 s) the default run
(geometric steps, the pixels the renderer cannot prove monotone sub-sampled)
and the previous default (lambda-verified steps) are compared per (pixel,
polarity) with a dense reference: lambda-verified steps with ``lambda = 0.1``
and at most 0.02 px of image motion, exact crossing times, the same seed.
Printed: the events of each run, the (pixel, polarity) pairs whose count
differs from the reference's, and the events missing / extra.
"""

from __future__ import annotations

import argparse
import copy
import os
import time
import tomllib
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from evedge.sim import parse_scene, simulate  # noqa: E402

SCENES = Path(__file__).resolve().parents[1] / "scenes"
RUNS = {"dense reference": dict(sampling="verified", max_step_px=0.02, **{"lambda": 0.1}),
        "default": {},
        "verified (lambda 0.5)": dict(sampling="verified")}


def _counts(rec, width, height):
    e = rec.events
    key = (e["y"].astype(np.int64) * width + e["x"]) * 2 + e["p"].astype(np.int64)
    return np.bincount(key, minlength=2 * width * height)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="the first 0.5 s of each scene")
    args = ap.parse_args()
    print(f"{'scene':20s} {'run':22s} {'events':>9s} {'samples':>8s} {'pairs off':>9s} {'missing':>8s} "
          f"{'extra':>6s} {'CPU s':>6s}")
    for name in ("shapes_translation", "shapes_rotation"):
        base = tomllib.loads((SCENES / f"{name}.toml").read_text())
        duration = 0.5 if args.quick else base["scene"]["duration_s"]
        ref = None
        for label, events in RUNS.items():
            data = copy.deepcopy(base)
            data["events"].update(events)
            scene = parse_scene(data, source=f"{name}.toml")
            t0 = time.process_time()
            rec = simulate(scene, duration_s=duration, frame_rate_hz=0, progress=False)
            cpu = time.process_time() - t0
            c = _counts(rec, scene.sensor.width, scene.sensor.height)
            if ref is None:
                ref = c
            off = int(np.count_nonzero(c != ref))
            missing = int(np.clip(ref - c, 0, None).sum())
            extra = int(np.clip(c - ref, 0, None).sum())
            print(f"{name:20s} {label:22s} {rec.events.shape[0]:9,d} {rec.metadata['n_samples']:8d} {off:9d} "
                  f"{missing:8d} {extra:6d} {cpu:6.2f}", flush=True)


if __name__ == "__main__":
    main()
