"""Fixtures for the I/O tests: real-data paths, small recordings, a tiny AEDAT4 writer."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from evedge.events import Frames, Recording, SensorSize, make_events

REALDATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "realdata"


@pytest.fixture
def realdata():
    """Return a function: relative path in shared/realdata -> Path, or skip when absent."""

    def get(relative: str) -> Path:
        path = REALDATA / relative
        if not path.exists():
            pytest.skip(f"real recording absent: {path}")
        return path

    return get


def _small_recording(n: int = 500, *, seed: int = 0, truth: bool = True, frames: bool = True) -> Recording:
    rng = np.random.default_rng(seed)
    size = SensorSize(40, 30)
    t = np.sort(rng.integers(0, 2_000_000, n))
    ev = make_events(rng.integers(0, size.width, n), rng.integers(0, size.height, n), t, rng.integers(0, 2, n))
    tr = None
    if truth:
        tr = np.empty(n, dtype=[("lifetime_us", "f8"), ("vx_px_s", "f4"), ("edge_id", "i4"),
                                ("valid", "?"), ("normal", "f8", (2,))])
        tr["lifetime_us"] = rng.uniform(100, 1e4, n)
        tr["lifetime_us"][::7] = np.nan
        tr["vx_px_s"] = rng.normal(size=n)
        tr["edge_id"] = rng.integers(-1, 5, n)
        tr["valid"] = rng.random(n) > 0.5
        tr["normal"] = rng.normal(size=(n, 2))
    fr = ed = None
    if frames:
        fr = Frames(np.array([0, 500_000, 1_000_000]), rng.integers(0, 256, (3, 30, 40), dtype=np.uint8))
        ed = Frames(np.array([250_000, 750_000]), rng.random((2, 30, 40)) > 0.8)
    return Recording(ev, size, frames=fr, truth=tr, edges=ed,
                     metadata={"scene": "test", "seed": seed, "params": {"c": 0.2}})


@pytest.fixture
def small_recording():
    """Return a factory of small random recordings (truth, frames and edge maps optional)."""
    return _small_recording


def _flatbuffer_ioheader(description: str) -> bytes:
    # IOHeader table {compression (absent: None), file_data_position (absent: -1), description}
    text = description.encode()
    body = struct.pack("<I", 20) + b"IOHE" + struct.pack("<HHHHH", 10, 8, 0, 0, 4) + b"\0\0"
    body += struct.pack("<i", 12) + struct.pack("<I", 4) + struct.pack("<I", len(text)) + text + b"\0"
    body += b"\0" * (-len(body) % 4)
    return struct.pack("<I", len(body)) + body


def _flatbuffer_event_packet(stream_id: int, x, y, t, on) -> bytes:
    # size-prefixed EventPacket {elements: [Event{t: i64, x: i16, y: i16, on: bool}]}, 8-aligned structs
    n = len(t)
    body = bytearray(struct.pack("<I", 0) + struct.pack("<I", 16) + b"EVTS" + struct.pack("<HHH", 6, 8, 4) + b"\0\0")
    body += struct.pack("<i", 8) + struct.pack("<I", 4) + struct.pack("<I", n)
    rec = np.zeros(n, dtype=[("t", "<i8"), ("x", "<i2"), ("y", "<i2"), ("on", "u1"), ("pad", "V3")])
    rec["t"], rec["x"], rec["y"], rec["on"] = t, x, y, on
    body += rec.tobytes()
    body[0:4] = struct.pack("<I", len(body) - 4)
    return struct.pack("<II", stream_id, len(body)) + bytes(body)


def _write_aedat4(path: Path, width: int, height: int, packets: list[tuple]) -> Path:
    """Write an uncompressed AEDAT 4 file with one event stream (id 0) and the given packets."""
    description = (
        '<dv version="2.0"><node name="outInfo"><node name="0">'
        '<attr key="typeIdentifier" type="string">EVTS</attr><node name="info">'
        f'<attr key="sizeX" type="int">{width}</attr><attr key="sizeY" type="int">{height}</attr>'
        "</node></node></node></dv>"
    )
    data = b"#!AER-DAT4.0\r\n" + _flatbuffer_ioheader(description)
    data += b"".join(_flatbuffer_event_packet(0, *cols) for cols in packets)
    path.write_bytes(data)
    return path


@pytest.fixture
def write_aedat4():
    """Return ``write(path, width, height, packets)``; each packet is ``(x, y, t, on)`` columns."""
    return _write_aedat4


# AEDAT 2.0 and 3.1 hand-encoded from iniVation's format documents (no writer in evedge or faery)


def _aedat2(path, header_lines, addresses, times):
    head = b"#!AER-DAT2.0\r\n" + b"".join(b"# " + line.encode() + b"\r\n" for line in header_lines)
    raw = np.empty(len(addresses), dtype=[("a", ">u4"), ("t", ">i4")])
    raw["a"], raw["t"] = addresses, times
    path.write_bytes(head + raw.tobytes())
    return path


def _dvs128(x, y, p, ext=0):
    return (ext << 15) | (y << 8) | (x << 1) | p


def _davis(x, y, p, aps=0, ext=0):
    return (aps << 31) | (y << 22) | (x << 12) | (p << 11) | (ext << 10)


def _aedat3(path, packets, header="#Source 1: DAVIS240C\r\n"):
    data = b"#!AER-DAT3.1\r\n#Format: RAW\r\n" + header.encode() + b"#!END-HEADER\r\n"
    for kind, overflow, events in packets:
        if kind == 1:
            body = np.empty(len(events), dtype=[("d", "<u4"), ("t", "<i4")])
            body["d"] = [(x << 17) | (y << 2) | (p << 1) | v for x, y, p, v, _ in events]
            body["t"] = [t for *_, t in events]
            body, size = body.tobytes(), 8
        else:
            body, size = bytes(12 * len(events)), 12
        n = len(events)
        data += np.array([(kind, 1, size, 4, overflow, n, n, n)], dtype=[
            ("a", "<i2"), ("b", "<i2"), ("c", "<i4"), ("d", "<i4"), ("e", "<i4"), ("f", "<i4"), ("g", "<i4"), ("h", "<i4")]).tobytes()
        data += body
    path.write_bytes(data)
    return path


def _dvs128(x, y, p, ext=0):
    return (ext << 15) | (y << 8) | (x << 1) | p


def _davis(x, y, p, aps=0, ext=0):
    return (aps << 31) | (y << 22) | (x << 12) | (p << 11) | (ext << 10)


@pytest.fixture
def aedat2_file():
    """Return ``write(path, header_lines, addresses, times)``: an AEDAT 2.0 file (big-endian address, time)."""
    return _aedat2


@pytest.fixture
def aedat3_file():
    """Return ``write(path, packets, header=...)``; packets are ``(type, ts_overflow, events)``,
    polarity events ``(x, y, p, valid, t)``."""
    return _aedat3


@pytest.fixture
def aedat2_address():
    """The address encoders ``(dvs128(x, y, p, ext), davis(x, y, p, aps, ext))``."""
    return _dvs128, _davis
