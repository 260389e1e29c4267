"""read_events: format detection, path errors, and the real recordings."""

from __future__ import annotations

import numpy as np
import pytest

from evedge.events import SensorSize
from evedge.io import EventFileError, detect_format, read_events, write_recording


def test_nonexistent_path(tmp_path):
    with pytest.raises(EventFileError, match=r"nope\.txt: no such file or directory"):
        read_events(tmp_path / "nope.txt")
    with pytest.raises(EventFileError, match="no such file or directory"):
        read_events(tmp_path / "nope.txt", format="ecd")


def test_unknown_extension(tmp_path):
    path = tmp_path / "events.csv"
    path.write_text("0.1,1,2,0\n")
    with pytest.raises(EventFileError, match=r"events\.csv: unknown event file type \(extension '\.csv'.*format="):
        read_events(path)


def test_format_option_overrides_extension(tmp_path):
    path = tmp_path / "events.csv"
    path.write_text("0.1 1 2 0\n")
    rec = read_events(path, format="ecd", sensor_size="dvs128")
    assert rec.events.size == 1 and rec.sensor_size == SensorSize(128, 128)
    with pytest.raises(ValueError, match="format='csv'"):
        read_events(path, format="csv")


def test_sensor_size_type_is_checked(tmp_path):
    path = tmp_path / "events.txt"
    path.write_text("0.1 1 2 0\n")
    with pytest.raises(TypeError, match="sensor_size must be a SensorSize"):
        read_events(path, sensor_size=(240, 180))


@pytest.mark.parametrize("name, garbage, message", [
    ("bad.h5", b"not hdf5" * 100, r"bad\.h5: not a readable HDF5 file"),
    ("bad.mat", b"this is not matlab data at all" * 10, r"bad\.mat: not a readable MATLAB \.mat file"),
    ("bad.aedat4", b"garbage", r"bad\.aedat4: not a readable AEDAT4 file"),
])
def test_garbage_with_a_known_extension_names_the_format(tmp_path, name, garbage, message):
    path = tmp_path / name
    path.write_bytes(garbage)
    with pytest.raises(EventFileError, match=message):
        read_events(path)


def test_hdf5_detected_by_magic_bytes(tmp_path, small_recording):
    path = write_recording(tmp_path / "rec.data", small_recording())
    assert detect_format(path) == "hdf5"
    assert detect_format(tmp_path) == "ecd"


def test_slider_depth_real_recording(realdata):
    path = realdata("slider_depth/events_chunk.txt")
    rec = read_events(path)
    assert rec.events.size == 50_000
    assert rec.sensor_size == SensorSize(240, 180)
    assert rec.metadata["sensor_size_from"] == "frames"
    assert len(rec.frames) == 87 and rec.frames.images.dtype == np.uint8
    assert rec.events["t"][0] == 3811 and rec.events["t"][-1] == 174_156
    assert rec.frames.t_us[1] == 38_766


def test_slider_depth_folder_finds_events_chunk(realdata):
    rec = read_events(realdata("slider_depth"))
    assert rec.events.size == 50_000
