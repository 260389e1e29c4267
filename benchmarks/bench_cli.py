"""``evedge detect`` end to end against its kernels: throughput, peak memory, cold start.

Input: ``stripes.mat`` repeated ``--copies`` times one after the other (30:
10.2 M events, 36 s of a 128x128 recording), written once as an HDF5 event
file in a temporary folder. Measured in one run:

* the kernels in this process: buffer (``filter_events``) + estimator
  (``estimate_lifetimes`` on the kept events) + edge frames at 30 fps
  (``edge_frames``), CPU time; alternated ``--rounds`` times (default 3) with the
  command below, the least of each (the VM's speed drifts within minutes);
* ``evedge detect FILE -o OUT --no-png`` (and once with its PNGs) as a
  subprocess with a warm numba cache: CPU time (user + system) and peak
  resident memory (``ru_maxrss``); the ratio kernels / CLI is the share of
  the CLI's time spent in the detector itself (target >= 0.8); memory per
  event = (peak - the peak of the same command on a 1000-event file) / events
  (target <= 64 bytes);
* which kernels a serial run compiles, each with its compilation time (numba's
  timers, wall clock; a child process with an empty cache);
* the cold start: the same command on the first ``--cold-events`` events (1 M
  and 10 M) with
  an empty numba cache (``NUMBA_CACHE_DIR`` set to a fresh folder) against the
  same with that cache filled (wall time; target cold <= 2x warm). The cold run
  compiles the estimator in a child process while it reads the input and
  compiles and runs the buffer (:mod:`evedge.detector._precompile`): a wall-time
  gain on a second free core, not a CPU gain (its CPU includes the child's); the
  same cold run with ``EVEDGE_COMPILE_AHEAD=0`` (everything compiled in one
  process, as before; the default when no core is free) is printed beside it;
* the event buffer alone (``filter_events``, its checks included) in ns per event on the
  big file (least of 3 calls, the first beside it) and on ``stripes.mat`` (least of 5)
  (issue 12 item 4's target <= 40);
* ``evedge detect --no-png --tiles N`` (default 2) against ``--tiles 1``, wall, alternated,
  best of 2 each (the buffer's passes at once, the estimator on strips; the edge image
  stays serial in the command).

The machine is shared: the load average is printed. Run:
``.venv/bin/python benchmarks/bench_cli.py [--copies 30] [--cold-events 1000000 10000000] [--tiles 2] [--rounds 3]``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_detector import load_stripes  # noqa: E402

from evedge.detector import edge_frames, estimate_lifetimes, filter_events  # noqa: E402
from evedge.events import Recording  # noqa: E402
from evedge.io.hdf5 import write_recording  # noqa: E402

EVEDGE = Path(sys.executable).with_name("evedge")
_RUNS = 0


def repeated(events, copies):
    span = int(events["t"][-1]) - int(events["t"][0]) + 1000
    parts = []
    for c in range(copies):
        e = events.copy()
        e["t"] += c * span
        parts.append(e)
    return np.concatenate(parts)


def run_cli(src: Path, out: Path, *extra, env=None):
    """``evedge detect`` as a child; (wall s, CPU s, peak RSS bytes) of that command alone.

    Through ``/usr/bin/time``: a child forked from this (large) process would count
    this process's pages in its own peak RSS.
    """
    global _RUNS
    _RUNS += 1
    out = out.with_name(f"{out.name}_{_RUNS}")  # a fresh folder each run (evedge detect refuses an existing one)
    w0 = time.perf_counter()
    proc = subprocess.run(["/usr/bin/time", "-f", "%e %U %S %M", str(EVEDGE), "detect", str(src), "-o", str(out),
                           "--quiet", *extra], env=env, capture_output=True, text=True)
    wall = time.perf_counter() - w0
    if proc.returncode != 0:
        raise SystemExit(f"evedge detect failed: {proc.stderr}")
    _, user, system, max_kb = proc.stderr.strip().splitlines()[-1].split()
    return wall, float(user) + float(system), int(max_kb) * 1024


_COMPILED = r"""
import sys, time
import numpy as np
from evedge.detector import detect, edge_frames
from evedge.detector import _buffer_kernels, _edges_kernels, _intra_kernels
from evedge import _splitmix
from evedge.events import make_events
g = np.random.default_rng(0)
ev = make_events(g.integers(0, 64, 3000), g.integers(0, 64, 3000), np.sort(g.integers(0, 10**6, 3000)),
                 g.random(3000) < 0.5)
c0 = time.process_time()
res = detect(ev, (64, 64))
edge_frames(ev[res.kept], res.lifetimes[res.kept], (64, 64), [10**6], display="predecessor")
print(f"  first detect + edge frames on 3000 events: CPU {time.process_time() - c0:.2f} s; compiled:")
for mod in (_intra_kernels, _buffer_kernels, _edges_kernels, _splitmix):
    for name in sorted(vars(mod)):
        for cres in getattr(getattr(mod, name), "overloads", {}).values():
            tm = (cres.metadata or {}).get("timers", {})
            print(f"    {mod.__name__.rsplit('.', 1)[-1]}.{name}: {tm.get('compiler_lock', 0):.2f} s wall "
                  f"(LLVM {tm.get('llvm_lock', 0):.2f}; a caller's time includes its callees')")
"""


def compiled_kernels(tmp: Path):
    """Which kernels a serial ``detect`` + edge frames compiles, with an empty numba cache (a child process)."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp / "numba_cache_list")}
    proc = subprocess.run([sys.executable, "-c", _COMPILED], env=env, capture_output=True, text=True)
    print(proc.stdout.rstrip() if proc.returncode == 0 else f"  (failed: {proc.stderr.strip()[-300:]})")


def _cpu(f) -> float:
    c0 = time.process_time()
    f()
    return time.process_time() - c0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--copies", type=int, default=30)
    ap.add_argument("--cold-events", type=int, nargs="+", default=[1_000_000, 10_000_000])
    ap.add_argument("--tiles", type=int, default=2, help="strips of the evedge detect --tiles row (1: skip it)")
    ap.add_argument("--rounds", type=int, default=3, help="kernels and command alternated, least of each")
    args = ap.parse_args(argv)
    data = load_stripes()
    if data is None:
        return
    ev, size = data
    big = repeated(ev, args.copies)
    n = big.size
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs; {n:,} events ({args.copies} x stripes.mat)")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        src = tmp / "events.h5"
        write_recording(src, Recording(big, size))
        tiny = tmp / "tiny.h5"
        write_recording(tiny, Recording(big[:1000], size))

        # the kernels, in this process (warm-up on a slice first: compilation excluded)
        frame_t = np.rint(np.arange(int(big["t"][0]) + 1e6 / 30, int(big["t"][-1]) + 1e6 / 60, 1e6 / 30)).astype(np.int64)
        kept = filter_events(big[:5000], size)
        estimate_lifetimes(big[:5000][kept], size)

        def run_kernels():
            c0 = time.process_time()
            kept = filter_events(big, size)
            c1 = time.process_time()
            sub = big[kept]
            lt = estimate_lifetimes(sub, size)
            edge_frames(sub, lt, size, frame_t, display="predecessor")
            return time.process_time() - c0, c1 - c0

        kernels, buf_first = run_kernels()
        # the buffer alone, as on stripes.mat: least of several calls (each call allocates and first
        # touches ~90 MB of fresh memory for its chain and mask here, whose page faults vary with the load)
        buf_big = min(buf_first, *(_cpu(lambda: filter_events(big, size)) for _ in range(2)))
        buf_small = min(_cpu(lambda: filter_events(ev, size)) for _ in range(5))
        print(f"kernels (buffer + estimator + {frame_t.size} edge frames), in process: CPU {kernels:.2f} s "
              f"({n / kernels / 1e6:.2f} M ev/s); of which the buffer (filter_events) {buf_first / n * 1e9:.0f} ns/event")
        print(f"buffer alone (filter_events, checks included): {buf_big / n * 1e9:.0f} ns/event on this file (least of 3 "
              f"calls; the first {buf_first / n * 1e9:.0f}), {buf_small / ev.size * 1e9:.0f} ns/event on stripes.mat "
              f"(least of 5); target <= 40")

        run_cli(tiny, tmp / "o0")  # fills the numba cache if needed
        _, _, base_rss = run_cli(tiny, tmp / "o0")
        # the kernels and the command alternated, the least CPU of each over --rounds: this VM's speed drifts
        # by 10-15 % within minutes, so one run of each would measure the drift as much as the ratio
        runs = {"--no-png": [], "with PNGs": []}
        kernel_cpu = [kernels]
        for r in range(args.rounds):
            if r:
                kernel_cpu.append(run_kernels()[0])
            for label in runs:
                runs[label].append(run_cli(src, tmp / "o1", *(("--no-png",) if label == "--no-png" else ())))
        kernels = min(kernel_cpu)
        print(f"kernels, least of {args.rounds} alternated with the command: CPU {kernels:.2f} s "
              f"({n / kernels / 1e6:.2f} M ev/s; all: {', '.join(f'{c:.2f}' for c in kernel_cpu)} s)")
        for label, results in runs.items():
            wall, cpu, rss = min(results, key=lambda r: r[1])
            print(f"evedge detect {label:9s}: wall {wall:.2f} s, CPU {cpu:.2f} s ({n / cpu / 1e6:.2f} M ev/s; least of "
                  f"{args.rounds}, all: {', '.join(f'{r[1]:.2f}' for r in results)} s); kernels / CLI = "
                  f"{kernels / cpu:.2f} (target >= 0.8); peak RSS {rss / 2**20:.0f} MiB, {(rss - base_rss) / n:.1f} "
                  f"B/event above the {base_rss / 2**20:.0f} MiB of a 1000-event run (target <= 64)")

        if args.tiles > 1:  # the whole command on strips, wall against one strip, alternated (best of 2 each)
            run_cli(tiny, tmp / "o0", "--tiles", str(args.tiles))  # the parallel kernels into the cache
            walls = {1: [], args.tiles: []}
            for _ in range(2):
                for k in walls:
                    walls[k].append(run_cli(src, tmp / "o2", "--no-png", "--tiles", str(k))[0])
            w1, wk = min(walls[1]), min(walls[args.tiles])
            print(f"evedge detect --no-png --tiles {args.tiles}: wall {wk:.2f} s against {w1:.2f} s on one strip, "
                  f"{w1 / wk:.2f}x (the same output: tests/detector/test_detect_cli.py); load "
                  f"{os.getloadavg()[0]:.2f}")

        print("cold start: the kernels compiled by a serial run")
        compiled_kernels(tmp)
        for m in args.cold_events:
            cold_src = tmp / f"cold{m}.h5"
            write_recording(cold_src, Recording(big[:m], size))
            env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp / f"numba_cache{m}")}
            env["EVEDGE_COMPILE_AHEAD"] = "1"  # the child whatever the load (by default only with a free core)
            serial_env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp / f"numba_cache_serial{m}"),
                          "EVEDGE_COMPILE_AHEAD": "0"}
            load0 = os.getloadavg()[0]
            cold = run_cli(cold_src, tmp / "o2", "--no-png", env=env)
            warm = run_cli(cold_src, tmp / "o3", "--no-png", env=env)
            serial = run_cli(cold_src, tmp / "o4", "--no-png", env=serial_env)
            print(f"cold start on {min(n, m):,} events: empty numba cache wall {cold[0]:.2f} s (CPU {cold[1]:.2f}, "
                  f"the compiling child's included), warm {warm[0]:.2f} s (CPU {warm[1]:.2f}): cold / warm = "
                  f"{cold[0] / warm[0]:.2f} wall, {cold[1] / warm[1]:.2f} CPU (target <= 2); all compiled in one "
                  f"process (EVEDGE_COMPILE_AHEAD=0): wall {serial[0]:.2f} s, CPU {serial[1]:.2f} "
                  f"({serial[0] / warm[0]:.2f} / {serial[1] / warm[1]:.2f}); load {load0:.2f}->{os.getloadavg()[0]:.2f}")
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
