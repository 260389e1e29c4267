"""CPU time to write and read each registered event file format (through evedge.io's registry).

Generates a synthetic recording (default 2 M events, DAVIS240 size, 20 s),
writes it in every writable format, reads each file back (checking the
events are unchanged), and prints CPU seconds (``time.process_time``, this
process only: faery's Rust decoders run in it) and M events per CPU second.
CPU time, not wall time: the machine is shared.

Run: ``.venv/bin/python benchmarks/bench_formats.py [--events N]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from evedge.events import Recording, SensorSize, make_events
from evedge.io import formats, read_events, write_events

EXTENSIONS = {"ecd": "", "hdf5": ".h5", "aedat4": ".aedat4", "evt3": ".raw", "evt2": ".raw", "dat": ".dat", "es": ".es"}


def _cpu(fn):
    start = time.process_time()
    out = fn()
    return time.process_time() - start, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--events", type=int, default=2_000_000)
    args = parser.parse_args()
    n = args.events
    rng = np.random.default_rng(0)
    size = SensorSize(240, 180)
    ev = make_events(rng.integers(0, 240, n), rng.integers(0, 180, n), np.sort(rng.integers(0, 20_000_000, n)),
                     rng.integers(0, 2, n))
    rec = Recording(ev, size)
    # numba compiles the EVT 3 kernels on first use (cached afterwards): warm them outside the timing
    with tempfile.TemporaryDirectory() as tmp:
        small = Recording(ev[:1000], size)
        read_events(write_events(Path(tmp) / "w.raw", small))
    print(f"{n:,} events, {size.width}x{size.height}, CPU seconds of this process")
    print(f"{'format':8} {'write s':>8} {'Mev/s':>7} {'read s':>8} {'Mev/s':>7} {'bytes/ev':>8}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, fmt in formats().items():
            if fmt.write is None:
                continue
            path = Path(tmp) / f"out_{name}{EXTENSIONS.get(name, '')}"
            tw, _ = _cpu(lambda: write_events(path, rec, format=name))
            tr, back = _cpu(lambda: read_events(path, format=name, sensor_size=size if name == "ecd" else None))
            if back.events.tobytes() != ev.tobytes():
                raise RuntimeError(f"{name}: the round trip changed the events")
            nbytes = sum(p.stat().st_size for p in path.rglob("*")) if path.is_dir() else path.stat().st_size
            print(f"{name:8} {tw:8.2f} {n / tw / 1e6:7.1f} {tr:8.2f} {n / tr / 1e6:7.1f} {nbytes / n:8.2f}")


if __name__ == "__main__":
    main()
