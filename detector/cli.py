"""``evedge detect``: lifetimes, flow and edge frames of an event file."""

from __future__ import annotations

import math
import re
from pathlib import Path

import click
import numpy as np

from evedge._cli_options import sensor_option
from evedge.video import edge_png

_CHUNK = 100_000
#: Most memory the edge frames (one byte per pixel) may take before --fps is refused as a mistake.
_MAX_FRAME_BYTES = 4 * 2**30
#: The largest float below 2**63: frame times at or above it do not fit int64 microseconds.
_LAST_FLOAT_US = float(np.nextafter(2.0**63, 0))
#: Memory of a method's per-pixel state by kind (lifetime estimators: buffer, SAE, estimator, edge image;
#: edge methods: accumulation), bytes per pixel,
#: and of a run's per-event memory, bytes per event: a bound with room above the peak that
#: benchmarks/bench_cli.py measures (the input, its columns, the keep mask, the lifetimes, flow and validity).
_STATE_BYTES_PER_PIXEL = {"estimator": 160, "edges": 16}
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


def _estimate(method, events, sensor, filter_name, filter_params, params, frame_t, display, quiet, ahead=None,
              n_tiles=1):
    """The per-event table (a dict of the LIFETIME_COLUMNS, one array each: estimates, NaN where
    none, and the filter's keep mask) and the edge frames at ``frame_t``, in one pass over chunks of the events.

    Each chunk's kept events go through the estimator and then the edge image
    (frames taken at the instants inside the chunk, as :func:`edge_frames` takes
    them); their estimates are written into the table in place. No copy of the
    kept events or of their estimates is made: here the peak is the filter's keep
    mask (the buffer reads the event fields in place; its ``prev`` chain is 8 bytes
    per event). detection.h5 is
    built in memory (``write_detection``) and frees each column once it is in the
    file image (``release_columns``): the image (39 bytes per event) replaces the
    table (26) rather than adding to it (``benchmarks/bench_cli.py``).

    ``ahead`` (:func:`evedge.detector._precompile.start`): a child compiling the
    estimator's kernel into numba's cache meanwhile; the buffer (compiled and run
    in :func:`keep_mask`) and the edge image are compiled here first, then the
    child is awaited before the estimator's first chunk.

    ``n_tiles``: the filter's keep mask and an estimator that takes strips run
    them (:func:`~evedge.detector.pipeline.detect`'s ``n_tiles``; the same output).
    """
    from tqdm import tqdm

    from evedge.io.detection import LIFETIME_COLUMNS

    from .edges import EdgeImage
    from ._checks import validated
    from ._stream_kernels import _expand_columns, _kept_columns
    from .intra import IntraPixelLifetime
    from .pipeline import _check_estimate, _with_tiles, keep_mask, make_method

    kept = (keep_mask(filter_name, events, sensor, filter_params, n_tiles=n_tiles) if filter_name
            else np.ones(events.size, bool))
    est = make_method(method, sensor, _with_tiles(method, params, n_tiles), kind="estimator")
    # one array per column (not a structured table): write_detection frees each once it is in the file image
    table = {name: (kept if name == "kept" else np.empty(events.size, dtype)) for name, dtype in LIFETIME_COLUMNS}
    image = EdgeImage(sensor, display=display)
    if ahead is not None:
        _compile_edges(sensor, display)  # while the child compiles the estimator
        ahead.wait()
    order = np.argsort(frame_t, kind="stable")
    ends = np.searchsorted(events["t"], frame_t[order], side="right")  # frame i counts events[:ends[i]]
    frames = np.zeros((frame_t.size, sensor.height, sensor.width), dtype=bool)
    f = 0
    # the built-in estimator on plain columns: the kept events' columns in one pass, its estimates written
    # into the table's columns in one pass, the edge image fed the same columns (no record copy, packing or
    # boolean scatter; the same table and frames as the records' path below, tests/detector/test_detect_cli.py)
    plain = type(est) is IntraPixelLifetime
    with tqdm(total=events.size, unit="ev", desc="lifetimes", disable=quiet) as bar:
        for start in range(0, events.size, _CHUNK):
            stop = min(start + _CHUNK, events.size)
            keep = kept[start:stop]
            if plain:
                cols = _kept_columns(events[start:stop], keep)
                est_cols = (est._estimate(*cols) if cols.shape[1] else
                            (np.empty(0), np.empty(0), np.empty(0), np.empty(0, bool)))
                _expand_columns(keep, *est_cols, *(table[name][start:stop] for name, _ in LIFETIME_COLUMNS[:4]))

                def feed(a, b, cols=cols, est_cols=est_cols):
                    image._apply(*(c[a:b] for c in cols), *(c[a:b] for c in est_cols))

                m = cols.shape[1]
                kept_t = cols[2]
            else:
                chunk = events[start:stop].compress(keep)  # (faster than boolean indexing on records)
                with validated(chunk, sensor):  # a subset, in order, of checked events: the stages' checks are O(1)
                    lt = _check_estimate(method, est.process(chunk), chunk.size)
                for name in lt.dtype.names:
                    col = table[name][start:stop]
                    col[...] = False if name == "valid" else np.nan
                    col[keep] = lt[name]

                def feed(a, b, chunk=chunk, lt=lt):
                    with validated(chunk, sensor):
                        image.process(chunk[a:b], lt[a:b])

                m = chunk.size
                kept_t = np.ascontiguousarray(chunk["t"])  # once: a strided field would be copied per frame
            # the edge image, frame by frame inside the chunk: a frame counts the kept events up to its instant
            done = 0
            while f < frame_t.size and ends[f] <= stop:
                upto = int(np.searchsorted(kept_t, frame_t[order[f]], side="right"))
                if upto > done:
                    feed(done, upto)
                    done = upto
                frames[order[f]] = image.image_at(int(frame_t[order[f]]))
                f += 1
            if done < m:
                feed(done, m)
            bar.update(stop - start)
    while f < frame_t.size:  # instants after the last event
        frames[order[f]] = image.image_at(int(frame_t[order[f]]))
        f += 1
    return table, kept, frames


def _compile_edges(sensor, display) -> None:
    """Compile (or load) the edge image's and the plain path's kernels on a few events, as :func:`_estimate` does.

    The same argument types as the real chunks (checked, read-only events; rows of
    the estimator's output), so no second specialisation is made.
    """
    from evedge.io.detection import LIFETIME_COLUMNS

    from ._checks import validated
    from ._precompile import sample_events
    from ._stream_kernels import _expand_columns, _kept_columns
    from .edges import EdgeImage
    from .result import empty_lifetimes

    ev = sample_events(sensor)
    keep = np.ones(ev.size, bool)
    with validated(ev, sensor):
        EdgeImage(sensor, display=display).process(ev, empty_lifetimes(ev.size))
        _kept_columns(ev, keep)  # and the built-in estimator's per-chunk columns (_estimate's plain path)
    outs = [np.empty(ev.size, dtype) for _, dtype in LIFETIME_COLUMNS[:4]]
    _expand_columns(keep, *(np.ascontiguousarray(c) for c in outs), *outs)


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
    """Write the frames into ``folder`` (a fresh folder inside the staged output).

    8-bit greyscale PNGs encoded by OpenCV (``cv2.imencode``; the same pixels as
    Pillow's encoder, ~6x less CPU per frame at its default compression: the PNGs
    were a quarter of ``evedge detect``'s CPU on a long recording), written as bytes
    so that any path works.
    """
    import cv2
    from tqdm import tqdm

    folder.mkdir()
    for i, (t, img) in enumerate(tqdm(list(zip(times, frames)), desc="PNG", unit="frame", disable=quiet)):
        # the report's convention: black edges on white
        ok, buf = cv2.imencode(".png", edge_png(np.asarray(img, bool)))
        if not ok:
            raise OSError(f"evedge detect: OpenCV could not encode edge frame {i} as PNG")
        (folder / f"edges_{i:06d}_{int(t)}us.png").write_bytes(buf.tobytes())


def _check_memory(n_events: int, size, n_frames: int, kind: str, method: str) -> None:
    """Refuse a run whose state, per-event outputs and frames cannot fit, before any work."""
    from evedge._resources import memory_shortfall

    pixels = size.width * size.height
    needed = pixels * _STATE_BYTES_PER_PIXEL[kind] + n_events * _BYTES_PER_EVENT + 2 * n_frames * pixels
    short = memory_shortfall(needed, f"--method {method} on {n_events} events of a {size.width}x{size.height} "
                                     f"sensor with {n_frames} edge frames")
    if short:
        raise click.ClickException(f"{short}; a smaller --sensor, fewer frames (--fps, --times) or a shorter "
                                   f"recording would fit")


class _DetectCommand(click.Command):
    """Lists the registered methods in ``--help`` (read from the registry when help is shown)."""

    def get_help(self, ctx):
        for p in self.params:
            if p.name == "method":
                p.help = _method_help()
        return super().get_help(ctx)


def _write_video(path: Path, rec, det, lifetimes, kept, colour, fps, quiet) -> None:
    """The edge frames of ``det`` as a video, coloured by lifetime/polarity of the events behind them.

    ``lifetimes``: the per-event table (a ``lifetime_us`` column aligned with the events) or None.
    """
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
                   "lifetime_only: a pixel is edge while its newest event lives (a burst from its first event), "
                   "nothing cleared.")
@click.option("--seed", type=click.IntRange(min=0, max=2**63 - 1), default=None,
              help="Seed of the method (same as --param seed=N).")
@click.option("--embed-events/--no-embed-events", default=True, show_default=True,
              help="Store the events in detection.h5 (else only the source's sha256 and absolute path).")
@click.option("--video", "video", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also write the edge frames as a video (.mp4 or .gif), over the grey frames when there are any.")
@click.option("--video-colour", type=click.Choice(["lifetime", "polarity", "mono"]), default=None,
              help="Edge colour in --video: by lifetime (default for lifetime methods), polarity, or mono.")
@click.option("--png/--no-png", "write_png", default=True, show_default=True,
              help="Also write each edge frame as OUT/edges/*.png (the frames are in detection.h5 either way).")
@click.option("--compress/--no-compress", "compress", default=False, show_default=True,
              help="gzip the per-event columns of detection.h5 (~2x smaller, ~0.9 us per event; edge frames "
                   "are always compressed).")
@click.option("--tiles", "n_tiles", type=click.IntRange(min=1), default=1, show_default=True,
              help="Row strips run in parallel (numba threads) by the intra estimator and the event buffer; the "
                   "same output for any value.")
@click.option("--overwrite", is_flag=True, help="Replace an existing OUT (a previous detect output).")
@click.option("--quiet", is_flag=True, help="No progress bars.")
def detect(events_file, out, method, param_items, config, fps, times, at_frames, window_ms, n_events, sensor, sort, use_buffer,
           display, seed, embed_events, video, video_colour, write_png, compress, n_tiles, overwrite, quiet):
    """Detect edges in an event file EVENTS (any format evedge.io reads) with any registered method.

    Writes OUT/detection.h5, a self-describing file (format evedge-detection:
    the events or their source's sha256 and path, per-event lifetime_us,
    vx_px_s, vy_px_s, valid and kept for lifetime methods, edge frames with
    their times, the method, every parameter, the display and the versions;
    read it with evedge info, evedge grade or evedge.io.read_detection), and
    one PNG per edge frame in OUT/edges/. Both are written into a temporary
    folder beside OUT and swapped in together at the end; an existing OUT is
    replaced only with --overwrite.
    """
    from evedge._output import OutputExistsError, check_output

    from . import _precompile
    from .edges import PRIMARY_DISPLAY
    from .pipeline import _default_filter, resolved_params
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
        replacing = check_output(out, overwrite=overwrite)
    except OutputExistsError as err:
        raise click.ClickException(str(err)) from None
    if replacing:
        _check_replaceable(out)

    # cold numba cache: the estimator compiles in a child while this process reads the input (_precompile)
    ahead = _precompile.start(method, _precompile.SAMPLE_SENSOR, params) if entry.kind == "estimator" else None
    try:
        _detect(events_file, out, method, entry, fps, times, at_frames, sensor, sort, display, params,
                params_all, filter_name, filter_all, embed_events, video, video_colour, write_png, compress,
                replacing, quiet, ahead, n_tiles)
    finally:
        if ahead is not None:
            ahead.close()


def _detect(events_file, out, method, entry, fps, times, at_frames, sensor, sort, display, params, params_all,
            filter_name, filter_all, embed_events, video, video_colour, write_png, compress, replacing, quiet,
            ahead, n_tiles=1):
    """The rest of :func:`detect`, from reading the input on (``ahead``: see :func:`_estimate`)."""
    from evedge._output import OutputExistsError, staged_folder
    from evedge.io import read_events
    from evedge.io.detection import Detection, file_sha256, write_detection
    from evedge.events import Frames

    from ._checks import validated
    from ._tiles import check_n_tiles
    from .pipeline import edge_frames_of

    try:
        rec = read_events(events_file, sensor_size=sensor, sort=sort)
    except (ValueError, TypeError, OSError) as err:
        raise click.ClickException(str(err)) from None
    events, size = rec.events, rec.sensor_size
    try:
        check_n_tiles(n_tiles, size.height)
    except ValueError as err:
        raise click.BadParameter(f"{err} ({events_file}: {size.width}x{size.height})", param_hint="'--tiles'") from None
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
    _check_memory(events.size, size, frame_t.size, entry.kind, method)
    if frame_t.size == 0 and events.size:
        span = int(events["t"][-1]) - int(events["t"][0])
        click.echo(f"Warning: no edge frame: the events span {span} us, less than one frame period "
                   f"({1e6 / fps:.0f} us at --fps {fps:g}); pass --times or a higher --fps", err=True)
    table = kept = None
    if entry.kind == "estimator":
        with validated(events, size):  # checked once, when read (Recording): the stages' checks are O(1)
            table, kept, frames = _estimate(method, events, size, filter_name, filter_all, params, frame_t, display,
                                            quiet, ahead, n_tiles)
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
    n_events, n_kept = events.size, int(kept.sum()) if kept is not None else 0
    n_valid = int(table["valid"].sum()) if table is not None else 0
    det = Detection(size, events if embed_events else None, table, Frames(frame_t, np.asarray(frames, bool)), meta)
    if video is None:  # write_detection frees the events and the per-event columns as they go into the file image
        events = kept = rec = None
    try:
        with staged_folder(out, allowed=_OUTPUT_NAMES) as stage:
            write_detection(stage / "detection.h5", det, compress_per_event=compress, release_columns=video is None)
            if write_png:
                _write_pngs(stage / "edges", frame_t, frames, quiet)
    except OutputExistsError as err:
        raise click.ClickException(str(err)) from None
    except OSError as err:
        raise click.ClickException(f"cannot write the output {out} (nothing of this run was kept): {err}") from None
    if replacing:
        click.echo(f"replaced the earlier output in {out}", err=True)
    try:
        if video is not None:
            _write_video(video, rec, det, table, kept, video_colour, fps, quiet)
    except OSError as err:
        raise click.ClickException(f"cannot write the video {video}: {err}") from None
    msg = f"{n_events} events, {frame_t.size} edge frames -> {out}"
    if table is not None:
        msg += f"; {n_kept} passed to the estimator, {n_valid} with a lifetime"
    click.echo(msg)
