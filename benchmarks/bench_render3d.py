"""Speed of the 3-D renderers: renders per second and simulated seconds per second.

Run: ``.venv/bin/python benchmarks/bench_render3d.py [--quick]``. Renders: 60 (exact) or 3
interleaved rounds of 100 (pyrender, median round) at distinct times (no cache hits) after one
warm-up render (GL start-up, numba compilation), wall-clock rate and CPU rate
(``time.process_time``, all threads of the process, llvmpipe's included) measured in one run.
Figures:

- the exact box renderer (:class:`evedge.sim.render3d.MeshRenderer`, no GL): exact intensity,
  per-pixel depth + flow, exact edges;
- the pyrender path (:class:`evedge.sim.mesh.RasterMeshRenderer`, EGL on Mesa llvmpipe) on the
  same boxes as meshes, at 1x1, 2x2 (the default) and 3x3 supersampling with 4x MSAA
  (llvmpipe's ``GL_MAX_SAMPLES``) and 3x3 without MSAA, each with its accuracy against the exact
  renderer over the timed frames' times: mean and max |error| over the pixels an edge crosses
  (exact edge map) and max over the others (the tested tolerance of the default is edge mean
  <= 0.012, max <= 0.06, others <= 0.5/255; see ``tests/sim/test_mesh.py``);
- simulated seconds per second (CPU) of ``scenes/boxes_3d.toml`` (exact path) and a part of
  ``scenes/textured_3d.toml`` (pyrender path), frames off, numba on one thread, and the ratio of
  the exact path to the 0.048x measured before the analytic visibility (same machine, issue 13).
"""

import argparse
import os
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from evedge.sim import load_scene, simulate  # noqa: E402
from evedge.sim.mesh import RasterMeshRenderer, box_mesh  # noqa: E402
from evedge.sim.render3d import Box3D, CameraTrajectory, MeshRenderer  # noqa: E402

SCENES = Path(__file__).resolve().parents[1] / "scenes"
BEFORE_X = 0.048  # boxes_3d real-time factor (CPU) of the sampled visibility, commit 2b8a6aa
BOXES = [Box3D((-1.0, 0.3, 4.0), (0.8, 1.2, 0.8), (0.2, 0.3, 0.25, 0.4, 0.7, 0.5)),
         Box3D((0.6, 0.0, 5.0), (1.0, 1.0, 1.0), (0.9, 0.1, 0.8, 0.2, 0.6, 0.3)),
         Box3D((1.8, -0.2, 6.0), (0.7, 1.6, 0.7), (0.15, 0.85, 0.3, 0.6, 0.35, 0.75))]
TRAJ = CameraTrajectory((0, 0, 0), (0.5, 0, 0), (0, 0, 0), (0, 0.1, 0))
ROUNDS = 3


def rate(fn, n=60):
    """(wall, CPU) calls per second of ``fn(t)`` at distinct times."""
    rate.k += 1
    w0, c0 = time.perf_counter(), time.process_time()
    for i in range(n):
        fn(1e-3 * (i + 1) + 1e-5 * rate.k)
    return n / (time.perf_counter() - w0), n / max(time.process_time() - c0, 1e-9)


rate.k = 0


def fmt(name, wc):
    return f"{name} {wc[0]:.0f}/s wall ({wc[1]:.0f}/s CPU)"


def sim_rate(name, duration_s=None):
    scene = load_scene(SCENES / f"{name}.toml")
    simulate(scene, duration_s=0.002, frame_rate_hz=0, progress=False)  # warm-up
    d = duration_s or scene.duration_s
    c0, w0 = time.process_time(), time.perf_counter()
    rec = simulate(scene, duration_s=d, frame_rate_hz=0, progress=False)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    return d, cpu, wall, rec.events.size, rec.metadata["n_samples"]


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--quick", action="store_true", help="240x180 only, shorter textured run")
    args = ap.parse_args()
    print(f"{os.cpu_count()} cpus, load average {os.getloadavg()[0]:.1f}, NUMBA_NUM_THREADS="
          f"{os.environ['NUMBA_NUM_THREADS']}")
    for (w, h) in [(240, 180)] + ([] if args.quick else [(346, 260)]):
        intr = (w, h, 0.8 * w, 0.8 * w, (w - 1) / 2, (h - 1) / 2)
        r = MeshRenderer(*intr, BOXES, TRAJ)
        r.intensity(0.0)
        out = [fmt("exact intensity", rate(lambda t: r.intensity(t))),
               fmt("depth+flow", rate(lambda t: r.flow(t))),
               fmt("exact edges", rate(lambda t: r.edges(t)))]
        assert r._renderer is None  # the exact path made no GL context
        r.close()
        print(f"{w}x{h} exact (no GL): " + ", ".join(out))
        meshes = [box_mesh(b.center_m, b.size_m, b.face_intensities) for b in BOXES]
        r = MeshRenderer(*intr, BOXES, TRAJ)
        configs = ((1, 4), (2, 4), (3, 4), (3, 0))
        raster = [RasterMeshRenderer(*intr, meshes, TRAJ, supersample=s, multisample=m) for s, m in configs]
        for g in raster:
            g.intensity(0.0)
        # ROUNDS interleaved rounds of 100 renders per configuration (the load of a shared machine
        # drifts): the median round of each
        rounds = [[rate(lambda t: g.intensity(t), 100) for g in raster] for _ in range(ROUNDS)]
        for k, ((s, m), g) in enumerate(zip(configs, raster)):
            wall, cpu = (float(np.median([rnd[k][i] for rnd in rounds])) for i in (0, 1))
            on, off = [], []
            for t in (0.0, 0.02, 0.04, 0.06):
                err, edge = abs(g.intensity(t) - r.intensity(t)), r.edges(t)
                on.append(err[edge])
                off.append(err[~edge])
            on, off = np.concatenate(on), np.concatenate(off)
            g.close()
            tag = " (default)" if (s, m) == (2, 4) else ""
            print(f"{w}x{h} pyrender (EGL llvmpipe) {s}x{s} x {m} MSAA{tag}: {wall:.0f}/s wall ({cpu:.0f}/s CPU); "
                  f"vs exact: edge px mean {on.mean():.4f} max {on.max():.3f}, other px mean {off.mean():.4f} "
                  f"max {off.max():.4f}")
        r.close()
    d, cpu, wall, n, samples = sim_rate("boxes_3d")
    print(f"boxes_3d (exact, 240x180): sim {d:.2f} s in {cpu:.2f} s CPU ({wall:.2f} s wall): {d / cpu:.3f}x real "
          f"time (CPU), {d / cpu / BEFORE_X:.1f}x the sampled visibility's {BEFORE_X}x; {n:,} events, {samples} samples")
    d, cpu, wall, n, samples = sim_rate("textured_3d", 0.02 if args.quick else 0.1)
    print(f"textured_3d (pyrender 2x2 x 4 MSAA, 240x180): sim {d:.2f} s in {cpu:.2f} s CPU ({wall:.2f} s wall): "
          f"{d / cpu:.4f}x real time (CPU); {n:,} events, {samples} samples")


if __name__ == "__main__":
    main()
