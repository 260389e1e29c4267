"""MATLAB .mat events [x, y, p(+-1), t(us)]: reading and every malformed-input error."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io

from evedge.events import SensorSize
from evedge.io import EventFileError, read_events, read_mat


def _save(tmp_path, **variables):
    path = tmp_path / "ev.mat"
    scipy.io.savemat(path, variables)
    return path


def _matrix():
    return np.array([[3, 4, 1, 0], [127, 0, -1, 10], [5, 127, 1, 10], [0, 9, -1, 25]], dtype=np.int32)


def test_reads_columns_with_dvs128_convention(tmp_path):
    path = _save(tmp_path, events=_matrix())
    rec = read_events(path)
    assert rec.events["x"].tolist() == [3, 127, 5, 0]
    assert rec.events["y"].tolist() == [4, 0, 127, 9]
    assert rec.events["p"].tolist() == [True, False, True, False]
    assert rec.events["t"].tolist() == [0, 10, 10, 25]
    assert rec.sensor_size == SensorSize(128, 128)
    assert rec.metadata == {"source": str(path), "format": "mat", "sensor_size_from": "dvs128 .mat convention"}


def test_sensor_option_overrides_convention(tmp_path):
    rec = read_mat(_save(tmp_path, events=_matrix()), sensor_size=SensorSize(200, 150))
    assert rec.sensor_size == SensorSize(200, 150) and rec.metadata["sensor_size_from"] == "option"


def test_integral_doubles_are_accepted(tmp_path):
    rec = read_mat(_save(tmp_path, events=_matrix().astype(np.float64)))
    assert rec.events["t"].tolist() == [0, 10, 10, 25]


def _edited(row, col, value, dtype=np.int32):
    m = _matrix().astype(dtype)
    m[row, col] = value
    return m


@pytest.mark.parametrize("variables, message", [
    pytest.param({"ev": _matrix(), "other": np.zeros(2)}, r"ev\.mat: no variable 'events' \(variables: ev, other\)",
                 id="missing_variable_lists_the_variables"),
    pytest.param({"events": _matrix()[:, :3]}, r"variable 'events' has shape \(4, 3\), expected N x 4",
                 id="wrong_shape"),
    pytest.param({"events": _edited(2, 3, 10.5, np.float64)},
                 r"variable 'events' row 2 \(0-based\): column 't' = 10.5 is not an integer",
                 id="non_integer_value_names_row_and_column"),
    pytest.param({"events": np.array([["a", "b", "c", "d"]])}, "expected integers", id="non_numeric_dtype"),
    pytest.param({"events": _edited(1, 2, 0)}, r"row 1 \(0-based\): polarity 0, expected -1 or \+1",
                 id="polarity_outside_plus_minus_one"),
    pytest.param({"events": _edited(3, 0, 128)},
                 r"row 3 \(0-based\): x=128 is outside the sensor 128x128 \(size from dvs128 \.mat convention\)",
                 id="out_of_range_names_row"),
])
def test_bad_content_is_an_error_naming_the_place(tmp_path, variables, message):
    with pytest.raises(EventFileError, match=message):
        read_mat(_save(tmp_path, **variables))


def test_unsorted_names_row_and_sort_option(tmp_path):
    m = _matrix()
    m[:, 3] = [0, 30, 10, 10]
    with pytest.raises(EventFileError, match=r"row 2 \(0-based\): timestamps are not sorted.*sort=True"):
        read_mat(_save(tmp_path, events=m))
    rec = read_mat(tmp_path / "ev.mat", sort=True)
    assert rec.events["t"].tolist() == [0, 10, 10, 30]
    assert rec.events["x"].tolist() == [3, 5, 0, 127]


def test_empty_matrix_gives_zero_events(tmp_path):
    rec = read_mat(_save(tmp_path, events=np.zeros((0, 4), dtype=np.int32)))
    assert rec.events.size == 0


def test_stripes_real_recording(realdata):
    rec = read_events(realdata("rpg_event_lifetime/stripes.mat"))
    assert rec.events.size == 340_394
    assert rec.sensor_size == SensorSize(128, 128)
    assert rec.events["t"][0] == 0 and rec.events["t"][-1] == 1_197_752


def test_empty_or_truncated_file_is_an_event_file_error(tmp_path):
    # scipy raises MatReadError (not a ValueError) for these
    empty = tmp_path / "empty.mat"
    empty.write_bytes(b"")
    with pytest.raises(EventFileError, match=r"empty\.mat: not a readable MATLAB \.mat file"):
        read_mat(empty)


def test_doubles_beyond_int64_are_an_error_not_a_wrapped_value(tmp_path):
    with pytest.raises(EventFileError, match=r"row 3 \(0-based\): column 't' = 1e\+30 is out of the int64 range"):
        read_mat(_save(tmp_path, events=_edited(3, 3, 1e30, np.float64)))


def test_text_file_read_as_mat_is_an_event_file_error(tmp_path):
    # scipy fails with an IndexError on this one
    path = tmp_path / "events.txt"
    path.write_text("0.1 1 1 1\n0.05 2 2 0\n")
    with pytest.raises(EventFileError, match=r"events\.txt: not a readable MATLAB \.mat file"):
        read_mat(path)


def test_a_file_that_crashes_scipy_is_an_error_not_a_segfault(tmp_path):
    import io
    import struct

    import scipy.io

    buf = io.BytesIO()
    scipy.io.savemat(buf, {"events": np.array([[1, 2, 1, 10], [3, 4, -1, 20]], dtype=np.int32)}, do_compression=False)
    data = bytearray(buf.getvalue())
    assert struct.unpack_from("<I", data, 184)[0] == 5  # the real part's data type: miINT32
    data[185] = 0xF5  # an unknown data type: scipy's reader dies of SIGSEGV or SIGBUS on it (scipy 1.16)
    path = tmp_path / "bad.mat"
    path.write_bytes(bytes(data))
    with pytest.raises(EventFileError, match=r"bad\.mat: (the scipy \.mat decoder crashed \(SIG[A-Z]+\)|not a readable)"):
        read_mat(path)


def test_a_size_larger_than_the_file_is_an_error(tmp_path):
    import io
    import struct

    import scipy.io

    buf = io.BytesIO()
    scipy.io.savemat(buf, {"events": np.array([[1, 2, 1, 10]], dtype=np.int32)}, do_compression=True)
    data = bytearray(buf.getvalue())
    data[132:136] = struct.pack("<I", 2**31 - 8)  # the compressed element claims 2 GiB
    path = tmp_path / "big.mat"
    path.write_bytes(bytes(data))
    with pytest.raises(EventFileError, match=r"big\.mat: "):
        read_mat(path)
