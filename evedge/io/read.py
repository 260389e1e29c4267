"""One entry point for every event file: :func:`read_events`."""

from __future__ import annotations

import os
from pathlib import Path

from ..events import Recording, SensorSize
from ._checks import EventFileError

#: format name -> file extensions
FORMATS = {
    "ecd": (".txt",),
    "mat": (".mat",),
    "hdf5": (".h5", ".hdf5"),
    "aedat4": (".aedat4",),
}
_MAGIC = {
    b"\x89HDF\r\n\x1a\n": "hdf5",
    b"#!AER-DAT4.0": "aedat4",
    b"MATLAB 5.0 MAT-file": "mat",
}


def detect_format(path: str | os.PathLike) -> str:
    """Name the format of ``path``: a folder is ECD, else by extension, else by magic bytes.

    Parameters
    ----------
    path : path-like
        A file or an Event Camera Dataset folder.

    Returns
    -------
    str
        A key of :data:`FORMATS`: ``"ecd"``, ``"mat"``, ``"hdf5"`` or ``"aedat4"``.

    Raises
    ------
    EventFileError
        When the path does not exist or the format cannot be told.
    """
    path = Path(path)
    if path.is_dir():
        return "ecd"
    if not path.exists():
        raise EventFileError(f"{path}: no such file or directory")
    suffix = path.suffix.lower()
    for name, extensions in FORMATS.items():
        if suffix in extensions:
            return name
    with open(path, "rb") as fh:
        head = fh.read(32)
    for magic, name in _MAGIC.items():
        if head.startswith(magic):
            return name
    known = ", ".join(f"{n} ({'/'.join(e)})" for n, e in FORMATS.items())
    raise EventFileError(
        f"{path}: unknown event file type (extension {suffix or 'none'!r}, content not recognised); "
        f"supported: {known}, or an Event Camera Dataset folder; pass format=... to choose"
    )


def read_events(
    path: str | os.PathLike,
    *,
    sensor_size: SensorSize | str | None = None,
    format: str | None = None,
    sort: bool = False,
) -> Recording:
    """Read an event recording, choosing the reader by folder, extension or content.

    Parameters
    ----------
    path : path-like
        An Event Camera Dataset folder (``events.txt`` [+ ``images.txt`` +
        ``images/``]) or text file, a MATLAB ``.mat`` (Mueggler et al.), an
        evedge ``.h5`` file, or an ``.aedat4`` file.
    sensor_size : SensorSize or str, optional
        ``SensorSize(240, 180)`` or ``"240x180"``/``"davis240"``. Used when the
        file does not say (ECD text without frames, ``.mat``); when the file
        does say (frames, HDF5 attributes, AEDAT4 description), a different
        value is an error.
    format : {"ecd", "mat", "hdf5", "aedat4"}, optional
        Skip detection.
    sort : bool
        Sort by time, stably, when the file's timestamps decrease (recorded as
        ``metadata["sorted_on_load"]``); by default that is an error.

    Returns
    -------
    Recording
        ``metadata`` records ``source``, ``format`` and ``sensor_size_from``.

    Raises
    ------
    EventFileError
        (a ``ValueError``) on any malformed input; the message names the file
        and the line, event index or variable.
    """
    from .aedat4 import read_aedat4
    from .ecd import read_ecd
    from .hdf5 import read_hdf5
    from .matlab import read_mat

    readers = {"ecd": read_ecd, "mat": read_mat, "hdf5": read_hdf5, "aedat4": read_aedat4}
    if isinstance(sensor_size, str):
        sensor_size = SensorSize.parse(sensor_size)
    elif sensor_size is not None and not isinstance(sensor_size, SensorSize):
        raise TypeError(f"read_events: sensor_size must be a SensorSize or 'WxH' string, got {sensor_size!r}")
    path = Path(path)
    if format is None:
        format = detect_format(path)
    elif format not in readers:
        raise ValueError(f"read_events: format={format!r}, expected one of {sorted(readers)}")
    elif not path.exists():
        raise EventFileError(f"{path}: no such file or directory")
    if format == "hdf5":
        from .detection import is_detection_file

        if is_detection_file(path):
            return _detection_recording(path, sensor_size, bool(sort))
    return readers[format](path, sensor_size=sensor_size, sort=bool(sort))


def _detection_recording(path: Path, sensor_size, sort: bool) -> Recording:
    """The events of an ``evedge detect`` output file, with its edge frames and metadata."""
    from ..events import sort_events
    from .detection import read_detection

    det = read_detection(path)
    if sensor_size is not None and sensor_size != det.sensor_size:
        raise EventFileError(f"{path}: the file says sensor {det.sensor_size.width}x{det.sensor_size.height}, "
                             f"sensor_size={sensor_size.width}x{sensor_size.height} was given")
    if det.events is None:
        src = det.metadata.get("source", {})
        raise EventFileError(f"{path}: this detection file holds no events, only the digest of its source "
                             f"{src.get('path')!r} (sha256 {src.get('sha256')}); read that file instead")
    events = det.events
    meta = dict(det.metadata, source=str(path), format="evedge-detection", sensor_size_from="file attributes",
                detection_source=det.metadata.get("source"))
    if sort:
        import numpy as np

        meta["sorted_on_load"] = bool(np.any(np.diff(events["t"]) < 0))
        events = sort_events(events)
    return Recording(events, det.sensor_size, edges=det.edges, metadata=meta)
