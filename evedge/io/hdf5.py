"""The project's own HDF5 format: events, per-event truth, frames and edge maps.

Layout (``format="evedge"``, ``format_version=2``)::

    /events/{x, y, t, p}        int16, int16, int64 (us), bool; chunked, gzip
    /truth/<field>              one dataset per field of the structured truth (optional)
    /frames/{t_us, images}      int64, (n, height, width) uint8 or float in [0, 1] (optional)
    /edges/{t_us, images}       int64, (n, height, width) bool (optional)
    /maps/<name>/{t_us, images} per-frame maps (depth, flow, ...), numbers (optional)
    /imu/<field>                1-D columns of one length, t_us among them (optional)
    attrs: format, format_version, sensor_width, sensor_height, metadata (JSON),
           calibration (9 floats, optional),
           checksums (JSON: sha256 of every dataset and of the other attributes)

Writes are byte-for-byte deterministic: no timestamps (``track_times=False``),
creation order tracked, fixed chunking and compression, sorted JSON.

Reading trusts nothing in the file: every link must be a hard link inside it
(no soft, external or virtual datasets), every size a dataset declares is
checked against the bytes it stores and against the machine's memory before
anything is read, every dataset and attribute is checked against its sha256
in ``checksums`` (a flipped byte is an error naming the dataset, never a
different recording), and values are checked for their documented domain.
Every failure of HDF5 itself (a corrupt B-tree, a failing filter) is an
:class:`EventFileError` naming the file and the dataset; the structure is
first parsed in a forked child with a time limit (:func:`probe`), since a
corrupt header can make the library loop for minutes inside one call.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .._resources import memory_shortfall
from ..calibration import CameraCalibration
from ..events import Frames, Recording, SensorSize
from ._atomic import atomic_path, check_output_file
from ._checks import EventFileError, finish_events, locate_index
from .registry import Format, register_format

FORMAT_NAME = "evedge"
FORMAT_VERSION = 2  # 2: checksums; version 1 files had none and are refused
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
    """An evedge HDF5 file written atomically at ``path``, its header attributes set (shared by the writers).

    The file is built in memory, sealed with its checksums (:func:`seal`) and
    then written through a temp file: HDF5 can crash the process when a disk
    fills during its own writes (:func:`evedge.io._atomic.write_hdf5_atomic`).
    """
    import io

    import h5py

    check_output_file(path, caller)
    buf = io.BytesIO()
    with h5py.File(buf, "w", track_order=True) as f:
        f.attrs["format"] = fmt
        f.attrs["format_version"] = np.int64(version)
        f.attrs["sensor_width"] = np.int64(sensor_size.width)
        f.attrs["sensor_height"] = np.int64(sensor_size.height)
        f.attrs["metadata"] = metadata
        yield f
        seal(f)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(buf.getbuffer())


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
        ``path`` is a folder (``IsADirectoryError``), or the disk is full;
        nothing is written.

    Notes
    -----
    The file is built in memory and then written through a temp file
    (:func:`evedge.io._atomic.write_hdf5_atomic`): HDF5 can crash the process
    when a disk fills during its own writes.
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


#: gzip cannot expand data more than about 1032 times; a chunked, compressed dataset
#: declaring more bytes than this many times what it stores is lying.
_MAX_EXPANSION = 1100
_ATTRS = ("format", "format_version", "sensor_width", "sensor_height", "metadata", "calibration")
_HASH_BLOCK = 1 << 20  # rows hashed per read when streaming


def _canonical(value):
    if isinstance(value, np.ndarray):
        return [value.dtype.str, value.tolist()]
    if isinstance(value, np.generic):
        return [value.dtype.str, value.item()]
    if isinstance(value, bytes):
        return ["bytes", value.decode("latin-1")]
    return [type(value).__name__, value]


def _attrs_digest(attrs) -> str:
    content = {name: _canonical(attrs[name]) for name in _ATTRS if name in attrs}
    return hashlib.sha256(json.dumps(content, sort_keys=True, default=repr).encode()).hexdigest()


def _new_hash(dtype: np.dtype, shape: tuple):
    h = hashlib.sha256()
    h.update(f"{np.dtype(dtype).str}{tuple(int(n) for n in shape)}".encode())
    return h


def _bytes_of(data: np.ndarray) -> np.ndarray:
    """The bytes of ``data`` in C order as a uint8 view (copied only when ``data`` is not C-contiguous)."""
    return np.ascontiguousarray(data).reshape(-1).view(np.uint8)


def _data_digest(data: np.ndarray) -> str:
    h = _new_hash(data.dtype, data.shape)
    h.update(_bytes_of(data))  # the same bytes as ``tobytes()``, not copied
    return h.hexdigest()


#: Rows of a dataset hashed at a time by :func:`seal` (the digest is that of the whole array's bytes).
_SEAL_ROWS = 1 << 20


def _dataset_digest(ds) -> str:
    """:func:`_data_digest` of an HDF5 dataset, read ``_SEAL_ROWS`` rows at a time (no whole copy in memory)."""
    h = _new_hash(ds.dtype, ds.shape)
    if ds.ndim == 0 or ds.shape[0] == 0:
        h.update(_bytes_of(np.asarray(ds[()])))
        return h.hexdigest()
    step = max(1, _SEAL_ROWS // max(1, math.prod(ds.shape[1:])))
    for start in range(0, ds.shape[0], step):
        h.update(_bytes_of(ds[start:start + step]))
    return h.hexdigest()


def seal(f) -> None:
    """Store the sha256 of every dataset and of the attributes in ``f.attrs["checksums"]``.

    Parameters
    ----------
    f : h5py.File
        Open for writing; every dataset is read once.
    """
    import h5py

    sums = {}

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset):
            sums[name] = _dataset_digest(obj)

    f.visititems(visit)
    sums["@attrs"] = _attrs_digest(f.attrs)
    f.attrs["checksums"] = json.dumps(sums, sort_keys=True)


#: Longest time HDF5 may take to parse a file's structure (attributes, links, dataset headers).
_PROBE_TIMEOUT_S = 10.0


def _probe_structure(path: Path) -> None:
    """Touch every attribute, link and dataset header (in a child process: see :func:`probe`)."""
    import h5py

    try:
        with h5py.File(path, "r") as f:
            def walk(group):
                for key in group.attrs:
                    group.attrs[key]
                for name in group:
                    if isinstance(group.get(name, getlink=True), h5py.HardLink):
                        obj = group[name]
                        if isinstance(obj, h5py.Group):
                            walk(obj)
                        elif isinstance(obj, h5py.Dataset):
                            _ = (obj.shape, obj.dtype, obj.chunks, obj.id.get_storage_size())
                            for key in obj.attrs:
                                obj.attrs[key]

            walk(f)
    except Exception:  # noqa: BLE001 - errors are named by the reader itself; the probe looks for hangs
        return


def probe(path: Path) -> None:
    """Parse the file's structure in a forked child first, with a time limit.

    A corrupt count in an attribute or object header can make the HDF5
    library loop for minutes inside one call, which no Python code can
    interrupt; the child is killed instead and the file named.

    Raises
    ------
    EventFileError
        The structure takes longer than 10 s to parse, or HDF5 crashes on it.
    """
    from ._isolated import run_isolated

    run_isolated(path, "HDF5", _probe_structure, path, timeout_s=_PROBE_TIMEOUT_S)


@contextmanager
def _reading(path: Path, place: list):
    """Turn any failure of HDF5 (or of numpy on what it returned) into an EventFileError."""
    try:
        yield
    except EventFileError:
        raise
    except (OSError, KeyError, RuntimeError, ValueError, TypeError, IndexError, OverflowError) as err:
        where = place[0] if place else "the file structure"
        raise EventFileError(f"{path}: {where}: cannot be read (corrupt file?): {type(err).__name__}: {err}") from None


def _open(path: Path, place: list):
    import h5py

    if path.is_dir():
        raise EventFileError(f"{path}: is a folder, not an HDF5 file")
    probe(path)
    try:
        f = h5py.File(path, "r")
    except (OSError, KeyError, RuntimeError, ValueError) as err:
        raise EventFileError(f"{path}: not a readable HDF5 file: {err}") from err
    try:
        with _reading(path, place):
            place[:] = ["attribute 'format'"]
            fmt = f.attrs.get("format")
            if isinstance(fmt, bytes):
                fmt = fmt.decode("utf-8", "replace")
            if fmt != FORMAT_NAME:
                raise EventFileError(f"{path}: not an evedge HDF5 file (attribute format={fmt!r}, expected {FORMAT_NAME!r})")
            place[:] = ["attribute 'format_version'"]
            version = f.attrs.get("format_version")
            if not (isinstance(version, (int, np.integer)) and int(version) == FORMAT_VERSION):
                raise EventFileError(
                    f"{path}: format_version={version} is not supported (this reader knows {FORMAT_VERSION})")
            place[:] = ["attribute 'checksums'"]
            sums = _checksums(f, path)
    except BaseException:
        f.close()
        raise
    return f, sums


def _checksums(f, path: Path) -> dict:
    raw = f.attrs.get("checksums")
    if raw is None:
        raise EventFileError(f"{path}: attribute 'checksums' is missing (every evedge HDF5 file has it)")
    if isinstance(raw, bytes):
        raw = raw.decode("utf-8", "replace")
    try:
        sums = json.loads(raw) if isinstance(raw, str) else None
    except ValueError:
        sums = None
    if not isinstance(sums, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in sums.items()):
        raise EventFileError(f"{path}: attribute 'checksums' is corrupt (not a JSON object of digests)")
    if sums.get("@attrs") != _attrs_digest(f.attrs):
        raise EventFileError(
            f"{path}: the attributes ({', '.join(_ATTRS)}) do not match their checksum: the file is corrupt")
    return sums


def _check_tree(f, path: Path, sums: dict) -> None:
    """Every link hard, every dataset plain and listed in the checksums, nothing listed missing."""
    import h5py

    found = set()

    def walk(group, prefix):
        for name in group:
            full = f"{prefix}{name}"
            link = group.get(name, getlink=True)
            if not isinstance(link, h5py.HardLink):
                kind = "a soft link" if isinstance(link, h5py.SoftLink) else "an external link"
                raise EventFileError(f"{path}: {full!r} is {kind}; the evedge format holds only its own data")
            obj = group[name]
            if isinstance(obj, h5py.Group):
                walk(obj, full + "/")
            elif isinstance(obj, h5py.Dataset):
                if obj.is_virtual or obj.external:
                    raise EventFileError(f"{path}: dataset {full!r} keeps its data outside the file")
                found.add(full)
            else:
                raise EventFileError(f"{path}: {full!r} is neither a group nor a dataset")

    walk(f, "")
    listed = set(sums) - {"@attrs"}
    extra = sorted(found - listed)
    if extra:
        raise EventFileError(f"{path}: dataset {extra[0]!r} has no checksum: not written by write_recording")
    missing = sorted(listed - found)
    if missing:
        raise EventFileError(f"{path}: missing dataset {missing[0]!r} (listed in the file's checksums)")


def _declared_bytes(ds, path: Path, full: str) -> int:
    """Bytes ``ds`` declares, after checking that the file stores that much."""
    nbytes = math.prod(ds.shape) * ds.dtype.itemsize if ds.shape is not None else 0
    if nbytes == 0:
        return 0
    storage = ds.id.get_storage_size()
    if ds.chunks is None:
        if storage < nbytes:
            raise EventFileError(f"{path}: dataset {full!r} declares {nbytes} bytes ({ds.shape}) but stores {storage}")
        return nbytes
    expected = math.prod(-(-n // c) for n, c in zip(ds.shape, ds.chunks))
    stored = ds.id.get_num_chunks()
    if stored < expected:
        raise EventFileError(
            f"{path}: dataset {full!r} declares shape {ds.shape} ({expected} chunks) but stores {stored} chunks")
    if nbytes > _MAX_EXPANSION * max(storage, 1):
        raise EventFileError(
            f"{path}: dataset {full!r} declares {nbytes} bytes but stores only {storage}: more than compression allows")
    return nbytes


def _read(ds, path: Path, full: str, sums: dict, place: list) -> np.ndarray:
    place[:] = [f"dataset {full!r}"]
    data = ds[()]
    if _data_digest(np.asarray(data)) != sums.get(full):
        raise EventFileError(f"{path}: dataset {full!r} does not match its checksum: the file is corrupt")
    return np.asarray(data)


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


def _event_datasets(f, path: Path) -> tuple:
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
    return tuple(cols)


def _check_t(path: Path, t: np.ndarray, start: int = 0) -> None:
    if t.dtype == np.uint64 and t.size and int(t.max()) > np.iinfo(np.int64).max:
        # would wrap to negative int64 microseconds
        i = int(np.flatnonzero(t > np.iinfo(np.int64).max)[0])
        raise EventFileError(f"{path}: {locate_index(start + i)}: 'events/t' = {int(t[i])} exceeds int64 microseconds")


def _stack_datasets(f, path: Path, name: str, kind: str | None = None):
    """The ``t_us`` and ``images`` datasets of stack ``name`` (kind: frames, edges or map), dtypes checked."""
    if name not in f:
        return None
    kind = kind or name
    group = _group(f, path, name)
    full = group.name.strip("/")
    t_us, images = (_dataset_in(group, path, part) for part in ("t_us", "images"))
    if t_us.dtype.kind not in "iu":
        raise EventFileError(f"{path}: dataset '{full}/t_us' has dtype {t_us.dtype}, expected integer microseconds")
    code = images.dtype.kind + (str(images.dtype.itemsize) if images.dtype.kind != "b" else "")
    wanted = {"edges": ("b",), "frames": ("u1", "f4", "f8")}.get(kind)
    ok = code in wanted if wanted else images.dtype.kind in "biuf"
    if not ok:
        expect = {"edges": "bool edge maps", "frames": "uint8 or float32/float64 frames"}.get(kind, "numbers")
        raise EventFileError(f"{path}: dataset '{full}/images' has dtype {images.dtype}, expected {expect}")
    return t_us, images


def _stack(path: Path, name: str, t_us: np.ndarray, images: np.ndarray, sensor: SensorSize,
           kind: str | None = None) -> Frames:
    if t_us.dtype == np.uint64 and t_us.size and int(t_us.max()) > np.iinfo(np.int64).max:
        raise EventFileError(f"{path}: '{name}/t_us' exceeds int64 microseconds")
    try:
        stack = Frames(t_us, images)
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
    img = stack.images
    if (kind or name) == "frames" and img.dtype.kind == "f" and img.size:
        bad = np.flatnonzero(~np.isfinite(img.ravel()) | (img.ravel() < 0) | (img.ravel() > 1))
        if bad.size:
            k, rest = divmod(int(bad[0]), img.shape[1] * img.shape[2])
            yy, xx = divmod(rest, img.shape[2])
            raise EventFileError(
                f"{path}: '{name}/images' frame {k} pixel (x={xx}, y={yy}) is {float(img.ravel()[bad[0]])}, "
                f"expected a finite intensity in [0, 1]")
    return stack


def _check_truth(path: Path, name: str, col: np.ndarray) -> None:
    if col.dtype.kind not in "biuf":
        raise EventFileError(f"{path}: dataset 'truth/{name}' has dtype {col.dtype}, expected numbers or booleans")
    if name == "is_signal" and col.dtype.kind != "b":
        raise EventFileError(f"{path}: dataset 'truth/is_signal' has dtype {col.dtype}, expected bool")
    if name == "lifetime_us" and col.size:
        bad = np.flatnonzero(col <= 0)  # NaN (noise, no estimate) and inf (no motion along the normal) allowed
        if bad.size:
            raise EventFileError(f"{path}: {locate_index(int(bad[0]))}: 'truth/lifetime_us' = "
                                 f"{float(col[bad[0]])}, expected > 0 (or NaN/inf)")


def _check_truth_times(path: Path, t_us: np.ndarray, t_ns: np.ndarray) -> None:
    """``truth/t_ns`` is each event's instant in ns: integers within 500 ns of its ``t`` (us, rounded)."""
    if t_ns.dtype.kind not in "iu" or t_ns.ndim != 1:
        raise EventFileError(f"{path}: dataset 'truth/t_ns' has dtype {t_ns.dtype}, expected int64 nanoseconds")
    # both come from the same float64 seconds: a few of its ulps apart late in a long run
    tol = 500 + 2e9 * np.spacing(np.abs(t_ns.astype(np.float64)) / 1e9)
    bad = np.flatnonzero(np.abs(t_ns.astype(np.float64) - t_us.astype(np.float64) * 1000) > tol)
    if bad.size:
        i = int(bad[0])
        raise EventFileError(f"{path}: {locate_index(i)}: 'truth/t_ns' = {int(t_ns[i])} ns is not the event's "
                             f"time t = {int(t_us[i])} us")


def read_hdf5(path: str | os.PathLike, *, sensor_size: SensorSize | None = None, sort: bool = False) -> Recording:
    """Read an evedge HDF5 file written by :func:`write_recording`, verifying it.

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
        a link or a virtual dataset, a declared size the file does not store
        or the machine cannot hold, a checksum mismatch (named), inconsistent
        lengths, values outside their domain (frames finite in [0, 1], edge
        maps boolean, increasing frame times, lifetimes > 0), coordinates
        outside the sensor, unsorted timestamps, any HDF5 read failure.

    Examples
    --------
    >>> from evedge.events import Recording, SensorSize, make_events
    >>> import tempfile, pathlib
    >>> rec = Recording(make_events([1, 2], [0, 1], [5, 9], [True, False]), SensorSize(4, 3))
    >>> path = write_recording(pathlib.Path(tempfile.mkdtemp()) / "r.h5", rec)
    >>> read_hdf5(path).events["t"].tolist()
    [5, 9]
    """
    path = Path(path)
    place: list = []
    f, sums = _open(path, place)
    with f, _reading(path, place):
        place[:] = ["the file structure"]
        _check_tree(f, path, sums)
        sensor = _sensor(f, path)
        if sensor_size is not None and sensor_size != sensor:
            raise EventFileError(
                f"{path}: sensor size {sensor_size.width}x{sensor_size.height} was given but the file says "
                f"{sensor.width}x{sensor.height}"
            )
        columns = _event_datasets(f, path)
        n = columns[0].shape[0]
        truth_sets = []
        if "truth" in f:
            group = _group(f, path, "truth")
            for name in group:
                ds = _dataset_in(group, path, name)
                if ds.ndim == 0:
                    raise EventFileError(f"{path}: dataset 'truth/{name}' is a scalar, expected one row per event")
                if ds.shape[0] != n:
                    raise EventFileError(f"{path}: dataset 'truth/{name}' has {ds.shape[0]} rows, there are {n} events")
                truth_sets.append((name, ds))
        stacks = {name: _stack_datasets(f, path, name) for name in ("frames", "edges")}
        if "maps" in f:
            group = _group(f, path, "maps")
            for name in group:
                stacks[f"maps/{name}"] = _stack_datasets(group, path, name, "map")
        imu_sets = []
        if "imu" in f:
            group = _group(f, path, "imu")
            imu_sets = [(name, _dataset_in(group, path, name)) for name in group]
            if (not imu_sets or "t_us" not in dict(imu_sets)
                    or any(ds.ndim != 1 or ds.shape != imu_sets[0][1].shape for _, ds in imu_sets)):
                raise EventFileError(f"{path}: group 'imu' needs 1-D datasets of one length, t_us among them")
        everything = [(ds.name.strip("/"), ds) for ds in columns] + [(f"truth/{k}", ds) for k, ds in truth_sets]
        everything += [(ds.name.strip("/"), ds) for pair in stacks.values() if pair for ds in pair]
        everything += [(f"imu/{k}", ds) for k, ds in imu_sets]
        declared = sum(_declared_bytes(ds, path, full) for full, ds in everything)
        # the columns, the event array built from them and the truth table built from its columns
        short = memory_shortfall(2 * declared + 16 * n, f"reading {n} events with their truth and frames")
        if short:
            raise EventFileError(f"{path}: {short}")
        x, y, t, p = (_read(ds, path, full, sums, place) for full, ds in everything[:4])
        _check_t(path, t)
        place[:] = ["attribute 'metadata'"]
        try:
            metadata = json.loads(f.attrs.get("metadata", "{}"))
        except (TypeError, ValueError) as err:
            raise EventFileError(f"{path}: attribute 'metadata' is not JSON: {err}") from err
        if not isinstance(metadata, dict):
            raise EventFileError(f"{path}: attribute 'metadata' must hold a JSON object, got {type(metadata).__name__}")
        truth = None
        if truth_sets:
            fields = []
            for name, ds in truth_sets:
                col = _read(ds, path, f"truth/{name}", sums, place)
                _check_truth(path, name, col)
                fields.append((name, col))
            truth = np.empty(n, dtype=[(k, c.dtype, c.shape[1:]) for k, c in fields])
            for name, col in fields:
                truth[name] = col
            if "t_ns" in truth.dtype.names:
                _check_truth_times(path, t, truth["t_ns"])
        frames = edges = None
        maps = {}
        for name, pair in stacks.items():
            if pair is not None:
                t_us, images = (_read(ds, path, f"{name}/{part}", sums, place)
                                for ds, part in zip(pair, ("t_us", "images")))
                kind = "map" if name.startswith("maps/") else name
                stack = _stack(path, name, t_us, images, sensor, kind)
                if kind == "map":
                    maps[name.split("/", 1)[1]] = stack
                elif name == "frames":
                    frames = stack
                else:
                    edges = stack
        imu = None
        if imu_sets:
            cols = [(name, _read(ds, path, f"imu/{name}", sums, place)) for name, ds in imu_sets]
            imu = np.empty(cols[0][1].shape[0], dtype=[(n, c.dtype) for n, c in cols])
            for name, col in cols:
                imu[name] = col
        calibration = None
        if "calibration" in f.attrs:
            place[:] = ["attribute 'calibration'"]
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
        As :func:`read_hdf5`. The event columns' checksums are verified in a
        first streaming pass (memory bounded by ``chunk_size``), so no chunk
        of a corrupt file is ever yielded. Each chunk is checked against the
        sensor and for time order (also across chunk boundaries); no ``sort``
        option.

    Examples
    --------
    >>> from evedge.events import Recording, SensorSize, make_events
    >>> import tempfile, pathlib
    >>> rec = Recording(make_events([1, 2, 3], [0, 1, 2], [5, 9, 9], [1, 0, 1]), SensorSize(4, 3))
    >>> path = write_recording(pathlib.Path(tempfile.mkdtemp()) / "r.h5", rec)
    >>> [c.size for c in iter_hdf5_events(path, chunk_size=2)]
    [2, 1]
    """
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, (int, np.integer)) or chunk_size < 1:
        raise ValueError(f"iter_hdf5_events: chunk_size must be a positive integer, got {chunk_size!r}")
    path = Path(path)
    place: list = []
    f, sums = _open(path, place)
    with f:
        with _reading(path, place):
            place[:] = ["the file structure"]
            _check_tree(f, path, sums)
            sensor = _sensor(f, path)
            columns = _event_datasets(f, path)
            n = columns[0].shape[0]
            for ds in columns:
                full = ds.name.strip("/")
                _declared_bytes(ds, path, full)
                place[:] = [f"dataset {full!r}"]
                h = _new_hash(ds.dtype, ds.shape)
                for start in range(0, n, max(chunk_size, _HASH_BLOCK)):
                    h.update(_bytes_of(ds[start:start + max(chunk_size, _HASH_BLOCK)]))
                if h.hexdigest() != sums.get(full):
                    raise EventFileError(f"{path}: dataset {full!r} does not match its checksum: the file is corrupt")
        last_t = None
        for start in range(0, n, chunk_size):
            with _reading(path, place):
                x, y, t, p = (ds[start:start + chunk_size] for ds in columns)
            _check_t(path, t, start)
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
