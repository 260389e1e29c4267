"""The shared event type: make_events, validate_events, sort_events, SensorSize, containers."""

from __future__ import annotations

import numpy as np
import pytest

from evedge.events import (
    EVENT_DTYPE, SENSOR_PRESETS, Frames, Recording, SensorSize, find_out_of_sensor, find_time_decrease, make_events,
    seconds_to_us, sort_events, validate_events,
)


def test_dtype_is_tonics():
    assert EVENT_DTYPE.names == ("x", "y", "t", "p")
    assert [EVENT_DTYPE[n] for n in "xytp"] == [np.dtype(np.int16)] * 2 + [np.dtype(np.int64), np.dtype(bool)]


def test_make_events_columns_and_polarity_conventions():
    ev = make_events([1, 2, 3], [4, 5, 6], [10, 20, 30], [-1, 0, 1])
    assert ev.dtype == EVENT_DTYPE
    assert ev["p"].tolist() == [False, False, True]
    assert make_events([1], [1], [1], [True])["p"].tolist() == [True]


@pytest.mark.parametrize("cols, message", [
    (([1, 2], [1], [1, 2], [0, 1]), "column 'y' must be 1-D of length 2"),
    (([1.5], [1], [1], [0]), "column 'x' must hold integers"),
    (([1], [1], [np.nan], [0]), "column 't' has a non-finite value at index 0"),
    (([40000], [1], [1], [0]), "column 'x' out of int16 range"),
    (([1], [1], [1e300], [0]), "column 't' out of int64 range"),
    (([1], [1], np.array([2**63], dtype=np.uint64), [0]), "column 't' out of int64 range"),
])
def test_make_events_errors(cols, message):
    with pytest.raises(ValueError, match=message):
        make_events(*cols)


def test_seconds_to_us_rounds_to_nearest():
    assert seconds_to_us([0.0000004, 0.0000006, 0.003820001, 1.9999996]).tolist() == [0, 1, 3820, 2_000_000]
    with pytest.raises(ValueError, match="non-finite value at index 1"):
        seconds_to_us([0.0, np.inf])


def test_validate_events_wrong_dtype():  # lossless other dtypes: tests/test_events_interop.py
    with pytest.raises(TypeError, match="mine: expected a structured array with fields x, y, t, p"):
        validate_events(np.zeros(3), name="mine")
    wrong = np.zeros(2, dtype=[("x", "f4"), ("y", "i4"), ("t", "i8"), ("p", "?")])
    with pytest.raises(TypeError, match="field 'x' must hold integer pixel coordinates, got float32"):
        validate_events(wrong)


def test_validate_events_range_and_order():
    ev = make_events([0, 5, 2], [0, 1, 2], [0, 10, 20], [1, 0, 1])
    assert validate_events(ev, SensorSize(6, 3)) is ev
    with pytest.raises(ValueError, match=r"event 1 has x=5 outside the sensor \(5x3\)"):
        validate_events(ev, SensorSize(5, 3))
    ev["t"][2] = 5
    with pytest.raises(ValueError, match="timestamps are not sorted: event 2 has t=5 us < t=10 us"):
        validate_events(ev)
    with pytest.raises(ValueError, match="1-D"):
        validate_events(ev.reshape(3, 1))


def test_find_out_of_sensor_and_time_decrease():
    size = SensorSize(4, 3)
    assert find_out_of_sensor([0, 3], [0, 2], size) is None
    # x before y; the count is of the reported axis; raw columns beyond int16 are fine
    assert find_out_of_sensor([0, 4, -1, 70000], [5, 0, 0, 0], size) == ("x", 1, 3)
    assert find_out_of_sensor(np.array([0, 1]), np.array([0, 3]), size) == ("y", 1, 1)
    assert find_time_decrease([0, 0, 5]) is None and find_time_decrease([]) is None
    assert find_time_decrease([0, 10, 5, 7, 6]) == (2, 2)


def test_sort_events_is_stable():
    ev = make_events([0, 1, 2, 3, 4], [0] * 5, [5, 1, 5, 1, 0], [1] * 5)
    assert sort_events(ev)["x"].tolist() == [4, 1, 3, 0, 2]


def test_sensor_size_parse_and_errors():
    assert SensorSize.parse("240x180") == SensorSize(240, 180)
    assert SensorSize.parse(" DAVIS346 ") == SENSOR_PRESETS["davis346"] == SensorSize(346, 260)
    assert SensorSize(240, 180).shape == (180, 240)
    for text in ("240", "240x", "axb", "240x180x2", "-240x180"):
        with pytest.raises(ValueError, match="expected WIDTHxHEIGHT"):
            SensorSize.parse(text)
    with pytest.raises(ValueError, match="SensorSize.width must be in 1..32767"):
        SensorSize.parse("0x10")
    with pytest.raises(TypeError, match="SensorSize.height must be an integer"):
        SensorSize(10, 2.5)


def test_frames_and_recording_checks():
    with pytest.raises(ValueError, match="do not match"):
        Frames([0, 1], np.zeros((3, 2, 2)))
    ev = make_events([1], [1], [0], [1])
    with pytest.raises(ValueError, match="frames are 3x2 but the sensor is 4x4"):
        Recording(ev, SensorSize(4, 4), frames=Frames([0], np.zeros((1, 2, 3))))
    with pytest.raises(ValueError, match="truth has 2 rows but there are 1 events"):
        Recording(ev, SensorSize(4, 4), truth=np.zeros(2, dtype=[("a", "f8")]))


def test_time_decrease_found_across_extreme_int64_values():
    # np.diff of these wraps around to a positive number
    t = np.array([100_000, np.iinfo(np.int64).min], dtype=np.int64)
    assert find_time_decrease(t) == (1, 1)
    ev = make_events([0, 0], [0, 0], t, [1, 1])
    with pytest.raises(ValueError, match="timestamps are not sorted: event 1"):
        validate_events(ev)


def test_seconds_to_us_refuses_values_beyond_int64():
    with pytest.raises(ValueError, match="value 1e\\+300 s at index 1 is out of the int64 microsecond range"):
        seconds_to_us([0.0, 1e300])
    assert seconds_to_us([-9e12]).tolist() == [-9_000_000_000_000_000_000]
