"""A user's own video or frames in: events by ESIM's algorithm, with evedge's pixel model.

Frames come from a video file (read with OpenCV), a folder of images, or
arrays. Each frame is one sample of the converter
(:class:`~evedge.sim.converter.EventConverter` in ``"frames"`` sampling): the
log intensity ``L = log(I + eps)`` of every pixel is interpolated linearly in
time between consecutive frames and each crossing of the pixel's reference
level plus or minus its threshold is an event at the interpolated instant,
exactly as ESIM's ``EventSimulator::imageCallback`` [1]_ (esim_py) does; the
pixel model is the scenes' one (per-pixel threshold mismatch drawn once from
the seed, refractory period, background noise, jitter, and the sensor
effects of :class:`~evedge.sim.converter.ConverterParams`).

Input intensity: linear (``uint8 / 255``, ``uint16 / 65535``, floats taken
as they are; colour converted to grey by OpenCV's BGR2GRAY) or already-log
(``log_input``: the values are ``L`` and ``I = exp(L) - eps`` is handed to the
converter, which takes the log back).

Timestamps: the container's (``CAP_PROP_POS_MSEC`` per frame, read from
its packets without decoding them when their times increase, else by a
decoding pass), a text file (one time in seconds per line, as esim_py's
``timestamps.txt``), or a rate (``t_k = k / rate_hz``). Event times are
relative to the first frame (its original time is in the recording's
metadata). A video is decoded once, during the run; 8-bit grey streams
(e.g. FFV1 grey) are read without OpenCV's conversion to BGR when that gives
the same frame 0.

Temporal upsampling (``upsample = k`` samples per frame interval):

- ``"log"``: sub-frames interpolated linearly in log intensity. The event
  times are those without upsampling (a linear function sampled more densely
  crosses its levels at the same instants); the sub-frames are the time base
  of the time-dependent sensor effects (photoreceptor low-pass), which then
  see a smoother input. Without sensor effects the converter does not build
  these sub-frames: :meth:`FramesRenderer.log_interval` hands it the two log
  frames and the fractions, and its kernel
  (:func:`evedge.sim._events._log_interval`) evaluates the same expression
  per changing pixel and decides on it directly, where the image path takes
  ``log(exp(L) - eps + eps)``: float times may differ in their last bits
  (about 1e-15 s); the stored microsecond and nanosecond times were the
  same bytes in every test (``tests/sim/test_frames.py``). Same seed, same
  bytes, and chunked = one-shot, hold as before.
- ``"flow"``: sub-frames from dense optical flow (OpenCV Farneback [2]_)
  between the two frames: at fraction ``a`` of the interval,
  ``I_a(x) = (1 - a) F0(x - a f(x)) + a F1(x + (1 - a) f(x))`` with ``f`` the
  flow from ``F0`` to ``F1``, so edges move between the frames instead of
  fading (as v2e's Super-SloMo upsampling [3]_ intends, without a network).

References
----------
.. [1] H. Rebecq, D. Gehrig, D. Scaramuzza, "ESIM: an Open Event Camera
       Simulator", CoRL 2018 (``esim_py``: github.com/uzh-rpg/rpg_vid2e).
.. [2] G. Farneback, "Two-frame motion estimation based on polynomial
       expansion", SCIA 2003 (``cv2.calcOpticalFlowFarneback``).
.. [3] Y. Hu, S.-C. Liu, T. Delbruck, "v2e: From video frames to realistic
       DVS events", CVPR Workshops 2021.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

#: Image file suffixes read from a frames folder (sorted by name).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".pgm", ".ppm")
UPSAMPLING = ("log", "flow")
#: Largest batch of images :meth:`FramesRenderer.samples` computes (decoded, resized, interpolated) in one call.
_FILLED_BATCH_BYTES = 1 << 20


class FramesError(ValueError):
    """Unreadable or inconsistent frames input; the message names the file and the problem."""


#: Longest span of frame times (s): the truth's ``t_ns`` are int64 nanoseconds (the converter's bound).
MAX_DURATION_S = 9e9
#: Working bytes per pixel of a frames run before any event: the decoded frame (up to 4 channels of 16 bit),
#: its float64 grey, the pair of frames held, sub-frames and flow, and the converter's per-pixel state.
_BYTES_PER_PIXEL = 8 + 8 * 6 + 96


def _check_size(width: int, height: int, source: str) -> None:
    """Refuse a frame size outside the sensor's range or too large for memory, before decoding anything."""
    from evedge._resources import memory_shortfall

    if not (1 <= width <= 32767 and 1 <= height <= 32767):
        raise FramesError(f"{source}: frame size {width}x{height} is outside 1..32767 pixels per side")
    short = memory_shortfall(width * height * _BYTES_PER_PIXEL, f"{source}: frames of {width}x{height}")
    if short:
        raise FramesError(short)


def _image_size(data: bytes, source: str) -> tuple[int, int]:
    """``(width, height)`` from an image file's header (PIL parses it without decoding the pixels).

    A JPEG must end with its end-of-image marker: it has no checksum, and
    OpenCV decodes a cut one with its missing rows grey.
    """
    import io
    import warnings

    from PIL import Image

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # DecompressionBombWarning: the size is checked here
            Image.MAX_IMAGE_PIXELS = None
            with Image.open(io.BytesIO(data)) as im:
                width, height, kind = im.size[0], im.size[1], im.format
    except Image.UnidentifiedImageError:
        raise FramesError(f"{source}: not a readable image (unknown or damaged header)") from None
    except Exception as err:  # noqa: BLE001 - PIL raises many types for a damaged header
        raise FramesError(f"{source}: not a readable image ({type(err).__name__}: {err})") from None
    if kind == "JPEG" and not data.rstrip(b"\0\r\n\t ")[-2:] == b"\xff\xd9":
        raise FramesError(f"{source}: the JPEG ends before its end-of-image marker (cut or damaged)")
    if kind == "PNG":
        _check_png_chunks(data, source)
    return width, height


def _check_png_chunks(data: bytes, source: str) -> None:
    """Every chunk inside the file and matching its CRC, up to IEND.

    OpenCV's PNG reader spends seconds per GB that a damaged chunk length
    declares past the end of the file (a flipped byte: a hang); libpng
    would ignore a damaged ancillary chunk.
    """
    import zlib

    pos = 8
    while pos + 12 <= len(data):
        length = int.from_bytes(data[pos:pos + 4], "big")
        kind = data[pos + 4:pos + 8]
        if pos + 12 + length > len(data):
            raise FramesError(f"{source}: PNG chunk {kind!r} at byte {pos} claims {length} bytes past the end of the file")
        if zlib.crc32(data[pos + 4:pos + 8 + length]) != int.from_bytes(data[pos + 8 + length:pos + 12 + length], "big"):
            raise FramesError(f"{source}: PNG chunk {kind!r} at byte {pos} fails its CRC: the file is corrupt")
        if kind == b"IEND":
            return
        pos += 12 + length
    raise FramesError(f"{source}: the PNG has no IEND chunk (cut short)")


def _grey(img: np.ndarray, source: str) -> np.ndarray:
    """A frame as float64 grey: ``uint8 / 255``, ``uint16 / 65535``, floats as given."""
    import cv2

    if img.ndim == 3 and img.shape[2] in (3, 4):
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY)
    elif img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.ndim != 2:
        raise FramesError(f"{source}: expected a grey or colour image, got shape {img.shape}")
    if img.dtype == np.uint8:
        return img.astype(np.float64) / 255.0
    if img.dtype == np.uint16:
        return img.astype(np.float64) / 65535.0
    if img.dtype.kind == "f":
        # no copy for float64 frames; non-finite values are caught by the converter's scan of the frame
        return np.ascontiguousarray(img, dtype=np.float64)
    raise FramesError(f"{source}: unsupported pixel type {img.dtype}")


def read_timestamps(path) -> np.ndarray:
    """Frame times from a text file: one time in seconds per line (blank lines and ``#`` comments skipped).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    numpy.ndarray
        float64 seconds, strictly increasing.

    Raises
    ------
    FramesError
        Unreadable file, a line that is not a number (its number named), or
        times that do not increase.

    Examples
    --------
    >>> read_timestamps("frames/timestamps.txt")  # doctest: +SKIP
    array([0.   , 0.001, 0.002])
    """
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise FramesError(f"{path}: cannot read timestamps: {exc}") from None
    out = []
    for k, line in enumerate(lines, 1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        try:
            value = float(text.split()[0])
        except ValueError:
            raise FramesError(f"{path}: line {k}: expected a time in seconds, got {text!r}") from None
        if not math.isfinite(value):
            raise FramesError(f"{path}: line {k}: time must be finite, got {text!r}")
        out.append(value)
    return _check_times(np.array(out, dtype=np.float64), str(path))


def _check_times(t: np.ndarray, source: str) -> np.ndarray:
    if t.ndim != 1:
        raise FramesError(f"{source}: frame times must be 1-D, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise FramesError(f"{source}: frame {int(np.flatnonzero(~np.isfinite(t))[0])} has a non-finite time")
    if t.shape[0] < 2:
        raise FramesError(f"{source}: need at least 2 frame times, got {t.shape[0]}")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise FramesError(f"{source}: frame times must increase: frame {i} at {float(t[i])!r} s follows {float(t[i - 1])!r} s")
    if not float(t[-1] - t[0]) <= MAX_DURATION_S:
        raise FramesError(f"{source}: frame times span {float(t[-1] - t[0])!r} s, more than {MAX_DURATION_S:g} s "
                          f"(frame 0 at {float(t[0])!r} s, frame {t.shape[0] - 1} at {float(t[-1])!r} s)")
    return t


class FrameSource:
    """Frames and their times, read one at a time (bounded memory).

    Use :func:`open_video`, :func:`open_frames_folder` or :func:`frames_from_arrays`.

    Attributes
    ----------
    times_s : numpy.ndarray
        float64 frame times (s), strictly increasing.
    width, height : int
    name : str
        What to call the source in messages and metadata.
    """

    def __init__(self, times_s, width, height, name, reader, block=None):
        self.times_s = _check_times(np.asarray(times_s, dtype=np.float64), name)
        self.width = int(width)
        self.height = int(height)
        self.name = str(name)
        self._reader = reader  # reader(k) -> float64 (H, W) frame k, called with k = 0, 1, 2, ...
        self._block = block  # block(k0, k1) -> float64 (k1 - k0, H, W) frames as they are, without a copy

    def block(self, k0: int, k1: int):
        """Frames ``k0 .. k1 - 1`` as one float64 ``(k1 - k0, H, W)`` array without a copy, or None.

        Only in-memory float64 frames have one (:func:`frames_from_arrays`);
        the others are read frame by frame with :meth:`frame`.
        """
        return None if self._block is None else self._block(k0, k1)

    def __len__(self) -> int:
        return int(self.times_s.shape[0])

    def frame(self, k: int) -> np.ndarray:
        """Frame ``k`` as float64 (H, W) (sequential access is the fast one for videos)."""
        img = self._reader(k)
        if img.shape != (self.height, self.width):
            raise FramesError(f"{self.name}: frame {k} is {img.shape[1]}x{img.shape[0]}, "
                              f"expected {self.width}x{self.height} like the first frame")
        return img

    def close(self) -> None:
        close = getattr(self._reader, "close", None)
        if close is not None:
            close()


def _times(n, source, container=None, timestamps=None, rate_hz=None):
    given = sum(x is not None for x in (timestamps, rate_hz))
    if given > 1:
        raise FramesError(f"{source}: give timestamps or rate_hz, not both")
    if rate_hz is not None:
        if isinstance(rate_hz, bool) or not isinstance(rate_hz, (int, float)) or not (0 < rate_hz < 1e9):
            raise FramesError(f"{source}: rate_hz must be a positive number, got {rate_hz!r}")
        return np.arange(n) / float(rate_hz)
    if timestamps is not None:
        t = timestamps if isinstance(timestamps, np.ndarray) else read_timestamps(timestamps)
        if t.shape[0] != n:
            raise FramesError(f"{source}: {n} frames but {t.shape[0]} timestamps")
        return t
    if container is None:
        raise FramesError(f"{source}: no frame times: give timestamps (a file, one time in s per line) or rate_hz")
    return container


def _fourcc(cap, cv2) -> bytes:
    """The decoder's pixel format as its four characters (``b"Y800"``: 8-bit grey), ``b""`` when unknown."""
    code = cap.get(cv2.CAP_PROP_CODEC_PIXEL_FORMAT)
    return int(code).to_bytes(4, "little") if 0 < code < 2 ** 32 else b""


def _container_times(path, cv2):
    """The container's frame times (s) from its packets, without decoding (OpenCV's raw stream mode), or None.

    ``CAP_PROP_FORMAT = -1`` makes ``grab`` read packets only, 30-60 times
    cheaper than decoding them (measured on FFV1, MPEG-4 part 2 and MJPEG,
    which give the same times both ways). Used only when OpenCV accepts the
    mode and the times strictly increase (packets come in decoding order: a
    stream that reorders frames, or without times, fails this check); None
    sends the caller to the decoding pass.
    """
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened() or not cap.set(cv2.CAP_PROP_FORMAT, -1):
            return None
        out = []
        while cap.grab():
            out.append(cap.get(cv2.CAP_PROP_POS_MSEC) * 1e-3)
    finally:
        cap.release()
    t = np.array(out)
    if t.shape[0] < 2 or not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        return None
    return t


class _VideoReader:
    """Frame ``k`` of a video (sequential decoding; a backward request reopens the file).

    ``grey``: the decoder gives 8-bit grey frames (``Y800``) and OpenCV's
    unconverted frame 0 equals the BGR-converted one's grey (checked by
    :func:`open_video`): frames are then read with ``CAP_PROP_CONVERT_RGB = 0``,
    which skips the grey-to-BGR-to-grey round trip. What comes back is still
    checked (:func:`_grey` takes 1, 3 or 4 channels; the frame's size is
    checked by :meth:`FrameSource.frame`).
    """

    def __init__(self, path, grey=False):
        import cv2

        self.path = path
        self.cap = None
        self.next = 0
        self.cv2 = cv2
        self.grey = bool(grey)

    def __call__(self, k):
        if self.cap is None or k < self.next:
            if self.cap is not None:
                self.cap.release()
            self.cap = self.cv2.VideoCapture(str(self.path))
            if self.grey:
                self.cap.set(self.cv2.CAP_PROP_CONVERT_RGB, 0)
            self.next = 0
        try:
            while self.next < k:
                self.cap.grab()
                self.next += 1
            ok, img = self.cap.read()
        except self.cv2.error as err:
            raise FramesError(f"{self.path}: cannot decode frame {k}: OpenCV: {str(err).strip()}") from None
        self.next += 1
        if not ok:
            raise FramesError(f"{self.path}: cannot decode frame {k}")
        return _grey(img, f"{self.path}: frame {k}")

    def close(self):
        if self.cap is not None:
            self.cap.release()
            self.cap = None


def open_video(path, *, timestamps=None, rate_hz=None) -> FrameSource:
    """A video file as a :class:`FrameSource` (OpenCV; times from the container unless given).

    Parameters
    ----------
    path : path-like
    timestamps : path-like or numpy.ndarray, optional
        Frame times (s): a text file of one time per line, or an array.
    rate_hz : float, optional
        Frame ``k`` at ``k / rate_hz``.

    Returns
    -------
    FrameSource

    Raises
    ------
    FramesError
        Missing or undecodable file, fewer than 2 frames, container times that
        do not increase (give ``rate_hz`` or ``timestamps`` instead), a
        timestamp count that does not match.

    Examples
    --------
    >>> rec = simulate_frames(open_video("clip.mp4"), progress=False)  # doctest: +SKIP
    >>> rec = simulate_frames(open_video("clip.avi", rate_hz=240.0), progress=False)  # doctest: +SKIP
    """
    import cv2

    path = Path(path)
    if not path.is_file():
        raise FramesError(f"{path}: no such video file")
    try:
        cap = cv2.VideoCapture(str(path))
        try:
            if not cap.isOpened():
                raise FramesError(f"{path}: OpenCV cannot open it as a video")
            # the stream's declared size, before FFmpeg decodes (and allocates) a frame
            declared = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
            if declared != (0, 0):
                _check_size(*declared, str(path))
            # the frame count and the container's times: from the packets (no decoding) when they are reliable
            container = _container_times(path, cv2)
            if container is None:
                container = []
                while cap.grab():  # a pass that decodes every frame
                    container.append(cap.get(cv2.CAP_PROP_POS_MSEC) * 1e-3)
                container = np.array(container)
        finally:
            cap.release()
        cap = cv2.VideoCapture(str(path))  # decodes the first frame (its size)
        try:
            ok, first = cap.read()
            grey_codec = ok and _fourcc(cap, cv2) == b"Y800"
        finally:
            cap.release()
        raw = None
        if grey_codec:  # frame 0 without OpenCV's conversion to BGR: used for all frames if it gives the same grey
            cap = cv2.VideoCapture(str(path))
            try:
                if cap.set(cv2.CAP_PROP_CONVERT_RGB, 0):
                    ok_raw, raw = cap.read()
                    raw = raw if ok_raw else None
            finally:
                cap.release()
    except cv2.error as err:
        raise FramesError(f"{path}: OpenCV cannot read it as a video: {str(err).strip()}") from None
    if not len(container) or not ok:
        raise FramesError(f"{path}: no decodable frame")
    _check_size(first.shape[1], first.shape[0], str(path))
    img = _grey(first, f"{path}: frame 0")
    grey = (raw is not None and raw.ndim == 2 and raw.dtype == np.uint8 and raw.shape == img.shape
            and np.array_equal(_grey(raw, f"{path}: frame 0"), img))
    t = _times(len(container), str(path), container, timestamps, rate_hz)
    return FrameSource(t, img.shape[1], img.shape[0], str(path), _VideoReader(path, grey))


def open_frames_folder(path, *, timestamps=None, rate_hz=None) -> FrameSource:
    """A folder of images (sorted by file name) as a :class:`FrameSource`.

    Parameters
    ----------
    path : path-like
        Folder of ``.png``, ``.jpg``, ``.tif``, ... images.
    timestamps : path-like or numpy.ndarray, optional
        Frame times (s); default the folder's ``timestamps.txt`` when there is
        one, else an Event Camera Dataset ``images.txt`` beside the folder
        (its first column).
    rate_hz : float, optional
        Frame ``k`` at ``k / rate_hz``.

    Returns
    -------
    FrameSource

    Raises
    ------
    FramesError
        Not a folder, fewer than 2 images, an unreadable image (named), no
        frame times.

    Examples
    --------
    >>> src = open_frames_folder("slider_depth/images")  # doctest: +SKIP
    >>> len(src), src.times_s[1]  # times from slider_depth/images.txt  # doctest: +SKIP
    (87, 0.038766001)
    """
    import cv2

    path = Path(path)
    if not path.is_dir():
        raise FramesError(f"{path}: not a folder")
    files = sorted(p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
    if len(files) < 2:
        raise FramesError(f"{path}: need at least 2 images ({', '.join(IMAGE_SUFFIXES)}), found {len(files)}")
    if timestamps is None and rate_hz is None:
        if (path / "timestamps.txt").is_file():
            timestamps = path / "timestamps.txt"
        elif (path.parent / "images.txt").is_file():
            # an Event Camera Dataset folder: images.txt beside images/, "t images/frame.png" per line
            timestamps = path.parent / "images.txt"

    size = []  # the first frame's (width, height): every frame's header is checked against it before decoding

    def read(k):
        try:
            data = files[k].read_bytes()
        except OSError as err:
            raise FramesError(f"{files[k]}: cannot read it: {err.strerror or err}") from None
        width, height = _image_size(data, str(files[k]))
        if not size:
            _check_size(width, height, str(files[k]))
            size.append((width, height))
        elif (width, height) != size[0]:
            raise FramesError(f"{files[k]}: frame {k} is {width}x{height}, expected {size[0][0]}x{size[0][1]} "
                              "like the first frame")
        try:
            img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        except cv2.error as err:
            raise FramesError(f"{files[k]}: OpenCV cannot decode it: {str(err).strip()}") from None
        if img is None:
            raise FramesError(f"{files[k]}: OpenCV cannot read it as an image")
        if img.shape[:2] != (height, width):
            raise FramesError(f"{files[k]}: decoded as {img.shape[1]}x{img.shape[0]}, its header says {width}x{height}")
        if img.dtype.kind == "f" and not (np.isfinite(img).all() and img.min() >= 0):  # float TIFF
            raise FramesError(f"{files[k]}: float pixels must be finite and >= 0")
        return _grey(img, str(files[k]))

    first = read(0)
    t = _times(len(files), str(path), None, timestamps, rate_hz)
    return FrameSource(t, first.shape[1], first.shape[0], str(path), read)


def frames_from_arrays(frames, times_s, name: str = "<frames>") -> FrameSource:
    """In-memory frames ``(n, H, W)`` (grey, types as :func:`open_video`) with their times (s)."""
    frames = np.asarray(frames)
    if frames.ndim != 3:
        raise FramesError(f"{name}: expected frames of shape (n, height, width), got {frames.shape}")
    try:
        times_s = np.asarray(times_s, dtype=np.float64)
    except (TypeError, ValueError):
        raise FramesError(f"{name}: times_s must be numbers (seconds), got {times_s!r}") from None
    if times_s.shape != (frames.shape[0],):
        raise FramesError(f"{name}: {frames.shape[0]} frames but times_s has shape {times_s.shape}")
    if not np.all(np.isfinite(times_s)):
        raise FramesError(f"{name}: times_s must be finite")
    block = None
    if frames.dtype == np.float64 and frames.flags.c_contiguous:
        block = lambda k0, k1: frames[k0:k1]  # noqa: E731  (the frames as _grey returns them: no copy)
    return FrameSource(times_s, frames.shape[2], frames.shape[1], name,
                       lambda k: _grey(frames[k], f"{name}: frame {k}"), block)


class FramesRenderer:
    """A :class:`FrameSource` as a renderer sampled at its frame (and sub-frame) times only.

    Parameters
    ----------
    source : FrameSource
    log_input : bool
        The frames hold log intensity ``L`` (the converter gets ``exp(L) - eps``).
    eps : float
        The converter's ``log_eps``.
    upsample : int
        Samples per frame interval (1: the frames only).
    interpolation : str
        ``"log"`` or ``"flow"`` (see the module docstring).
    resize : tuple of int, optional
        ``(width, height)``: frames resized with ``cv2.INTER_AREA`` (a sensor
        preset's resolution).

    Notes
    -----
    The converter asks :meth:`next_sample_s` for its next sample and renders
    exactly that time; the first frame is at ``t = 0``. There is no motion
    field: the truth's flow and normal are NaN.
    """

    has_flow = False

    def __init__(self, source: FrameSource, *, log_input: bool = False, eps: float = 1e-3, upsample: int = 1,
                 interpolation: str = "log", resize=None):
        if isinstance(upsample, bool) or not isinstance(upsample, (int, np.integer)) or not 1 <= upsample <= 1000:
            raise ValueError(f"upsample must be an integer in 1..1000, got {upsample!r}")
        if interpolation not in UPSAMPLING:
            raise ValueError(f"interpolation must be one of {list(UPSAMPLING)}, got {interpolation!r}")
        self.source = source
        self.log_input = bool(log_input)
        self.eps = float(eps)
        self.upsample = int(upsample)
        self.interpolation = interpolation
        self.resize = None if resize is None else (int(resize[0]), int(resize[1]))
        self.name = source.name  # what the converter calls it in messages
        self.width, self.height = self.resize or (source.width, source.height)
        self.t0_s = float(source.times_s[0])
        self._t = source.times_s - self.t0_s
        self.duration_s = float(self._t[-1])
        self._k = -1  # frame interval [k, k + 1] held
        self._pair = None
        self._next = None  # (time, k, j) of the last next_sample_s answer
        self._buf = None  # images of the last samples() call (reused)

    # sample times: frame k at _t[k], sub-sample j of interval k at _t[k] + j / upsample * (_t[k+1] - _t[k])
    def _sample_time(self, k, j):
        if j == 0:
            return float(self._t[k])
        return float(self._t[k] + (self._t[k + 1] - self._t[k]) * (j / self.upsample))

    def _locate(self, t_s):
        k = int(np.searchsorted(self._t, t_s, side="right")) - 1
        k = min(max(k, 0), len(self._t) - 1)
        if k == len(self._t) - 1:
            return k, 0
        for j in range(self.upsample):
            if self._sample_time(k, j) == t_s:
                return k, j
        return k, None

    def next_sample_s(self, t_s: float) -> float:
        """The first sample time after ``t_s`` (remembered, so that :meth:`intensity` finds it without a search)."""
        k = int(np.searchsorted(self._t, t_s, side="right")) - 1
        if k >= len(self._t) - 1:
            self._next = (self.duration_s, len(self._t) - 1, 0)
            return self.duration_s
        k = max(k, 0)
        for j in range(1, self.upsample):
            tj = self._sample_time(k, j)
            if tj > t_s:
                self._next = (tj, k, j)
                return tj
        self._next = (float(self._t[k + 1]), k + 1, 0)
        return self._next[0]

    def _frame(self, k):
        """Frame ``k`` as log intensity, or as linear intensity when no sub-frame needs the log (faster)."""
        img = self.source.frame(k)
        if self.resize is not None and img.shape != (self.height, self.width):
            import cv2

            img = cv2.resize(img, (self.width, self.height), interpolation=cv2.INTER_AREA)
        if self.log_input or self.upsample == 1:
            return img
        return np.log(img + self.eps)

    def _load_pair(self, k):
        if self._k == k:
            return
        if self._pair is not None and self._k + 1 == k:
            first = self._pair[1]
        else:
            first = self._frame(k)
        second = self._frame(k + 1) if k + 1 < len(self._t) else first
        self._pair = (first, second)
        self._k = k
        self._flow01 = None

    def _log_at(self, k, j):
        self._load_pair(k)
        l0, l1 = self._pair
        if j == 0:
            return l0
        a = j / self.upsample
        if self.interpolation == "log":
            return (1.0 - a) * l0 + a * l1
        return self._flow_blend(a)

    def _flow_blend(self, a):
        import cv2

        l0, l1 = self._pair
        if self._flow01 is None:
            lo, hi = min(l0.min(), l1.min()), max(l0.max(), l1.max())
            scale = 255.0 / (hi - lo) if hi > lo else 0.0
            g0 = np.clip((l0 - lo) * scale, 0, 255).astype(np.uint8)
            g1 = np.clip((l1 - lo) * scale, 0, 255).astype(np.uint8)
            self._flow01 = cv2.calcOpticalFlowFarneback(g0, g1, None, 0.5, 3, 15, 3, 5, 1.2, 0)
            yy, xx = np.mgrid[0:self.height, 0:self.width].astype(np.float32)
            self._grid = (xx, yy)
        fx, fy = self._flow01[..., 0], self._flow01[..., 1]
        xx, yy = self._grid
        w0 = cv2.remap(l0.astype(np.float32), xx - a * fx, yy - a * fy, cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_REPLICATE)
        w1 = cv2.remap(l1.astype(np.float32), xx + (1 - a) * fx, yy + (1 - a) * fy, cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_REPLICATE)
        return (1.0 - a) * w0.astype(np.float64) + a * w1.astype(np.float64)

    def intensity(self, t_s: float) -> np.ndarray:
        """Linear intensity at sample time ``t_s`` (a frame or sub-frame time; others are refused)."""
        t_s = float(t_s)
        k, j = self._next[1:] if self._next is not None and self._next[0] == t_s else self._locate(t_s)
        if j is None:
            raise ValueError(f"FramesRenderer.intensity: {t_s!r} s is not a sample time of {self.source.name}")
        if k == len(self._t) - 1:
            self._load_pair(k - 1) if k > 0 else self._load_pair(k)
            lg = self._pair[1]
        else:
            lg = self._log_at(k, j)
        if self.upsample == 1 and not self.log_input:
            return lg  # linear frames as they are
        return np.exp(lg) - self.eps

    def samples(self, t_s: float, until_s: float, max_n: int):
        """The next samples after ``t_s`` in one array: ``(times_s, images)``, as :meth:`next_sample_s` and
        :meth:`intensity` give them one by one.

        At most ``max_n`` samples, and about 1 MB of them when the images are
        computed here (read, resized, interpolated: the converter then scans
        them while they are in the cache); the last one is the first at or
        after ``until_s`` (or the last frame). ``images`` is ``(n, H, W)`` float64:
        a view of in-memory float64 frames when there is no upsampling,
        resizing or log input, else a buffer reused by the next call.
        """
        last = len(self._t) - 1
        t = self.next_sample_s(t_s)
        k, j = self._next[1:]
        times, kj = [t], [(k, j)]
        if not (self.upsample == 1 and not self.log_input and self.resize is None and self.source._block is not None):
            # images computed here are scanned right after: a batch that stays in the cache (about 1 MB; a
            # 16 MB batch was slower than frame by frame)
            max_n = min(max_n, max(1, _FILLED_BATCH_BYTES // (8 * self.width * self.height)))
        while len(times) < max_n and t < until_s and k < last:
            # the successor of sample (k, j): the smallest sample time after t, as next_sample_s(t)
            while k < last:
                j += 1
                if j == self.upsample:
                    k, j = k + 1, 0
                tj = self._sample_time(k, j)
                if tj > t:
                    break
            else:
                break
            t = tj
            times.append(t)
            kj.append((k, j))
        n = len(times)
        times = np.array(times)
        if self.upsample == 1 and not self.log_input and self.resize is None:
            view = self.source.block(kj[0][0], kj[0][0] + n)
            if view is not None:
                return times, view
        if self._buf is None or self._buf.shape[0] < n:
            self._buf = np.empty((n, self.height, self.width))
        for r, (tk, (k, j)) in enumerate(zip(times, kj)):
            self._next = (float(tk), k, j)
            self._buf[r] = self.intensity(float(tk))
        return times, self._buf[:n]

    def log_interval(self, t_s: float, until_s: float):
        """The next samples after ``t_s`` inside its frame interval, as log frames and fractions (no images).

        For ``"log"`` upsampling: ``(l0, l1, a_prev, alphas, times_s)``, the
        flat log frames at the ends of the interval of sample ``t_s``, its
        fraction ``a_prev``, and the following samples' fractions and times
        (up to the interval's end, the last one the first at or after
        ``until_s``): the samples :meth:`samples` gives, whose log intensity
        is ``(1 - a) * l0 + a * l1``. None when that does not apply (no log
        upsampling, ``t_s`` not a sample time, or sample times that tie
        across a frame); the converter then takes :meth:`samples`.
        """
        if self.upsample == 1 or self.interpolation != "log":
            return None
        t = float(t_s)
        kp, jp = self._locate(t)
        if jp is None or kp >= len(self._t) - 1:
            return None
        k, j = kp, jp
        times, alphas = [], []
        while True:  # the successors of sample (k, j), as in samples()
            j += 1
            if j == self.upsample:
                k, j = k + 1, 0
            tj = self._sample_time(k, j)
            if tj <= t:
                if k > kp:
                    return None  # a sub-sample time ties the frame's: the general path
                continue
            t = tj
            times.append(t)
            alphas.append(1.0 if k > kp else j / self.upsample)
            if k > kp or t >= until_s:
                break
        self._load_pair(kp)
        l0, l1 = (np.ascontiguousarray(x, dtype=np.float64).reshape(-1) for x in self._pair)
        return l0, l1, jp / self.upsample, np.array(alphas), np.array(times)

    def flow(self, t_s: float):
        return None

    def edges(self, t_s: float) -> np.ndarray:
        raise NotImplementedError("frames input has no exact edge map")

    def max_speed_px_s(self, t0_s: float, t1_s: float) -> float:
        return 0.0

    def close(self) -> None:
        self.source.close()


def _check_memory(renderer: FramesRenderer, params) -> None:
    """Refuse a run whose per-pixel state and noise events cannot fit, before any work (as scenes' simulate)."""
    from evedge._resources import memory_shortfall
    from evedge.events import EVENT_DTYPE

    from .truth import TRUTH_DTYPE

    pixels = renderer.width * renderer.height
    noise_events = params.noise_rate_hz * pixels * renderer.duration_s
    # events and truth are held in chunks, then concatenated once: twice their size at the end
    needed = pixels * _BYTES_PER_PIXEL + 2 * noise_events * (EVENT_DTYPE.itemsize + TRUTH_DTYPE.itemsize)
    short = memory_shortfall(needed, f"{renderer.name}: {renderer.width}x{renderer.height} for "
                                     f"{renderer.duration_s:g} s of frames (about {noise_events:.3g} noise events "
                                     f"at noise_rate_hz={params.noise_rate_hz:g})")
    if short:
        raise FramesError(f"{short}; lower noise_rate_hz or give shorter frame times")


def simulate_frames(source: FrameSource, params=None, *, seed: int = 0, log_input: bool = False, upsample: int = 1,
                    interpolation: str = "log", resize=None, progress: bool = True, chunk_s: float = 0.05):
    """Events of a user's frames: a :class:`~evedge.events.Recording` (events, truth with ``t_ns``, metadata).

    Parameters
    ----------
    source : FrameSource
        From :func:`open_video`, :func:`open_frames_folder` or :func:`frames_from_arrays`.
    params : ConverterParams, optional
        Pixel model (thresholds, mismatch, refractory, noise, ...); the
        sampling fields are unused (the frames are the samples).
    seed : int
        Seeds the threshold mismatch, the noise and the jitter.
    log_input, upsample, interpolation, resize
        See :class:`FramesRenderer`.
    progress : bool
        tqdm bar over the frames' time (stderr).
    chunk_s : float
        Simulated time per chunk (bounds the working memory; the output does not depend on it).

    Returns
    -------
    Recording
        Events relative to the first frame; truth rows are signal (flow
        unknown: NaN) or noise, with ``t_ns``.

    Examples
    --------
    >>> import numpy as np
    >>> frames = np.linspace(0.2, 0.8, 5)[:, None, None] * np.ones((5, 2, 3))
    >>> rec = simulate_frames(frames_from_arrays(frames, np.arange(5) / 100.0), progress=False)
    >>> rec.events.shape[0] > 0
    True
    """
    import sys

    from tqdm import tqdm

    from evedge.events import Recording, SensorSize
    from .converter import ConverterParams, EventConverter
    from .simulate import _versions

    if not isinstance(source, FrameSource):
        raise TypeError("simulate_frames: source must be a FrameSource (open_video, open_frames_folder or "
                        f"frames_from_arrays), got {type(source).__name__}")
    if params is None:
        params = ConverterParams()
    if not isinstance(params, ConverterParams):
        raise TypeError(f"simulate_frames: params must be a ConverterParams, got {type(params).__name__}")
    if not (isinstance(chunk_s, (int, float)) and not isinstance(chunk_s, bool) and math.isfinite(chunk_s)
            and chunk_s > 0):
        raise ValueError(f"simulate_frames: chunk_s must be > 0, got {chunk_s!r}")
    renderer = FramesRenderer(source, log_input=log_input, eps=params.log_eps, upsample=upsample,
                              interpolation=interpolation, resize=resize)
    try:
        _check_memory(renderer, params)
        conv = EventConverter(renderer, params, seed=seed, duration_s=renderer.duration_s)
        ev_parts, tr_parts = [], []
        with tqdm(total=len(source) - 1, unit="frame", desc=f"simulate {Path(source.name).name}",
                  disable=not progress, file=sys.stderr) as bar:
            done = 0
            t = 0.0
            while not conv.done:
                # a chunk reaches at least the next frame: a long gap between frames is one chunk, not many
                k = int(np.searchsorted(renderer._t, t, side="right"))
                t = min(renderer.duration_s, max(t + chunk_s, float(renderer._t[min(k, len(renderer._t) - 1)])))
                ev, tr = conv.process(t)
                ev_parts.append(ev)
                tr_parts.append(tr)
                now = int(np.searchsorted(renderer._t, conv.t, side="right")) - 1
                bar.update(now - done)
                done = now
    finally:
        renderer.close()
    events = np.concatenate(ev_parts)
    truth = np.concatenate(tr_parts)
    from dataclasses import asdict

    metadata = {
        "source": "evedge.sim.simulate_frames",
        "input": os.fspath(source.name),
        "first_frame_s": renderer.t0_s,
        "n_frames": len(source),
        "log_input": bool(log_input),
        "upsample": int(upsample),
        "interpolation": interpolation,
        "seed": int(seed),
        "duration_s": renderer.duration_s,
        "converter": asdict(params),
        "log_intensity": f"L = log(I + {params.log_eps})",
        "n_samples": conv.n_samples,
        "n_signal": int(np.count_nonzero(truth["is_signal"])),
        "n_noise": int(np.count_nonzero(~truth["is_signal"])),
        "versions": _versions("frames"),
    }
    return Recording(events=events, sensor_size=SensorSize(renderer.width, renderer.height), truth=truth,
                     metadata=metadata)
