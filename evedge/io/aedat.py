"""AEDAT 2.0 (jAER) and AEDAT 3.1 (cAER) files, ``.aedat``, decoded with numpy.

No maintained Python package decodes these (faery and ``aedat`` read AEDAT
4 only; tonic's readers assume a camera and skip all checks), and both are
short, documented layouts:

* **AEDAT 2.0**: ``#`` header lines (the first ``#!AER-DAT2.0``), then
  big-endian pairs of uint32 address and int32 timestamp (us). The address
  layout depends on the camera: DVS128 (bit 0 polarity, bits 1-7 x, bits
  8-14 y, bit 15 external) or DAVIS (bit 31 APS/IMU, bits 22-30 y, bits
  12-21 x, bit 11 polarity, bit 10 external). jAER puts the origin at the
  lower left and stores DAVIS x mirrored; evedge's rows go downwards, so
  y becomes ``height - 1 - y`` (and, for DAVIS, x becomes ``width - 1 - x``),
  as tonic's ``read_davis_346`` does. The camera is named in the header
  (``# AEChip: ...DVS128`` / ``...DAVIS240C``), else taken from ``sensor_size``
  (128x128: DVS128, else DAVIS).
* **AEDAT 3.1**: ``#`` header lines from ``#!AER-DAT3.1`` to
  ``#!END-HEADER``, then packets: a 28-byte little-endian header (int16
  type, int16 source, int32 size, int32 timestamp offset, int32 timestamp
  overflow, int32 capacity, int32 number, int32 valid) and ``capacity x
  size`` bytes. Polarity packets (type 1, 8-byte events): uint32 data (bit 0
  valid, bit 1 polarity, bits 2-16 y, bits 17-31 x, origin top-left) and an
  int32 timestamp, extended to 64 bits by ``overflow << 31``. The sensor size
  comes from the header's ``dvsSizeX``/``dvsSizeY`` or the camera name.

References
----------
.. [1] iniVation, "AEDAT 2.0" and "AEDAT 3.1" file formats, docs.inivation.com.
.. [2] jAER, ``DVS128.java`` and ``DavisBaseCamera.java`` (address layouts),
       github.com/SensorsINI/jaer.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ..events import SENSOR_PRESETS, Recording, SensorSize
from ._checks import EventFileError, finish_events, locate_index
from .registry import Format, register_format

#: Camera names in headers -> (layout, sensor size), most specific first.
CAMERAS = (
    ("DVS128", ("dvs128", SENSOR_PRESETS["dvs128"])),
    ("DAVIS240", ("davis", SENSOR_PRESETS["davis240"])),
    ("DAVIS346", ("davis", SENSOR_PRESETS["davis346"])),
    ("DVXPLORER", ("davis", SensorSize(640, 480))),
)


def _header(path: Path, data: bytes, end_marker: bytes | None) -> int:
    """Offset of the first data byte after the ``#`` lines (after ``end_marker`` when given)."""
    if end_marker is not None:
        at = data.find(end_marker)
        if at < 0:
            raise EventFileError(f"{path}: no {end_marker.decode().strip()!r} line: the header is incomplete (truncated file?)")
        return at + len(end_marker)
    pos = 0
    while pos < len(data) and data[pos:pos + 1] == b"#":
        eol = data.find(b"\n", pos)
        pos = len(data) if eol < 0 else eol + 1
    return pos


def _camera(text: str) -> tuple[str, SensorSize] | None:
    upper = text.upper()
    for key, found in CAMERAS:
        if key in upper:
            return found
    return None


def _size_from(path: Path, found: SensorSize | None, given: SensorSize | None, what: str) -> tuple[SensorSize, str]:
    if found is not None:
        if given is not None and given != found:
            raise EventFileError(f"{path}: sensor size {given.width}x{given.height} was given but the {what} "
                                 f"header says {found.width}x{found.height}")
        return found, "file header"
    if given is not None:
        return given, "option"
    raise EventFileError(f"{path}: the {what} header names no camera or sensor size; pass it "
                         f"(sensor_size=SensorSize(240, 180), CLI: --sensor 240x180)")


def _finish(path, x, y, t, p, sensor, size_from, fmt, sort, extra) -> Recording:
    events, was_sorted = finish_events(path, x, y, t, p, sensor, size_from, locate_index, sort)
    metadata = {"source": str(path), "format": fmt, "sensor_size_from": size_from, **extra}
    if was_sorted:
        metadata["sorted_on_load"] = True
    return Recording(events, sensor, metadata=metadata)


def read_aedat2(path: str | os.PathLike, *, sensor_size: SensorSize | None = None, sort: bool = False) -> Recording:
    """Read the polarity events of an AEDAT 2.0 file (jAER).

    Parameters
    ----------
    path : path-like
    sensor_size : SensorSize, optional
        Needed when the header names no camera; must match it otherwise.
    sort : bool
        Sort by time (stable) instead of raising on decreasing timestamps
        (jAER's 32-bit timestamps wrap after 71 minutes).

    Returns
    -------
    Recording
        ``metadata["aedat2_layout"]`` is ``"dvs128"`` or ``"davis"``; APS,
        IMU and external events are counted and skipped.

    Raises
    ------
    EventFileError
        Wrong magic, data not a whole number of 8-byte events (truncated),
        unknown camera without ``sensor_size``, coordinates outside the
        sensor, unsorted timestamps.
    """
    path = Path(path)
    data = path.read_bytes()
    if not data.startswith(b"#!AER-DAT2"):
        raise EventFileError(f"{path}: not an AEDAT 2.0 file (the first line is not '#!AER-DAT2.0')")
    start = _header(path, data, None)
    text = data[:start].decode("latin-1")
    camera = _camera(text)
    sensor, size_from = _size_from(path, camera[1] if camera else None, sensor_size, "AEDAT 2.0")
    layout = camera[0] if camera else ("dvs128" if sensor == SENSOR_PRESETS["dvs128"] else "davis")
    trailing = (len(data) - start) % 8
    if trailing:
        raise EventFileError(f"{path}: the data end inside an 8-byte event ({trailing} trailing bytes at byte offset "
                             f"{len(data) - trailing}): the file is truncated")
    raw = np.frombuffer(data, dtype=[("address", ">u4"), ("t", ">i4")], offset=start)
    a = raw["address"].astype(np.int64)
    if layout == "dvs128":
        keep = (a >> 15) & 1 == 0
        x = (a >> 1) & 0x7F
        y = sensor.height - 1 - ((a >> 8) & 0x7F)
        p = (a & 1) == 1
    else:
        keep = ((a >> 31) & 1 == 0) & ((a >> 10) & 1 == 0)
        x = sensor.width - 1 - ((a >> 12) & 0x3FF)
        y = sensor.height - 1 - ((a >> 22) & 0x1FF)
        p = (a >> 11) & 1 == 1
    skipped = int((~keep).sum())
    extra = {"aedat2_layout": layout, **({"aedat2_skipped_non_dvs": skipped} if skipped else {})}
    return _finish(path, x[keep], y[keep], raw["t"][keep].astype(np.int64), p[keep], sensor, size_from, "aedat2",
                   sort, extra)


_PACKET = np.dtype([("type", "<i2"), ("source", "<i2"), ("size", "<i4"), ("ts_offset", "<i4"),
                    ("ts_overflow", "<i4"), ("capacity", "<i4"), ("number", "<i4"), ("valid", "<i4")])


def read_aedat3(path: str | os.PathLike, *, sensor_size: SensorSize | None = None, sort: bool = False) -> Recording:
    """Read the polarity events of an AEDAT 3.1 file (cAER); other packets are counted and skipped.

    Parameters
    ----------
    path : path-like
    sensor_size : SensorSize, optional
        Needed when the header gives no size or camera; must match it otherwise.
    sort : bool
        Sort by time (stable) instead of raising on decreasing timestamps.

    Returns
    -------
    Recording
        Only events with their valid bit set.

    Raises
    ------
    EventFileError
        Wrong magic, no end of header, a packet header or body cut short
        (named by packet number and byte offset), a polarity packet whose
        event size is not 8, coordinates outside the sensor, unsorted timestamps.
    """
    path = Path(path)
    data = path.read_bytes()
    if not re.match(rb"#!AER-DAT3\.[01]", data):
        raise EventFileError(f"{path}: not an AEDAT 3.x file (the first line is not '#!AER-DAT3.1')")
    start = _header(path, data, b"#!END-HEADER\r\n")
    text = data[:start].decode("latin-1")
    sx, sy = re.search(r"dvsSizeX\D{0,40}?(\d+)", text), re.search(r"dvsSizeY\D{0,40}?(\d+)", text)
    try:
        found = SensorSize(int(sx.group(1)), int(sy.group(1))) if sx and sy else None
    except ValueError as err:
        raise EventFileError(f"{path}: the AEDAT 3.1 header has an impossible sensor size: {err}") from None
    if found is None:
        camera = _camera(text)
        found = camera[1] if camera else None
    sensor, size_from = _size_from(path, found, sensor_size, "AEDAT 3.1")
    chunks, skipped, invalid = [], {}, 0
    pos, packet = start, 0
    while pos < len(data):
        if len(data) - pos < _PACKET.itemsize:
            raise EventFileError(f"{path}: packet {packet} at byte offset {pos}: header cut short "
                                 f"({len(data) - pos} of 28 bytes): the file is truncated")
        head = np.frombuffer(data, dtype=_PACKET, count=1, offset=pos)[0]
        size, capacity = int(head["size"]), int(head["capacity"])
        body = size * capacity
        if size <= 0 or capacity < 0 or pos + 28 + body > len(data):
            raise EventFileError(f"{path}: packet {packet} at byte offset {pos}: {capacity} events of {size} bytes "
                                 f"do not fit in the {len(data) - pos - 28} bytes left (truncated or corrupt file)")
        if int(head["type"]) == 1:
            if size != 8:
                raise EventFileError(f"{path}: packet {packet} at byte offset {pos}: polarity events of {size} bytes, expected 8")
            n = int(head["number"])
            if n < 0:
                raise EventFileError(f"{path}: packet {packet} at byte offset {pos}: event count {n} is negative "
                                     f"(corrupt file)")
            n = min(n, capacity)
            ev = np.frombuffer(data, dtype=[("data", "<u4"), ("t", "<i4")], count=n, offset=pos + 28)
            valid = (ev["data"] & 1) == 1
            invalid += int((~valid).sum())
            ev = ev[valid]
            d = ev["data"].astype(np.int64)
            t = (np.int64(int(head["ts_overflow"])) << 31) | ev["t"].astype(np.int64)
            chunks.append(((d >> 17) & 0x7FFF, (d >> 2) & 0x7FFF, t, ((d >> 1) & 1) == 1))
        else:
            key = f"type {int(head['type'])}"
            skipped[key] = skipped.get(key, 0) + 1
        pos += 28 + body
        packet += 1
    cols = [np.concatenate([c[i] for c in chunks]) if chunks else np.empty(0, np.int64) for i in range(4)]
    extra = {}
    if skipped:
        extra["aedat3_skipped_packets"] = skipped
    if invalid:
        extra["aedat3_invalid_events"] = invalid
    return _finish(path, cols[0], cols[1], cols[2], cols[3].astype(bool), sensor, size_from, "aedat3", sort, extra)


register_format(Format("aedat3", "AEDAT 3.1 (cAER, .aedat): polarity events", extensions=(".aedat",),
                       read=read_aedat3, sniff=lambda head: re.match(rb"#!AER-DAT3\.[01]", head) is not None))
register_format(Format("aedat2", "AEDAT 2.0 (jAER, .aedat/.dat): DVS128 or DAVIS events", extensions=(".aedat", ".dat"),
                       read=read_aedat2, sniff=lambda head: head.startswith(b"#!AER-DAT2")))
