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


def _big_detection(n):
    g = np.random.default_rng(3)
    ev = make_events(g.integers(0, 8, n), g.integers(0, 4, n), np.sort(g.integers(0, 10**6, n)), g.random(n) < .5)
    lt = np.zeros(n, dtype=list(LIFETIME_COLUMNS))
    for name, _ in LIFETIME_COLUMNS:
        lt[name] = g.random(n) < .5 if name in ("valid", "kept") else g.random(n)
    return Detection(SensorSize(8, 4), ev, lt, Frames([5, 9], g.random((2, 4, 8)) < .5), {"method": "intra"})


@pytest.mark.parametrize("compress", [False, True])
def test_columns_written_in_slices_give_the_bytes_of_one_write(tmp_path, monkeypatch, compress):
    from evedge.io import detection

    d = _big_detection(103)
    monkeypatch.setattr(detection, "_CHUNK", 4)
    monkeypatch.setattr(detection, "_WRITE_ROWS", 10**9)  # every column in one write (reference)
    whole = write_detection(tmp_path / "whole.h5", d, compress_per_event=compress).read_bytes()
    monkeypatch.setattr(detection, "_WRITE_ROWS", 8)  # 13 slices of 2 chunks, the last one short
    sliced = write_detection(tmp_path / "sliced.h5", d, compress_per_event=compress)
    assert sliced.read_bytes() == whole
    got = read_detection(sliced)
    assert got.events.tobytes() == d.events.tobytes() and got.lifetimes.tobytes() == d.lifetimes.tobytes()


def test_lifetime_columns_as_a_dict_and_released_give_the_same_file(tmp_path, monkeypatch):
    from evedge.io import detection

    monkeypatch.setattr(detection, "_WRITE_ROWS", 16)
    d = _big_detection(50)
    ref = write_detection(tmp_path / "ref.h5", d).read_bytes()
    cols = {name: d.lifetimes[name].copy() for name, _ in LIFETIME_COLUMNS}
    kept = Detection(d.sensor_size, d.events, dict(cols), d.edges, d.metadata)
    assert write_detection(tmp_path / "dict.h5", kept).read_bytes() == ref
    assert kept.events is d.events and set(kept.lifetimes) == set(cols)  # nothing released by default
    owned = Detection(d.sensor_size, d.events.copy(), dict(cols), d.edges, d.metadata)
    assert write_detection(tmp_path / "owned.h5", owned, release_columns=True).read_bytes() == ref
    assert owned.events is None and owned.lifetimes == {}
    bad = Detection(d.sensor_size, d.events, {**cols, "kept": cols["kept"][:-1]}, d.edges, d.metadata)
    with pytest.raises(ValueError, match="1-D of one length"):
        write_detection(tmp_path / "bad.h5", bad)
    assert not (tmp_path / "bad.h5").exists()


def test_released_columns_are_freed_while_the_image_grows(tmp_path, monkeypatch):
    import weakref

    from evedge.io import detection

    monkeypatch.setattr(detection, "_WRITE_ROWS", 1 << 12)  # the sliced writes at a size the test can afford
    n = 3 * detection._WRITE_ROWS // 2
    d = _big_detection(n)
    cols = {name: np.ascontiguousarray(d.lifetimes[name]) for name, _ in LIFETIME_COLUMNS}
    refs = {name: weakref.ref(col) for name, col in cols.items()}
    ev_ref = weakref.ref(d.events)
    seen = {}
    real = detection._dataset

    def spy(group, name, data, *args):
        # no gc.collect(): freed means freed by reference counting, at once (a collection of the whole
        # heap of a long test session per dataset costs seconds, and would hide a reference cycle)
        seen[f"{group.name}/{name}"] = (ev_ref() is None, sorted(k for k, r in refs.items() if r() is None))
        real(group, name, data, *args)

    owned = Detection(d.sensor_size, d.events, cols, d.edges, d.metadata)
    del d, cols
    detection._dataset, real_dataset = spy, real
    try:
        write_detection(tmp_path / "d.h5", owned, release_columns=True)
    finally:
        detection._dataset = real_dataset
    assert seen["/events/p"] == (False, [])  # the events are still in use while their columns are written
    assert seen["/lifetimes/lifetime_us"] == (True, [])  # then freed, before the first lifetime column
    assert seen["/lifetimes/kept"] == (True, ["lifetime_us", "valid", "vx_px_s", "vy_px_s"])
