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
    return get_format(format).read(path, sensor_size=sensor_size, sort=bool(sort))
