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
interpolation). The default rows of ``stripes`` and ``shapes_translation`` at 240x180 are the
best of 3 runs and also print their ratio to the target of issue 15 (3x real time on one core):
``= 1.25x the 3 target`` (>= 1: met). Frames rows: ``shapes_translation`` rendered (not timed) at 1 kHz and 5 kHz
into memory, then converted by :func:`evedge.sim.simulate_frames` (ESIM's
algorithm, the scenes' pixel model): the frames path's speed without decoding, as the
best of 3 runs and as a ratio to the 2.5 sim-s/s target; the same frames converted
frame by frame (the converter without its batches of frames), 1 kHz frames upsampled
x5 (log interpolation: 5 kHz samples) and the same through sub-frame images (A/B), and end to end from a lossless 8-bit video
(FFV1, written to a temporary folder, not timed) with the share of opening and decoding, and the 5 kHz
video once more as before its single decoding (an opening pass that decoded every frame, frames through
BGR): the A/B ratio in one run.
"""

from __future__ import annotations

import argparse
import copy
import math
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
    cpu = math.inf
    for _ in range(3 if target else 1):  # target rows: the best of 3 (the machine is shared)
        t0 = time.process_time()
        rec = simulate(scene, duration_s=duration_s, frame_rate_hz=0, progress=False)
        cpu = min(cpu, time.process_time() - t0)
    n = rec.events.shape[0]
    speed = duration_s / cpu
    goal = (f"  = {speed / TARGET_SIM_S_PER_S:4.2f}x the {TARGET_SIM_S_PER_S:g} target (best of 3)"
            if target else "")
    print(f"{label:44s} {scene.sensor.width}x{scene.sensor.height}  sim {duration_s:5.2f} s in "
          f"{cpu:6.2f} s CPU: {speed:6.3f} sim-s/s, {n / cpu / 1e6:6.3f} Mev/s "
          f"({n:,} events, {rec.metadata['n_samples']} samples, {rec.metadata['sampling_used']}){goal}", flush=True)


#: The frames path's speed target (simulated s per CPU s at 240x180; esim_py: 3.3 on the same frames).
FRAMES_TARGET = 2.5


def _best_cpu(fn, repeats: int):
    """The smallest CPU time of ``repeats`` runs of ``fn()`` (other processes only ever add to it) and its result."""
    best, out = float("inf"), None
    for _ in range(repeats):
        t0 = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t0)
    return best, out


def _frames_row(label, scene, duration_s, cpu, rec, what):
    n = rec.events.shape[0]
    rate = duration_s / cpu
    print(f"{label:44s} {scene.sensor.width}x{scene.sensor.height}  sim {duration_s:5.2f} s in "
          f"{cpu:6.3f} s CPU: {rate:6.3f} sim-s/s = {rate / FRAMES_TARGET:4.2f}x the {FRAMES_TARGET} target, "
          f"{n / cpu / 1e6:6.3f} Mev/s ({n:,} events, {what})", flush=True)


def _frames(label: str, scene, duration_s: float, rate_hz: float, repeats: int, upsample: int = 1,
            per_frame: bool = False, sub_frame_images: bool = False) -> None:
    """Frames in memory (rendered, not timed). ``per_frame``: without batches of frames; ``sub_frame_images``:
    log upsampling through sub-frame images (before the log-interval kernel), for the A/B ratio in one run."""
    import numpy as np

    from evedge.sim import frames_from_arrays, simulate_frames
    from evedge.sim.frames import FramesRenderer

    r = scene.build_renderer()
    t = np.arange(int(round(duration_s * rate_hz)) + 1) / rate_hz
    frames = np.stack([r.intensity(float(tk)) for tk in t])
    samples, log_interval = FramesRenderer.samples, FramesRenderer.log_interval
    if per_frame:  # the converter without batches of frames (what it does with sensor effects on)
        FramesRenderer.samples = None
    if sub_frame_images:
        FramesRenderer.log_interval = None
    try:
        def run(fr=frames, tt=t, seed=scene.seed):
            return simulate_frames(frames_from_arrays(fr, tt), scene.params, seed=seed, upsample=upsample,
                                   progress=False)

        run(frames[:5], t[:5])  # warm-up
        cpu, rec = _best_cpu(run, repeats)
    finally:
        FramesRenderer.samples, FramesRenderer.log_interval = samples, log_interval
    what = f"{len(t)} frames at {rate_hz:g} Hz" + (f", upsampled x{upsample} (log)" if upsample > 1 else "")
    _frames_row(label, scene, duration_s, cpu, rec, what + f", best of {repeats}")


def _video(label: str, scene, duration_s: float, rate_hz: float, repeats: int, two_decodes: bool = False) -> None:
    """End to end from a lossless 8-bit video file (FFV1 in AVI, OpenCV), with the share of opening and decoding.

    ``two_decodes``: as before the packet-time opening and the unconverted grey frames (an opening pass that
    decodes every frame, then frames converted to BGR and back to grey), for the A/B ratio in one run.
    """
    import tempfile

    import cv2
    import numpy as np

    import evedge.sim.frames as frames_mod
    from evedge.sim import open_video, simulate_frames

    patched = {"_container_times": lambda path, cv: None, "_fourcc": lambda cap, cv: b""} if two_decodes else {}
    saved = {name: getattr(frames_mod, name) for name in patched}
    for name, f in patched.items():
        setattr(frames_mod, name, f)

    r = scene.build_renderer()
    t = np.arange(int(round(duration_s * rate_hz)) + 1) / rate_hz
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "frames.avi"
        # the AVI muxer drops frames above 1000 fps: a faster clip is written at 1000 fps, read at its rate
        wr = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), min(rate_hz, 1000.0),
                             (scene.sensor.width, scene.sensor.height), isColor=False)
        for tk in t:
            wr.write(np.rint(np.clip(r.intensity(float(tk)), 0, 1) * 255).astype(np.uint8))
        wr.release()

        rate = None if rate_hz <= 1000.0 else rate_hz

        def decode_only():
            src = open_video(path, rate_hz=rate)
            for k in range(len(src)):
                src.frame(k)
            src.close()

        simulate_frames(open_video(path, rate_hz=rate), scene.params, progress=False)  # warm-up
        cpu, rec = _best_cpu(lambda: simulate_frames(open_video(path, rate_hz=rate), scene.params, seed=scene.seed,
                                                     progress=False), repeats)
        cpu_open, _ = _best_cpu(lambda: open_video(path, rate_hz=rate).close(), repeats)
        cpu_decode, _ = _best_cpu(decode_only, repeats)
    for name, f in saved.items():
        setattr(frames_mod, name, f)
    _frames_row(label, scene, duration_s, cpu, rec, f"{len(t)} frames at {rate_hz:g} Hz, best of {repeats}")
    print(f"{'':44s} of which opening (frame count and times) {cpu_open:.3f} s, opening + decoding "
          f"to grey float64 {cpu_decode:.3f} s = {cpu_decode / cpu:.0%} of the total", flush=True)


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
          f"times are CPU seconds (time.process_time); load average {os.getloadavg()[0]:.1f}")
    tr = _scene("shapes_translation")
    reps = 1 if args.quick else 3
    _frames("shapes_translation frames in (1 kHz)", tr, 1.0 * k, 1000.0, reps)
    _frames("shapes_translation frames in (5 kHz)", tr, 0.4 * k, 5000.0, reps)
    _frames("... 5 kHz, frame by frame (no batches)", tr, 0.4 * k, 5000.0, reps, per_frame=True)
    _frames("... 1 kHz upsampled x5 (5 kHz samples)", tr, 0.4 * k, 1000.0, reps, upsample=5)
    _frames("... the same, sub-frame images (A/B)", tr, 0.4 * k, 1000.0, reps, upsample=5, sub_frame_images=True)
    _video("shapes_translation video in (1 kHz, FFV1)", tr, 1.0 * k, 1000.0, reps)
    _video("shapes_translation video in (5 kHz, FFV1)", tr, 0.4 * k, 5000.0, reps)
    _video("... 5 kHz video, decoded twice (A/B)", tr, 0.4 * k, 5000.0, reps, two_decodes=True)
    print(f"load average at the end {os.getloadavg()[0]:.1f}")
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
