"""Load and write rates of the event file formats.

Generates a synthetic recording (default 5 M events, DAVIS240 size) in a temp
directory, writes it as Event Camera Dataset text and as evedge HDF5, reads
both back, and times the real .mat recordings when present. Prints events/s.

Run: ``.venv/bin/python benchmarks/bench_io.py [--events N] [--repeat R]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from evedge.events import Recording, SensorSize, make_events
from evedge.io import read_events, write_ecd, write_recording

REALDATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "realdata"


def _best(fn, repeat: int) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return best, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--events", type=int, default=5_000_000)
    parser.add_argument("--repeat", type=int, default=3, help="best of R runs")
    args = parser.parse_args()
    n = args.events
    rng = np.random.default_rng(0)
    size = SensorSize(240, 180)
    ev = make_events(rng.integers(0, 240, n), rng.integers(0, 180, n),
                     np.sort(rng.integers(0, 10 * n, n)), rng.integers(0, 2, n))
    rec = Recording(ev, size)
    print(f"{n:,} events, sensor {size.width}x{size.height}, best of {args.repeat}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        rows = []
        dt, _ = _best(lambda: write_ecd(tmp / "ecd", rec), args.repeat)
        rows.append(("ECD text write", dt, n, (tmp / "ecd" / "events.txt").stat().st_size))
        dt, back = _best(lambda: read_events(tmp / "ecd", sensor_size=size), args.repeat)
        if not np.array_equal(back.events, ev):
            raise RuntimeError("ECD text round trip changed the events")
        rows.append(("ECD text read", dt, n, (tmp / "ecd" / "events.txt").stat().st_size))
        dt, _ = _best(lambda: write_recording(tmp / "rec.h5", rec), args.repeat)
        rows.append(("HDF5 write", dt, n, (tmp / "rec.h5").stat().st_size))
        dt, back = _best(lambda: read_events(tmp / "rec.h5"), args.repeat)
        if not np.array_equal(back.events, ev):
            raise RuntimeError("HDF5 round trip changed the events")
        rows.append(("HDF5 read", dt, n, (tmp / "rec.h5").stat().st_size))
    for name in ("stripes.mat", "garfield.mat", "flip.mat", "building.mat"):
        path = REALDATA / "rpg_event_lifetime" / name
        if not path.exists():
            print(f"(skipping {name}: absent at {path})")
            continue
        dt, back = _best(lambda: read_events(path), args.repeat)
        rows.append((f".mat read ({name}, {back.events.size:,} ev)", dt, back.events.size, path.stat().st_size))
    for name, dt, count, nbytes in rows:
        print(f"{name:<40} {dt:8.3f} s  {count / dt / 1e6:8.2f} M ev/s  {nbytes / 1e6:8.1f} MB")


if __name__ == "__main__":
    main()
