"""Renders per second of evedge.sim.render3d.MeshRenderer (3 boxes, moving camera).

Run: ``.venv/bin/python benchmarks/bench_render3d.py``. Each figure is 60 renders at distinct
times (no cache hits), after one warm-up render (GL start-up, numba compilation).
"""
import time
from evedge.sim.render3d import Box3D, CameraTrajectory, MeshRenderer
boxes = [Box3D((-1.0, 0.3, 4.0), (0.8, 1.2, 0.8), (0.2, 0.3, 0.25, 0.4, 0.7, 0.5)),
         Box3D((0.6, 0.0, 5.0), (1.0, 1.0, 1.0), (0.9, 0.1, 0.8, 0.2, 0.6, 0.3)),
         Box3D((1.8, -0.2, 6.0), (0.7, 1.6, 0.7), (0.15, 0.85, 0.3, 0.6, 0.35, 0.75))]
tr = CameraTrajectory((0, 0, 0), (0.5, 0, 0), (0, 0, 0), (0, 0.1, 0))
def rate(fn, n=60):
    t0 = time.perf_counter()
    for i in range(n): fn(1e-3 * (i + 1) + 1e-5 * rate.k)
    rate.k += 1
    return n / (time.perf_counter() - t0)
rate.k = 0
for (w, h) in [(240, 180), (346, 260)]:
    r = MeshRenderer(w, h, 0.8 * w, 0.8 * w, (w - 1) / 2, (h - 1) / 2, boxes, tr, supersample=3)
    r.intensity(0.0)
    out = dict(
        exact_intensity=rate(lambda t: r.intensity(t)),
        raster3x3_intensity=rate(lambda t: r.intensity(t, method="raster")),
        depth_flow=rate(lambda t: r.flow(t)),
        exact_edges=rate(lambda t: r.edges(t)),
        all_exact=rate(lambda t: (r.intensity(t), r.flow(t), r.edges(t))),
    )
    r.close()
    print(f"{w}x{h}: " + ", ".join(f"{k} {v:.0f}/s" for k, v in out.items()))
