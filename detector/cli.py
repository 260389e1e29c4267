"""``evedge detect``: lifetimes, flow and edge frames of an event file."""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import click
import numpy as np

from evedge._cli_options import sensor_option

_CHUNK = 100_000
#: Most memory the edge frames (one byte per pixel) may take before --fps is refused as a mistake.
_MAX_FRAME_BYTES = 4 * 2**30
#: The largest float below 2**63: frame times at or above it do not fit int64 microseconds.
_LAST_FLOAT_US = float(np.nextafter(2.0**63, 0))
#: Memory of the lifetime methods' per-pixel state (buffer, SAE, estimator, edge image), bytes per pixel,
#: and of their per-event outputs (lifetimes, flow, validity, buffer links), bytes per event.
_STATE_BYTES_PER_PIXEL = {"intra": 160, "mueggler": 160, "time": 16, "count": 16}
_BYTES_PER_EVENT = 96
#: What OUT may hold for detect to replace it (with --overwrite).
_OUTPUT_NAMES = ("detection.h5", "edges")
_PNG_NAME = re.compile(r"edges_\d{6}_-?\d+us\.png")


def _check_replaceable(out: Path) -> None:
    """An OUT to replace must hold only what detect writes: no links, no other files."""
    edges = out / "edges"
    if edges.is_dir() and not edges.is_symlink():
        for entry in edges.iterdir():
            if entry.is_symlink() or not _PNG_NAME.fullmatch(entry.name):
                raise click.ClickException(f"{entry} was not written by evedge detect: {out} is not replaced; "
                                           f"move it away or choose another output folder")


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
    decrease = times[1:] < times[:-1]  # not np.diff: -5e18, 5e18 would wrap int64
    if np.any(decrease):
        i = int(np.flatnonzero(decrease)[0])
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
    ts = np.rint(np.arange(t0 + step, t1 + step / 2, step))
    # near the int64 limit a float time rounds to 2**63, which would wrap to -2**63 us
    return ts[ts < _LAST_FLOAT_US].astype(np.int64)


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
    from evedge.io._atomic import write_hdf5_atomic

    def fill(f):  # built in memory: HDF5 can crash the process when the disk fills during its own writes
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

    write_hdf5_atomic(path, fill)


def _write_pngs(folder: Path, times, frames, quiet) -> None:
    """Write the frames into ``folder`` (a fresh folder inside the staged output)."""
    from PIL import Image
    from tqdm import tqdm

    folder.mkdir()
    for i, (t, img) in enumerate(tqdm(list(zip(times, frames)), desc="PNG", unit="frame", disable=quiet)):
        Image.fromarray((img * 255).astype(np.uint8)).save(folder / f"edges_{i:06d}_{int(t)}us.png", format="PNG")


def _check_memory(n_events: int, size, n_frames: int, method: str) -> None:
    """Refuse a run whose state, per-event outputs and frames cannot fit, before any work."""
    from evedge._resources import memory_shortfall

    pixels = size.width * size.height
    needed = pixels * _STATE_BYTES_PER_PIXEL[method] + n_events * _BYTES_PER_EVENT + 2 * n_frames * pixels
    short = memory_shortfall(needed, f"--method {method} on {n_events} events of a {size.width}x{size.height} "
                                     f"sensor with {n_frames} edge frames")
    if short:
        raise click.ClickException(f"{short}; a smaller --sensor, fewer frames (--fps, --times) or a shorter "
                                   f"recording would fit")


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
@click.option("--seed", type=click.IntRange(min=0, max=2**63 - 1), default=0, show_default=True,
              help="RANSAC seed (intra).")
@click.option("--overwrite", is_flag=True, help="Replace an existing OUT (a previous detect output).")
@click.option("--quiet", is_flag=True, help="No progress bars.")
def detect(events_file, out, method, fps, times, window_ms, n_events, sensor, sort, use_buffer, clear_behind, seed,
           overwrite, quiet):
    """Detect edges in an event file EVENTS (any format evedge.io reads).

    Writes OUT/detection.h5 (per-event lifetime_us, vx_px_s, vy_px_s, valid and
    kept for lifetime methods; edge frames with their times) and one PNG per
    edge frame in OUT/edges/. Both are written into a temporary folder beside
    OUT and swapped in together at the end; an existing OUT is replaced only
    with --overwrite.
    """
    from evedge._output import OutputExistsError, check_output
    from evedge.io import read_events

    try:
        replacing = check_output(out, overwrite=overwrite)
    except OutputExistsError as err:
        raise click.ClickException(str(err)) from None
    if replacing:
        _check_replaceable(out)

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
    _check_memory(events.size, size, frame_t.size, method)
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

            res = run(events, size, method="mueggler", use_buffer=use_buffer)
            lifetimes, kept = res.lifetimes, res.kept
        frames = edge_frames(events[kept], lifetimes[kept], size, frame_t, clear_behind=clear_behind)
    elif method == "time":
        from .accumulate import accumulate_time

        frames = accumulate_time(events, size, frame_t, int(round(window_ms * 1000)))
    else:
        from .accumulate import accumulate_count

        frames = accumulate_count(events, size, frame_t, n_events)
    meta = {"source": str(events_file), "method": method, "sensor_width": size.width, "sensor_height": size.height}
    from evedge._output import staged_folder

    try:
        with staged_folder(out, allowed=_OUTPUT_NAMES) as stage:
            _write_h5(stage / "detection.h5", lifetimes, kept, frame_t, frames, meta)
            _write_pngs(stage / "edges", frame_t, frames, quiet)
    except OutputExistsError as err:
        raise click.ClickException(str(err)) from None
    except OSError as err:
        raise click.ClickException(f"cannot write the output {out} (nothing of this run was kept): {err}") from None
    if replacing:
        click.echo(f"replaced the earlier output in {out}", err=True)
    n_valid = int(lifetimes["valid"].sum()) if lifetimes is not None else None
    msg = f"{events.size} events, {frame_t.size} edge frames -> {out}"
    if n_valid is not None:
        msg += f"; {int(kept.sum())} passed to the estimator, {n_valid} with a lifetime"
    click.echo(msg)
