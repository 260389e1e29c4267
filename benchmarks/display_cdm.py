"""CDM of the display policies against Canny, the exact edges and the thin exact edges.

The proposed detector's lifetimes (pipeline defaults) shown three ways
(:func:`evedge.detector.edges.edge_frames`):

``predecessor``       each event clears the pixel behind it (Mueggler's display, ``clear_behind``);
``lifetime_only``     the paper's definition: a pixel lives for its newest event's lifetime;
``lifetime_burst``    the same, expiry counted from the burst's first event (``burst_lifetimes=1``).

Scenes: ``shapes_translation`` (sections ``slow`` and ``fast``) and vertical
stripes moving at 200 px/s (axis-aligned, as in issue 11) and at 20 degrees.
References: Canny (the MATLAB-like setting of :mod:`evedge.bench.canny`), the
simulator's exact edge map (``exact``, every pixel whose open square a boundary
crosses) and the thin exact map (``exact_thin``, one pixel per crossing of each
row and column). Printed: median CDM per scene, section, policy and reference.

Run: ``.venv/bin/python benchmarks/display_cdm.py`` (``--quick``: fewer frames).
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

from evedge.bench.canny import CANNY_SETTINGS, canny_edges
from evedge.bench.cdm import cdm
from evedge.detector.edges import edge_frames
from evedge.detector.pipeline import detect
from evedge.sim import edge_map, load_scene, parse_scene, simulate, thin_edge_map

POLICIES = {"predecessor": dict(clear_behind=True), "lifetime_only": dict(),
            "lifetime_burst": dict(burst_lifetimes=1.0)}
WARMUP_US = 30_000


def _stripes(angle_deg: float, speed: float = 200.0):
    a = math.radians(angle_deg)
    return parse_scene({
        "scene": {"name": f"stripes_{angle_deg:g}deg_{speed:g}px_s", "kind": "stripes", "duration_s": 0.4, "seed": 2,
                  "frame_rate_hz": 50, "background": 0.5},
        "sensor": {"width": 128, "height": 96},
        "events": {"contrast_pos": 0.3, "contrast_neg": 0.3, "contrast_sigma": 0.02, "refractory_us": 100,
                   "noise_rate_hz": 0.1},
        "stripes": [{"period_px": 20, "angle_deg": angle_deg, "velocity_px_s": [speed * math.cos(a),
                                                                               speed * math.sin(a)],
                     "dark": 0.25, "light": 0.75}],
    }, "<stripes>")


def run(scene, quick: bool, sections=None):
    rec = simulate(scene, progress=False)
    det = detect(rec.events, rec.sensor_size)
    ev, lt = rec.events[det.kept], det.lifetimes[det.kept]
    ft = rec.frames.t_us
    idx = np.flatnonzero(ft >= int(rec.events["t"][0]) + WARMUP_US)
    if quick and idx.size > 12:
        idx = idx[np.linspace(0, idx.size - 1, 12).round().astype(int)]
    times = ft[idx]
    refs = {"canny": np.stack([canny_edges(rec.frames.images[i], CANNY_SETTINGS[0]) for i in idx]),
            "exact": np.stack([edge_map(scene, t / 1e6) for t in times]),
            "exact_thin": np.stack([thin_edge_map(scene, t / 1e6) for t in times])}
    groups = {"all": np.ones(times.size, bool)}
    for s in rec.metadata.get("sections", []):
        groups[s["name"]] = (times >= s["start_us"]) & (times < s["end_us"])
    out = {}
    for name, kw in POLICIES.items():
        maps = edge_frames(ev, lt, rec.sensor_size, times, **kw)
        px = maps.reshape(maps.shape[0], -1).sum(axis=1)
        for ref, r in refs.items():
            scores = np.array([cdm(m, g) for m, g in zip(maps, r)])
            for s, sel in groups.items():
                out[(name, ref, s)] = float(np.median(scores[sel])) if sel.any() else math.nan
        for ref, r in refs.items():
            out[(name, f"px/{ref}", "all")] = float(px.sum() / max(1, r.sum()))
    return out, list(groups)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    scenes = [("shapes_translation", load_scene("scenes/shapes_translation.toml")),
              ("stripes 0 deg, 200 px/s", _stripes(0.0)), ("stripes 20 deg, 200 px/s", _stripes(20.0))]
    t0 = time.process_time()
    for label, scene in scenes:
        res, secs = run(scene, args.quick)
        print(f"\n{label}: median CDM (sections {', '.join(secs)}); edge pixels per reference pixel")
        print(f"  {'policy':16s}" + "".join(f"{ref:>22s}" for ref in ("canny", "exact", "exact_thin")) +
              f"{'px/exact_thin':>15s}")
        for name in POLICIES:
            cells = [" / ".join(f"{res[(name, ref, s)]:.1f}" for s in secs) for ref in ("canny", "exact", "exact_thin")]
            ratio = res[(name, "px/exact_thin", "all")]
            print(f"  {name:16s}" + "".join(f"{c:>22s}" for c in cells) + f"{ratio:>15.2f}")
    print(f"\nCPU time {time.process_time() - t0:.1f} s (time.process_time, this process)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
