"""Where one robustness-grid cell loses its signal coverage and its accuracy: buffer, rules, time.

For one cell of :mod:`evedge.bench.robustness` (a ``stripes`` cell by default: angle, speed,
contrast ratio r, noise rate; 96x72 and seed 7 as the full grid), simulated once, it prints
for the proposed detector:

* the steady-state signal (event time >= 0.1 s, as the grid scores it) the event buffer keeps,
  the share of those the estimator estimates, and the grid's figures (``sig``, ``med``, ``>2x``,
  ``noise``), for the defaults and for ``--preset`` (``noise`` by default) with the buffer
  preset (``line`` by default);
  (``--buffer-preset none``: no buffer; ``--intra key=value`` changes the preset's fields);
* the same with each of the preset's rules turned off in turn (one field back to the
  defaults' value): which rule costs how much coverage and saves how many gross errors;
* for the preset, the estimates more than 2x off by 0.1 s bin of the recording, against all
  estimates there, and whether they are too short or too long: start-up errors cluster in
  the first bins.

Run: ``.venv/bin/python benchmarks/cell_breakdown.py [--angle 0] [--speed 10] [--r 5] [--noise 0]
[--preset noise] [--buffer-preset line|paper|none] [--intra key=value ...]``. Measurements: the README, "Robustness".
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _intra_options import PRESETS, _parse_intra  # noqa: E402

from evedge.bench import robustness as grid  # noqa: E402
from evedge.detector.buffer import BufferParams, line_params  # noqa: E402
from evedge.detector.intra import IntraParams  # noqa: E402
from evedge.detector.pipeline import detect  # noqa: E402
from evedge.sim import parse_scene, simulate  # noqa: E402

BUFFER_PRESETS = {"paper": BufferParams, "line": line_params, "none": lambda: None}  # none: no buffer at all


def breakdown(rec, steady_signal, params, buffer_params):
    """``detect`` with these parameters: (result, kept share, estimated share of the kept, the grid's figures)."""
    res = detect(rec.events, rec.sensor_size, params=params, buffer_params=buffer_params,
                 use_buffer=buffer_params is not None)
    kept = res.kept[steady_signal].mean()
    est = res.lifetimes["valid"][steady_signal & res.kept].mean()
    return res, kept, est, grid.score(rec, res.lifetimes)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kind", default="stripes", choices=("stripes", "rotation", "shapes"))
    ap.add_argument("--angle", type=float, default=0.0, help="stripes: angle in degrees")
    ap.add_argument("--speed", type=float, default=10.0, help="stripes, shapes: px/s")
    ap.add_argument("--r", type=float, default=5.0, help="log contrast / threshold")
    ap.add_argument("--noise", type=float, default=0.0, help="background noise, Hz per pixel")
    ap.add_argument("--size", default="96x72")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--preset", choices=sorted(PRESETS), default="noise")
    ap.add_argument("--buffer-preset", choices=sorted(BUFFER_PRESETS), default="line",
                    help="the preset's event buffer (none: no buffer, every event to the estimator)")
    ap.add_argument("--intra", action="append", default=[], metavar="KEY=VALUE", help="IntraParams field on the preset")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.size.lower().split("x"))
    kw = {"r": args.r, "noise_hz": args.noise}
    if args.kind == "stripes":
        kw["angle_deg"] = args.angle
    if args.kind != "rotation":
        kw["speed"] = args.speed
    rec = simulate(parse_scene(grid.build(args.kind, w, h, args.seed, **kw), f"<{args.kind} cell>"), progress=False)
    t = rec.events["t"]
    steady = rec.truth["is_signal"] & np.isfinite(rec.truth["lifetime_us"]) & (t >= int(t[0]) + grid.STEADY_US)
    print(f"{args.kind} {kw}, {w}x{h}, seed {args.seed}: {t.size:,} events over {(t[-1] - t[0]) / 1e6:.2f} s, "
          f"{int(steady.sum()):,} steady-state signal events")
    preset = _parse_intra(args.intra, PRESETS[args.preset]())
    buffer = BUFFER_PRESETS[args.buffer_preset]()
    header = f"{'setting':44s} {'kept':>6s} {'est|kept':>8s} {'sig':>6s} {'med':>6s} {'>2x':>7s} {'noise':>6s}"
    print(header)
    runs = [("defaults, paper buffer", IntraParams(), BufferParams()),
            (f"{args.preset}{' + ' + ', '.join(args.intra) if args.intra else ''}, {args.buffer_preset} buffer",
             preset, buffer)]
    base = IntraParams()
    needs = {"refine_window": ("curvature_f",)}  # a field reverted with the options that need it
    for f in dataclasses.fields(IntraParams):
        if getattr(preset, f.name) != getattr(base, f.name):
            back = {g: getattr(base, g) for g in (f.name, *needs.get(f.name, ()))}
            runs.append(("  " + ", ".join(f"{g} = {v!r}" for g, v in back.items()),
                         dataclasses.replace(preset, **back), buffer))
    results = {}
    for label, params, buf in runs:
        res, kept, est, s = breakdown(rec, steady, params, buf)
        results[label] = res
        print(f"{label:44s} {kept:6.3f} {est:8.3f} {s['sig']:6.3f} {s['med']:6.3f} {s['over2x']:7.4f} "
              f"{s['noise']:6.3f}")
    res = results[runs[1][0]]
    v = res.lifetimes["valid"] & steady
    ratio = res.lifetimes["lifetime_us"][v] / rec.truth["lifetime_us"][v]
    bad = (ratio > 2) | (ratio < 0.5)
    when = (t[v] - int(t[0])) / 1e6
    bins = np.arange(0.0, when.max() + 0.1, 0.1) if when.size else np.zeros(1)
    print(f"\n{runs[1][0]}: {int(bad.sum())} of {v.sum()} estimates more than 2x off ({int((ratio > 2).sum())} too "
          f"long, {int((ratio < 0.5).sum())} too short; ratio quantiles 10/50/90 % "
          + (" / ".join(f"{q:.2f}" for q in np.quantile(ratio[bad], [0.1, 0.5, 0.9])) if bad.any() else "-")
          + ")")
    print("by 0.1 s bin of the recording (> 2x off / estimates):")
    print("  " + "  ".join(f"{a:.1f}s {b}/{c}" for a, b, c in zip(bins[:-1], np.histogram(when[bad], bins)[0],
                                                                     np.histogram(when, bins)[0])))


if __name__ == "__main__":
    main()
