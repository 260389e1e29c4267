"""Speed of the Closest Distance Metric on 240x180 edge maps.

Run: .venv/bin/python benchmarks/bench_cdm.py

Maps: random line drawings (about 3-6 % of the pixels) against a jittered copy
(typical of an event edge map against Canny), and against a 3-px dilated copy
(thick accumulation maps, the hardest case: large connected components).

Then Canny, the CDM's ground truth (``bench/canny.py``), on a 240x180 frame of the
simulated ``shapes_translation``: CPU time per frame with the scikit-image
backend and with the OpenCV one, each setting, and their ratio (one run).
"""

import time

import numpy as np
from scipy.ndimage import binary_dilation
from skimage.draw import line

from evedge.bench.cdm import cdm_details


def drawing(rng, n_lines=60, shape=(180, 240)):
    f = np.zeros(shape, bool)
    g = np.zeros(shape, bool)
    for _ in range(n_lines):
        r0, r1 = rng.integers(0, shape[0], 2)
        c0, c1 = rng.integers(0, shape[1], 2)
        rr, cc = line(r0, c0, r1, c1)
        f[rr, cc] = True
        g[np.clip(rr + rng.integers(-2, 3, rr.size), 0, shape[0] - 1),
          np.clip(cc + rng.integers(-2, 3, cc.size), 0, shape[1] - 1)] = True
    return f, g


def timeit(fn, repeat=10):
    fn()  # warm-up
    t = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        t.append(time.perf_counter() - t0)
    return np.median(t)


def main():
    rng = np.random.default_rng(0)
    for n_lines in (20, 60):
        f, g = drawing(rng, n_lines)
        thick = binary_dilation(f, iterations=3)
        for label, other in (("jittered copy", g), ("3-px dilated copy", thick)):
            r = cdm_details(f, other)
            dt = timeit(lambda: cdm_details(f, other))
            print(f"{n_lines:3d} lines: {int(f.sum()):5d} vs {int(other.sum()):5d} px ({label:18s}) "
                  f"CDM {r.score:6.2f}  {1e3 * dt:7.1f} ms per call (median of 10)")
    bench_canny()


def bench_canny(repeat=20):
    from pathlib import Path

    from evedge.bench.canny import CANNY_SETTINGS, canny_edges
    from evedge.sim import simulate

    scene = Path(__file__).resolve().parents[1] / "scenes" / "shapes_translation.toml"
    frame = simulate(str(scene), duration_s=0.3, frame_rate_hz=5, progress=False).frames.images[1]
    for setting in CANNY_SETTINGS:
        cpu = {}
        for backend in ("skimage", "opencv"):
            canny_edges(frame, setting, backend=backend)
            c0 = time.process_time()
            for _ in range(repeat):
                canny_edges(frame, setting, backend=backend)
            cpu[backend] = (time.process_time() - c0) / repeat
        print(f"Canny {setting.name:11s} {frame.shape[1]}x{frame.shape[0]}: skimage {cpu['skimage'] * 1e3:5.2f} ms, "
              f"opencv {cpu['opencv'] * 1e3:5.2f} ms per frame (CPU): {cpu['skimage'] / cpu['opencv']:.1f}x")


if __name__ == "__main__":
    main()
