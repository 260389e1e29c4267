"""Where the rotating star's lifetime error comes from: signed and absolute error by radius.

The robustness grid's rotation cells (``benchmarks/robustness_grid.py``, a star
rotating about the sensor's centre, ``evedge.bench.robustness.rotation_scene``)
miss the median-error goal at every contrast, clean or noisy, while the
stripes and shapes at the same contrast meet it. This prints, for each preset
asked, the steady-state signal events' relative error ``estimate / truth - 1``
binned by the distance of the event's pixel centre from the rotation centre:
the signed median (a bias) beside the median of the absolute value (what the
grid reports), and the share of the estimates in each ring. The star's inner
vertices lie at ``0.45 x`` its outer radius (concave corners: two edges in one
window), its tips at the outer radius.

Usage::

    .venv/bin/python benchmarks/rotation_radial.py [--r 5] [--noise 0] [--preset defaults noise ...]
        [--intra key=value ...]

Figures go to the README (Robustness section) and the issue notes, with the
command and the load; this script prints no target (it is an analysis).
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from _intra_options import PRESETS, _parse_intra  # noqa: E402

from evedge.bench.robustness import STEADY_US, build  # noqa: E402
from evedge.detector import detect  # noqa: E402
from evedge.detector.buffer import line_params  # noqa: E402
from evedge.sim import parse_scene, simulate  # noqa: E402


def radial_table(rec, lifetimes, edges_px):
    """Rows ``(lo, hi, n, share, signed median, absolute median)`` of the steady-state signal estimates."""
    ev, truth = rec.events, rec.truth
    w, h = rec.sensor_size.width, rec.sensor_size.height
    m = (truth["is_signal"] & np.isfinite(truth["lifetime_us"]) & lifetimes["valid"]
         & (ev["t"] >= int(ev["t"][0]) + STEADY_US))
    err = lifetimes["lifetime_us"][m] / truth["lifetime_us"][m] - 1.0
    rho = np.hypot(ev["x"][m] + 0.5 - w / 2, ev["y"][m] + 0.5 - h / 2)
    rows = [(0.0, np.inf, err.size, 1.0, np.median(err), np.median(np.abs(err)))] if err.size else []
    for lo, hi in zip(edges_px[:-1], edges_px[1:]):
        s = (rho >= lo) & (rho < hi)
        if s.any():
            rows.append((lo, hi, int(s.sum()), s.mean(), np.median(err[s]), np.median(np.abs(err[s]))))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--r", type=float, default=5.0, help="contrast ratio r (log contrast / threshold)")
    ap.add_argument("--noise", type=float, default=0.0, help="background noise, Hz per pixel")
    ap.add_argument("--size", default="96x72", help="sensor WxH (the grid's default)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--preset", nargs="+", default=["defaults", "noise"], choices=sorted(PRESETS))
    ap.add_argument("--intra", action="append", default=[], metavar="KEY=VALUE",
                    help="an IntraParams field on top of each preset (repeatable)")
    args = ap.parse_args(argv)
    try:
        w, h = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise SystemExit(f"--size: expected WxH, got {args.size!r}") from None
    rec = simulate(parse_scene(build("rotation", w, h, args.seed, r=args.r, noise_hz=args.noise), "<rotation>"),
                   progress=False)
    outer = 0.42 * min(w, h)  # rotation_scene's star radius
    edges = np.r_[0.0, 0.45 * outer, 0.6 * outer, 0.75 * outer, 0.9 * outer, np.inf]
    print(f"rotation cell {w}x{h}, r = {args.r}, noise {args.noise} Hz/pixel: {rec.events.size:,} events; "
          f"star inner vertices at {0.45 * outer:.1f} px, tips at {outer:.1f} px from the centre")
    for name in args.preset:
        params = _parse_intra(args.intra, PRESETS[name]())
        res = detect(rec.events, rec.sensor_size, params=params, buffer_params=line_params())
        print(f"\n{name}{' + ' + ' '.join(args.intra) if args.intra else ''} (line rule buffer):")
        print("  radius px      estimates  share   signed median   |error| median")
        for lo, hi, n, share, signed, absolute in radial_table(rec, res.lifetimes, edges):
            ring = "all" if lo == 0 and hi == np.inf else f"{lo:4.1f}-{hi:4.1f}"
            print(f"  {ring:>11s}  {n:11,d}  {share:5.2f}  {signed * 100:+12.2f} %  {absolute * 100:13.2f} %")


if __name__ == "__main__":
    main()
