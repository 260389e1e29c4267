"""Event Stream files (``.es``, Marcireau et al.), through faery.

The header is the magic ``Event Stream``, three version bytes, an event
type byte (0 generic, 1 DVS, 2 ATIS, 3 colour) and, for DVS and ATIS, the
sensor width and height (uint16 little-endian): the sensor size always comes
from the file. ATIS exposure measurements are dropped (faery keeps the
change detections). The format stores times relative to the recording's
start; y is stored bottom-up and faery flips it to image rows.

References
----------
.. [1] A. Marcireau, "Event Stream" specification, github.com/neuromorphic-paris/event_stream.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..events import Recording, SensorSize
from ._checks import EventFileError
from ._native import faery_decode, faery_encode
from .prophesee import _recording
from .registry import Format, register_format

MAGIC = b"Event Stream"
_TYPES = {0: "generic", 1: "dvs", 2: "atis", 3: "color"}


def read_es(path: str | os.PathLike, *, sensor_size: SensorSize | None = None, sort: bool = False) -> Recording:
    """Read the DVS or ATIS events of an Event Stream ``.es`` file.

    Parameters
    ----------
    path : path-like
    sensor_size : SensorSize, optional
        Must match the header when given.
    sort : bool
        Sort by time (stable) instead of raising on decreasing timestamps.

    Returns
    -------
    Recording

    Raises
    ------
    EventFileError
        Wrong magic, a header shorter than 20 bytes, an event type other than
        DVS/ATIS, a size mismatch, or data the decoder rejects.
    """
    path = Path(path)
    with open(path, "rb") as fh:
        head = fh.read(20)
    if not head.startswith(MAGIC):
        raise EventFileError(f"{path}: not an Event Stream file (the first bytes are {head[:12]!r}, not {MAGIC!r})")
    if len(head) < 16:
        raise EventFileError(f"{path}: the Event Stream header ends at byte {len(head)} (truncated file)")
    kind = _TYPES.get(head[15], f"unknown ({head[15]})")
    if kind not in ("dvs", "atis"):
        raise EventFileError(f"{path}: byte offset 15: Event Stream type {kind}; only dvs and atis hold x, y events")
    if len(head) < 20:
        raise EventFileError(f"{path}: the Event Stream header ends at byte {len(head)}, before the sensor size (truncated file)")
    try:
        sensor = SensorSize(int.from_bytes(head[16:18], "little"), int.from_bytes(head[18:20], "little"))
    except ValueError as err:
        raise EventFileError(f"{path}: byte offset 16: impossible sensor size: {err}") from None
    if sensor_size is not None and sensor_size != sensor:
        raise EventFileError(f"{path}: sensor size {sensor_size.width}x{sensor_size.height} was given but the "
                             f"Event Stream header says {sensor.width}x{sensor.height}")
    raw = faery_decode(path, "Event Stream", "es")
    extra = {"es_version": ".".join(str(b) for b in head[12:15]), "es_type": kind}
    return _recording(path, raw["x"], raw["y"], raw["t"], raw["on"], sensor, "file header", "es", sort, extra)


def write_es(path: str | os.PathLike, recording: Recording) -> Path:
    """Write the events as an Event Stream DVS file through faery, atomically (events only)."""
    return faery_encode(Path(path), recording, "Event Stream", "es", zero_t0=False, who="write_es")


register_format(Format("es", "Event Stream (.es, DVS/ATIS)", extensions=(".es",), read=read_es, write=write_es,
                       sniff=lambda head: head.startswith(MAGIC)))
