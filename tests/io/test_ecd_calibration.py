"""An Event Camera Dataset folder's calib.txt is read, kept, written and stored in HDF5."""

from __future__ import annotations

import pytest

from evedge.calibration import CameraCalibration
from evedge.events import Recording, SensorSize, make_events
from evedge.io import EventFileError, read_events, write_events, write_recording

# slider_depth/calib.txt
ECD = CameraCalibration(335.419462958, 335.352935612, 129.924663379, 99.1864303447,
                        -0.138592767408, 0.0933736664192, -0.000335586987532, 0.000173720158228, 0.0)
SENSOR = SensorSize(240, 180)


def test_ecd_folder_keeps_calib_txt(tmp_path, realdata):
    rec = Recording(make_events([1, 2], [1, 2], [0, 10], [1, 0]), SENSOR, calibration=ECD)
    write_events(tmp_path / "ecd", rec)
    assert (tmp_path / "ecd" / "calib.txt").is_file()
    back = read_events(tmp_path / "ecd", sensor_size=SENSOR)
    assert back.calibration == ECD and back.metadata["calibration_source"].endswith("calib.txt")
    write_events(tmp_path / "ecd", Recording(rec.events, SENSOR))
    assert not (tmp_path / "ecd" / "calib.txt").exists()
    assert read_events(write_recording(tmp_path / "r.h5", rec)).calibration == ECD
    (tmp_path / "ecd" / "calib.txt").write_text("335.4 nan 1 2\n")
    with pytest.raises(EventFileError, match=r"calib.txt: CameraCalibration.fy_px must be finite"):
        read_events(tmp_path / "ecd", sensor_size=SENSOR)
    real = read_events(realdata("slider_depth"))
    assert real.calibration == ECD
