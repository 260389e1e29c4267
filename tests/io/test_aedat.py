"""AEDAT 2.0 and 3.1, hand-encoded from iniVation's format documents."""

from __future__ import annotations

import pytest

from evedge.events import SensorSize
from evedge.io import EventFileError, detect_format, read_events


def test_aedat2_dvs128(tmp_path, aedat2_file, aedat2_address):
    _dvs128, _ = aedat2_address
    path = aedat2_file(tmp_path / "a.aedat", ["AEChip: ch.unizh.ini.jaer.chip.retina.DVS128"],
                   [_dvs128(5, 0, 1), _dvs128(127, 127, 0), _dvs128(3, 3, 1, ext=1), _dvs128(0, 10, 0)],
                   [10, 20, 25, 30])
    assert detect_format(path) == "aedat2"
    rec = read_events(path)
    assert rec.sensor_size == SensorSize(128, 128)
    # jAER's origin is the lower left: rows go down in evedge
    assert rec.events["x"].tolist() == [5, 127, 0]
    assert rec.events["y"].tolist() == [127, 0, 117]
    assert rec.events["p"].tolist() == [True, False, False]
    assert rec.events["t"].tolist() == [10, 20, 30]
    assert rec.metadata["aedat2_layout"] == "dvs128" and rec.metadata["aedat2_skipped_non_dvs"] == 1


def test_aedat2_davis_and_errors(tmp_path, aedat2_file, aedat2_address):
    _, _davis = aedat2_address
    path = aedat2_file(tmp_path / "d.aedat", ["AEChip: eu.seebetter.ini.chips.davis.DAVIS240C"],
                   [_davis(0, 0, 1), _davis(239, 179, 0), _davis(5, 5, 1, aps=1)], [1, 2, 3])
    rec = read_events(path)
    assert rec.sensor_size == SensorSize(240, 180)
    assert rec.events["x"].tolist() == [239, 0] and rec.events["y"].tolist() == [179, 0]
    bare = aedat2_file(tmp_path / "b.aedat", [], [_davis(1, 1, 1)], [1])
    with pytest.raises(EventFileError, match=r"b.aedat: the AEDAT 2.0 header names no camera or sensor size"):
        read_events(bare)
    assert read_events(bare, sensor_size="346x260").events["x"].tolist() == [344]
    cut = tmp_path / "cut.aedat"
    cut.write_bytes(path.read_bytes()[:-3])
    with pytest.raises(EventFileError, match=r"cut.aedat: the data end inside an 8-byte event \(5 trailing bytes"):
        read_events(cut)
    with pytest.raises(EventFileError, match=r"sensor size 8x8 was given but the AEDAT 2.0 header says 240x180"):
        read_events(path, sensor_size="8x8")


def test_aedat3_packets(tmp_path, aedat3_file):
    path = aedat3_file(tmp_path / "c.aedat", [
        (1, 0, [(3, 4, 1, 1, 100), (239, 179, 0, 1, 200), (1, 1, 1, 0, 250)]),  # the last one is invalid
        (2, 0, [None, None]),                                                   # a non-polarity packet
        (1, 2, [(0, 0, 1, 1, 5)]),                                               # ts overflow 2: t = 2 << 31 | 5
    ])
    assert detect_format(path) == "aedat3"
    rec = read_events(path)
    assert rec.sensor_size == SensorSize(240, 180)
    assert rec.events["x"].tolist() == [3, 239, 0] and rec.events["y"].tolist() == [4, 179, 0]
    assert rec.events["t"].tolist() == [100, 200, (2 << 31) | 5]
    assert rec.events["p"].tolist() == [True, False, True]
    assert rec.metadata["aedat3_invalid_events"] == 1 and rec.metadata["aedat3_skipped_packets"] == {"type 2": 1}
    sized = aedat3_file(tmp_path / "s.aedat", [(1, 0, [(30, 3, 1, 1, 1)])],
                    header='#-Source 1: <attr key="dvsSizeX" type="short">32</attr><attr key="dvsSizeY" type="short">8</attr>\r\n')
    assert read_events(sized).sensor_size == SensorSize(32, 8)


def test_aedat3_damage(tmp_path, aedat3_file):
    path = aedat3_file(tmp_path / "c.aedat", [(1, 0, [(3, 4, 1, 1, 100), (5, 5, 0, 1, 200)])])
    data = path.read_bytes()
    for cut, message in ((len(data) - 3, r"packet 0 at byte offset \d+: 2 events of 8 bytes do not fit"),
                         (len(data) - 10, r"packet 0 .* do not fit"),
                         (data.index(b"#!END") + 14 + 10, r"packet 0 at byte offset \d+: header cut short \(10 of 28 bytes\)"),
                         (data.index(b"#!END") + 3, r"no '#!END-HEADER' line")):
        bad = tmp_path / "bad.aedat"
        bad.write_bytes(data[:cut])
        with pytest.raises(EventFileError, match=message):
            read_events(bad)


def test_aedat3_negative_event_count_is_named(tmp_path, aedat3_file):
    """Found by the fuzz campaign: eventNumber -5 reached np.frombuffer(count=-5), a ValueError traceback."""
    import struct

    path = aedat3_file(tmp_path / "c.aedat", [(1, 0, [(3, 4, 1, 1, 100), (5, 5, 0, 1, 200)])])
    data = bytearray(path.read_bytes())
    header = data.index(b"#!END-HEADER\r\n") + 14
    data[header + 20:header + 24] = struct.pack("<i", -5)  # the packet's eventNumber
    path.write_bytes(bytes(data))
    with pytest.raises(EventFileError, match=r"c\.aedat: packet 0 at byte offset \d+: event count -5 is negative"):
        read_events(path)
