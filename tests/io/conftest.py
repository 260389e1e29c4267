"""Fixtures for the I/O tests: real-data paths, small recordings, a tiny AEDAT4 writer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from evedge._fuzz.corpus import aedat4_bytes
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


def _write_aedat4(path: Path, width: int, height: int, packets: list[tuple]) -> Path:
    """Write an uncompressed AEDAT 4 file with one event stream (id 0) and the given packets."""
    path.write_bytes(aedat4_bytes(width, height, packets))
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
