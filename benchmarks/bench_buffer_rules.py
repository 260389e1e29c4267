"""CPU time per event of the event buffer: the paper's rule (default) and with the line rule, in one run.

On the real ``stripes.mat`` (DVS128) and on a simulated robustness-grid cell (64x48 slow oblique low-contrast
stripes with 5 Hz/pixel noise, :mod:`evedge.bench.robustness`). Best of ``--repeat`` runs after a warm-up
(compilation excluded), as thread CPU time (``time.thread_time``, robust on a shared machine); prints ns per
event, the ratio line / default measured in the same run, the share of events kept, and the load average.

Run: ``.venv/bin/python benchmarks/bench_buffer_rules.py [--repeat 7]``.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from evedge.detector.buffer import BufferParams, filter_events, line_params
from evedge.events import SensorSize, make_events

STRIPES = Path(__file__).resolve().parents[1] / ".." / "shared" / "realdata" / "rpg_event_lifetime" / "stripes.mat"


def _stripes():
    from scipy.io import loadmat

    e = loadmat(str(STRIPES))["events"]
    return make_events(e[:, 0], e[:, 1], e[:, 3], e[:, 2]), SensorSize(128, 128)


def _cell():
    from evedge.bench.robustness import build
    from evedge.sim import parse_scene, simulate

    rec = simulate(parse_scene(build("stripes", 64, 48, 7, angle_deg=20, speed=10, r=1.3, noise_hz=5.0), "<cell>"),
                   progress=False)
    return rec.events, rec.sensor_size


def _best(fn, repeat):
    fn()
    best = np.inf
    for _ in range(repeat):
        c = time.thread_time()
        fn()
        best = min(best, time.thread_time() - c)
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args(argv)
    load0 = os.getloadavg()[0]
    inputs = []
    if STRIPES.exists():
        inputs.append(("stripes.mat", *_stripes()))
    else:
        print(f"(stripes.mat absent: {STRIPES})")
    inputs.append(("sim 20 deg, 10 px/s, r 1.3, 5 Hz noise", *_cell()))
    rules = [("default (paper)", BufferParams()), ("line_params()", line_params())]
    for name, ev, size in inputs:
        out = []
        for label, params in rules:
            s = _best(lambda: filter_events(ev, size, params), args.repeat)
            kept = filter_events(ev, size, params).mean()
            out.append(s)
            print(f"{name:40s} {label:16s} {1e9 * s / ev.size:6.1f} ns/event  kept {100 * kept:5.1f} %  "
                  f"({ev.size} events)")
        print(f"{name:40s} line / default {out[1] / out[0]:.2f}x")
    print(f"load average {load0:.1f} -> {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs "
          f"(thread CPU time, best of {args.repeat})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
