"""Pictures and videos of what the detector sees: edge frames and event frames, as PNG, MP4 or GIF.

Edge frames are drawn as the report draws them: black edges on white, or,
when the recording has grey frames, in colour over the latest grey frame
(at or before each frame's time). Edge pixels are coloured by the lifetime
of their latest event (log scale, viridis: short lifetimes = fast edges are
dark blue, long ones yellow) or by its polarity (ON red, OFF blue). Event
frames show the events of a time window before each instant, coloured by
polarity. Every frame is upscaled by an integer factor (nearest neighbour:
one event pixel stays one visible block) and carries a caption bar with its
time. MP4 goes through OpenCV (``mp4v``), GIF through Pillow; both are
written to a temp file and renamed, so a failed write leaves nothing.

This module imports neither ``sim`` nor ``bench``: the detector's CLI uses it.

Examples
--------
>>> import numpy as np
>>> from evedge.events import Frames
>>> edges = Frames([1000, 2000], np.eye(20, 30, dtype=bool)[None].repeat(2, 0))
>>> frames = list(edge_video_frames(edges, colour="mono", scale=2))
>>> frames[0].shape  # a 20-row caption bar above the 2x upscaled 30x20 frame
(60, 60, 3)
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from .events import Frames, SensorSize, validate_events

__all__ = ["COLOURINGS", "edge_png", "edge_video_frames", "event_video_frames", "auto_scale", "write_video"]

#: How edge pixels are coloured.
COLOURINGS = ("lifetime", "polarity", "mono")
#: Lifetime colour scale (us): log from 0.1 ms to 100 ms, clipped outside.
LIFETIME_RANGE_US = (100.0, 100_000.0)
ON_RGB = (220, 40, 40)
OFF_RGB = (40, 80, 230)
MONO_ON_GREY_RGB = (255, 40, 40)
_CAPTION_BG = (32, 32, 32)


def edge_png(edges: np.ndarray) -> np.ndarray:
    """A boolean edge map as the report draws it: uint8, 0 (black) on edges, 255 (white) elsewhere."""
    edges = np.asarray(edges)
    if edges.dtype != bool:
        raise TypeError(f"edge_png: expected a boolean edge map, got {edges.dtype}")
    return np.where(edges, 0, 255).astype(np.uint8)


def auto_scale(sensor_size: SensorSize, min_height_px: int = 480) -> int:
    """The smallest integer factor that makes the frame at least ``min_height_px`` high (1 for big sensors)."""
    return max(1, -(-min_height_px // sensor_size.height))


def _grey_rgb(image: np.ndarray) -> np.ndarray:
    img = np.asarray(image)
    if img.dtype != np.uint8:
        img = np.clip(np.rint(np.asarray(img, dtype=np.float64) * 255), 0, 255).astype(np.uint8)
    return np.repeat(img[..., None], 3, axis=2)


def _latest_before(stack: Frames | None, t_us: int) -> np.ndarray | None:
    if stack is None or not len(stack):
        return None
    i = int(np.searchsorted(stack.t_us, t_us, side="right")) - 1
    return stack.images[max(i, 0)]


def _lifetime_colours(lifetime_us: np.ndarray) -> np.ndarray:
    """RGB (n, 3) of lifetimes on the log viridis scale of :data:`LIFETIME_RANGE_US`."""
    import cv2

    if np.size(lifetime_us) == 0:
        return np.zeros((0, 3), np.uint8)
    lo, hi = np.log10(LIFETIME_RANGE_US[0]), np.log10(LIFETIME_RANGE_US[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        level = (np.log10(np.asarray(lifetime_us, dtype=np.float64)) - lo) / (hi - lo)
    idx = np.clip(np.nan_to_num(level, nan=1.0) * 255, 0, 255).astype(np.uint8)
    bgr = cv2.applyColorMap(idx.reshape(-1, 1), cv2.COLORMAP_VIRIDIS).reshape(-1, 3)
    return bgr[:, ::-1]


def _caption(frame: np.ndarray, text: str, legend: str | None) -> np.ndarray:
    """Put a dark bar with ``text`` (and a colour legend) above ``frame``."""
    import cv2

    h, w = frame.shape[:2]
    font_scale = max(0.35, min(0.8, w / 900))
    bar_h = int(round(28 * font_scale / 0.5))
    bar = np.empty((bar_h, w, 3), np.uint8)
    bar[:] = _CAPTION_BG
    # OpenCV draws on BGR; the bar is uniform and the text white, so RGB order does not matter here
    cv2.putText(bar, text, (6, int(bar_h * 0.7)), cv2.FONT_HERSHEY_SIMPLEX, font_scale, (255, 255, 255), 1, cv2.LINE_AA)
    if legend == "lifetime" and w >= 260:
        x0, x1 = w - int(w * 0.35), w - 6
        ramp = _lifetime_colours(np.logspace(np.log10(LIFETIME_RANGE_US[0]), np.log10(LIFETIME_RANGE_US[1]), x1 - x0))
        top, bottom = int(bar_h * 0.2), int(bar_h * 0.45)
        bar[top:bottom, x0:x1] = ramp[None]
        small = font_scale * 0.75
        for label, x in (("0.1 ms", x0), ("100 ms", x1 - int(48 * small / 0.4))):
            cv2.putText(bar, label, (x, int(bar_h * 0.9)), cv2.FONT_HERSHEY_SIMPLEX, small, (230, 230, 230), 1, cv2.LINE_AA)
    elif legend == "polarity" and w >= 200:
        small = font_scale * 0.8
        x = w - int(150 * small / 0.4)
        cv2.putText(bar, "ON", (x, int(bar_h * 0.7)), cv2.FONT_HERSHEY_SIMPLEX, small, ON_RGB, 1, cv2.LINE_AA)
        cv2.putText(bar, "OFF", (x + int(40 * small / 0.4), int(bar_h * 0.7)), cv2.FONT_HERSHEY_SIMPLEX, small,
                    OFF_RGB, 1, cv2.LINE_AA)
    return np.concatenate([bar, frame], axis=0)


def _upscale(frame: np.ndarray, scale: int) -> np.ndarray:
    return frame if scale == 1 else np.repeat(np.repeat(frame, scale, axis=0), scale, axis=1)


def _check_scale(scale, sensor: SensorSize) -> int:
    if scale is None:
        return auto_scale(sensor)
    if isinstance(scale, bool) or not isinstance(scale, (int, np.integer)) or not 1 <= scale <= 64:
        raise ValueError(f"scale must be an integer in 1..64, got {scale!r}")
    return int(scale)


class _LatestPerPixel:
    """Per pixel, the polarity and lifetime of the latest event up to a time (times fed in order)."""

    def __init__(self, events: np.ndarray, lifetime_us: np.ndarray | None, sensor: SensorSize) -> None:
        self.events, self.lifetime_us, self.sensor = events, lifetime_us, sensor
        self.pos = 0
        self.pol = np.zeros(sensor.shape, bool)
        self.life = np.full(sensor.shape, np.nan)

    def advance(self, t_us: int) -> None:
        stop = int(np.searchsorted(self.events["t"], t_us, side="right"))
        if stop <= self.pos:
            return
        chunk = self.events[self.pos:stop]
        flat = chunk["y"].astype(np.int64) * self.sensor.width + chunk["x"].astype(np.int64)
        # the last occurrence of each pixel: unique over the reversed chunk
        _, rev = np.unique(flat[::-1], return_index=True)
        last = flat.size - 1 - rev
        pix = flat[last]
        self.pol.flat[pix] = chunk["p"][last]
        if self.lifetime_us is not None:
            self.life.flat[pix] = self.lifetime_us[self.pos:stop][last]
        self.pos = stop


def edge_video_frames(
    edges: Frames,
    *,
    grey: Frames | None = None,
    events: np.ndarray | None = None,
    lifetime_us: np.ndarray | None = None,
    colour: str = "lifetime",
    scale: int | None = None,
    label: str = "",
) -> Iterator[np.ndarray]:
    """RGB frames (uint8, ``(H, W, 3)``) of edge maps, ready for :func:`write_video`.

    Parameters
    ----------
    edges : Frames
        Boolean edge maps with their times (``evedge detect``'s edge frames).
    grey : Frames, optional
        Grey frames; each edge map is drawn over the latest one at or before
        its time. Without them the background is white.
    events, lifetime_us : numpy.ndarray, optional
        The time-sorted events behind the edge maps and their lifetimes
        (aligned), needed for ``colour="lifetime"`` (lifetimes) and
        ``"polarity"`` (events); NaN lifetimes draw as the top of the scale.
    colour : {"lifetime", "polarity", "mono"}
        ``"mono"``: black edges on white, or red edges over grey frames.
    scale : int, optional
        Integer upscaling; default :func:`auto_scale` (at least 480 rows).
    label : str
        Shown in the caption after the time.

    Yields
    ------
    numpy.ndarray
        One RGB frame per edge map, caption bar on top.
    """
    if not isinstance(edges, Frames) or edges.images.dtype != bool:
        raise TypeError("edge_video_frames: edges must be Frames of boolean edge maps")
    if colour not in COLOURINGS:
        raise ValueError(f"colour={colour!r}, expected one of {', '.join(COLOURINGS)}")
    sensor = SensorSize(edges.images.shape[2], edges.images.shape[1])
    scale = _check_scale(scale, sensor)
    latest = None
    if colour != "mono":
        if events is None or (colour == "lifetime" and lifetime_us is None):
            need = "events and lifetime_us" if colour == "lifetime" else "events"
            raise ValueError(f"colour={colour!r} needs {need}")
        events = validate_events(events, sensor, name="edge_video_frames: events")
        if lifetime_us is not None:
            lifetime_us = np.asarray(lifetime_us, dtype=np.float64)
            if lifetime_us.shape != events.shape:
                raise ValueError(f"lifetime_us has shape {lifetime_us.shape}, the events {events.shape}")
        latest = _LatestPerPixel(events, lifetime_us, sensor)
    if grey is not None and grey.images.shape[1:] != sensor.shape:
        raise ValueError(f"grey frames are {grey.images.shape[2]}x{grey.images.shape[1]}, the edge maps "
                         f"{sensor.width}x{sensor.height}")
    for t, edge in zip(edges.t_us, edges.images):
        base = _latest_before(grey, int(t))
        frame = _grey_rgb(base) if base is not None else np.full(sensor.shape + (3,), 255, np.uint8)
        if colour == "mono":
            frame[edge] = MONO_ON_GREY_RGB if base is not None else (0, 0, 0)
        else:
            latest.advance(int(t))
            if colour == "lifetime":
                frame[edge] = _lifetime_colours(latest.life[edge])
            else:
                pol = latest.pol[edge]
                frame[edge] = np.where(pol[:, None], ON_RGB, OFF_RGB)
        text = f"t = {int(t) / 1e6:.6f} s" + (f"  {label}" if label else "")
        yield _caption(_upscale(frame, scale), text, colour if colour != "mono" else None)


def event_video_frames(
    events: np.ndarray,
    sensor_size: SensorSize,
    times_us: Iterable[int],
    *,
    window_us: int,
    grey: Frames | None = None,
    scale: int | None = None,
    label: str = "",
) -> Iterator[np.ndarray]:
    """RGB frames of the events in ``(T - window_us, T]`` for each ``T``, coloured by polarity.

    The latest event of a pixel in the window sets its colour (ON red, OFF
    blue), over the latest grey frame at or before ``T`` or on white.

    Parameters
    ----------
    events : numpy.ndarray
        Time-sorted events (any array :func:`evedge.events.as_events` accepts).
    sensor_size : SensorSize
    times_us : iterable of int
        Frame instants, non-decreasing.
    window_us : int
        Window length, > 0.
    grey : Frames, optional
    scale : int, optional
    label : str

    Yields
    ------
    numpy.ndarray
    """
    events = validate_events(events, sensor_size, name="event_video_frames: events")
    if isinstance(window_us, bool) or not isinstance(window_us, (int, np.integer)) or window_us <= 0:
        raise ValueError(f"window_us must be a positive integer, got {window_us!r}")
    scale = _check_scale(scale, sensor_size)
    t = events["t"]
    for T in times_us:
        T = int(T)
        lo, hi = np.searchsorted(t, T - window_us, side="right"), np.searchsorted(t, T, side="right")
        base = _latest_before(grey, T)
        frame = _grey_rgb(base) if base is not None else np.full(sensor_size.shape + (3,), 255, np.uint8)
        chunk = events[lo:hi]
        # later events overwrite earlier ones: assign in time order, one pixel at a time is not needed
        # because np.unique of the reversed chunk picks the last event per pixel
        flat = chunk["y"].astype(np.int64) * sensor_size.width + chunk["x"].astype(np.int64)
        _, rev = np.unique(flat[::-1], return_index=True)
        last = flat.size - 1 - rev
        rgb = np.where(chunk["p"][last][:, None], ON_RGB, OFF_RGB).astype(np.uint8)
        frame.reshape(-1, 3)[flat[last]] = rgb
        text = f"t = {T / 1e6:.6f} s  events in {window_us / 1000:g} ms" + (f"  {label}" if label else "")
        yield _caption(_upscale(frame, scale), text, "polarity")


def write_video(path, frames: Iterable[np.ndarray], *, fps: float = 30.0, n_frames: int | None = None,
                quiet: bool = True) -> Path:
    """Write RGB frames to ``path``: MP4 (OpenCV, ``mp4v``) or GIF (Pillow), by its extension; atomic.

    Parameters
    ----------
    path : path-like
        ``*.mp4`` or ``*.gif``.
    frames : iterable of numpy.ndarray
        uint8 ``(H, W, 3)`` RGB frames, all of one size (odd sizes are padded
        by one white row/column for the MP4 encoder).
    fps : float
        Playback rate, > 0.
    n_frames : int, optional
        For the progress bar.
    quiet : bool
        No progress bar.

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        Unknown extension, no frames, frames of different sizes, bad ``fps``.
    OSError
        When the encoder cannot open the temp file; nothing is left behind.
    """
    from tqdm import tqdm

    from .io._atomic import atomic_path, check_output_file

    path = Path(path)
    kind = path.suffix.lower()
    if kind not in (".mp4", ".gif"):
        raise ValueError(f"write_video: {path}: expected a .mp4 or .gif file name, got {kind or 'no extension'!r}")
    if isinstance(fps, bool) or not isinstance(fps, (int, float, np.integer, np.floating)) or not 0 < fps <= 1000:
        raise ValueError(f"write_video: fps must be a number in (0, 1000], got {fps!r}")
    check_output_file(path, "write_video")
    bar = tqdm(frames, total=n_frames, desc="video", unit="frame", disable=quiet)
    with atomic_path(path, suffix=f".tmp{kind}") as tmp:
        count = _write_mp4(tmp, bar, float(fps)) if kind == ".mp4" else _write_gif(tmp, bar, float(fps))
        if count == 0:
            raise ValueError(f"write_video: {path}: no frames to write")
    return path


def _check_frame(frame: np.ndarray, shape, k: int) -> np.ndarray:
    frame = np.asarray(frame)
    if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
        raise ValueError(f"write_video: frame {k} must be uint8 (H, W, 3) RGB, got {frame.dtype} {frame.shape}")
    if shape is not None and frame.shape != shape:
        raise ValueError(f"write_video: frame {k} is {frame.shape[1]}x{frame.shape[0]}, frame 0 is {shape[1]}x{shape[0]}")
    return frame


def _write_mp4(tmp: Path, frames, fps: float) -> int:
    import cv2

    writer = None
    shape = None
    k = 0
    try:
        for k, frame in enumerate(frames):
            frame = _check_frame(frame, shape, k)
            if writer is None:
                shape = frame.shape
                h, w = shape[0] + shape[0] % 2, shape[1] + shape[1] % 2
                writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
                if not writer.isOpened():
                    raise OSError(f"write_video: OpenCV cannot open an MP4 writer for {tmp}")
            if frame.shape[0] % 2 or frame.shape[1] % 2:
                frame = np.pad(frame, ((0, frame.shape[0] % 2), (0, frame.shape[1] % 2), (0, 0)), constant_values=255)
            writer.write(np.ascontiguousarray(frame[..., ::-1]))
        return 0 if shape is None else k + 1
    finally:
        if writer is not None:
            writer.release()


def _write_gif(tmp: Path, frames, fps: float) -> int:
    from PIL import Image

    images = []
    shape = None
    for k, frame in enumerate(frames):
        frame = _check_frame(frame, shape, k)
        shape = frame.shape
        images.append(Image.fromarray(frame).quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE))
    if images:
        images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=round(1000 / fps),
                       loop=0, disposal=1)
    return len(images)
