"""Crossing-time error against the closed form of a straight edge at constant speed, exact vs linear.

Run: ``.venv/bin/python benchmarks/sim_exact_times.py``. A vertical edge (a stripe
of period 400 px, and the left side of a polygon) sweeps a 3-row sensor at 100
and 1000 px/s; pixel ``x``'s dark fraction is ``clamp(x + 0.5 - e(t), 0, 1)``
so every level of ``log(I + eps)`` is crossed at a time known in closed form.
Prints the median, 95th percentile and maximum of |t_ns - closed form| in us
for the exact crossing times (default) and ESIM's linear interpolation.
(``tests/sim/test_exact_times.py`` asserts the same on the same scenes.)
"""

from __future__ import annotations

import math

import numpy as np

from evedge.sim import parse_scene, simulate

EPS, C, DARK, LIGHT = 1e-3, 0.2, 0.2, 0.8


def scene(kind, width, speed, times):
    ev = {"contrast_pos": C, "contrast_neg": C, "crossing_times": times}
    head = {"kind": kind, "duration_s": (width + 4) / speed, "seed": 0, "frame_rate_hz": 0}
    if kind == "stripes":
        d = {"scene": head, "sensor": {"width": width, "height": 3}, "events": ev,
             "stripes": [{"period_px": 400.0, "velocity_px_s": [speed, 0.0], "dark": DARK, "light": LIGHT,
                          "phase_px": -2.5}]}
        return parse_scene(d, "edge.toml"), -2.5, speed
    x0 = width + 1.5
    d = {"scene": dict(head, background=LIGHT), "sensor": {"width": width, "height": 3}, "events": ev,
         "motion": {"velocity_px_s": [-speed, 0.0]},
         "shapes": [{"kind": "polygon", "intensity": DARK,
                     "vertices_px": [[x0, -50.0], [x0 + 500.0, -50.0], [x0 + 500.0, 60.0], [x0, 60.0]]}]}
    return parse_scene(d, "square.toml"), x0, -speed


def closed_form(x, edge0, speed):
    frac = lambda t: min(1.0, max(0.0, x + 0.5 - (edge0 + speed * t)))  # noqa: E731
    l0, l1 = (math.log(LIGHT + frac(t) * (DARK - LIGHT) + EPS) for t in (0.0, 1e3))
    step = C if l1 > l0 else -C
    out, k = [], 1
    while (l0 + k * step <= l1) if step > 0 else (l0 + k * step >= l1):
        f = (math.exp(l0 + k * step) - EPS - LIGHT) / (DARK - LIGHT)
        out.append((x + 0.5 - f - edge0) / speed)
        k += 1
    return np.array(out)


def main() -> None:
    print(f"{'edge':8s} {'px/s':>6s} {'times':7s} {'events':>7s} {'median us':>10s} {'p95 us':>9s} {'max us':>9s}")
    for kind in ("stripes", "shapes"):
        for speed in (100.0, 1000.0):
            for times in ("exact", "linear"):
                width = 12 if speed < 500 else 30
                sc, edge0, v = scene(kind, width, speed, times)
                rec = simulate(sc, progress=False)
                err = []
                for x in range(width):
                    want = closed_form(x, edge0, v)
                    for y in range(3):
                        sel = (rec.events["x"] == x) & (rec.events["y"] == y)
                        got = np.sort(rec.truth["t_ns"][sel]) / 1e3
                        assert got.shape == want.shape, (kind, speed, times, x, y)
                        err.append(np.abs(got - want * 1e6))
                err = np.concatenate(err)
                print(f"{kind:8s} {speed:6.0f} {times:7s} {err.size:7d} {np.median(err):10.5f} "
                      f"{np.percentile(err, 95):9.5f} {err.max():9.5f}")


if __name__ == "__main__":
    main()
