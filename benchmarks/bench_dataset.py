"""Dataset generation on Dask: sequences per minute with 1 and 2 workers, their ratio, memory per worker.

Run: ``.venv/bin/python benchmarks/bench_dataset.py [--count 16] [--repeats 1]``.

Both cluster sizes are measured in this one run, one after the other (1, 2,
1, 2, ... with ``--repeats``), on the same spec (``--count`` sequences drawn
like ``scenes/datasets/small.toml`` but on a DVS128 sensor for 1 s, so each
sequence is about half a second of CPU and the scheduling overhead is small
beside it). Each cluster is started and every worker warmed up (imports,
numba compilation from the on-disk cache, one tiny simulation) before the
clock starts; the time counted is from submitting the first sequence to
writing the last one's manifest row, into a fresh folder. Memory: the peak
resident set size of each worker process (``ru_maxrss``) after the run; a
sequence is simulated in chunks and only its own events, truth and frames are
held, so it does not grow with ``--count``. The load average (1 min) at the
start and the end is printed: the machine may be shared.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

from evedge.parallel import dask_client  # noqa: E402
from evedge.sim.dataset import parse_dataset  # noqa: E402
from evedge.sim.dataset_run import generate_dataset  # noqa: E402


def _spec(count: int):
    return parse_dataset({
        "dataset": {"name": "bench", "seed": 1, "count": count},
        "parameters": {"family": {"choice": ["stripes", "shapes"]}, "sensor": "dvs128", "duration_s": 1.0,
                       "frame_rate_hz": 100, "speed_px_s": {"log_uniform": [40, 320]},
                       "direction_deg": {"uniform": [0, 360]}, "angle_deg": {"uniform": [0, 180]},
                       "contrast": {"uniform": [0.3, 0.8]}, "shape_count": {"integers": [1, 4]},
                       "shape_radius_px": {"uniform": [8, 20]}, "noise_rate_hz": {"choice": [0, 1, 5]},
                       "threshold_mismatch": 0.02},
    }, "bench_dataset")


def _warm_up() -> int:
    from evedge.sim import parse_scene, simulate

    scene = parse_scene({"scene": {"kind": "stripes", "duration_s": 0.01}, "sensor": {"width": 16, "height": 12},
                         "stripes": [{"period_px": 6, "velocity_px_s": [100, 0]}]})
    simulate(scene, progress=False)
    shape = parse_scene({"scene": {"kind": "shapes", "duration_s": 0.01}, "sensor": {"width": 16, "height": 12},
                         "shapes": [{"kind": "star", "center_px": [8, 6], "radius_px": 4}],
                         "motion": {"velocity_px_s": [50, 0]}})
    return simulate(shape, progress=False).events.shape[0]


def _peak_rss_mib() -> float:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux: KiB


def _measure(workers: int, spec, root: Path) -> dict:
    with dask_client(workers=workers) as c:
        c.run(_warm_up)
        out = Path(tempfile.mkdtemp(dir=root, prefix=f"w{workers}-"))
        t0, c0 = time.perf_counter(), time.process_time()
        run = generate_dataset(spec, out, client=c, progress=False)
        wall = time.perf_counter() - t0
        client_cpu = time.process_time() - c0
        rss = sorted(c.run(_peak_rss_mib).values())
    shutil.rmtree(out)
    assert run.failed == 0, [r["error"] for r in run.rows.values() if r["status"] != "ok"]
    cpu = sum(r["cpu_s"] for r in run.rows.values())
    events = sum(r["n_events"] for r in run.rows.values())
    return {"workers": workers, "wall_s": wall, "per_min": 60 * spec.count / wall, "task_cpu_s": cpu,
            "client_cpu_s": client_cpu, "events": events, "rss_mib": rss}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=16, help="sequences per measurement (default 16)")
    ap.add_argument("--repeats", type=int, default=1, help="alternate 1 and 2 workers this many times")
    args = ap.parse_args()
    spec = _spec(args.count)
    print(f"load average (1 min) at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores", flush=True)
    with tempfile.TemporaryDirectory(prefix="bench_dataset-") as tmp:
        results = {1: [], 2: []}
        for _ in range(args.repeats):
            for w in (1, 2):
                r = _measure(w, spec, Path(tmp))
                results[w].append(r)
                print(f"{w} worker{'s' if w > 1 else ' '}: {spec.count} sequences ({r['events']:,} events) in "
                      f"{r['wall_s']:6.2f} s wall = {r['per_min']:6.1f} sequences/min; task CPU "
                      f"{r['task_cpu_s']:.1f} s ({r['task_cpu_s'] / spec.count:.2f} s/seq), client CPU "
                      f"{r['client_cpu_s']:.1f} s; peak RSS per worker "
                      f"{', '.join(f'{m:.0f}' for m in r['rss_mib'])} MiB", flush=True)
    best = {w: max(r["per_min"] for r in rs) for w, rs in results.items()}
    print(f"speed-up 2 workers / 1 worker: {best[2] / best[1]:.2f}x (best of {args.repeats} each; "
          f"target >= 1.7x on 2 free cores)")
    print(f"load average (1 min) at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
