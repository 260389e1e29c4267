"""Simulator speed: simulated seconds per second of CPU time (``time.process_time``) and events per CPU second.

CPU time, not wall time: the machine is shared, and one process on one numba
thread uses one core. Ratios ``sim-s/s`` above 1 are faster than real time.

Run: ``.venv/bin/python benchmarks/bench_sim.py [--quick] [--no-3d] [--frames-only]``. Scenes:
``stripes`` (on a 240x180 sensor, and as shipped on 128x128), ``shapes_translation``
(240x180; also the speed inside its slow and fast sections), both analytic, and
``boxes_3d`` (pyrender). Frames are off (pure event generation); each scene is
run once briefly first so numba compilation and GL start-up are not counted.
One process, numba on one thread. Section rows count samples, not events.
Rows say the sampling (default on the analytic scenes: geometric steps, bounded by
``max_step_px`` only, exact crossing times; on the shapes the pixels the renderer cannot prove
monotone over a step are sub-sampled; ``verified``: steps verified by the lambda rule, the
previous default of the shapes) and the crossing times (default exact; ``linear``: ESIM's
interpolation). The default rows of ``stripes`` and ``shapes_translation`` at 240x180 also print
their ratio to the target of issue 15 (3x real time on one core): ``target 3x: ... (>= 1 met)``. Frames rows: ``shapes_translation`` rendered (not timed) at 1 kHz and 5 kHz
into memory, then converted by :func:`evedge.sim.simulate_frames` (ESIM's
algorithm, the scenes' pixel model): the frames path's speed without decoding.
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


def _scene(name: str, sensor: str | None = None, **events):
    data = copy.deepcopy(tomllib.loads((SCENES / f"{name}.toml").read_text()))
    if sensor:
        data["sensor"] = {"preset": sensor}
    data.setdefault("events", {}).update(events)
    return parse_scene(data, source=f"{name}.toml")


#: Issue 15's target for the analytic scenes at 240x180: simulated seconds per CPU second.
TARGET_SIM_S_PER_S = 3.0


def _run(label: str, scene, duration_s: float, target: bool = False) -> None:
    simulate(scene, duration_s=min(0.01, duration_s), frame_rate_hz=0, progress=False)  # warm-up
    t0 = time.process_time()
    rec = simulate(scene, duration_s=duration_s, frame_rate_hz=0, progress=False)
    cpu = time.process_time() - t0
    n = rec.events.shape[0]
    speed = duration_s / cpu
    goal = f"  target {TARGET_SIM_S_PER_S:g}x: {speed / TARGET_SIM_S_PER_S:.2f}" if target else ""
    print(f"{label:44s} {scene.sensor.width}x{scene.sensor.height}  sim {duration_s:5.2f} s in "
          f"{cpu:6.2f} s CPU: {speed:6.3f} sim-s/s, {n / cpu / 1e6:6.3f} Mev/s "
          f"({n:,} events, {rec.metadata['n_samples']} samples, {rec.metadata['sampling_used']}){goal}", flush=True)


def _frames(label: str, scene, duration_s: float, rate_hz: float) -> None:
    import numpy as np

    from evedge.sim import frames_from_arrays, simulate_frames

    r = scene.build_renderer()
    t = np.arange(int(round(duration_s * rate_hz)) + 1) / rate_hz
    frames = np.stack([r.intensity(float(tk)) for tk in t])
    simulate_frames(frames_from_arrays(frames[:5], t[:5]), scene.params, progress=False)  # warm-up
    t0 = time.process_time()
    rec = simulate_frames(frames_from_arrays(frames, t), scene.params, seed=scene.seed, progress=False)
    cpu = time.process_time() - t0
    n = rec.events.shape[0]
    print(f"{label:44s} {scene.sensor.width}x{scene.sensor.height}  sim {duration_s:5.2f} s in "
          f"{cpu:6.2f} s CPU: {duration_s / cpu:6.3f} sim-s/s, {n / cpu / 1e6:6.3f} Mev/s "
          f"({n:,} events, {len(t)} frames at {rate_hz:g} Hz)", flush=True)


def _sections(label: str, scene) -> None:
    """Speed inside each named section, from one streaming run of the converter."""
    from evedge.sim import EventConverter

    simulate(scene, duration_s=0.01, frame_rate_hz=0, progress=False)  # warm-up
    renderer = scene.build_renderer()
    conv = EventConverter(renderer, scene.params, seed=scene.seed, duration_s=scene.duration_s)
    for sec in scene.sections:
        conv.process(sec.start_s)
        n0, t0 = conv.n_samples, time.process_time()
        ev, _ = conv.process(sec.end_s)
        cpu = time.process_time() - t0
        span = sec.end_s - sec.start_s
        print(f"{label + ' ' + sec.name + ' section':44s} {scene.sensor.width}x{scene.sensor.height}  "
              f"sim {span:5.2f} s in {cpu:6.2f} s CPU: {span / cpu:6.3f} sim-s/s "
              f"({conv.n_samples - n0} samples)", flush=True)
    renderer.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="shorter runs")
    ap.add_argument("--no-3d", action="store_true", help="skip the pyrender scene")
    ap.add_argument("--frames-only", action="store_true", help="only the frames-input rows")
    args = ap.parse_args()
    k = 0.25 if args.quick else 1.0
    threads = os.environ["NUMBA_NUM_THREADS"]
    print(f"python {sys.version.split()[0]}, {os.cpu_count()} cpus, NUMBA_NUM_THREADS={threads}; "
          f"times are CPU seconds (time.process_time)")
    tr = _scene("shapes_translation")
    _frames("shapes_translation frames in (1 kHz)", tr, 1.0 * k, 1000.0)
    _frames("shapes_translation frames in (5 kHz)", tr, 0.4 * k, 5000.0)
    if args.frames_only:
        return
    _run("stripes (analytic, 50 + 125 px/s)", _scene("stripes", "davis240"), 0.8 * k, target=True)
    _run("stripes, verified steps", _scene("stripes", "davis240", sampling="verified"), 0.8 * k)
    _run("stripes, linear times (ESIM)", _scene("stripes", "davis240", crossing_times="linear"), 0.8 * k)
    _run("stripes (analytic, dvs128 as shipped)", _scene("stripes"), 0.8 * k)
    _run("shapes_translation (analytic, full 2 s)", tr, 2.0 * k, target=True)
    _run("shapes_translation, verified steps", _scene("shapes_translation", sampling="verified"), 2.0 * k)
    _run("shapes_translation, linear times (ESIM)", _scene("shapes_translation", crossing_times="linear"), 2.0 * k)
    _run("shapes_rotation (analytic, full 2 s)", _scene("shapes_rotation"), 2.0 * k)
    if not args.quick:
        _sections("shapes_translation", tr)
    if not args.no_3d:
        _run("boxes_3d (pyrender, 240x180)", _scene("boxes_3d"), 0.5 * k)


if __name__ == "__main__":
    main()
