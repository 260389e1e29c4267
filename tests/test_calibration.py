"""calib.txt and undistortion, against the closed-form distortion model."""

from __future__ import annotations

import numpy as np
import pytest

from evedge.calibration import CameraCalibration, distort_points, undistort_events, undistort_frames, undistortion_map
from evedge.events import Frames, SensorSize, make_events

# the Event Camera Dataset's DAVIS240C calibration (slider_depth/calib.txt)
ECD = CameraCalibration(335.419462958, 335.352935612, 129.924663379, 99.1864303447,
                        -0.138592767408, 0.0933736664192, -0.000335586987532, 0.000173720158228, 0.0)
STRONG = CameraCalibration(150.0, 150.0, 119.5, 89.5, k1=-0.35, k2=0.12, p1=0.002, p2=-0.003, k3=0.01)
SENSOR = SensorSize(240, 180)


def test_parse_and_errors(tmp_path):
    assert CameraCalibration.from_text(" ".join(map(str, ECD.as_list()))) == ECD
    assert CameraCalibration.from_text("100 100 50 40").k1 == 0.0
    with pytest.raises(ValueError, match=r"c.txt: number 3 \('x'\) is not a number"):
        CameraCalibration.from_text("1 2 x 4", source="c.txt")
    with pytest.raises(ValueError, match=r"expected 'fx fy cx cy k1 k2 p1 p2 k3' \(9 numbers\), found 2"):
        CameraCalibration.from_text("1 2")
    with pytest.raises(ValueError, match=r"fx_px must be > 0"):
        CameraCalibration.from_text("0 1 2 3")


def test_zero_distortion_is_the_identity():
    calib = CameraCalibration(200.0, 210.0, 119.5, 89.5)
    mx, my = undistortion_map(calib, SENSOR)
    yy, xx = np.mgrid[0:180, 0:240]
    assert np.abs(mx - xx).max() < 1e-9 and np.abs(my - yy).max() < 1e-9
    ev = make_events([0, 239, 17], [0, 179, 3], [1, 2, 3], [1, 0, 1])
    out, kept = undistort_events(ev, calib, SENSOR)
    assert out.tobytes() == ev.tobytes() and kept.all()
    img = np.random.default_rng(0).integers(0, 256, (2, 180, 240), dtype=np.uint8)
    assert np.array_equal(undistort_frames(Frames([0, 5], img), calib).images, img)


@pytest.mark.parametrize("calib", [ECD, STRONG])
def test_undistorted_points_distort_back_to_the_pixel(calib):
    # the closed-form forward model applied to OpenCV's inverse gives every pixel back
    mx, my = undistortion_map(calib, SENSOR)
    u, v = distort_points(calib, mx, my)
    yy, xx = np.mgrid[0:180, 0:240]
    assert np.abs(u - xx).max() < 1e-6 and np.abs(v - yy).max() < 1e-6


def test_events_round_to_the_nearest_pixel_and_drop_outside():
    mx, my = undistortion_map(STRONG, SENSOR)
    rng = np.random.default_rng(1)
    n = 2000
    ev = make_events(rng.integers(0, 240, n), rng.integers(0, 180, n), np.arange(n), rng.integers(0, 2, n))
    out, kept = undistort_events(ev, STRONG, SENSOR)
    ux, uy = np.rint(mx[ev["y"], ev["x"]]), np.rint(my[ev["y"], ev["x"]])
    inside = (ux >= 0) & (ux < 240) & (uy >= 0) & (uy < 180)
    assert np.array_equal(kept, inside) and 0 < (~kept).sum() < n  # barrel: the corners leave the sensor
    assert np.array_equal(out["x"], ux[kept]) and np.array_equal(out["y"], uy[kept])
    assert np.array_equal(out["t"], ev["t"][kept]) and np.array_equal(out["p"], ev["p"][kept])
    # the principal point does not move
    centre = make_events([120], [90], [0], [1])
    assert undistort_events(centre, STRONG, SENSOR)[0]["x"].tolist() == [120]


def test_frames_sample_the_input_at_the_distorted_position():
    # a linear image is reproduced exactly by bilinear interpolation: result(p) = I(distort(p))
    yy, xx = np.mgrid[0:180, 0:240].astype(np.float64)
    image = (0.3 * xx + 0.7 * yy).astype(np.float32)
    out = undistort_frames(Frames([0], image[None]), STRONG).images[0]
    u, v = distort_points(STRONG, xx, yy)
    inside = (u >= 1) & (u <= 238) & (v >= 1) & (v <= 178)
    expected = 0.3 * u + 0.7 * v
    assert np.abs(out[inside] - expected[inside]).max() < 0.02  # OpenCV's maps are float32, 5-bit subpixel
    with pytest.raises(TypeError, match="boolean edge maps cannot be interpolated"):
        undistort_frames(Frames([0], np.zeros((1, 4, 4), bool)), STRONG)
