"""``simulate``: scene in, :class:`evedge.events.Recording` out (events, truth, frames, edges)."""

from __future__ import annotations

import math
import numbers
import os
import platform
import sys
from dataclasses import asdict, replace

import numpy as np

from evedge.events import Frames, Recording, SensorSize
from .converter import EventConverter
from .scene import MAX_DURATION_S, Scene, load_scene
from .truth import TRUTH_DTYPE

#: What the frames of a simulated recording hold.
FRAMES_NOTE = "clean linear intensity, float32 in [0, 1] (no noise, no log)"
EDGES_NOTE = ("exact edge maps: pixel is edge when a shape boundary passes through the interior of its "
              "square (analytic scenes: 1e-9 < area coverage < 1 - 1e-9)")


def _versions(kind: str) -> dict[str, str]:
    import numba

    from evedge import __version__

    out = {"evedge": __version__, "python": platform.python_version(), "numpy": np.__version__,
           "numba": numba.__version__}
    if kind == "mesh":
        for name in ("pyrender", "trimesh", "OpenGL"):
            mod = sys.modules.get(name)
            if mod is not None:
                out[name] = str(getattr(mod, "__version__", "?"))
    return out


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.generic,)):
        return value.item()
    if hasattr(value, "isoformat"):
        return value.isoformat()
    return value


def _is_real(value) -> bool:
    """A real number, numpy scalars included (``np.float32(0.1)``), but not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _time_s(t_s, who: str) -> float:
    if not _is_real(t_s) or not math.isfinite(t_s):
        raise ValueError(f"{who}: t_s must be a finite number of seconds, got {t_s!r}")
    return float(t_s)


def _as_scene(scene) -> Scene:
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, (str, os.PathLike)):
        return load_scene(scene)
    raise TypeError(f"scene must be a Scene or a path to a scene file, got {type(scene).__name__}")


#: Per-pixel state of the converter and renderer (references, thresholds, log images, coverage), bytes.
_STATE_BYTES_PER_PIXEL = 96


def _check_memory(scene, params, frame_rate_hz: float) -> None:
    """Refuse a run whose frames, noise events and per-pixel state cannot fit, before any work."""
    from evedge._resources import memory_shortfall
    from evedge.events import EVENT_DTYPE

    from .truth import TRUTH_DTYPE

    pixels = scene.sensor.width * scene.sensor.height
    n_frames = math.floor(scene.duration_s * frame_rate_hz + 1e-9) + 1 if frame_rate_hz > 0 else 0
    noise_events = params.noise_rate_hz * pixels * scene.duration_s
    # events and truth are held in chunks, then concatenated once: twice their size at the end
    needed = (n_frames * pixels * 5 + 2 * noise_events * (EVENT_DTYPE.itemsize + TRUTH_DTYPE.itemsize)
              + pixels * _STATE_BYTES_PER_PIXEL)
    what = (f"simulate: {scene.sensor.width}x{scene.sensor.height} for {scene.duration_s:g} s "
            f"({n_frames} frames at frame_rate_hz={frame_rate_hz:g}, about {noise_events:.3g} noise events at "
            f"noise_rate_hz={params.noise_rate_hz:g})")
    short = memory_shortfall(needed, what)
    if short:
        raise MemoryError(f"{short}; lower duration_s, frame_rate_hz, noise_rate_hz or the sensor size")


def simulate(scene, *, seed: int | None = None, duration_s: float | None = None,
             frame_rate_hz: float | None = None, progress: bool = True, chunk_s: float = 0.05,
             lambda_: float | None = None) -> Recording:
    """Simulate a scene: events with per-event ground truth, clean frames and exact edge maps.

    Parameters
    ----------
    scene : Scene, str or path-like
        A validated :class:`~evedge.sim.scene.Scene` or a scene TOML file.
    seed : int, optional
        Overrides the scene's seed (threshold mismatch, noise, jitter).
    duration_s : float, optional
        Overrides the scene's duration (> 0, <= 9e9 s: the truth's times are
        int64 nanoseconds).
    frame_rate_hz : float, optional
        Rate of the clean frames and edge maps (default: the scene's
        ``frame_rate_hz``, 100 Hz unless set); 0 for none. Frames are at
        ``t = k / frame_rate_hz``, ``k = 0, 1, ...`` up to the duration.
    progress : bool
        Show a tqdm bar (stderr) over simulated time.
    chunk_s : float
        Simulated time per chunk; bounds the working memory. The output does
        not depend on it (same bytes).
    lambda_ : float, optional
        Overrides the sampling safety factor of the scene.

    Returns
    -------
    Recording
        ``events`` (EVENT_DTYPE, sorted), ``truth`` (:data:`TRUTH_DTYPE`,
        aligned), ``frames`` (float32 linear intensity in [0, 1]), ``edges``
        (bool, at the frame times) and ``metadata`` (scene dict, sections in
        microseconds, seed, parameters, versions, sample counts).

    Raises
    ------
    SceneError
        ``scene`` is a file that is not a valid scene.
    ValueError
        An override out of range (named); ``frame_rate_hz`` above 1e6.
    MemoryError
        The frames and edge maps do not fit in memory (their count, size
        and GiB are named).
    """
    scene = _as_scene(scene)
    if seed is not None:
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        scene = replace(scene, seed=int(seed))
    if duration_s is not None:
        if not _is_real(duration_s) or not duration_s > 0 \
                or not math.isfinite(duration_s):
            raise ValueError(f"duration_s must be a positive number, got {duration_s!r}")
        if duration_s > MAX_DURATION_S:
            raise ValueError(f"duration_s must be <= {MAX_DURATION_S:g} (the truth's times are int64 nanoseconds), "
                             f"got {duration_s!r}")
        scene = replace(scene, duration_s=float(duration_s))
    if frame_rate_hz is None:
        frame_rate_hz = scene.frame_rate_hz
    if not (_is_real(frame_rate_hz) and frame_rate_hz >= 0 and math.isfinite(frame_rate_hz)):
        raise ValueError(f"frame_rate_hz must be >= 0, got {frame_rate_hz!r}")
    frame_rate_hz = float(frame_rate_hz)
    if frame_rate_hz > 1e6:
        # frame times are whole microseconds: faster frames would share timestamps
        raise ValueError(f"frame_rate_hz must be <= 1e6 (frame times are whole microseconds), got {frame_rate_hz!r}")
    if not (_is_real(chunk_s) and chunk_s > 0 and math.isfinite(chunk_s)):
        raise ValueError(f"chunk_s must be > 0, got {chunk_s!r}")
    chunk_s = float(chunk_s)  # a numpy float32 would turn the chunk targets into float32
    params = scene.params if lambda_ is None else replace(scene.params, lambda_=lambda_)
    _check_memory(scene, params, frame_rate_hz)

    from tqdm import tqdm

    renderer = scene.build_renderer()
    try:
        conv = EventConverter(renderer, params, seed=scene.seed, duration_s=scene.duration_s)
        if frame_rate_hz > 0:
            n_frames = int(math.floor(scene.duration_s * frame_rate_hz + 1e-9)) + 1
        else:
            n_frames = 0
        try:
            frame_t = np.arange(n_frames) / frame_rate_hz if n_frames else np.empty(0)
            images = np.empty((frame_t.shape[0], scene.sensor.height, scene.sensor.width), dtype=np.float32)
            edges = np.empty(images.shape, dtype=bool)
        except (MemoryError, ValueError):  # numpy: ValueError 'Maximum allowed size exceeded'
            gib = n_frames * scene.sensor.height * scene.sensor.width * 5 / 2**30
            raise MemoryError(
                f"simulate: {n_frames} frames and edge maps of {scene.sensor.width}x{scene.sensor.height} "
                f"(frame_rate_hz={frame_rate_hz}, duration_s={scene.duration_s}) need {gib:.1f} GiB; "
                f"lower frame_rate_hz or duration_s"
            ) from None
        # 3-D scenes: per-frame depth and motion field (the renderer knows its geometry)
        maps = {}
        if scene.kind == "mesh" and frame_t.shape[0]:
            maps = {name: np.empty(images.shape, dtype=np.float32) for name in ("depth_m", "flow_x_px_s", "flow_y_px_s")}
        ev_parts, tr_parts = [], []
        next_frame = 0
        t_done = 0.0
        done_ms = 0
        # progress in simulated milliseconds (integers: no float overshoot of the bar)
        with tqdm(total=int(round(scene.duration_s * 1000)), unit="ms", desc=f"simulate {scene.name}",
                  disable=not progress, file=sys.stderr) as bar:
            while not conv.done:
                target = min(scene.duration_s, t_done + chunk_s)
                ev, tr = conv.process(target)
                ev_parts.append(ev)
                tr_parts.append(tr)
                while next_frame < frame_t.shape[0] and (frame_t[next_frame] <= conv.t or conv.done):
                    images[next_frame] = renderer.intensity(float(frame_t[next_frame]))
                    edges[next_frame] = renderer.edges(float(frame_t[next_frame]))
                    if maps:
                        maps["depth_m"][next_frame] = renderer.depth(float(frame_t[next_frame]))
                        maps["flow_x_px_s"][next_frame], maps["flow_y_px_s"][next_frame] = \
                            renderer.flow(float(frame_t[next_frame]))
                    next_frame += 1
                now_ms = min(int(round(conv.t * 1000)), bar.total)
                bar.update(now_ms - done_ms)
                done_ms = now_ms
                t_done = conv.t
    finally:
        renderer.close()
    imu_rows = None
    imu_cfg = scene.setup_3d.get("imu") if scene.kind == "mesh" else None
    if imu_cfg and imu_cfg["rate_hz"] > 0:
        from .build import build_trajectory
        from .trajectory import imu_table

        imu_rows = imu_table(build_trajectory(scene.motion), imu_cfg["rate_hz"], scene.duration_s,
                             imu_cfg["gravity_m_s2"])
    events = np.concatenate(ev_parts)
    truth = np.concatenate(tr_parts) if tr_parts else np.empty(0, dtype=TRUTH_DTYPE)
    frame_us = np.rint(frame_t * 1e6).astype(np.int64)
    metadata = {
        "source": "evedge.sim.simulate",
        "scene_name": scene.name,
        "scene_kind": scene.kind,
        "scene_file": scene.source,
        "scene": _jsonable(scene.raw),
        "seed": scene.seed,
        "duration_s": scene.duration_s,
        "sections": [{"name": s.name, "start_us": int(round(s.start_s * 1e6)), "end_us": int(round(s.end_s * 1e6))}
                     for s in scene.sections],
        "converter": asdict(params),
        "sensor": asdict(scene.sensor),
        "frames": FRAMES_NOTE,
        "edges": EDGES_NOTE,
        "log_intensity": f"L = log(I + {params.log_eps})",
        "crossing_times_used": "exact" if conv.exact else "linear",
        "sampling_used": ("geometric" if conv.geometric_steps else "verified" if conv.verified else "predicted"),
        "n_samples": conv.n_samples,
        "n_rejected_steps": conv.n_rejected,
        "n_signal": int(np.count_nonzero(truth["is_signal"])),
        "n_noise": int(np.count_nonzero(~truth["is_signal"])),
        "versions": _versions(scene.kind),
    }
    return Recording(
        events=events,
        sensor_size=SensorSize(scene.sensor.width, scene.sensor.height),
        frames=Frames(frame_us, images) if frame_t.size else None,
        truth=truth,
        edges=Frames(frame_us, edges) if frame_t.size else None,
        metadata=metadata,
        maps={name: Frames(frame_us, stack) for name, stack in maps.items()},
        imu=imu_rows,
    )


def _query_once(scene, query):
    """``query(renderer)`` on a renderer built for ``scene`` (Scene or file), closed afterwards."""
    r = _as_scene(scene).build_renderer()
    try:
        return query(r)
    finally:
        r.close()


def render_frame(scene, t_s: float) -> np.ndarray:
    """Clean linear intensity of ``scene`` at ``t_s``.

    Parameters
    ----------
    scene : Scene, str or path-like
        A validated scene or a scene TOML file.
    t_s : float
        Time in seconds (finite).

    Returns
    -------
    numpy.ndarray
        (height, width) float64 in [0, 1].
    """
    t_s = _time_s(t_s, "render_frame")
    return _query_once(scene, lambda r: r.intensity(t_s))


def edge_map(scene, t_s: float) -> np.ndarray:
    """Exact edge map of ``scene`` at ``t_s`` (definition in :mod:`evedge.sim.planar`).

    Parameters
    ----------
    scene : Scene, str or path-like
        A validated scene or a scene TOML file.
    t_s : float
        Time in seconds (finite).

    Returns
    -------
    numpy.ndarray
        (height, width) bool, True on edge pixels.
    """
    t_s = _time_s(t_s, "edge_map")
    return _query_once(scene, lambda r: r.edges(t_s))


def thin_edge_map(scene, t_s: float) -> np.ndarray:
    """Thin exact edge map of ``scene`` at ``t_s``: one pixel per boundary crossing of each row and column.

    Beside :func:`edge_map` (every pixel whose open square a boundary crosses,
    about ``|cos a| + |sin a|`` pixels per row for an edge at angle ``a``), this
    map is as thin as Canny's; definition in :mod:`evedge.sim.thin_edges`.

    Parameters
    ----------
    scene : Scene, str or path-like
        A validated planar scene (``stripes`` or ``shapes``) or a scene TOML file.
    t_s : float
        Time in seconds (finite).

    Returns
    -------
    numpy.ndarray
        (height, width) bool, True on edge pixels.

    Raises
    ------
    NotImplementedError
        For a scene whose renderer has no analytic geometry (``mesh``).

    Examples
    --------
    >>> from evedge.sim import edge_map, parse_scene, thin_edge_map
    >>> scene = parse_scene({"scene": {"kind": "stripes", "duration_s": 1.0}, "sensor": {"width": 32, "height": 8},
    ...                      "stripes": [{"period_px": 16, "angle_deg": 20, "velocity_px_s": [0, 0],
    ...                                   "phase_px": 4}]})
    >>> thin_edge_map(scene, 0.0).sum(axis=1).tolist()  # four boundaries, one pixel each per row
    [4, 4, 4, 4, 4, 4, 4, 4]
    >>> edge_map(scene, 0.0).sum(axis=1).tolist()  # every pixel whose open square a boundary crosses
    [4, 6, 6, 5, 5, 6, 6, 4]
    """
    t_s = _time_s(t_s, "thin_edge_map")

    def query(r):
        if not hasattr(r, "thin_edges"):
            raise NotImplementedError(f"thin_edge_map: the {type(r).__name__} of scene kind "
                                      f"{_as_scene(scene).kind!r} has no analytic geometry (planar scenes only)")
        return r.thin_edges(t_s)

    return _query_once(scene, query)
