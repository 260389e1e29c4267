"""Prophesee files: EVT 3.0 and EVT 2.0 ``.raw``, and ``.dat``.

A ``.raw`` file starts with text header lines beginning with ``%``
(``% evt 3.0``, ``% format EVT3;height=720;width=1280``, ``% geometry
1280x720``, ``% end``), then little-endian words: 16-bit for EVT 3, 32-bit
for EVT 2. A ``.dat`` file has ``%`` lines too (``% Version 2``,
``% Width 640``, ``% Height 480``), two bytes (event type, event size), then
8-byte events. The sensor size comes from the header when it is there,
else from ``sensor_size=``.

EVT 3 is decoded and encoded here (numba, ``_evt3_kernels.py``): faery 0.7.1
decodes EVT 3 timestamps wrongly after the first wrap of its 24-bit time
(16.78 s: an event at 17.0 s comes back at 16.5 s, tests/io/test_prophesee.py).
EVT 2 and ``.dat`` go through faery, whose decoders round-trip exactly.
A file that ends inside a word is refused as truncated, naming the offset;
a decoder's failure on damaged data becomes an :class:`EventFileError`.

References
----------
.. [1] Prophesee, "EVT 3.0 Format", "EVT 2.0 Format" and "DAT File Format",
       Metavision SDK documentation (docs.prophesee.ai).
.. [2] A. Marcireau et al., faery (PyPI), github.com/aestream/faery.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

from ..events import Recording, SensorSize, as_events
from ._atomic import atomic_path, check_output_file
from ._checks import EventFileError, finish_events, locate_index
from ._native import faery_decode, faery_encode
from .registry import Format, register_format

#: Bytes read to find the end of the text header.
_HEADER_LIMIT = 1 << 20


def parse_header(path: Path) -> tuple[int, dict[str, str]]:
    """The byte offset where the data start, and the header's ``key -> value`` lines.

    Keys are lower-case (``"evt"``, ``"format"``, ``"geometry"``, ``"width"``,
    ``"height"``, ``"version"``, ``"t0"``); a line ``% end`` ends the header.
    """
    with open(path, "rb") as fh:
        head = fh.read(_HEADER_LIMIT)
    fields: dict[str, str] = {}
    pos = 0
    while pos < len(head) and head[pos:pos + 1] == b"%":
        eol = head.find(b"\n", pos)
        if eol < 0:
            eol = len(head)
        line = head[pos + 1:eol].decode("latin-1").strip()
        pos = eol + 1
        if line.lower() == "end":
            break
        key, _, value = line.partition(" ")
        if key:
            fields.setdefault(key.lower(), value.strip())
    return min(pos, len(head)), fields


def header_version(fields: dict[str, str]) -> str | None:
    """``"evt2"``, ``"evt2.1"``, ``"evt3"`` from ``% evt X`` or ``% format EVTX;...``, else None."""
    evt = fields.get("evt", "")
    if evt:
        return {"2.0": "evt2", "2.1": "evt2.1", "3.0": "evt3", "2": "evt2", "3": "evt3"}.get(evt)
    fmt = fields.get("format", "").split(";")[0].strip().upper()
    return {"EVT2": "evt2", "EVT21": "evt2.1", "EVT2.1": "evt2.1", "EVT3": "evt3"}.get(fmt)


def header_size(fields: dict[str, str]) -> SensorSize | None:
    """The sensor size from ``format ...;width=W;height=H``, ``geometry WxH`` or ``Width``/``Height``."""
    parts = dict(p.split("=", 1) for p in fields.get("format", "").split(";")[1:] if "=" in p)
    candidates = [
        (parts.get("width"), parts.get("height")),
        tuple(fields.get("geometry", "").lower().split("x", 1)) if "x" in fields.get("geometry", "").lower() else (None, None),
        (fields.get("width"), fields.get("height")),
    ]
    for w, h in candidates:
        if w and h and w.strip().isdigit() and h.strip().isdigit():
            return SensorSize(int(w), int(h))
    return None


def _sensor(path: Path, fields: dict[str, str], given: SensorSize | None, label: str) -> tuple[SensorSize, str]:
    try:
        from_file = header_size(fields)
    except (TypeError, ValueError) as err:
        raise EventFileError(f"{path}: the {label} header has an impossible sensor size: {err}") from None
    if from_file is not None:
        if given is not None and given != from_file:
            raise EventFileError(
                f"{path}: sensor size {given.width}x{given.height} was given but the {label} header says "
                f"{from_file.width}x{from_file.height}"
            )
        return from_file, "file header"
    if given is not None:
        return given, "option"
    raise EventFileError(
        f"{path}: the {label} header has no sensor size (no 'format ...;width=;height=' or 'geometry' line); "
        f"pass it (sensor_size=SensorSize(1280, 720), CLI: --sensor 1280x720)"
    )


def _check_words(path: Path, start: int, word_bytes: int, label: str) -> int:
    size = path.stat().st_size
    trailing = (size - start) % word_bytes
    if trailing:
        raise EventFileError(
            f"{path}: the {label} data end inside a {word_bytes}-byte word ({trailing} trailing bytes at byte "
            f"offset {size - trailing}): the file is truncated"
        )
    return size


def _recording(path: Path, raw_x, raw_y, raw_t, raw_p, sensor: SensorSize, size_from: str, fmt: str,
               sort: bool, extra: dict) -> Recording:
    if raw_t.size and raw_t.dtype == np.uint64 and int(raw_t.max()) > np.iinfo(np.int64).max:
        raise EventFileError(f"{path}: timestamps exceed int64 microseconds")
    events, was_sorted = finish_events(
        path, raw_x.astype(np.int64), raw_y.astype(np.int64), raw_t.astype(np.int64), raw_p.astype(bool),
        sensor, size_from, locate_index, sort,
    )
    metadata = {"source": str(path), "format": fmt, "sensor_size_from": size_from, **extra}
    if was_sorted:
        metadata["sorted_on_load"] = True
    return Recording(events, sensor, metadata=metadata)


def _t0(path: Path, fields: dict[str, str]) -> int:
    """faery's ``% t0 N`` line: the time (us) added to every timestamp (0 when absent)."""
    text = fields.get("t0", "0") or "0"
    if not re.fullmatch(r"\d{1,18}", text):
        raise EventFileError(f"{path}: header line '% t0 {text}' is not a time in microseconds")
    return int(text)


def read_evt3(path: str | os.PathLike, *, sensor_size: SensorSize | None = None, sort: bool = False) -> Recording:
    """Read a Prophesee EVT 3.0 ``.raw`` file (CD events; triggers counted and skipped).

    Parameters
    ----------
    path : path-like
    sensor_size : SensorSize, optional
        Used when the header has no size; must match it otherwise.
    sort : bool
        Sort by time (stable) instead of raising on decreasing timestamps.

    Returns
    -------
    Recording
        Timestamps as stored, plus a ``% t0`` header offset when present.

    Raises
    ------
    EventFileError
        Header of another version, no sensor size, data ending inside a
        16-bit word, a reserved word type (not EVT 3 data), coordinates
        outside the sensor, unsorted timestamps.
    """
    from ._evt3_kernels import evt3_decode, evt3_max_events

    path = Path(path)
    start, fields = parse_header(path)
    version = header_version(fields)
    if version not in (None, "evt3"):
        raise EventFileError(f"{path}: the header says {version}, not EVT 3; read it with format={version!r}")
    sensor, size_from = _sensor(path, fields, sensor_size, "EVT 3")
    _check_words(path, start, 2, "EVT 3")
    words = np.fromfile(path, dtype="<u2", offset=start)
    n_max = evt3_max_events(words)
    x = np.empty(n_max, np.int64)
    y = np.empty(n_max, np.int64)
    t = np.empty(n_max, np.int64)
    p = np.empty(n_max, np.int64)
    n, n_trig, n_other, bad = evt3_decode(words, _t0(path, fields), x, y, t, p)
    if bad >= 0:
        raise EventFileError(
            f"{path}: byte offset {start + 2 * bad}: word 0x{int(words[bad]):04x} has the reserved type "
            f"0x{int(words[bad]) >> 12:x}: not EVT 3 data, or a corrupt file"
        )
    extra = {"evt3_triggers_skipped": int(n_trig)} if n_trig else {}
    return _recording(path, x[:n], y[:n], t[:n], p[:n], sensor, size_from, "evt3", sort, extra)


def _read_faery(path: Path, sensor_size, sort, *, label: str, fmt: str, file_type: str, version: str,
                start: int, fields: dict, word_bytes: int) -> Recording:
    sensor, size_from = _sensor(path, fields, sensor_size, label)
    _check_words(path, start, word_bytes, label)
    raw = faery_decode(path, label, file_type, dimensions=(sensor.width, sensor.height), version=version)
    return _recording(path, raw["x"], raw["y"], raw["t"], raw["on"], sensor, size_from, fmt, sort, {})


def read_evt2(path: str | os.PathLike, *, sensor_size: SensorSize | None = None, sort: bool = False) -> Recording:
    """Read a Prophesee EVT 2.0 ``.raw`` file through faery (parameters as :func:`read_evt3`)."""
    path = Path(path)
    start, fields = parse_header(path)
    version = header_version(fields)
    if version == "evt2.1":
        # faery 0.7.1 panics on it ("not yet implemented: implement EVT2.1")
        raise EventFileError(f"{path}: EVT 2.1 files are not supported (no maintained decoder installs here)")
    if version not in (None, "evt2"):
        raise EventFileError(f"{path}: the header says {version}, not EVT 2; read it with format={version!r}")
    return _read_faery(path, sensor_size, sort, label="EVT 2", fmt="evt2", file_type="evt", version="evt2",
                       start=start, fields=fields, word_bytes=4)


def read_dat(path: str | os.PathLike, *, sensor_size: SensorSize | None = None, sort: bool = False) -> Recording:
    """Read a Prophesee ``.dat`` file of CD events through faery (parameters as :func:`read_evt3`)."""
    path = Path(path)
    start, fields = parse_header(path)
    size = path.stat().st_size
    if size < start + 2:
        raise EventFileError(f"{path}: the DAT file ends before its event type and size bytes (byte offset {start})")
    with open(path, "rb") as fh:
        fh.seek(start)
        kind, ev_size = fh.read(2)
    if kind != 0x0C or ev_size != 8:
        what = {0x00: "2D", 0x0C: "CD", 0x0E: "trigger"}.get(kind, f"0x{kind:02x}")
        raise EventFileError(
            f"{path}: byte offset {start}: DAT event type {what} of size {ev_size}; only CD events "
            f"(type 0x0c, 8 bytes) are events"
        )
    dat_version = "dat1" if fields.get("version", "2").strip() == "1" else "dat2"
    return _read_faery(path, sensor_size, sort, label="DAT", fmt="dat", file_type="dat", version=dat_version,
                       start=start + 2, fields=fields, word_bytes=8)


def write_evt3(path: str | os.PathLike, recording: Recording) -> Path:
    """Write the events of ``recording`` as Prophesee EVT 3.0 (``.raw``), atomically.

    The header holds ``% evt 3.0``, the format and geometry lines, and
    ``% t0`` (faery's convention) when the first event is past the first 24-bit
    wrap, so that the words need not count wraps from time 0.

    Parameters
    ----------
    path : path-like
    recording : Recording
        Frames and truth are not written (EVT 3 holds events only).

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        Negative timestamps, or a sensor wider or higher than 2048 (11-bit coordinates).
    """
    from ._evt3_kernels import evt3_encode

    path = Path(path)
    check_output_file(path, "write_evt3")
    ev = as_events(recording.events)
    sensor = recording.sensor_size
    if sensor.width > 2048 or sensor.height > 2048:
        raise ValueError(f"write_evt3: {path}: EVT 3 coordinates have 11 bits; the sensor is {sensor.width}x{sensor.height}")
    t = ev["t"].astype(np.int64)
    if t.size and t[0] < 0:
        raise ValueError(f"write_evt3: {path}: EVT 3 has no negative times; event 0 has t={int(t[0])} us")
    t0 = (int(t[0]) >> 24) << 24 if t.size else 0
    words = evt3_encode(ev["x"].astype(np.int64), ev["y"].astype(np.int64), t - t0, ev["p"].astype(np.int64))
    header = f"% evt 3.0\n% format EVT3;height={sensor.height};width={sensor.width}\n% geometry {sensor.width}x{sensor.height}\n"
    if t0:
        header += f"% t0 {t0}\n"
    header += "% end\n"
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(header.encode("ascii"))
            fh.write(words.astype("<u2").tobytes())
    return path


def write_evt2(path: str | os.PathLike, recording: Recording) -> Path:
    """Write the events as Prophesee EVT 2.0 through faery, atomically (events only)."""
    return faery_encode(Path(path), recording, "EVT 2", "evt", version="evt2", zero_t0=True, who="write_evt2")


def write_dat(path: str | os.PathLike, recording: Recording) -> Path:
    """Write the events as a Prophesee ``.dat`` (DAT 2, CD events) through faery, atomically."""
    return faery_encode(Path(path), recording, "DAT", "dat", version="dat2", zero_t0=True, who="write_dat")


def _sniff(version: str):
    def sniff(head: bytes) -> bool:
        if not head.startswith(b"%"):
            return False
        text = head.split(b"\n% end", 1)[0].decode("latin-1").lower()
        evt = {"evt3": ("% evt 3", "format evt3"), "evt2": ("% evt 2", "format evt2")}[version]
        return any(key in text for key in evt)
    return sniff


# EVT 3 first: the default writer of .raw
register_format(Format("evt3", "Prophesee EVT 3.0 (.raw)", extensions=(".raw",), read=read_evt3, write=write_evt3,
                       sniff=_sniff("evt3")))
register_format(Format("evt2", "Prophesee EVT 2.0 (.raw)", extensions=(".raw",), read=read_evt2, write=write_evt2,
                       sniff=_sniff("evt2")))
register_format(Format("dat", "Prophesee DAT (.dat, CD events)", extensions=(".dat",), read=read_dat, write=write_dat,
                       sniff=lambda head: head.startswith(b"%")))
