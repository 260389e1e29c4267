"""The detection file: what a method said about a recording, self-describing.

Written by ``evedge detect``, read by :func:`read_detection` (and by
:func:`evedge.io.read_events`, ``evedge info`` and ``evedge grade``). One
HDF5 file (``format="evedge-detection"``, ``format_version=1``)::

    /events/{x, y, t, p}     the events the method saw (optional: else the source's
                             sha256 and absolute path in the metadata)
    /lifetimes/{lifetime_us, vx_px_s, vy_px_s, valid, kept}
                             per event, aligned with the events (lifetime methods)
    /edges/{t_us, images}    edge frames (optional)
    attrs: format, format_version, sensor_width, sensor_height,
           metadata (JSON: method, kind, display, params, filter, filter_params,
           source {path, sha256, n_events, format}, versions, command)

Written through a temporary file renamed into place; the same inputs give
the same bytes (no HDF5 timestamps).

Examples
--------
>>> import numpy as np, tempfile, pathlib
>>> from evedge.events import SensorSize, make_events
>>> ev = make_events([0, 1], [0, 0], [10, 20], [True, False])
>>> path = pathlib.Path(tempfile.mkdtemp()) / "d.h5"
>>> _ = write_detection(path, Detection(SensorSize(2, 1), events=ev, metadata={"method": "x"}))
>>> read_detection(path).events["t"].tolist()
[10, 20]
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..events import EVENT_DTYPE, Frames, SensorSize, make_events
from ._checks import EventFileError
from .hdf5 import _metadata_json, _new_file

__all__ = ["DETECTION_FORMAT", "DETECTION_FORMAT_VERSION", "LIFETIME_COLUMNS", "Detection", "file_sha256",
           "is_detection_file", "read_detection", "write_detection"]

DETECTION_FORMAT = "evedge-detection"
DETECTION_FORMAT_VERSION = 1

#: Per-event columns of ``/lifetimes`` (LIFETIME_DTYPE's fields, then the filter's decision).
LIFETIME_COLUMNS = (("lifetime_us", np.float64), ("vx_px_s", np.float64), ("vy_px_s", np.float64),
                    ("valid", np.bool_), ("kept", np.bool_))
_CHUNK = 1 << 18


@dataclass
class Detection:
    """The content of a detection file.

    Attributes
    ----------
    sensor_size : SensorSize
    events : numpy.ndarray or None
        EVENT_DTYPE events the method saw (None: only their digest is in ``metadata["source"]``).
    lifetimes : numpy.ndarray or None
        Structured per-event columns :data:`LIFETIME_COLUMNS` (lifetime methods).
    edges : Frames or None
        Edge frames with their times.
    metadata : dict
        JSON-serialisable: method, params, versions, source, ...
    """

    sensor_size: SensorSize
    events: np.ndarray | None = None
    lifetimes: np.ndarray | None = None
    edges: Frames | None = None
    metadata: dict[str, Any] = field(default_factory=dict)


def file_sha256(path: str | os.PathLike) -> str:
    """sha256 of a file, or of a folder's files (sorted relative paths and contents)."""
    path = Path(path)
    h = hashlib.sha256()
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for p in files:
        if path.is_dir():
            h.update(str(p.relative_to(path)).encode() + b"\0")
        with open(p, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


def _dataset(group, name: str, data: np.ndarray, compress: bool = True) -> None:
    options = {"track_times": False}
    if data.size and compress:
        chunks = (max(1, min(data.shape[0], _CHUNK if data.ndim == 1 else 1)),) + data.shape[1:]
        options.update(chunks=chunks, compression="gzip", compression_opts=4, shuffle=True)
    group.create_dataset(name, data=data, **options)


def write_detection(path: str | os.PathLike, detection: Detection, *, compress_per_event: bool = False) -> Path:
    """Write a :class:`Detection` (temporary file, then rename).

    The edge frames are gzip-compressed; the per-event columns (events, lifetimes)
    only with ``compress_per_event``: gzip costs ~0.9 us per event (about as much
    as the whole detector) for a file ~2x smaller; readers see no difference.

    Raises
    ------
    TypeError, ValueError
        For a wrong ``detection`` (not a Detection, events not EVENT_DTYPE,
        per-event columns not aligned, metadata not JSON); nothing is written.
    """
    if not isinstance(detection, Detection):
        raise TypeError(f"write_detection: expected a Detection, got {type(detection).__name__}")
    size = detection.sensor_size
    ev = detection.events
    if ev is not None and (not isinstance(ev, np.ndarray) or ev.dtype != EVENT_DTYPE):
        raise TypeError(f"write_detection: events must be EVENT_DTYPE, got {getattr(ev, 'dtype', type(ev))}")
    lt = detection.lifetimes
    if lt is not None:
        missing = [n for n, _ in LIFETIME_COLUMNS if n not in (lt.dtype.names or ())]
        if missing:
            raise ValueError(f"write_detection: lifetimes lack columns {missing}")
        if ev is not None and lt.shape[0] != ev.shape[0]:
            raise ValueError(f"write_detection: {lt.shape[0]} lifetime rows for {ev.shape[0]} events")
    metadata = _metadata_json(detection.metadata, "write_detection: metadata")
    path = Path(path)
    with _new_file(path, "write_detection", DETECTION_FORMAT, DETECTION_FORMAT_VERSION, size, metadata) as f:
        if ev is not None:
            g = f.create_group("events", track_order=True)
            for name in ("x", "y", "t", "p"):
                _dataset(g, name, np.ascontiguousarray(ev[name]), compress_per_event)
        if lt is not None:
            g = f.create_group("lifetimes", track_order=True)
            for name, dtype in LIFETIME_COLUMNS:
                _dataset(g, name, np.ascontiguousarray(lt[name], dtype=dtype), compress_per_event)
        if detection.edges is not None:
            g = f.create_group("edges", track_order=True)
            _dataset(g, "t_us", np.asarray(detection.edges.t_us, np.int64))
            _dataset(g, "images", np.asarray(detection.edges.images, bool))
    return path


def is_detection_file(path: str | os.PathLike) -> bool:
    """True when ``path`` is an HDF5 file with ``format="evedge-detection"``."""
    import h5py

    path = Path(path)
    if not path.is_file():
        return False
    try:
        with h5py.File(path, "r") as f:
            fmt = f.attrs.get("format")
    except OSError:
        return False
    return (fmt.decode() if isinstance(fmt, bytes) else fmt) == DETECTION_FORMAT


def _read(f, path: Path, name: str) -> np.ndarray:
    try:
        return np.asarray(f[name][()])
    except (OSError, KeyError, ValueError) as err:
        raise EventFileError(f"{path}: dataset {name!r} is unreadable: {err}") from None


def read_detection(path: str | os.PathLike) -> Detection:
    """Read a detection file written by :func:`write_detection` (``evedge detect``).

    Raises
    ------
    EventFileError
        Naming the file and the attribute or dataset that is missing or malformed.
    """
    import h5py

    path = Path(path)
    try:
        f = h5py.File(path, "r")
    except (OSError, IsADirectoryError) as err:
        raise EventFileError(f"{path}: not a readable HDF5 file: {err}") from None
    with f:
        fmt = f.attrs.get("format")
        fmt = fmt.decode() if isinstance(fmt, bytes) else fmt
        if fmt != DETECTION_FORMAT:
            raise EventFileError(f"{path}: not an evedge detection file (attribute format={fmt!r}, "
                                 f"expected {DETECTION_FORMAT!r})")
        version = f.attrs.get("format_version")
        if not (isinstance(version, (int, np.integer)) and int(version) == DETECTION_FORMAT_VERSION):
            raise EventFileError(f"{path}: detection format_version={version} is not supported "
                                 f"(this reader knows {DETECTION_FORMAT_VERSION})")
        try:
            size = SensorSize(int(f.attrs["sensor_width"]), int(f.attrs["sensor_height"]))
            metadata = json.loads(f.attrs.get("metadata", "{}"))
        except (KeyError, ValueError, TypeError) as err:
            raise EventFileError(f"{path}: bad sensor_width/sensor_height/metadata attribute: {err}") from None
        events = None
        if "events" in f:
            cols = [_read(f, path, f"events/{c}") for c in ("x", "y", "t", "p")]
            if len({c.shape for c in cols}) != 1:
                raise EventFileError(f"{path}: events/x, y, t, p have different lengths {[c.shape for c in cols]}")
            try:
                events = make_events(*cols)
            except (ValueError, TypeError) as err:
                raise EventFileError(f"{path}: events: {err}") from None
        lifetimes = None
        if "lifetimes" in f:
            n = None
            lifetimes_cols = {}
            for name, dtype in LIFETIME_COLUMNS:
                col = _read(f, path, f"lifetimes/{name}")
                if col.ndim != 1 or (n is not None and col.shape[0] != n):
                    raise EventFileError(f"{path}: lifetimes/{name} has shape {col.shape}, expected ({n},)")
                n = col.shape[0]
                lifetimes_cols[name] = col.astype(dtype, copy=False)
            if events is not None and n != events.shape[0]:
                raise EventFileError(f"{path}: {n} lifetime rows for {events.shape[0]} events")
            lifetimes = np.empty(n, dtype=list(LIFETIME_COLUMNS))
            for name, col in lifetimes_cols.items():
                lifetimes[name] = col
        edges = None
        if "edges" in f:
            t = _read(f, path, "edges/t_us")
            images = _read(f, path, "edges/images")
            try:
                edges = Frames(t, images.astype(bool, copy=False))
            except ValueError as err:
                raise EventFileError(f"{path}: edges: {err}") from None
            if len(edges) and edges.images.shape[1:] != size.shape:
                raise EventFileError(f"{path}: edges/images are {images.shape[2]}x{images.shape[1]}, the sensor "
                                     f"is {size.width}x{size.height}")
    return Detection(size, events, lifetimes, edges, metadata)
