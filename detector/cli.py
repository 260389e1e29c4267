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
from evedge.video import edge_png

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


def _parse_value(text: str):
    """A ``--param`` value as TOML reads it (``3``, ``0.5``, ``true``, ``"buffered"``), else the bare string."""
    import tomllib

    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def _params(ctx, param, values):
    """``--param key=value`` (repeatable) -> {"method": {...}, "buffer": {...}}."""
    out: dict = {"method": {}, "buffer": {}}
    for item in values:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise click.BadParameter(f"expected key=value, got {item!r}", ctx=ctx, param=param)
        group = "method"
        if key.startswith(("buffer.", "filter.")):
            group, key = "buffer", key.split(".", 1)[1]
        out[group][key] = _parse_value(value.strip())
    return out


def _config(ctx, param, value):
    """``--config FILE.toml``: tables ``[params]`` (the method's) and ``[buffer]`` (the filter's); ``method``."""
    if value is None:
        return None
    import tomllib

    try:
        with open(value, "rb") as fh:
            data = tomllib.load(fh)
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise click.BadParameter(f"{value}: {err}", ctx=ctx, param=param) from None
    unknown = sorted(set(data) - {"method", "params", "buffer", "display"})
    if unknown:
        raise click.BadParameter(f"{value}: unknown key(s) {unknown}; expected method, display, [params], [buffer]",
                                 ctx=ctx, param=param)
    for table in ("params", "buffer"):
        if not isinstance(data.get(table, {}), dict):
            raise click.BadParameter(f"{value}: {table!r} must be a table", ctx=ctx, param=param)
    return data


def _method(ctx, param, value):
    from .protocols import METHODS

    try:
        METHODS.get(value, kind=("estimator", "edges"))
    except (LookupError, ValueError) as err:
        raise click.BadParameter(str(err), ctx=ctx, param=param) from None
    return value


def _method_help() -> str:
    from .protocols import METHODS

    return ("Registered method: " + ", ".join(f"{e.name} ({e.display_name})" for e in
                                               METHODS.entries(kind=("estimator", "edges")))
            + "; or package.module:factory of a third-party method.")


def _estimate(method, events, sensor, filter_name, filter_params, params, quiet):
    """Per-event lifetimes (LIFETIME_DTYPE) and the filter's keep mask; chunked with a progress bar."""
    from tqdm import tqdm

    from .pipeline import _check_estimate, keep_mask, make_method
    from .result import empty_lifetimes

    kept = keep_mask(filter_name, events, sensor, filter_params) if filter_name else np.ones(events.size, bool)
    sub = events[kept]
    est = make_method(method, sensor, params, kind="estimator")
    parts = []
    with tqdm(total=sub.size, unit="ev", desc="lifetimes", disable=quiet) as bar:
        for start in range(0, sub.size, _CHUNK):
            chunk = sub[start : start + _CHUNK]
            parts.append(_check_estimate(method, est.process(chunk), chunk.size))
            bar.update(chunk.size)
    out = empty_lifetimes(events.size)
    if parts:
        out[kept] = np.concatenate(parts)
    return out, kept


def _versions() -> dict:
    import platform
    from importlib.metadata import PackageNotFoundError, version

    out = {"python": platform.python_version()}
    for pkg in ("evedge", "numpy", "numba", "h5py", "scipy"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = "absent"
    return out


def _write_pngs(folder: Path, times, frames, quiet) -> None:
    from PIL import Image
    from tqdm import tqdm

    folder.mkdir(parents=True, exist_ok=True)
    written = set()
    for i, (t, img) in enumerate(tqdm(list(zip(times, frames)), desc="PNG", unit="frame", disable=quiet)):
        target = folder / f"edges_{i:06d}_{int(t)}us.png"
        # the report's convention: black edges on white
        _atomic(target, lambda tmp, img=img: Image.fromarray(edge_png(np.asarray(img, bool))).save(tmp, format="PNG"))
        written.add(target.name)
    # A rerun into the same folder must not leave frames of an earlier run beside the new ones.
    for old in folder.iterdir():
        if _PNG_NAME.fullmatch(old.name) and old.name not in written:
            old.unlink()


class _DetectCommand(click.Command):
    """Lists the registered methods in ``--help`` (read from the registry when help is shown)."""

    def get_help(self, ctx):
        for p in self.params:
            if p.name == "method":
                p.help = _method_help()
        return super().get_help(ctx)


def _write_video(path: Path, rec, det, lifetimes, kept, colour, fps, quiet) -> None:
    """The edge frames of ``det`` as a video, coloured by lifetime/polarity of the events behind them."""
    from evedge.video import edge_video_frames, write_video

    colour = colour or ("lifetime" if lifetimes is not None else "mono")
    events, life = rec.events, None
    if lifetimes is not None:
        events, life = rec.events[kept], lifetimes["lifetime_us"][kept]
    elif colour == "lifetime":
        raise click.BadParameter(f"method {det.metadata['method']!r} gives no lifetimes", param_hint="'--video-colour'")
    label = f"{det.metadata['method']}" + (f", {colour}" if colour != "mono" else "")
    frames = edge_video_frames(det.edges, grey=rec.frames, events=events, lifetime_us=life, colour=colour, label=label)
    try:
        write_video(path, frames, fps=min(fps, 60.0), n_frames=len(det.edges), quiet=quiet)
    except ValueError as err:
        raise click.ClickException(str(err)) from None


@click.command(cls=_DetectCommand)
@click.argument("events_file", metavar="EVENTS", type=click.Path(exists=True, path_type=str))
@click.option("-o", "--out", "out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Output folder: detection.h5 and edges/*.png.")
@click.option("--method", default=None, metavar="NAME", help="Registered method (see --help), default intra.")
@click.option("--param", "param_items", multiple=True, metavar="KEY=VALUE", callback=_params,
              help="A parameter of the method (e.g. delta_px=0.3, seed=2), or of the noise filter with the prefix "
                   "buffer. (e.g. buffer.tau_min_us=5000, buffer.mode=causal); repeatable; overrides --config.")
@click.option("--config", "config", type=click.Path(exists=True, dir_okay=False, path_type=str), callback=_config,
              help="TOML file: method = NAME, display = POLICY, [params] (the method's) and [buffer] (the filter's).")
@click.option("--fps", type=click.FloatRange(min=0, min_open=True), default=30.0, callback=_finite, show_default=True,
              help="Edge frames per second over the recording (ignored with --times).")
@click.option("--times", callback=_times, metavar="T1,T2,...",
              help="Edge-frame instants in microseconds, non-decreasing.")
@click.option("--at-frames", is_flag=True,
              help="Edge frames at the input's own frame times (its exact edge maps, else its grey frames), "
                   "as evedge grade compares them; replaces --fps/--times.")
@click.option("--window-ms", type=click.FloatRange(min=0.001), default=None, callback=_finite,
              help="Time window of --method time (default 30; same as --param window_us=...).")
@click.option("--count", "n_events", type=click.IntRange(min=1), default=None,
              help="Events per frame of --method count (default 2000; same as --param n_events=...).")
@sensor_option()
@click.option("--sort", "sort", is_flag=True, help="Sort events by time (stable) if the file is unsorted.")
@click.option("--buffer/--no-buffer", "use_buffer", default=None,
              help="Event-buffer noise filter (default: the method's registered default: on for intra, off for "
                   "mueggler).")
@click.option("--display", type=click.Choice(["predecessor", "lifetime_only"]), default=None,
              help="How lifetimes become edge frames. Default predecessor (clear the pixel behind each event, "
                   "Mueggler's display), the same as the primary display of the report of evedge bench; "
                   "lifetime_only: a pixel is edge while its newest event lives, nothing cleared.")
@click.option("--seed", type=click.IntRange(min=0), default=None, help="Seed of the method (same as --param seed=N).")
@click.option("--embed-events/--no-embed-events", default=True, show_default=True,
              help="Store the events in detection.h5 (else only the source's sha256 and absolute path).")
@click.option("--video", "video", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also write the edge frames as a video (.mp4 or .gif), over the grey frames when there are any.")
@click.option("--video-colour", type=click.Choice(["lifetime", "polarity", "mono"]), default=None,
              help="Edge colour in --video: by lifetime (default for lifetime methods), polarity, or mono.")
@click.option("--quiet", is_flag=True, help="No progress bars.")
def detect(events_file, out, method, param_items, config, fps, times, at_frames, window_ms, n_events, sensor, sort, use_buffer,
           display, seed, embed_events, video, video_colour, quiet):
    """Detect edges in an event file EVENTS (any format evedge.io reads) with any registered method.

    Writes OUT/detection.h5, a self-describing file (format evedge-detection:
    the events or their source's sha256 and path, per-event lifetime_us,
    vx_px_s, vy_px_s, valid and kept for lifetime methods, edge frames with
    their times, the method, every parameter, the display and the versions;
    read it with evedge info, evedge grade or evedge.io.read_detection), and
    one PNG per edge frame in OUT/edges/.
    """
    from evedge.io import read_events
    from evedge.io.detection import Detection, file_sha256, write_detection
    from evedge.events import Frames

    from .edges import PRIMARY_DISPLAY, edge_frames
    from .pipeline import _default_filter, edge_frames_of, resolved_params
    from .protocols import METHODS

    config = config or {}
    method = _method(None, None, method or config.get("method", "intra"))
    entry = METHODS.get(method)
    display = display or config.get("display", PRIMARY_DISPLAY)
    if display not in ("predecessor", "lifetime_only"):
        raise click.BadParameter(f"display must be predecessor or lifetime_only, got {display!r}",
                                 param_hint="'--config'")
    params = dict(config.get("params", {}))
    buffer_params = dict(config.get("buffer", {}))
    if seed is not None:
        params["seed"] = seed
    if window_ms is not None:
        params["window_us"] = int(round(window_ms * 1000))
    if n_events is not None:
        params["n_events"] = n_events
    params.update(param_items["method"])
    buffer_params.update(param_items["buffer"])
    try:
        params_all = resolved_params(method, params)
        filter_name = _default_filter(method, use_buffer, None) if entry.kind == "estimator" else None
        if buffer_params and not filter_name:
            raise ValueError(f"buffer parameters {sorted(buffer_params)} given but no noise filter runs before "
                             f"{method!r} (add --buffer)")
        filter_all = resolved_params(filter_name, buffer_params) if filter_name else {}
    except (TypeError, ValueError) as err:
        raise click.BadParameter(str(err), param_hint="'--param' / '--config'") from None
    try:
        rec = read_events(events_file, sensor_size=sensor, sort=sort)
    except (ValueError, TypeError, OSError) as err:
        raise click.ClickException(str(err)) from None
    events, size = rec.events, rec.sensor_size
    if at_frames:
        stack = rec.edges if rec.edges is not None and len(rec.edges) else rec.frames
        if stack is None or not len(stack):
            raise click.BadParameter(f"{events_file} has no frames or edge maps", param_hint="'--at-frames'")
        times = np.asarray(stack.t_us, dtype=np.int64)
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
    if entry.kind == "estimator":
        lifetimes, kept = _estimate(method, events, size, filter_name, filter_all, params, quiet)
        frames = edge_frames(events[kept], lifetimes[kept], size, frame_t, display=display)
    else:
        frames = edge_frames_of(method, events, size, frame_t, params)
    source = Path(events_file).resolve()
    meta = {"method": method, "method_display_name": entry.display_name, "kind": entry.kind,
            "method_source": entry.source, "params": params_all,
            "filter": filter_name, "filter_params": filter_all,
            "display": display if entry.kind == "estimator" else None,
            "source": {"path": str(source), "sha256": file_sha256(source), "n_events": int(events.size),
                       "format": rec.metadata.get("format"), "sorted_on_load": bool(rec.metadata.get("sorted_on_load", False))},
            "events_embedded": bool(embed_events), "frame_times": "--at-frames" if at_frames else "--times" if times is not None else f"--fps {fps:g}",
            "versions": _versions(), "command": "evedge detect"}
    table = None
    if lifetimes is not None:
        from evedge.io.detection import LIFETIME_COLUMNS

        table = np.empty(events.size, dtype=list(LIFETIME_COLUMNS))
        for name in lifetimes.dtype.names:
            table[name] = lifetimes[name]
        table["kept"] = kept
    det = Detection(size, events if embed_events else None, table, Frames(frame_t, np.asarray(frames, bool)), meta)
    try:
        out.mkdir(parents=True, exist_ok=True)
        write_detection(out / "detection.h5", det)
        _write_pngs(out / "edges", frame_t, frames, quiet)
        if video is not None:
            _write_video(video, rec, det, lifetimes, kept, video_colour, fps, quiet)
    except OSError as err:
        raise click.ClickException(f"cannot write the output into {out}: {err}") from None
    msg = f"{events.size} events, {frame_t.size} edge frames -> {out}"
    if lifetimes is not None:
        msg += f"; {int(kept.sum())} passed to the estimator, {int(lifetimes['valid'].sum())} with a lifetime"
    click.echo(msg)
