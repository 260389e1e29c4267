"""Simulator speed: simulated seconds per wall-clock second and events per wall-clock second.

Run: ``.venv/bin/python benchmarks/bench_sim.py [--quick] [--no-3d]``. Scenes:
``stripes`` (on a 240x180 sensor, and as shipped on 128x128), ``shapes_translation``
(240x180; also the speed inside its slow and fast sections), both analytic, and
``boxes_3d`` (pyrender). Frames are off (pure event generation); each scene is
run once briefly first so numba compilation and GL start-up are not counted.
One process, numba on one thread. Section rows count samples, not events.
"""

from __future__ import annotations

import argparse
import copy
import os
import sys
import time
import tomllib
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from evedge.sim import parse_scene, simulate  # noqa: E402

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def _scene(name: str, sensor: str | None = None):
    data = tomllib.loads((SCENES / f"{name}.toml").read_text())
    if sensor:
        data = copy.deepcopy(data)
        data["sensor"] = {"preset": sensor}
    return parse_scene(data, source=f"{name}.toml")


def _run(label: str, scene, duration_s: float) -> None:
    simulate(scene, duration_s=min(0.01, duration_s), frame_rate_hz=0, progress=False)  # warm-up
    t0 = time.perf_counter()
    rec = simulate(scene, duration_s=duration_s, frame_rate_hz=0, progress=False)
    wall = time.perf_counter() - t0
    n = rec.events.shape[0]
    print(f"{label:44s} {scene.sensor.width}x{scene.sensor.height}  sim {duration_s:5.2f} s in "
          f"{wall:6.2f} s wall: {duration_s / wall:6.3f} sim-s/s, {n / wall / 1e6:6.3f} Mev/s "
          f"({n:,} events, {rec.metadata['n_samples']} samples)", flush=True)


def _sections(label: str, scene) -> None:
    """Speed inside each named section, from one streaming run of the converter."""
    from evedge.sim import EventConverter

    simulate(scene, duration_s=0.01, frame_rate_hz=0, progress=False)  # warm-up
    renderer = scene.build_renderer()
    conv = EventConverter(renderer, scene.params, seed=scene.seed, duration_s=scene.duration_s)
    for sec in scene.sections:
        conv.process(sec.start_s)
        n0, t0 = conv.n_samples, time.perf_counter()
        ev, _ = conv.process(sec.end_s)
        wall = time.perf_counter() - t0
        span = sec.end_s - sec.start_s
        print(f"{label + ' ' + sec.name + ' section':44s} {scene.sensor.width}x{scene.sensor.height}  "
              f"sim {span:5.2f} s in {wall:6.2f} s wall: {span / wall:6.3f} sim-s/s "
              f"({conv.n_samples - n0} samples)", flush=True)
    renderer.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="shorter runs")
    ap.add_argument("--no-3d", action="store_true", help="skip the pyrender scene")
    args = ap.parse_args()
    k = 0.25 if args.quick else 1.0
    threads = os.environ["NUMBA_NUM_THREADS"]
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cpus, NUMBA_NUM_THREADS={threads}")
    _run("stripes (analytic, 50 + 125 px/s)", _scene("stripes", "davis240"), 0.8 * k)
    _run("stripes (analytic, dvs128 as shipped)", _scene("stripes"), 0.8 * k)
    tr = _scene("shapes_translation")
    _run("shapes_translation (analytic, full 2 s)", tr, 2.0 * k)
    if not args.quick:
        _sections("shapes_translation", tr)
    if not args.no_3d:
        _run("boxes_3d (pyrender, 240x180)", _scene("boxes_3d"), 0.5 * k)


if __name__ == "__main__":
    main()
