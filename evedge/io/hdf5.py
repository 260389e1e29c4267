"""The project's own HDF5 format: events, per-event truth, frames and edge maps.

Layout (``format="evedge"``, ``format_version=1``)::

    /events/{x, y, t, p}        int16, int16, int64 (us), bool; chunked, gzip
    /truth/<field>              one dataset per field of the structured truth (optional)
    /frames/{t_us, images}      int64, (n, height, width) (optional)
    /edges/{t_us, images}       int64, (n, height, width) bool (optional)
    attrs: format, format_version, sensor_width, sensor_height, metadata (JSON)

Writes are byte-for-byte deterministic: no timestamps (``track_times=False``),
creation order tracked, fixed chunking and compression, sorted JSON.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..calibration import CameraCalibration
from ..events import Frames, Recording, SensorSize
from ._atomic import atomic_path, check_output_file
from ._checks import EventFileError, finish_events, locate_index
from .registry import Format, register_format

FORMAT_NAME = "evedge"
FORMAT_VERSION = 1
_EVENT_CHUNK = 1 << 18  # 256 k events per chunk: ~0.5-2 MB per column, fast gzip
_GZIP_LEVEL = 4


def _dataset(group, name: str, data: np.ndarray, chunks) -> None:
    options = {"track_times": False}
    if data.size:  # HDF5 cannot chunk an empty dataset without maxshape; keep it contiguous
        options.update(chunks=chunks, compression="gzip", compression_opts=_GZIP_LEVEL, shuffle=True)
    # flush now: HDF5 writes a chunk (and allocates its file space) when the dataset's chunk cache is
    # flushed, i.e. when Python frees the dataset object; a reference cycle freed later by the garbage
    # collector would then move chunks in the file, and the same recording would not give the same bytes
    group.create_dataset(name, data=data, **options).flush()


def _write_stack(parent, name: str, stack: Frames) -> None:
    group = parent.create_group(name, track_order=True)
    _dataset(group, "t_us", stack.t_us, (max(1, min(len(stack), 4096)),))
    _dataset(group, "images", stack.images, (1,) + stack.images.shape[1:])


def _metadata_json(metadata, what: str) -> str:
    """``metadata`` as the sorted JSON stored in a file's ``metadata`` attribute; ``what`` names it in the error."""
    try:
        return json.dumps(metadata, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{what} is not JSON-serialisable: {err}") from err


@contextmanager
def _new_file(path: Path, caller: str, fmt: str, version: int, sensor_size: SensorSize, metadata: str):
    """An evedge HDF5 file written atomically at ``path``, its header attributes set (shared by the writers)."""
    import h5py

    check_output_file(path, caller)
    with atomic_path(path) as tmp:
        with h5py.File(tmp, "w", track_order=True) as f:
            f.attrs["format"] = fmt
            f.attrs["format_version"] = np.int64(version)
            f.attrs["sensor_width"] = np.int64(sensor_size.width)
            f.attrs["sensor_height"] = np.int64(sensor_size.height)
            f.attrs["metadata"] = metadata
            yield f


def write_recording(path: str | os.PathLike, recording: Recording) -> Path:
    """Write a recording to the evedge HDF5 format (temp file, then rename).

    Parameters
    ----------
    path : path-like
        Usually ``*.h5``.
    recording : Recording
        Its ``metadata`` must be JSON-serialisable.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    TypeError
        ``recording`` is not a :class:`Recording`, or its truth is not structured.
    ValueError
        ``metadata`` is not JSON-serialisable.
    OSError
        The folder of ``path`` does not exist (``FileNotFoundError``) or
        ``path`` is a folder (``IsADirectoryError``); nothing is written.
    """
    if not isinstance(recording, Recording):
        raise TypeError(f"write_recording: expected a Recording, got {type(recording).__name__}")
    metadata = _metadata_json(recording.metadata, "write_recording: Recording.metadata")
    path = Path(path)
    with _new_file(path, "write_recording", FORMAT_NAME, FORMAT_VERSION, recording.sensor_size, metadata) as f:
        if recording.calibration is not None:
            # fx fy cx cy k1 k2 p1 p2 k3, as in calib.txt
            f.attrs["calibration"] = np.asarray(recording.calibration.as_list(), dtype=np.float64)
        ev = recording.events
        group = f.create_group("events", track_order=True)
        chunk = (max(1, min(ev.size, _EVENT_CHUNK)),)
        for name in ("x", "y", "t", "p"):
            _dataset(group, name, np.ascontiguousarray(ev[name]), chunk)
        if recording.truth is not None:
            truth = recording.truth
            if truth.dtype.names is None:
                raise TypeError("write_recording: Recording.truth must be a structured array")
            group = f.create_group("truth", track_order=True)
            for name in truth.dtype.names:
                col = np.ascontiguousarray(truth[name])
                _dataset(group, name, col, (max(1, min(truth.size, _EVENT_CHUNK)),) + col.shape[1:])
        if recording.frames is not None:
            _write_stack(f, "frames", recording.frames)
        if recording.edges is not None:
            _write_stack(f, "edges", recording.edges)
        if recording.maps:
            group = f.create_group("maps", track_order=True)
            for name, stack in recording.maps.items():
                _write_stack(group, name, stack)
        if recording.imu is not None:
            group = f.create_group("imu", track_order=True)
            for name in recording.imu.dtype.names:
                _dataset(group, name, np.ascontiguousarray(recording.imu[name]), (max(1, min(recording.imu.size, 4096)),))
    return path


def _open(path: Path):
    import h5py

    if path.is_dir():
        raise EventFileError(f"{path}: is a folder, not an HDF5 file")
    try:
        f = h5py.File(path, "r")
    except OSError as err:
        raise EventFileError(f"{path}: not a readable HDF5 file: {err}") from err
    fmt = f.attrs.get("format")
    if isinstance(fmt, bytes):
        fmt = fmt.decode()
    if fmt != FORMAT_NAME:
        f.close()
        raise EventFileError(f"{path}: not an evedge HDF5 file (attribute format={fmt!r}, expected {FORMAT_NAME!r})")
    version = f.attrs.get("format_version")
    if not (isinstance(version, (int, np.integer)) and int(version) == FORMAT_VERSION):
        f.close()
        raise EventFileError(f"{path}: format_version={version} is not supported (this reader knows {FORMAT_VERSION})")
    return f


def _group(f, path: Path, name: str):
    import h5py

    obj = f.get(name)
    if obj is None:
        raise EventFileError(f"{path}: missing group {name!r} in the evedge HDF5 file")
    if not isinstance(obj, h5py.Group):
        raise EventFileError(f"{path}: {name!r} is not a group")
    return obj


def _dataset_in(group, path: Path, name: str):
    import h5py

    obj = group.get(name)
    full = f"{group.name.strip('/')}/{name}"
    if obj is None:
        raise EventFileError(f"{path}: missing dataset {full!r}")
    if not isinstance(obj, h5py.Dataset):
        raise EventFileError(f"{path}: {full!r} is not a dataset")
    return obj


def _sensor(f, path: Path) -> SensorSize:
    values = []
    for name in ("sensor_width", "sensor_height"):
        if name not in f.attrs:
            raise EventFileError(f"{path}: missing attribute {name!r}")
        value = f.attrs[name]
        # int() would truncate 10.5 to 10 and read '10' as text: accept integers only
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
            raise EventFileError(f"{path}: attribute {name!r} must be an integer, got {value!r}")
        values.append(int(value))
    try:
        return SensorSize(*values)
    except (TypeError, ValueError) as err:
        raise EventFileError(f"{path}: bad sensor size attributes: {err}") from err


def _columns(f, path: Path, start: int = 0, stop: int | None = None) -> tuple[np.ndarray, ...]:
    group = _group(f, path, "events")
    n = None
    cols = []
    for name in ("x", "y", "t", "p"):
        ds = _dataset_in(group, path, name)
        if ds.ndim != 1:
            raise EventFileError(f"{path}: dataset 'events/{name}' has shape {ds.shape}, expected 1-D")
        if n is not None and ds.shape[0] != n:
            raise EventFileError(f"{path}: dataset 'events/{name}' has {ds.shape[0]} rows, 'events/x' has {n}")
        n = ds.shape[0]
        kinds = "b" if name == "p" else "iu"
        if ds.dtype.kind not in kinds:
            raise EventFileError(f"{path}: dataset 'events/{name}' has dtype {ds.dtype}, expected {'bool' if name == 'p' else 'integers'}")
        cols.append(ds)
    out = tuple(ds[start:stop] for ds in cols)
    t = out[2]
    if t.dtype == np.uint64 and t.size and int(t.max()) > np.iinfo(np.int64).max:
        # would wrap to negative int64 microseconds
        i = int(np.flatnonzero(t > np.iinfo(np.int64).max)[0])
        raise EventFileError(f"{path}: {locate_index(start + i)}: 'events/t' = {int(t[i])} exceeds int64 microseconds")
    return out


def _stack(f, path: Path, name: str, sensor: SensorSize) -> Frames | None:
    if name not in f:
        return None
    group = _group(f, path, name)
    t_us, images = (_dataset_in(group, path, part) for part in ("t_us", "images"))
    try:
        stack = Frames(t_us[()], images[()])
    except ValueError as err:
        raise EventFileError(f"{path}: group {name!r}: {err}") from err
    dec = np.flatnonzero(stack.t_us[1:] < stack.t_us[:-1])
    if dec.size:
        raise EventFileError(f"{path}: '{name}/t_us' decreases at frame {int(dec[0]) + 1}")
    if stack.images.shape[1:] != sensor.shape:
        raise EventFileError(
            f"{path}: '{name}/images' are {stack.images.shape[2]}x{stack.images.shape[1]}, the sensor is "
            f"{sensor.width}x{sensor.height}"
        )
    return stack


def read_hdf5(path: str | os.PathLike, *, sensor_size: SensorSize | None = None, sort: bool = False) -> Recording:
    """Read an evedge HDF5 file written by :func:`write_recording`.

    Parameters
    ----------
    path : path-like
    sensor_size : SensorSize, optional
        Must match the file's ``sensor_width`` x ``sensor_height`` when given.
    sort : bool
        Sort by time (stable) instead of raising on decreasing timestamps
        (truth rows follow their events).

    Returns
    -------
    Recording
        Stored metadata, updated with ``source``, ``format`` (``"evedge-hdf5"``)
        and ``sensor_size_from`` (``"file metadata"``).

    Raises
    ------
    EventFileError
        Not HDF5, not the evedge format, missing group/dataset (named),
        inconsistent lengths, coordinates outside the sensor, unsorted timestamps.
    """
    path = Path(path)
    f = _open(path)
    with f:
        sensor = _sensor(f, path)
        if sensor_size is not None and sensor_size != sensor:
            raise EventFileError(
                f"{path}: sensor size {sensor_size.width}x{sensor_size.height} was given but the file says "
                f"{sensor.width}x{sensor.height}"
            )
        x, y, t, p = _columns(f, path)
        try:
            metadata = json.loads(f.attrs.get("metadata", "{}"))
        except (TypeError, ValueError) as err:
            raise EventFileError(f"{path}: attribute 'metadata' is not JSON: {err}") from err
        if not isinstance(metadata, dict):
            raise EventFileError(f"{path}: attribute 'metadata' must hold a JSON object, got {type(metadata).__name__}")
        truth = None
        if "truth" in f:
            group = _group(f, path, "truth")
            fields = []
            for name in group:
                ds = _dataset_in(group, path, name)
                if ds.ndim == 0:
                    raise EventFileError(f"{path}: dataset 'truth/{name}' is a scalar, expected one row per event")
                if ds.shape[:1] != x.shape:
                    raise EventFileError(f"{path}: dataset 'truth/{name}' has {ds.shape[0]} rows, there are {x.size} events")
                fields.append((name, ds[()]))
            truth = np.empty(x.size, dtype=[(n, c.dtype, c.shape[1:]) for n, c in fields])
            for name, col in fields:
                truth[name] = col
        frames = _stack(f, path, "frames", sensor)
        edges = _stack(f, path, "edges", sensor)
        maps = {}
        if "maps" in f:
            group = _group(f, path, "maps")
            maps = {name: _stack(group, path, name, sensor) for name in group}
        imu = None
        if "imu" in f:
            group = _group(f, path, "imu")
            cols = [(name, _dataset_in(group, path, name)[()]) for name in group]
            if not cols or any(c.ndim != 1 or c.shape != cols[0][1].shape for _, c in cols) or "t_us" not in dict(cols):
                raise EventFileError(f"{path}: group 'imu' needs 1-D datasets of one length, t_us among them")
            imu = np.empty(cols[0][1].shape[0], dtype=[(n, c.dtype) for n, c in cols])
            for name, col in cols:
                imu[name] = col
        calibration = None
        if "calibration" in f.attrs:
            try:
                calibration = CameraCalibration(*np.asarray(f.attrs["calibration"], dtype=np.float64).reshape(9).tolist())
            except (TypeError, ValueError) as err:
                raise EventFileError(f"{path}: attribute 'calibration' is not 9 numbers fx fy cx cy k1 k2 p1 p2 k3: {err}") from None
    order = None
    if sort:
        order = np.argsort(t, kind="stable")
    events, was_sorted = finish_events(path, x, y, t, p, sensor, "file metadata", locate_index, sort)
    if was_sorted and truth is not None:
        truth = truth[order]
    metadata.update({"source": str(path), "format": "evedge-hdf5", "sensor_size_from": "file metadata"})
    if was_sorted:
        metadata["sorted_on_load"] = True
    return Recording(events, sensor, frames=frames, truth=truth, edges=edges, metadata=metadata,
                     calibration=calibration, maps=maps, imu=imu)


def iter_hdf5_events(path: str | os.PathLike, chunk_size: int = 1_000_000) -> Iterator[np.ndarray]:
    """Stream the events of an evedge HDF5 file in chunks of at most ``chunk_size``.

    Parameters
    ----------
    path : path-like
        An evedge HDF5 file (:func:`write_recording`).
    chunk_size : int
        Most events per chunk (>= 1).

    Yields
    ------
    numpy.ndarray
        Events of :data:`evedge.events.EVENT_DTYPE`, in file order.

    Raises
    ------
    EventFileError
        As :func:`read_hdf5`. Each chunk is checked against the sensor and
        for time order (also across chunk boundaries); no ``sort`` option.
    """
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer)) or chunk_size < 1:
        raise ValueError(f"iter_hdf5_events: chunk_size must be a positive integer, got {chunk_size!r}")
    path = Path(path)
    f = _open(path)
    with f:
        sensor = _sensor(f, path)
        n = _dataset_in(_group(f, path, "events"), path, "t").shape[0]
        last_t = None
        for start in range(0, n, chunk_size):
            x, y, t, p = _columns(f, path, start, start + chunk_size)
            if last_t is not None and t.size and t[0] < last_t:
                raise EventFileError(f"{path}: event index {start}: timestamps are not sorted (t={int(t[0])} us after {last_t} us)")

            def locate(i: int, start=start) -> str:
                return locate_index(start + i)

            events, _ = finish_events(path, x, y, t, p, sensor, "file metadata", locate, False)
            last_t = int(t[-1]) if t.size else last_t
            yield events



register_format(Format(
    "hdf5", "evedge HDF5 (events, truth, frames, edge maps, metadata)",
    extensions=(".h5", ".hdf5"), read=read_hdf5, write=write_recording,
    sniff=lambda head: head.startswith(b"\x89HDF\r\n\x1a\n"), holds=("frames", "truth", "edges"),
))
