"""The evedge HDF5 format: round trip of everything, determinism, and its errors."""

from __future__ import annotations

import hashlib
import json
import time

import h5py
import numpy as np
import pytest

from evedge.events import SensorSize
from evedge.io import EventFileError, iter_hdf5_events, read_events, read_hdf5, write_recording
from evedge.io.hdf5 import seal


def _equal_structured(a, b):
    assert a.dtype == b.dtype
    for name in a.dtype.names:
        np.testing.assert_array_equal(a[name], b[name])  # NaN == NaN here


def test_round_trip_with_truth_frames_and_edges(tmp_path, small_recording):
    rec = small_recording()
    path = write_recording(tmp_path / "rec.h5", rec)
    back = read_events(path)
    np.testing.assert_array_equal(back.events, rec.events)
    _equal_structured(back.truth, rec.truth)
    for a, b in ((back.frames, rec.frames), (back.edges, rec.edges)):
        np.testing.assert_array_equal(a.t_us, b.t_us)
        np.testing.assert_array_equal(a.images, b.images)
        assert a.images.dtype == b.images.dtype
    assert back.sensor_size == rec.sensor_size
    assert back.metadata == {**rec.metadata, "source": str(path), "format": "evedge-hdf5",
                             "sensor_size_from": "file metadata"}


def test_layout_and_attributes(tmp_path, small_recording):
    path = write_recording(tmp_path / "rec.h5", small_recording())
    with h5py.File(path, "r") as f:
        assert f.attrs["format"] == "evedge" and int(f.attrs["format_version"]) == 2
        assert (int(f.attrs["sensor_width"]), int(f.attrs["sensor_height"])) == (40, 30)
        assert json.loads(f.attrs["metadata"])["scene"] == "test"
        assert list(f["events"]) == ["x", "y", "t", "p"]
        assert list(f["truth"]) == ["lifetime_us", "vx_px_s", "edge_id", "valid", "normal"]
        assert f["events/t"].dtype == np.int64 and f["events/t"].compression == "gzip"
        assert list(f["frames"]) == ["t_us", "images"] and f["edges/images"].dtype == bool


def test_minimal_and_empty_recordings(tmp_path, small_recording):
    rec = small_recording(n=0, truth=False, frames=False)
    back = read_hdf5(write_recording(tmp_path / "e.h5", rec))
    assert back.events.size == 0 and back.truth is None and back.frames is None and back.edges is None


def test_bytes_are_deterministic(tmp_path, small_recording):
    rec = small_recording()
    a = write_recording(tmp_path / "a.h5", rec)
    time.sleep(1.1)  # an embedded timestamp would differ by then
    b = write_recording(tmp_path / "b.h5", rec)
    assert hashlib.sha256(a.read_bytes()).hexdigest() == hashlib.sha256(b.read_bytes()).hexdigest()


def test_streaming_reader_equals_one_shot(tmp_path, small_recording):
    rec = small_recording(n=1000)
    path = write_recording(tmp_path / "rec.h5", rec)
    chunks = list(iter_hdf5_events(path, chunk_size=300))
    assert [c.size for c in chunks] == [300, 300, 300, 100]
    np.testing.assert_array_equal(np.concatenate(chunks), rec.events)


def test_hdf5_but_not_evedge(tmp_path):
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as f:
        f["events"] = np.zeros(3)
    with pytest.raises(EventFileError, match=r"not an evedge HDF5 file \(attribute format=None"):
        read_hdf5(path)


def _tamper(path, action, reseal=True):
    """Change the file; resealed (checksums recomputed) as a buggy writer would leave it."""
    with h5py.File(path, "a") as f:
        action(f)
        if reseal:
            seal(f)


def _drop_last_row(name):
    def action(f):
        v = f[name][:-1]
        del f[name]
        f[name] = v
    return action


@pytest.mark.parametrize("kwargs, action, message", [
    pytest.param({}, lambda f: f.__delitem__("events"), r"rec\.h5: missing group 'events'", id="missing_events_group"),
    pytest.param({}, lambda f: f.__delitem__("events/p"), r"missing dataset 'events/p'", id="missing_dataset"),
    pytest.param({"truth": False, "frames": False}, _drop_last_row("events/x"),
                 r"'events/y' has 500 rows, 'events/x' has 499", id="length_mismatch"),
    pytest.param({"frames": False}, _drop_last_row("truth/valid"),
                 r"'truth/valid' has 499 rows, there are 500 events", id="truth_length_mismatch"),
    pytest.param({}, lambda f: f.attrs.__setitem__("format_version", 3), "format_version=3 is not supported",
                 id="wrong_version"),
])
def test_tampered_file_is_an_error(tmp_path, small_recording, kwargs, action, message):
    path = write_recording(tmp_path / "rec.h5", small_recording(**kwargs))
    _tamper(path, action)
    with pytest.raises(EventFileError, match=message):
        read_hdf5(path)


def test_unsorted_and_out_of_range_name_the_index(tmp_path, small_recording):
    path = write_recording(tmp_path / "rec.h5", small_recording(frames=False))
    _tamper(path, lambda f: f["events/t"].__setitem__(10, 10**9))
    with pytest.raises(EventFileError, match=r"event index 11: timestamps are not sorted"):
        read_hdf5(path)
    rec = read_hdf5(path, sort=True)  # truth follows its events
    assert rec.events["t"][-1] == 10**9 and rec.truth["edge_id"][-1] == small_recording().truth["edge_id"][10]
    _tamper(path, lambda f: f["events/y"].__setitem__(3, 30))
    with pytest.raises(EventFileError, match=r"event index 3: y=30 is outside the sensor 40x30 \(size from file metadata\)"):
        read_hdf5(path, sort=True)


def test_sensor_option_must_match(tmp_path, small_recording):
    path = write_recording(tmp_path / "rec.h5", small_recording())
    with pytest.raises(EventFileError, match="240x180 was given but the file says 40x30"):
        read_events(path, sensor_size=SensorSize(240, 180))


def test_metadata_must_be_json(tmp_path, small_recording):
    rec = small_recording(frames=False)
    rec.metadata["bad"] = object()
    with pytest.raises(ValueError, match="not JSON-serialisable"):
        write_recording(tmp_path / "rec.h5", rec)
    assert list(tmp_path.iterdir()) == []  # no half-written or temp file


def test_write_rejects_non_recording(tmp_path):
    with pytest.raises(TypeError, match="expected a Recording"):
        write_recording(tmp_path / "x.h5", np.zeros(3))


def _replace(name, value):
    def action(f):
        del f[name]
        f[name] = value
    return action


@pytest.mark.parametrize("action, message", [
    pytest.param(_replace("events/t", np.array([0] * 499 + [2**63 + 5], dtype=np.uint64)),
                 r"event index 499: 'events/t' = 9223372036854775813 exceeds int64", id="uint64_time_would_wrap"),
    pytest.param(_replace("truth/valid", True), r"'truth/valid' is a scalar", id="scalar_truth_dataset"),
    pytest.param(lambda f: f.attrs.__setitem__("sensor_width", 40.5),
                 r"attribute 'sensor_width' must be an integer, got np.float64\(40.5\)", id="non_integer_sensor"),
    pytest.param(_replace("frames/t_us", np.array([0, 500_000, 400_000])), r"'frames/t_us' decreases at frame 2",
                 id="frame_times_decrease"),
])
def test_more_tampering_is_an_error_not_a_traceback_or_silent(tmp_path, small_recording, action, message):
    path = write_recording(tmp_path / "rec.h5", small_recording())
    _tamper(path, action)
    with pytest.raises(EventFileError, match=message):
        read_hdf5(path)


def test_write_to_a_missing_folder_or_onto_a_folder_is_a_clear_error(tmp_path, small_recording):
    with pytest.raises(FileNotFoundError, match=r"write_recording: cannot write .*rec\.h5: folder .*nodir does not exist"):
        write_recording(tmp_path / "nodir" / "rec.h5", small_recording())
    (tmp_path / "adir").mkdir()
    with pytest.raises(IsADirectoryError, match=r"adir: it is an existing folder"):
        write_recording(tmp_path / "adir", small_recording())
    assert [p.name for p in tmp_path.iterdir()] == ["adir"]  # no temp file left


def test_written_file_gets_the_umask_mode(tmp_path, small_recording):
    import os
    import stat

    mask = os.umask(0o022)
    try:
        path = write_recording(tmp_path / "rec.h5", small_recording())
    finally:
        os.umask(mask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644  # not mkstemp's 0600


def test_folder_read_as_hdf5_is_named(tmp_path):
    with pytest.raises(EventFileError, match=r"is a folder, not an HDF5 file"):
        read_events(tmp_path, format="hdf5")


# ---------------------------------------------------------------- corruption and crafted structures


def test_a_changed_value_fails_its_checksum_naming_the_dataset(tmp_path, small_recording):
    for name in ("events/t", "truth/lifetime_us", "frames/images", "edges/images"):
        path = write_recording(tmp_path / "rec.h5", small_recording())

        def change(f, name=name):
            data = f[name][()]
            flat = data.reshape(-1)
            flat[5] = flat[5] + 1 if flat.dtype != bool else not flat[5]
            f[name][...] = data

        _tamper(path, change, reseal=False)
        with pytest.raises(EventFileError, match=rf"dataset '{name}' does not match its checksum"):
            read_hdf5(path)
    path = write_recording(tmp_path / "rec.h5", small_recording())
    _tamper(path, lambda f: f.attrs.__setitem__("sensor_width", 41), reseal=False)
    with pytest.raises(EventFileError, match=r"the attributes .* do not match their checksum"):
        read_hdf5(path)
    _tamper(path, lambda f: f.attrs.__delitem__("checksums"), reseal=False)
    with pytest.raises(EventFileError, match=r"attribute 'checksums' is missing"):
        read_hdf5(path)


def test_a_corrupt_byte_on_disk_is_an_error_naming_file_and_dataset(tmp_path, small_recording):
    path = write_recording(tmp_path / "rec.h5", small_recording(n=3000))
    with h5py.File(path) as f:
        offset = f["events/t"].id.get_chunk_info(0).byte_offset
    data = bytearray(path.read_bytes())
    data[offset + 40] ^= 0x55  # inside the compressed chunk: gzip fails, or decodes to other numbers
    path.write_bytes(bytes(data))
    with pytest.raises(EventFileError, match=r"rec\.h5: dataset 'events/t'"):
        read_hdf5(path)
    with pytest.raises(EventFileError, match=r"rec\.h5: dataset 'events/t'"):
        list(iter_hdf5_events(path))


@pytest.mark.parametrize("action, message", [
    pytest.param(lambda f: (f["events"].__delitem__("x"), f["events"].__setitem__("x", h5py.SoftLink("/events/x"))),
                 r"'events/x' is a soft link", id="soft_link_loop"),
    pytest.param(lambda f: (f.__delitem__("events"), f.__setitem__("events", h5py.SoftLink("/events"))),
                 r"'events' is a soft link", id="group_link_loop"),
    pytest.param(lambda f: (f["events"].__delitem__("x"), f["events"].__setitem__("x", h5py.ExternalLink("/etc/x.h5", "/x"))),
                 r"'events/x' is an external link", id="external_link"),
    pytest.param(lambda f: [(f["events"].__delitem__(k), f["events"].create_dataset(k, shape=(2**33,), dtype=d, chunks=(1 << 16,), compression="gzip"))
                            for k, d in (("x", "i2"), ("y", "i2"), ("t", "i8"), ("p", "?"))],
                 r"'events/x' declares shape \(8589934592,\) \(131072 chunks\) but stores 0 chunks", id="huge_declared_rows"),
    pytest.param(lambda f: (f["frames"].__delitem__("images"), f["frames"].create_dataset("images", shape=(3, 30, 40), dtype="f4")),
                 r"'frames/images' declares 14400 bytes \(\(3, 30, 40\)\) but stores 0", id="unwritten_frames"),
])
def test_crafted_structures_are_refused_before_reading(tmp_path, small_recording, action, message):
    path = write_recording(tmp_path / "rec.h5", small_recording(truth=False))
    _tamper(path, action, reseal=False)  # the checksums would still match: these fail before any data is read
    with pytest.raises(EventFileError, match=message):
        read_hdf5(path)


def _with_frames(images):
    def action(f):
        del f["frames/images"]
        f["frames/images"] = images
    return action


@pytest.mark.parametrize("action, message", [
    pytest.param(_with_frames(np.full((3, 30, 40), np.nan, np.float32)), r"frame 0 pixel \(x=0, y=0\) is nan",
                 id="nan_frames"),
    pytest.param(_with_frames(np.full((3, 30, 40), -0.5)), r"is -0.5, expected a finite intensity in \[0, 1\]",
                 id="negative_frames"),
    pytest.param(_with_frames(np.full((3, 30, 40), b"x")), r"'frames/images' has dtype \|S1", id="string_frames"),
    pytest.param(_replace("frames/t_us", np.array([0.0, np.nan, 1.0])), r"'frames/t_us' has dtype float64",
                 id="float_frame_times"),
    pytest.param(_replace("edges/images", np.ones((2, 30, 40), np.uint8)), r"'edges/images' has dtype uint8, expected bool",
                 id="integer_edges"),
    pytest.param(_replace("truth/lifetime_us", np.full(500, -3.0)), r"event index 0: 'truth/lifetime_us' = -3.0",
                 id="negative_lifetime"),
])
def test_values_outside_their_domain_are_refused(tmp_path, small_recording, action, message):
    rec = small_recording()
    rec.truth = np.empty(rec.events.size, dtype=[("lifetime_us", "f8")])
    rec.truth["lifetime_us"] = 5.0
    path = write_recording(tmp_path / "rec.h5", rec)
    _tamper(path, action)
    with pytest.raises(EventFileError, match=message):
        read_hdf5(path)


def test_version_1_files_without_checksums_are_refused(tmp_path, small_recording):
    path = write_recording(tmp_path / "rec.h5", small_recording())
    with h5py.File(path, "a") as f:
        f.attrs["format_version"] = 1
        del f.attrs["checksums"]
    with pytest.raises(EventFileError, match="format_version=1 is not supported"):
        read_hdf5(path)


def test_a_half_written_temp_file_is_an_error(tmp_path, small_recording):
    path = write_recording(tmp_path / "rec.h5", small_recording())
    data = path.read_bytes()
    for cut in (100, len(data) // 3, len(data) - 10):
        tmp = tmp_path / f".rec.h5.{cut}.tmp"
        tmp.write_bytes(data[:cut])
        with pytest.raises(EventFileError, match=rf"\.rec\.h5\.{cut}\.tmp"):
            read_events(tmp, format="hdf5")


def test_truth_times_must_be_the_events_times(tmp_path, small_recording):
    rec = small_recording()
    rec.truth = np.empty(rec.events.size, dtype=[("is_signal", "?"), ("t_ns", "i8")])
    rec.truth["is_signal"] = True
    rec.truth["t_ns"] = rec.events["t"].astype(np.int64) * 1000 + 499  # within the rounding of t (us)
    path = write_recording(tmp_path / "rec.h5", rec)
    assert np.array_equal(read_hdf5(path).truth["t_ns"], rec.truth["t_ns"])
    shifted = rec.truth["t_ns"].copy()
    shifted[7] += 2000
    _tamper(path, _replace("truth/t_ns", shifted))  # resealed: only the domain check can see it
    with pytest.raises(EventFileError, match=r"event index 7: 'truth/t_ns' = \d+ ns is not the event's time"):
        read_hdf5(path)
    _tamper(path, _replace("truth/t_ns", rec.truth["t_ns"].astype(np.float64)))
    with pytest.raises(EventFileError, match=r"'truth/t_ns' has dtype float64, expected int64 nanoseconds"):
        read_hdf5(path)


def _tobytes_digest(data: np.ndarray) -> str:
    """The checksum as version 2 files store it, from its definition (a copy of the bytes; reference)."""
    h = hashlib.sha256(f"{data.dtype.str}{tuple(int(n) for n in data.shape)}".encode())
    h.update(np.ascontiguousarray(data).tobytes())
    return h.hexdigest()


@pytest.mark.parametrize("data", [
    np.arange(11, dtype=np.int64),                                   # 1-D, several slices
    np.arange(90, dtype=np.float32).reshape(6, 3, 5),                # N-D: rows of 15
    np.zeros((0, 4), np.uint8),                                      # empty
    np.array(7.5),                                                   # scalar
    np.arange(13) % 3 == 0,                                          # bool
    np.arange(40, dtype=np.int16)[::3],                              # not contiguous
], ids=["1d", "nd", "empty", "scalar", "bool", "strided"])
def test_checksums_without_copies_are_the_stored_ones(tmp_path, monkeypatch, data):
    from evedge.io import hdf5

    monkeypatch.setattr(hdf5, "_SEAL_ROWS", 4)  # seal reads 4 elements' rows at a time: 1-D and N-D sliced
    assert hdf5._data_digest(data) == _tobytes_digest(data)
    with h5py.File(tmp_path / "d.h5", "w") as f:
        f.create_dataset("a", data=data)
        assert hdf5._dataset_digest(f["a"]) == _tobytes_digest(data)
        seal(f)
        assert json.loads(f.attrs["checksums"])["a"] == _tobytes_digest(data)


def test_sealed_recording_checksums_are_the_stored_ones(tmp_path, small_recording, monkeypatch):
    from evedge.io import hdf5

    monkeypatch.setattr(hdf5, "_SEAL_ROWS", 7)
    path = write_recording(tmp_path / "r.h5", small_recording())
    with h5py.File(path) as f:
        sums = json.loads(f.attrs["checksums"])
        names = []
        f.visititems(lambda name, obj: names.append(name) if isinstance(obj, h5py.Dataset) else None)
        assert names and all(sums[name] == _tobytes_digest(f[name][()]) for name in names)
    read_hdf5(path)
