"""One entry point for every event file: :func:`read_events`, dispatching through the format registry."""

from __future__ import annotations

import os
from pathlib import Path

from ..events import Recording, SensorSize
from ._checks import EventFileError
from .registry import detect_format, get_format

__all__ = ["detect_format", "read_events"]


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
        A file or folder of any registered format (``evedge.io.formats()``):
        Event Camera Dataset folder or text, MATLAB ``.mat`` (Mueggler et
        al.), evedge ``.h5``, AEDAT 4, AEDAT 2.0/3.1 (``.aedat``), Prophesee
        EVT 2/EVT 3 (``.raw``) and ``.dat``, Event Stream ``.es``.
    sensor_size : SensorSize or str, optional
        ``SensorSize(240, 180)`` or ``"240x180"``/``"davis240"``. Used when the
        file does not say; when the file does say (frames, header, HDF5
        attributes, AEDAT4 description), a different value is an error.
    format : str, optional
        A registered format name (``"evt3"``, ``"aedat2"``, ...): skip detection.
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
        and the line, event index, byte offset or variable.

    Examples
    --------
    >>> from evedge.io import read_events
    >>> rec = read_events("recording.raw", sensor_size="640x480")  # doctest: +SKIP
    """
    if isinstance(sensor_size, str):
        sensor_size = SensorSize.parse(sensor_size)
    elif sensor_size is not None and not isinstance(sensor_size, SensorSize):
        raise TypeError(f"read_events: sensor_size must be a SensorSize or 'WxH' string, got {sensor_size!r}")
    path = Path(path)
    if format is None:
        format = detect_format(path)
    else:
        try:
            get_format(format, need="read")
        except ValueError as err:
            raise ValueError(f"read_events: {err}") from None
        if not path.exists():
            raise EventFileError(f"{path}: no such file or directory")
    if format == "hdf5":
        # an evedge detect output is HDF5 too; its reader lives beside the detection file format
        from .detection import is_detection_file

        if is_detection_file(path):
            return _detection_recording(path, sensor_size, bool(sort))
    return get_format(format).read(path, sensor_size=sensor_size, sort=bool(sort))


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
