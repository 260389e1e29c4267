"""``evedge detect``: lifetimes, flow and edge frames of an event file."""

from __future__ import annotations

import math
import os
import re
import tempfile
from pathlib import Path

import click
import numpy as np

from evedge._cli_options import sensor_option

_CHUNK = 100_000
#: Most memory the edge frames (one byte per pixel) may take before --fps is refused as a mistake.
_MAX_FRAME_BYTES = 4 * 2**30
#: Names of the PNG frames this command writes (and may replace on a rerun).
_PNG_NAME = re.compile(r"edges_\d{6}_-?\d+us\.png")


def _times(ctx, param, value):
    if value is None:
        return None
    try:
        times = np.array([int(v) for v in value.split(",") if v.strip()], dtype=np.int64)
    except (ValueError, OverflowError):
        raise click.BadParameter(f"expected comma-separated microseconds (int64), got {value!r}",
                                 ctx=ctx, param=param) from None
    if times.size == 0:
        raise click.BadParameter("no instant given", ctx=ctx, param=param)
    if np.any(np.diff(times) < 0):
        i = int(np.flatnonzero(np.diff(times) < 0)[0])
        raise click.BadParameter(f"instants must be non-decreasing, got {times[i]} then {times[i + 1]}",
                                 ctx=ctx, param=param)
    return times


def _finite(ctx, param, value):
    """FloatRange lets nan and inf through; neither is a frame rate or a window."""
    if value is not None and not math.isfinite(value):
        raise click.BadParameter(f"must be a finite number, got {value}", ctx=ctx, param=param)
    return value


def _frame_times(events, fps, times):
    if times is not None:
        return times
    if events.size == 0:
        return np.empty(0, np.int64)
    step = 1e6 / fps
    t0, t1 = int(events["t"][0]), int(events["t"][-1])
    return np.rint(np.arange(t0 + step, t1 + step / 2, step)).astype(np.int64)


def _atomic(path: Path, write) -> None:
    """Write through a temp file in the target's directory, then rename over it."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    # mkstemp makes the file private (0600); give it the mode a plain open() would
    mask = os.umask(0o022)
    os.umask(mask)
    os.fchmod(fd, 0o666 & ~mask)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


#: Methods that draw random numbers (RANSAC), hence take --seed.
_SEEDED = ("intra", "mueggler")


def _lifetimes_intra(events, sensor, use_buffer, seed, quiet):
    from tqdm import tqdm

    from .buffer import filter_events
    from .intra import IntraParams, IntraPixelLifetime
    from .result import empty_lifetimes

    kept = filter_events(events, sensor) if use_buffer else np.ones(events.size, bool)
    sub = events[kept]
    est = IntraPixelLifetime(sensor, IntraParams(seed=seed))
    parts = []
    with tqdm(total=sub.size, unit="ev", desc="lifetimes", disable=quiet) as bar:
        for start in range(0, sub.size, _CHUNK):
            parts.append(est.process(sub[start : start + _CHUNK]))
            bar.update(min(_CHUNK, sub.size - start))
    out = empty_lifetimes(events.size)
    if parts:
        out[kept] = np.concatenate(parts)
    return out, kept


def _write_h5(path: Path, lifetimes, kept, times, frames, meta) -> None:
    import h5py

    def write(tmp):
        with h5py.File(tmp, "w") as f:
            for key, value in meta.items():
                f.attrs[key] = value
            if lifetimes is not None:
                g = f.create_group("lifetimes")
                for name in lifetimes.dtype.names:
                    g.create_dataset(name, data=lifetimes[name], compression="gzip")
                g.create_dataset("kept", data=kept, compression="gzip")
            e = f.create_group("edges")
            e.create_dataset("t_us", data=times)
            e.create_dataset("images", data=frames, compression="gzip")

    _atomic(path, write)


def _write_pngs(folder: Path, times, frames, quiet) -> None:
    from PIL import Image
    from tqdm import tqdm

    folder.mkdir(parents=True, exist_ok=True)
    written = set()
    for i, (t, img) in enumerate(tqdm(list(zip(times, frames)), desc="PNG", unit="frame", disable=quiet)):
        target = folder / f"edges_{i:06d}_{int(t)}us.png"
        _atomic(target, lambda tmp, img=img: Image.fromarray((img * 255).astype(np.uint8)).save(tmp, format="PNG"))
        written.add(target.name)
    # A rerun into the same folder must not leave frames of an earlier run beside the new ones.
    for old in folder.iterdir():
        if _PNG_NAME.fullmatch(old.name) and old.name not in written:
            old.unlink()


@click.command()
@click.argument("events_file", metavar="EVENTS", type=click.Path(exists=True, path_type=str))
@click.option("-o", "--out", "out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Output folder: detection.h5 and edges/*.png.")
@click.option("--method", type=click.Choice(["intra", "mueggler", "time", "count"]), default="intra",
              show_default=True, help="Lifetime method, or accumulation over a time window / an event count.")
@click.option("--fps", type=click.FloatRange(min=0, min_open=True), default=30.0, callback=_finite, show_default=True,
              help="Edge frames per second over the recording (ignored with --times).")
@click.option("--times", callback=_times, metavar="T1,T2,...",
              help="Edge-frame instants in microseconds, non-decreasing.")
@click.option("--window-ms", type=click.FloatRange(min=0.001), default=30.0, show_default=True, callback=_finite,
              help="Time window of --method time.")
@click.option("--count", "n_events", type=click.IntRange(min=1), default=2000, show_default=True,
              help="Events per frame of --method count.")
@sensor_option()
@click.option("--sort", "sort", is_flag=True, help="Sort events by time (stable) if the file is unsorted.")
@click.option("--buffer/--no-buffer", "use_buffer", default=None,
              help="Event-buffer noise filter (default: on for intra, off for mueggler).")
@click.option("--clear-behind", is_flag=True, help="Clear the pixel behind each event (Mueggler's display).")
@click.option("--seed", type=click.IntRange(min=0, max=2**63 - 1), default=None,
              help="RANSAC seed of the lifetime methods (intra, mueggler; default 0); refused by time and count, "
                   "which draw no random numbers.")
@click.option("--quiet", is_flag=True, help="No progress bars.")
def detect(events_file, out, method, fps, times, window_ms, n_events, sensor, sort, use_buffer, clear_behind, seed,
           quiet):
    """Detect edges in an event file EVENTS (any format evedge.io reads).

    Writes OUT/detection.h5 (per-event lifetime_us, vx_px_s, vy_px_s, valid and
    kept for lifetime methods; edge frames with their times) and one PNG per
    edge frame in OUT/edges/.
    """
    from evedge.io import read_events

    if seed is not None and method not in _SEEDED:
        raise click.BadParameter(f"method {method!r} draws no random numbers, so a seed would change nothing; "
                                 f"--seed applies to {' and '.join(_SEEDED)}", param_hint="'--seed'")
    seed = 0 if seed is None else seed
    try:
        rec = read_events(events_file, sensor_size=sensor, sort=sort)
    except (ValueError, TypeError, OSError) as err:
        raise click.ClickException(str(err)) from None
    events, size = rec.events, rec.sensor_size
    if times is None and events.size:
        n_frames = int((int(events["t"][-1]) - int(events["t"][0])) * fps / 1e6)
        if n_frames * size.width * size.height > _MAX_FRAME_BYTES:
            raise click.BadParameter(
                f"{n_frames} edge frames of {size.width}x{size.height} over the recording would need "
                f"{n_frames * size.width * size.height / 2**30:.1f} GiB; lower --fps or give --times",
                param_hint="'--fps'")
    frame_t = _frame_times(events, fps, times)
    if frame_t.size == 0 and events.size:
        span = int(events["t"][-1]) - int(events["t"][0])
        click.echo(f"Warning: no edge frame: the events span {span} us, less than one frame period "
                   f"({1e6 / fps:.0f} us at --fps {fps:g}); pass --times or a higher --fps", err=True)
    lifetimes = kept = None
    if method in ("intra", "mueggler"):
        from .edges import edge_frames

        if method == "intra":
            lifetimes, kept = _lifetimes_intra(events, size, True if use_buffer is None else use_buffer, seed, quiet)
        else:
            from .pipeline import detect as run

            from .mueggler import MuegglerParams

            res = run(events, size, method="mueggler", use_buffer=use_buffer, params=MuegglerParams(seed=seed))
            lifetimes, kept = res.lifetimes, res.kept
        frames = edge_frames(events[kept], lifetimes[kept], size, frame_t, clear_behind=clear_behind)
    elif method == "time":
        from .accumulate import accumulate_time

        frames = accumulate_time(events, size, frame_t, int(round(window_ms * 1000)))
    else:
        from .accumulate import accumulate_count

        frames = accumulate_count(events, size, frame_t, n_events)
    meta = {"source": str(events_file), "method": method, "sensor_width": size.width, "sensor_height": size.height}
    try:
        out.mkdir(parents=True, exist_ok=True)
        _write_h5(out / "detection.h5", lifetimes, kept, frame_t, frames, meta)
        _write_pngs(out / "edges", frame_t, frames, quiet)
    except OSError as err:
        raise click.ClickException(f"cannot write the output into {out}: {err}") from None
    n_valid = int(lifetimes["valid"].sum()) if lifetimes is not None else None
    msg = f"{events.size} events, {frame_t.size} edge frames -> {out}"
    if n_valid is not None:
        msg += f"; {int(kept.sum())} passed to the estimator, {n_valid} with a lifetime"
    click.echo(msg)
