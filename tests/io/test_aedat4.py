"""AEDAT 4 through the ``aedat`` package, on small files written by the test itself.

The files are hand-built (IOHeader + size-prefixed EventPacket flatbuffers,
no compression); no real AEDAT4 recording is available offline.
"""

from __future__ import annotations

import pytest

from evedge.events import SensorSize
from evedge.io import EventFileError, read_events


def test_reads_events_across_packets(tmp_path, write_aedat4):
    path = write_aedat4(tmp_path / "a.aedat4", 32, 24, [
        ([0, 1, 2], [0, 23, 4], [1_700_000_000_000_010, 1_700_000_000_000_020, 1_700_000_000_000_030], [1, 0, 1]),
        ([31, 5], [5, 6], [1_700_000_000_000_040, 1_700_000_000_000_050], [0, 1]),
    ])
    rec = read_events(path)
    assert rec.sensor_size == SensorSize(32, 24)
    assert rec.events["x"].tolist() == [0, 1, 2, 31, 5]
    assert rec.events["y"].tolist() == [0, 23, 4, 5, 6]
    assert rec.events["t"].tolist() == [1_700_000_000_000_000 + k for k in (10, 20, 30, 40, 50)]
    assert rec.events["p"].tolist() == [True, False, True, False, True]
    assert rec.metadata["format"] == "aedat4" and rec.metadata["sensor_size_from"] == "file metadata"


def test_out_of_range_and_unsorted(tmp_path, write_aedat4):
    path = write_aedat4(tmp_path / "a.aedat4", 8, 8, [([1, 8], [1, 1], [5, 6], [1, 1])])
    with pytest.raises(EventFileError, match=r"event index 1: x=8 is outside the sensor 8x8"):
        read_events(path)
    path = write_aedat4(tmp_path / "b.aedat4", 8, 8, [([1, 2, 3], [1, 1, 1], [5, 9, 7], [1, 1, 0])])
    with pytest.raises(EventFileError, match=r"event index 2: timestamps are not sorted"):
        read_events(path)
    assert read_events(path, sort=True).events["x"].tolist() == [1, 3, 2]


def test_sensor_option_must_match_description(tmp_path, write_aedat4):
    path = write_aedat4(tmp_path / "a.aedat4", 8, 8, [([1], [1], [5], [1])])
    with pytest.raises(EventFileError, match="9x8 was given but the file's event stream 0 is 8x8"):
        read_events(path, sensor_size=SensorSize(9, 8))


def test_truncated_file_is_an_error_not_a_short_read(tmp_path, write_aedat4):
    path = write_aedat4(tmp_path / "a.aedat4", 8, 8, [([1, 2, 3, 4], [1, 1, 1, 1], [1, 2, 3, 4], [1, 1, 0, 0])])
    data = path.read_bytes()
    path.write_bytes(data[:-20])
    with pytest.raises(EventFileError, match=r"AEDAT4 packet 1 cannot be decoded"):
        read_events(path)


def test_detected_by_magic_bytes_without_extension(tmp_path, write_aedat4):
    path = write_aedat4(tmp_path / "recording.bin", 8, 8, [([1], [2], [3], [0])])
    rec = read_events(path)
    assert rec.events["y"].tolist() == [2] and rec.metadata["format"] == "aedat4"


def test_impossible_sensor_size_in_the_description_names_the_file(tmp_path, write_aedat4):
    path = write_aedat4(tmp_path / "a.aedat4", 0, 8, [([0], [1], [5], [1])])
    with pytest.raises(EventFileError, match=r"a\.aedat4: event stream 0 has a bad sensor size: SensorSize\.width"):
        read_events(path)


def test_decoder_panics_and_aborts_are_errors_naming_the_file(tmp_path, write_aedat4):
    import struct

    path = write_aedat4(tmp_path / "a.aedat4", 16, 16, [([1, 2], [3, 4], [10, 20], [1, 0])])
    good = path.read_bytes()
    header_end = 14 + 4 + struct.unpack_from("<I", good, 14)[0]
    cases = {
        # a negative packet size: the decoder reserves 4 GiB and aborts the process (SIGABRT) when it cannot
        "size": good[:header_end + 4] + struct.pack("<i", -5) + good[header_end + 8:],
        # an IOHeader size of 0: a Rust panic (pyo3 PanicException, a BaseException)
        "header": good[:14] + struct.pack("<I", 0) + good[18:],
    }
    for name, data in cases.items():
        bad = tmp_path / f"{name}.aedat4"
        bad.write_bytes(data)
        with pytest.raises(EventFileError, match=rf"{name}\.aedat4: "):
            read_events(bad)
    assert read_events(path).events.size == 2  # the reader still works in this process
