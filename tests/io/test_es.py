"""Event Stream (.es) through faery: header checks and round trip."""

from __future__ import annotations

import pytest

from evedge.events import Recording, SensorSize, make_events
from evedge.io import EventFileError, read_events, write_events


def test_round_trip_and_header(tmp_path):
    pytest.importorskip("faery")
    ev = make_events([0, 5, 7], [0, 3, 5], [0, 40, 90_000], [1, 0, 1])
    path = write_events(tmp_path / "a.es", Recording(ev, SensorSize(8, 6)))
    rec = read_events(path)
    assert rec.events.tobytes() == ev.tobytes() and rec.sensor_size == SensorSize(8, 6)
    assert rec.metadata["es_type"] == "dvs" and rec.metadata["sensor_size_from"] == "file header"
    data = path.read_bytes()
    with pytest.raises(EventFileError, match="sensor size 4x4 was given but the Event Stream header says 8x6"):
        read_events(path, sensor_size="4x4")
    (tmp_path / "b.es").write_bytes(data[:17])
    with pytest.raises(EventFileError, match=r"b.es: the Event Stream header ends at byte 17, before the sensor size"):
        read_events(tmp_path / "b.es")
    (tmp_path / "c.es").write_bytes(data[:15] + b"\x00" + data[16:])
    with pytest.raises(EventFileError, match=r"c.es: byte offset 15: Event Stream type generic"):
        read_events(tmp_path / "c.es")
    (tmp_path / "d.es").write_bytes(b"Event Strea")
    with pytest.raises(EventFileError, match=r"not an Event Stream file"):
        read_events(tmp_path / "d.es")
