"""The detection file: round trip, self-description, refusals; read_events and info read it."""

import h5py
import numpy as np
import pytest

from evedge.events import Frames, SensorSize, make_events
from evedge.io import read_events
from evedge.io._checks import EventFileError
from evedge.io.hdf5 import seal
from evedge.io.detection import LIFETIME_COLUMNS, Detection, read_detection, write_detection
from evedge.io.summary import format_summary, summarize


def _detection(n=5, embed=True):
    ev = make_events(np.arange(n) % 4, np.zeros(n), np.arange(n) * 10, np.arange(n) % 2 == 0)
    lt = np.zeros(n, dtype=list(LIFETIME_COLUMNS))
    lt["lifetime_us"] = np.linspace(1, 2, n)
    lt["valid"] = lt["kept"] = True
    edges = Frames([15, 40], np.zeros((2, 1, 4), bool))
    meta = {"method": "intra", "kind": "estimator", "display": "predecessor", "params": {"delta_px": 0.25},
            "source": {"path": "/abs/x.h5", "sha256": "ab" * 32, "n_events": n}}
    return Detection(SensorSize(4, 1), ev if embed else None, lt, edges, meta)


def test_round_trip_and_same_bytes(tmp_path):
    d = _detection()
    a = write_detection(tmp_path / "a.h5", d)
    b = write_detection(tmp_path / "b.h5", d)
    assert a.read_bytes() == b.read_bytes()
    got = read_detection(a)
    assert got.events.tobytes() == d.events.tobytes()
    assert got.lifetimes.tobytes() == d.lifetimes.tobytes()
    np.testing.assert_array_equal(got.edges.t_us, [15, 40])
    assert got.metadata == d.metadata and got.sensor_size == SensorSize(4, 1)
    with h5py.File(a) as f:
        assert f.attrs["format"] == "evedge-detection" and f.attrs["format_version"] == 2


def test_read_events_and_info_read_it(tmp_path):
    path = write_detection(tmp_path / "d.h5", _detection())
    rec = read_events(path)
    assert rec.events.size == 5 and len(rec.edges) == 2
    info = summarize(rec)
    assert info["format"] == "evedge-detection" and info["detection"]["method"] == "intra"
    text = format_summary(info)
    assert "method     intra" in text and "delta_px=0.25" in text and "/abs/x.h5" in text
    with pytest.raises(EventFileError, match="sensor 4x1"):
        read_events(path, sensor_size=SensorSize(5, 5))
    digest_only = write_detection(tmp_path / "n.h5", _detection(embed=False))
    with pytest.raises(EventFileError, match="holds no events.*/abs/x.h5"):
        read_events(digest_only)
    assert read_detection(digest_only).events is None


def test_malformed_files_are_named(tmp_path):
    with pytest.raises(TypeError, match="Detection"):
        write_detection(tmp_path / "x.h5", {"not": "a detection"})
    d = _detection()
    d.lifetimes = d.lifetimes[:3]
    with pytest.raises(ValueError, match="3 lifetime rows for 5 events"):
        write_detection(tmp_path / "x.h5", d)
    assert not (tmp_path / "x.h5").exists()
    path = write_detection(tmp_path / "d.h5", _detection())
    with h5py.File(path, "a") as f:
        f.attrs["format_version"] = 99
    with pytest.raises(EventFileError, match="format_version=99"):
        read_detection(path)
    path = write_detection(tmp_path / "e.h5", _detection())
    with h5py.File(path, "a") as f:
        del f["lifetimes/valid"]
        f["lifetimes/valid"] = np.zeros(2, bool)
        seal(f)  # as a writer with a bug would leave it: the checksums match, the shapes do not
    with pytest.raises(EventFileError, match="lifetimes/valid has shape"):
        read_detection(path)
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f.attrs["format"] = "something"
    with pytest.raises(EventFileError, match="not an evedge detection file"):
        read_detection(tmp_path / "other.h5")


def test_a_changed_byte_is_a_checksum_error_naming_the_dataset(tmp_path):
    path = write_detection(tmp_path / "d.h5", _detection())
    with h5py.File(path, "a") as f:
        f["lifetimes/lifetime_us"][0] += 1.0
    with pytest.raises(EventFileError, match=r"dataset 'lifetimes/lifetime_us' does not match its checksum"):
        read_detection(path)
    data = bytearray(write_detection(tmp_path / "e.h5", _detection()).read_bytes())
    for i in range(200, len(data), 997):  # bytes of the structure and the data: never read as another detection
        bad = tmp_path / "bad.h5"
        bad.write_bytes(bytes(data[:i]) + bytes([data[i] ^ 0x5A]) + bytes(data[i + 1:]))
        try:
            got = read_detection(bad)
        except EventFileError as err:
            assert "bad.h5" in str(err)
        else:
            ref = read_detection(tmp_path / "e.h5")
            assert np.array_equal(got.lifetimes, ref.lifetimes) and np.array_equal(got.events, ref.events)


def test_a_header_that_makes_hdf5_loop_is_an_error_within_the_time_limit(tmp_path, monkeypatch):
    """Found by the fuzz campaign: a count of 2**31 in an object header made h5py spin inside one attribute read."""
    import struct

    import evedge.io.hdf5 as hdf5
    from evedge._fuzz.corpus import Seeds

    data = bytearray(Seeds(tmp_path / "seeds").detection()[0])
    data[416:420] = struct.pack("<I", 2**31)
    data[341:370] = bytes(29)
    path = tmp_path / "loop.h5"
    path.write_bytes(bytes(data))
    monkeypatch.setattr(hdf5, "_PROBE_TIMEOUT_S", 1.0)
    for read in (read_detection, read_events):
        with pytest.raises(EventFileError, match=r"loop\.h5: the HDF5 parser did not finish within 1 s"):
            read(path)
