"""Lifetime accuracy of the intra-pixel-area detector and Mueggler's on a grid of simulated scenes.

Each cell is one simulated scene (``evedge.sim``, exact per-event truth):

* ``stripes``: straight stripes (period 20 px, edge normal at ``angle`` degrees)
  moving along their normal at ``speed`` px/s (truth lifetime ``1e6 / speed`` us);
* ``rotation``: a dark star rotating about its centre (speed grows with the radius);
* ``shapes``: a triangle, a square at 45 degrees and a disc translating diagonally.

The contrast ratio ``r = log-contrast / threshold`` sets the events per edge
and pixel (``r = 1.3``: one, sometimes two; ``r = 5``: five); background noise
is Poisson, ``noise`` Hz per pixel. Both methods run as the project's pipeline
(:func:`evedge.detector.pipeline.detect`: intra with the event buffer, Mueggler
without, as its original). Printed per cell and method:

``med``    median |estimate / truth - 1| over signal events with an estimate, steady state
           (event time >= 0.1 s);
``>2x``    share of those estimates more than 2x off the truth (above 2x or below 1/2);
``sig``    share of the steady-state signal events with an estimate;
``noise``  share of the noise events given a lifetime (``-`` without noise);
``first``  median |relative error| over the first 0.1 s (start-up, reported apart).

Run ``.venv/bin/python benchmarks/robustness_grid.py --quick`` (a reduced grid,
a few minutes on one core) or without ``--quick`` for the whole grid;
``--intra key=value`` (repeatable) changes an :class:`~evedge.detector.intra.IntraParams`
field, e.g. ``--intra split=paper`` to measure a departure from the paper;
``--scene SCENE.toml`` scores one scene file instead (the ``--intra`` parameters,
:func:`~evedge.detector.intra.robust_params` and Mueggler's); ``--csv FILE`` writes every cell's figures, ``--plot FILE.png`` draws them (clean stripes:
median error and share > 2x off against speed per contrast ratio, median over the angles;
noisy cells: share of noise events given a lifetime against the noise rate).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import itertools
import math
import sys
import time

import numpy as np

from evedge.detector.intra import IntraParams
from evedge.detector.pipeline import detect
from evedge.sim import parse_scene, simulate

THRESHOLD = 0.25  # C+ = C- (log units)
LIGHT = 0.8
LOG_EPS = 1e-3
STEADY_US = 100_000
PERIOD_PX = 20.0


def _dark_for(r: float) -> float:
    """Dark intensity whose log-contrast against LIGHT is ``r`` thresholds."""
    return math.exp(math.log(LIGHT + LOG_EPS) - r * THRESHOLD) - LOG_EPS


def _duration_s(speed: float) -> float:
    # every pixel sees at least about two edge passages, and steady state lasts >= 0.1 s
    return float(min(1.2, max(0.25, 2.5 * PERIOD_PX / speed)))


def _events_table(noise_hz: float, seed: int) -> dict:
    return {"contrast_pos": THRESHOLD, "contrast_neg": THRESHOLD, "contrast_sigma": 0.02,
            "refractory_us": 100, "noise_rate_hz": float(noise_hz), "log_eps": LOG_EPS}


def stripes_scene(width, height, angle_deg, speed, r, noise_hz, seed):
    a = math.radians(angle_deg)
    return {
        "scene": {"name": f"stripes_{angle_deg}_{speed}", "kind": "stripes", "duration_s": _duration_s(speed),
                  "seed": seed, "frame_rate_hz": 0, "background": LIGHT},
        "sensor": {"width": width, "height": height},
        "events": _events_table(noise_hz, seed),
        "stripes": [{"rows_fraction": [0.0, 1.0], "period_px": PERIOD_PX, "angle_deg": float(angle_deg),
                     "velocity_px_s": [speed * math.cos(a), speed * math.sin(a)], "dark": _dark_for(r),
                     "light": LIGHT, "phase_px": 3.3}],
    }


def rotation_scene(width, height, r, noise_hz, seed, deg_s=120.0):
    rad = 0.42 * min(width, height)
    return {
        "scene": {"name": "rotation", "kind": "shapes", "duration_s": 0.6, "seed": seed, "frame_rate_hz": 0,
                  "background": LIGHT},
        "sensor": {"width": width, "height": height},
        "events": _events_table(noise_hz, seed),
        "motion": {"center_px": [width / 2, height / 2], "angular_velocity_deg_s": deg_s},
        "shapes": [{"kind": "star", "center_px": [width / 2, height / 2], "radius_px": rad, "inner_ratio": 0.45,
                    "intensity": _dark_for(r)}],
    }


def shapes_scene(width, height, speed, r, noise_hz, seed):
    v = speed / math.sqrt(2)
    rad = 0.16 * min(width, height)
    return {
        "scene": {"name": "shapes", "kind": "shapes", "duration_s": _duration_s(speed) * 0.8, "seed": seed,
                  "frame_rate_hz": 0, "background": LIGHT},
        "sensor": {"width": width, "height": height},
        "events": _events_table(noise_hz, seed),
        "motion": {"velocity_px_s": [v, v * 0.6]},
        "shapes": [
            {"kind": "triangle", "center_px": [0.25 * width, 0.3 * height], "radius_px": rad,
             "intensity": _dark_for(r)},
            {"kind": "square", "center_px": [0.6 * width, 0.3 * height], "radius_px": rad, "rotation_deg": 45,
             "intensity": _dark_for(r)},
            {"kind": "circle", "center_px": [0.4 * width, 0.7 * height], "radius_px": rad, "intensity": _dark_for(r)},
        ],
    }


def score(rec, lifetimes) -> dict:
    """The cell's figures for one method (see the module notes)."""
    t = rec.events["t"]
    sig = rec.truth["is_signal"]
    truth = rec.truth["lifetime_us"]
    valid = lifetimes["valid"]
    est = lifetimes["lifetime_us"]
    steady = t >= int(t[0]) + STEADY_US if t.size else np.zeros(0, bool)
    ok = sig & np.isfinite(truth)
    out = {}
    m = ok & steady
    sel = m & valid
    ratio = est[sel] / truth[sel]
    out["med"] = float(np.median(np.abs(ratio - 1))) if ratio.size else math.nan
    out["over2x"] = float(np.mean((ratio > 2) | (ratio < 0.5))) if ratio.size else math.nan
    out["sig"] = float(valid[m].mean()) if m.any() else math.nan
    noise = ~sig
    out["noise"] = float(valid[noise].mean()) if noise.any() else math.nan
    first = ok & ~steady & valid
    r0 = est[first] / truth[first]
    out["first"] = float(np.median(np.abs(r0 - 1))) if r0.size else math.nan
    out["n_signal"] = int(m.sum())
    out["n_noise"] = int(noise.sum())
    return out


def cells(quick: bool):
    """(label, scene dict builder kwargs) of the grid."""
    if quick:
        angles, speeds, ratios, noises = (0, 20, 45, 70), (10, 200, 2000), (1.3, 2.2, 5.0), (0.0, 2.0, 5.0)
    else:
        angles, speeds, ratios, noises = (0, 20, 45, 70), (10, 50, 200, 1000, 2000), (1.3, 1.7, 2.2, 3.0, 5.0), \
            (0.0, 0.5, 2.0, 5.0)
    out = []
    # clean: every angle x speed x contrast
    for a, v, r in itertools.product(angles, speeds, ratios):
        out.append(("stripes", dict(angle_deg=a, speed=v, r=r, noise_hz=0.0)))
    # noise: every contrast and noise level at two angles and speeds
    for a, v, r, nz in itertools.product((0, 20) if quick else (0, 20, 45), (10, 200), ratios, noises[1:]):
        out.append(("stripes", dict(angle_deg=a, speed=v, r=r, noise_hz=nz)))
    for r, nz in itertools.product(ratios, (0.0, noises[-1])):
        out.append(("rotation", dict(r=r, noise_hz=nz)))
        out.append(("shapes", dict(speed=100.0, r=r, noise_hz=nz)))
    return out


def build(kind, width, height, seed, **kw):
    if kind == "stripes":
        return stripes_scene(width, height, kw["angle_deg"], kw["speed"], kw["r"], kw["noise_hz"], seed)
    if kind == "rotation":
        return rotation_scene(width, height, kw["r"], kw["noise_hz"], seed)
    return shapes_scene(width, height, kw["speed"], kw["r"], kw["noise_hz"], seed)


def _parse_intra(items) -> IntraParams:
    fields = {f.name: f for f in dataclasses.fields(IntraParams)}
    kw = {}
    for item in items:
        key, _, value = item.partition("=")
        if key not in fields:
            raise SystemExit(f"--intra: unknown IntraParams field {key!r} (fields: {', '.join(fields)})")
        default = getattr(IntraParams(), key)
        if isinstance(default, bool):
            kw[key] = value.lower() in ("1", "true", "yes", "on")
        elif isinstance(default, (int, float)):
            kw[key] = type(default)(float(value))
        else:
            kw[key] = value
    return IntraParams(**kw)


def _fmt(v, pct=True):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    return f"{100 * v:.1f}" if pct else f"{v}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="reduced grid (a few minutes on one core)")
    ap.add_argument("--size", default=None, help="sensor WxH (default 96x72, --quick 64x48)")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--intra", action="append", default=[], metavar="KEY=VALUE", help="IntraParams field")
    ap.add_argument("--no-mueggler", action="store_true", help="skip the baseline")
    ap.add_argument("--only", default=None, help="only cells whose kind is this (stripes, rotation, shapes)")
    ap.add_argument("--csv", default=None)
    ap.add_argument("--plot", default=None, help="write a figure of the grid (PNG)")
    ap.add_argument("--scene", default=None, metavar="SCENE.toml",
                    help="instead of the grid: score one scene file (defaults, robust_params(), Mueggler)")
    args = ap.parse_args(argv)
    from tqdm import tqdm

    if args.scene:
        return score_scene(args.scene, _parse_intra(args.intra))
    size = args.size or ("64x48" if args.quick else "96x72")
    width, height = (int(v) for v in size.lower().split("x"))
    params = _parse_intra(args.intra)
    grid = [c for c in cells(args.quick) if args.only is None or c[0] == args.only]
    methods = ("intra",) if args.no_mueggler else ("intra", "mueggler")
    rows = []
    t0 = time.process_time()
    for kind, kw in tqdm(grid, desc="cells", unit="cell", file=sys.stderr):
        rec = simulate(parse_scene(build(kind, width, height, args.seed, **kw), f"<{kind}>"), progress=False)
        row = {"kind": kind, **{k: kw.get(k, "") for k in ("angle_deg", "speed", "r", "noise_hz")},
               "n_events": int(rec.events.size)}
        for m in methods:
            res = detect(rec.events, rec.sensor_size, method=m, params=params if m == "intra" else None)
            for k, v in score(rec, res.lifetimes).items():
                row[f"{m}_{k}"] = v
        rows.append(row)
    cpu = time.process_time() - t0
    head = f"{'kind':9s}{'ang':>4s}{'speed':>6s}{'r':>5s}{'noise':>6s} |" + "".join(
        f" {m[:6]:>6s}:{'med':>6s}{'>2x':>6s}{'sig':>6s}{'noise':>6s}{'first':>6s} |" for m in methods)
    print(f"grid {size}, seed {args.seed}, intra params: {params}")
    print(head)
    for row in rows:
        line = f"{row['kind']:9s}{str(row['angle_deg']):>4s}{str(row['speed']):>6s}{str(row['r']):>5s}" \
               f"{str(row['noise_hz']):>6s} |"
        for m in methods:
            line += f" {'':6s} " + "".join(f"{_fmt(row[f'{m}_{k}']):>6s}" for k in ("med", "over2x", "sig", "noise",
                                                                                   "first")) + " |"
        print(line)
    _summary(rows, methods)
    print(f"CPU time {cpu:.1f} s (time.process_time, this process)")
    if args.plot:
        plot(rows, methods, args.plot)
        print(f"figure: {args.plot}")
    if args.csv:
        with open(args.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    return 0


def _goals(r) -> dict:
    """Whether intra meets each of issue 11's goals in cell ``r`` (noise: only counted in noisy cells)."""
    noisy = r["noise_hz"] not in (0.0, "")
    med_goal = 0.05 if noisy else (0.02 if r["r"] >= 3 else 0.03)
    sig_goal = 0.95 if r["r"] >= 3 else 0.85
    med, o2, sig, nz = (r[f"intra_{k}"] for k in ("med", "over2x", "sig", "noise"))
    return {"med": bool(med <= med_goal), "over2x": bool(o2 <= 0.01), "sig": bool(sig >= sig_goal),
            "noise": bool(noisy and nz <= 0.10)}


def score_scene(path, params) -> int:
    """Score one scene file: the detector with ``params``, with :func:`robust_params`, and Mueggler's."""
    from evedge.detector.intra import robust_params
    from evedge.sim import load_scene

    rec = simulate(load_scene(path), progress=False)
    runs = {f"intra {params}": dict(method="intra", params=params),
            "intra robust_params()": dict(method="intra", params=robust_params()),
            "mueggler": dict(method="mueggler")}
    print(f"{path}: {rec.events.size} events ({100 * rec.truth['is_signal'].mean():.1f} % signal); steady state "
          f"from {STEADY_US} us")
    for name, kw in runs.items():
        sc = score(rec, detect(rec.events, rec.sensor_size, **kw).lifetimes)
        print(f"  {name}\n    median error {100 * sc['med']:.1f} %, > 2x off {100 * sc['over2x']:.2f} %, "
              f"signal estimated {100 * sc['sig']:.1f} %, noise given a lifetime {100 * sc['noise']:.1f} %, "
              f"first 0.1 s error {100 * sc['first']:.1f} %")
    return 0


def plot(rows, methods, path) -> None:
    """Median error and > 2x share against speed (clean stripes), noise share against rate (noisy cells)."""
    from evedge.bench._plot import pyplot

    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    clean = [r for r in rows if r["kind"] == "stripes" and r["noise_hz"] == 0.0]
    ratios = sorted({r["r"] for r in clean})
    speeds = sorted({r["speed"] for r in clean})
    styles = {"intra": "-", "mueggler": ":"}
    for m in methods:
        for i, ratio in enumerate(ratios):
            colour = plt.cm.viridis(i / max(1, len(ratios) - 1))
            for ax, key in ((axes[0], "med"), (axes[1], "over2x")):
                ys = [np.nanmedian([r[f"{m}_{key}"] for r in clean if r["r"] == ratio and r["speed"] == v] or [np.nan])
                      for v in speeds]
                ax.plot(speeds, 100 * np.asarray(ys), styles.get(m, "--"), color=colour, marker="o", ms=3,
                        label=f"{m}, r = {ratio:g}")
    axes[0].set_ylabel("median |relative error| (%)")
    axes[1].set_ylabel("estimates > 2x off (%)")
    for ax in axes[:2]:
        ax.set_xscale("log")
        ax.set_yscale("symlog", linthresh=1)
        ax.set_ylim(bottom=0)
        ax.set_xlabel("speed (px/s)")
        ax.grid(alpha=0.3)
    axes[0].axhline(2, color="k", lw=0.6)
    axes[1].axhline(1, color="k", lw=0.6)
    axes[0].legend(fontsize=6, ncol=2)
    noisy = [r for r in rows if r["noise_hz"] not in (0.0, "")]
    rates = sorted({r["noise_hz"] for r in noisy})
    for m in methods:
        ys = [np.nanmedian([r[f"{m}_noise"] for r in noisy if r["noise_hz"] == z]) for z in rates]
        axes[2].plot(rates, 100 * np.asarray(ys), styles.get(m, "--"), marker="o", label=m)
    axes[2].axhline(10, color="k", lw=0.6)
    axes[2].set_xlabel("background noise (Hz per pixel)")
    axes[2].set_ylabel("noise events given a lifetime (%, median over cells)")
    axes[2].legend()
    axes[2].set_ylim(bottom=0)
    axes[2].grid(alpha=0.3)
    fig.suptitle("robustness grid: clean stripes, median over angles (solid: proposed, dotted: Mueggler)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _summary(rows, methods) -> None:
    """Worst cells against the issue's goals (clean / noisy, by contrast)."""
    print("\nsummary (worst cell per group; med and >2x steady state; sig = signal events estimated):")
    groups = {
        "clean r>=3": lambda r: r["noise_hz"] in (0.0, "") and r["r"] >= 3,
        "clean r<3": lambda r: r["noise_hz"] in (0.0, "") and r["r"] < 3,
        "noisy": lambda r: r["noise_hz"] not in (0.0, ""),
    }
    for name, pred in groups.items():
        sel = [r for r in rows if pred(r)]
        if not sel:
            continue
        parts = []
        for m in methods:
            med = max(r[f"{m}_med"] for r in sel)
            o2 = max(r[f"{m}_over2x"] for r in sel)
            sig = min(r[f"{m}_sig"] for r in sel)
            nz = [r[f"{m}_noise"] for r in sel if not math.isnan(r[f"{m}_noise"])]
            fi = np.nanmedian([r[f"{m}_first"] for r in sel])
            parts.append(f"{m}: max med {100 * med:.1f} %, max >2x {100 * o2:.2f} %, min sig {100 * sig:.1f} %, "
                         f"max noise {100 * max(nz) if nz else math.nan:.1f} %, median first {100 * fi:.1f} %")
        print(f"  {name:11s} ({len(sel)} cells) " + " | ".join(parts))
    goals = {k: 0 for k in ("med", "over2x", "sig", "noise")}
    for r in rows:
        ok = _goals(r)
        for k in goals:
            goals[k] += ok[k]
    n_noisy = sum(1 for r in rows if r["noise_hz"] not in (0.0, ""))
    print(f"  intra cells meeting the goals: median error {goals['med']}/{len(rows)}, >2x share {goals['over2x']}/"
          f"{len(rows)}, signal estimated {goals['sig']}/{len(rows)}, noise given a lifetime <= 10 % "
          f"{goals['noise']}/{n_noisy}")
    if "mueggler" in methods:
        bad = [r for r in rows if r["mueggler_sig"] >= 0.2 and r["intra_med"] > 0.5 * r["mueggler_med"]]
        print(f"  cells where intra's med > half Mueggler's (Mueggler sig >= 20 %): {len(bad)} of "
              f"{sum(r['mueggler_sig'] >= 0.2 for r in rows)}")
        nb = [r for r in rows if not math.isnan(r["intra_noise"]) and r["intra_noise"] > 2 * r["mueggler_noise"]]
        print(f"  noisy cells where intra's noise share > 2x Mueggler's: {len(nb)}")


if __name__ == "__main__":
    raise SystemExit(main())
