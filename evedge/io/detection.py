"""The detection file: what a method said about a recording, self-describing.

Written by ``evedge detect``, read by :func:`read_detection` (and by
:func:`evedge.io.read_events`, ``evedge info`` and ``evedge grade``). One
HDF5 file (``format="evedge-detection"``, ``format_version=2``)::

    /events/{x, y, t, p}     the events the method saw (optional: else the source's
                             sha256 and absolute path in the metadata)
    /lifetimes/{lifetime_us, vx_px_s, vy_px_s, valid, kept}
                             per event, aligned with the events (lifetime methods)
    /edges/{t_us, images}    edge frames (optional)
    attrs: format, format_version, sensor_width, sensor_height,
           metadata (JSON: method, kind, display, params, filter, filter_params,
           source {path, sha256, n_events, format}, versions, command),
           checksums (sha256 of every dataset and attribute, verified on read)

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

from .._resources import memory_shortfall
from ..events import EVENT_DTYPE, Frames, SensorSize, make_events
from ._checks import EventFileError
from .hdf5 import _metadata_json, _new_file

__all__ = ["DETECTION_FORMAT", "DETECTION_FORMAT_VERSION", "LIFETIME_COLUMNS", "Detection", "file_sha256",
           "is_detection_file", "read_detection", "write_detection"]

DETECTION_FORMAT = "evedge-detection"
DETECTION_FORMAT_VERSION = 2  # 2: sha256 checksums of every dataset and attribute (evedge.io.hdf5.seal)

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
    lifetimes : numpy.ndarray, dict or None
        Structured per-event columns :data:`LIFETIME_COLUMNS` (lifetime methods); for
        :func:`write_detection` also a dict of those columns as 1-D arrays (what
        ``evedge detect`` hands it, so that each can be freed once written);
        :func:`read_detection` gives the structured array.
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


#: Rows of a per-event column written at a time (a multiple of ``_CHUNK``: every write covers whole chunks).
_WRITE_ROWS = 1 << 20


def _dataset(group, name: str, data: np.ndarray, compress: bool = True, dtype=None) -> None:
    """Dataset ``name`` holding ``data`` (as ``dtype``) in ``group``.

    A 1-D ``data`` (e.g. a field of a structured array: strided) is written
    ``_WRITE_ROWS`` rows at a time, so no contiguous copy of the whole column
    is made; the file's bytes are those of one whole write.
    """
    dtype = np.dtype(data.dtype if dtype is None else dtype)
    options = {"track_times": False}
    if data.size and compress:
        chunks = (max(1, min(data.shape[0], _CHUNK if data.ndim == 1 else 1)),) + data.shape[1:]
        options.update(chunks=chunks, compression="gzip", compression_opts=4, shuffle=True)
    if data.ndim != 1 or data.shape[0] <= _WRITE_ROWS:
        group.create_dataset(name, data=np.asarray(data, dtype=dtype), **options)
        return
    ds = group.create_dataset(name, shape=data.shape, dtype=dtype, **options)
    for start in range(0, data.shape[0], _WRITE_ROWS):
        part = np.ascontiguousarray(data[start:start + _WRITE_ROWS], dtype=dtype)
        ds[start:start + part.shape[0]] = part


def write_detection(path: str | os.PathLike, detection: Detection, *, compress_per_event: bool = False,
                    release_columns: bool = False) -> Path:
    """Write a :class:`Detection` (temporary file, then rename).

    The edge frames are gzip-compressed; the per-event columns (events, lifetimes)
    only with ``compress_per_event``: gzip costs ~0.9 us per event (about as much
    as the whole detector) for a file ~2x smaller; readers see no difference.

    Parameters
    ----------
    path : path-like
    detection : Detection
        ``lifetimes`` may also be a dict of the :data:`LIFETIME_COLUMNS` as 1-D
        arrays of one length (the same file as the structured array).
    compress_per_event : bool
    release_columns : bool
        Take ownership of the per-event arrays: ``detection.events`` is set to
        None once the events are in the file image (built in memory) and, with
        ``lifetimes`` a dict, each column is removed from it once it is in the
        image (the dict is left empty, also when the write fails), so that
        their memory is freed while the image grows when the caller holds no
        other reference (``evedge detect``).

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
    n_rows = None
    if lt is not None:
        names = tuple(lt) if isinstance(lt, dict) else (lt.dtype.names or ())
        missing = [n for n, _ in LIFETIME_COLUMNS if n not in names]
        if missing:
            raise ValueError(f"write_detection: lifetimes lack columns {missing}")
        if isinstance(lt, dict):
            shapes = {n: np.shape(lt[n]) for n, _ in LIFETIME_COLUMNS}
            if len(set(shapes.values())) != 1 or len(next(iter(shapes.values()))) != 1:
                raise ValueError(f"write_detection: the lifetimes columns must be 1-D of one length, got {shapes}")
            n_rows = next(iter(shapes.values()))[0]
        else:
            n_rows = lt.shape[0]
        if ev is not None and n_rows != ev.shape[0]:
            raise ValueError(f"write_detection: {n_rows} lifetime rows for {ev.shape[0]} events")
    metadata = _metadata_json(detection.metadata, "write_detection: metadata")
    path = Path(path)
    try:
        with _new_file(path, "write_detection", DETECTION_FORMAT, DETECTION_FORMAT_VERSION, size, metadata) as f:
            if ev is not None:
                g = f.create_group("events", track_order=True)
                for name in ("x", "y", "t", "p"):
                    _dataset(g, name, ev[name], compress_per_event)  # written in slices: no whole-column copy
                if release_columns:
                    detection.events = ev = None  # freed now if the caller holds no other reference
            if lt is not None:
                g = f.create_group("lifetimes", track_order=True)
                for name, dtype in LIFETIME_COLUMNS:
                    _dataset(g, name, np.asarray(lt[name]), compress_per_event, dtype)
                    if release_columns and isinstance(lt, dict):
                        del lt[name]  # its memory freed now, while the image grows
            if detection.edges is not None:
                g = f.create_group("edges", track_order=True)
                _dataset(g, "t_us", np.asarray(detection.edges.t_us, np.int64))
                _dataset(g, "images", np.asarray(detection.edges.images, bool))
    finally:
        if release_columns and isinstance(lt, dict):
            lt.clear()
    return path


def is_detection_file(path: str | os.PathLike) -> bool:
    """True when ``path`` is an HDF5 file with ``format="evedge-detection"``."""
    import h5py

    from .hdf5 import probe

    path = Path(path)
    if not path.is_file():
        return False
    probe(path)  # a corrupt header can make HDF5 loop for minutes: an EventFileError instead
    try:
        with h5py.File(path, "r") as f:
            fmt = f.attrs.get("format")
    except Exception:  # noqa: BLE001 - h5py raises OSError, KeyError, RuntimeError on corrupt files
        return False  # not a (readable) detection file; the HDF5 reader names what is wrong
    if isinstance(fmt, bytes):
        fmt = fmt.decode("utf-8", "replace")
    return fmt == DETECTION_FORMAT


def read_detection(path: str | os.PathLike) -> Detection:
    """Read a detection file written by :func:`write_detection` (``evedge detect``), verifying it.

    Raises
    ------
    EventFileError
        Naming the file and the attribute or dataset that is missing or
        malformed: a link or virtual dataset, a declared size the file does not
        store or the machine cannot hold, a checksum mismatch (a flipped byte),
        edge maps that are not boolean, any HDF5 read failure.
    """
    import h5py

    from .hdf5 import _check_tree, _checksums, _declared_bytes, _read, _reading, probe

    path = Path(path)
    if path.is_dir():
        raise EventFileError(f"{path}: is a folder, not a detection file")
    if not path.exists():
        raise EventFileError(f"{path}: no such file")
    probe(path)
    try:
        f = h5py.File(path, "r")
    except (OSError, KeyError, RuntimeError, ValueError) as err:
        raise EventFileError(f"{path}: not a readable HDF5 file: {err}") from None
    place: list = []
    with f, _reading(path, place):
        place[:] = ["attribute 'format'"]
        fmt = f.attrs.get("format")
        fmt = fmt.decode("utf-8", "replace") if isinstance(fmt, bytes) else fmt
        if fmt != DETECTION_FORMAT:
            raise EventFileError(f"{path}: not an evedge detection file (attribute format={fmt!r}, "
                                 f"expected {DETECTION_FORMAT!r})")
        version = f.attrs.get("format_version")
        if not (isinstance(version, (int, np.integer)) and int(version) == DETECTION_FORMAT_VERSION):
            raise EventFileError(f"{path}: detection format_version={version} is not supported "
                                 f"(this reader knows {DETECTION_FORMAT_VERSION})")
        sums = _checksums(f, path)
        place[:] = ["the file structure"]
        _check_tree(f, path, sums)
        try:
            size = SensorSize(int(f.attrs["sensor_width"]), int(f.attrs["sensor_height"]))
            metadata = json.loads(f.attrs.get("metadata", "{}"))
        except (KeyError, ValueError, TypeError, OverflowError) as err:
            raise EventFileError(f"{path}: bad sensor_width/sensor_height/metadata attribute: {err}") from None
        if not isinstance(metadata, dict):
            raise EventFileError(f"{path}: attribute 'metadata' must hold a JSON object")

        def dataset(name):
            obj = f.get(name)
            if not isinstance(obj, h5py.Dataset):
                raise EventFileError(f"{path}: {name!r} is missing or not a dataset")
            return obj

        wanted = []
        if "events" in f:
            wanted += [f"events/{c}" for c in ("x", "y", "t", "p")]
        if "lifetimes" in f:
            wanted += [f"lifetimes/{name}" for name, _ in LIFETIME_COLUMNS]
        if "edges" in f:
            wanted += ["edges/t_us", "edges/images"]
        sets = {name: dataset(name) for name in wanted}
        lengths = {name: ds.shape for name, ds in sets.items() if name.startswith(("events/", "lifetimes/"))}
        for name, shape in lengths.items():
            first = next(iter(lengths.values()))
            if len(shape) != 1:
                raise EventFileError(f"{path}: {name} has shape {shape}, expected one row per event")
            if name.startswith("lifetimes/") and shape != lengths.get(f"lifetimes/{LIFETIME_COLUMNS[0][0]}"):
                raise EventFileError(f"{path}: {name} has shape {shape}, expected "
                                     f"{lengths[f'lifetimes/{LIFETIME_COLUMNS[0][0]}']}")
            if shape != first and name.startswith("events/"):
                raise EventFileError(f"{path}: events/x, y, t, p have different lengths")
        if "edges/images" in sets and sets["edges/images"].dtype != np.bool_:
            raise EventFileError(f"{path}: edges/images has dtype {sets['edges/images'].dtype}, expected bool")
        if "edges/t_us" in sets and sets["edges/t_us"].dtype.kind not in "iu":
            raise EventFileError(f"{path}: edges/t_us has dtype {sets['edges/t_us'].dtype}, expected integers")
        declared = sum(_declared_bytes(ds, path, name) for name, ds in sets.items())
        short = memory_shortfall(2 * declared, "reading this detection file")
        if short:
            raise EventFileError(f"{path}: {short}")
        data = {name: _read(ds, path, name, sums, place) for name, ds in sets.items()}
        events = None
        if "events/x" in data:
            try:
                events = make_events(*(data[f"events/{c}"] for c in ("x", "y", "t", "p")))
            except (ValueError, TypeError) as err:
                raise EventFileError(f"{path}: events: {err}") from None
        lifetimes = None
        if "lifetimes/kept" in data:
            n = data["lifetimes/kept"].shape[0]
            if events is not None and n != events.shape[0]:
                raise EventFileError(f"{path}: {n} lifetime rows for {events.shape[0]} events")
            lifetimes = np.empty(n, dtype=list(LIFETIME_COLUMNS))
            for name, dtype in LIFETIME_COLUMNS:
                col = data[f"lifetimes/{name}"]
                if (dtype == np.bool_) != (col.dtype == np.bool_):
                    raise EventFileError(f"{path}: lifetimes/{name} has dtype {col.dtype}, expected {np.dtype(dtype)}")
                lifetimes[name] = col
        edges = None
        if "edges/t_us" in data:
            try:
                edges = Frames(data["edges/t_us"], data["edges/images"])
            except ValueError as err:
                raise EventFileError(f"{path}: edges: {err}") from None
            if len(edges) and edges.images.shape[1:] != size.shape:
                raise EventFileError(f"{path}: edges/images are {edges.images.shape[2]}x{edges.images.shape[1]}, "
                                     f"the sensor is {size.width}x{size.height}")
    return Detection(size, events, lifetimes, edges, metadata)
