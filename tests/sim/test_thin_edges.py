"""Thin exact edge maps: one pixel per boundary crossing of each row / column (known answers)."""

import math

import numpy as np
import pytest

from evedge.sim import edge_map, load_scene, parse_scene, thin_edge_map
from evedge.sim.thin_edges import mark_circle, mark_segments


def _stripes(angle_deg, width=48, height=40, period=200.0, phase=30.0):
    return parse_scene({"scene": {"kind": "stripes", "duration_s": 1.0, "frame_rate_hz": 0},
                        "sensor": {"width": width, "height": height},
                        "stripes": [{"period_px": period, "angle_deg": angle_deg, "velocity_px_s": [0, 0],
                                     "phase_px": phase, "duty": 0.5}]})


@pytest.mark.parametrize("angle_deg", [0, 10, 20, 33, 44])
def test_straight_steep_edge_has_exactly_one_pixel_per_row(angle_deg):
    """One boundary (the period exceeds the sensor) at normal angle < 45 degrees: exactly one pixel per row,
    at the column where the boundary crosses the row's centre line."""
    scene = _stripes(angle_deg)
    thin = thin_edge_map(scene, 0.0)
    a = math.radians(angle_deg)
    # boundary u = cos a x + sin a y - phase = 0 (u mod period = 0) -> x(y) = (phase - sin a y) / cos a
    for y in range(thin.shape[0]):
        want = math.floor((30.0 - math.sin(a) * y) / math.cos(a) + 0.5)
        assert np.flatnonzero(thin[y]).tolist() == [want], y
    # the open-square map is thicker on oblique edges: the squares a line crosses, 1 + |tan a| per row
    thick = edge_map(scene, 0.0).sum(axis=1).mean()
    assert thick == pytest.approx(1 + abs(math.tan(a)), abs=0.05)


@pytest.mark.parametrize("angle_deg", [46, 60, 80, 90])
def test_straight_flat_edge_has_exactly_one_pixel_per_column(angle_deg):
    thin = thin_edge_map(_stripes(angle_deg, width=40, height=48), 0.0)
    assert (thin.sum(axis=0) == 1).all()


def test_thin_is_inside_the_exact_map_on_shapes():
    scene = load_scene("scenes/shapes_translation.toml")
    for t in (0.0, 0.5, 1.7):
        thin, thick = thin_edge_map(scene, t), edge_map(scene, t)
        assert thin.any() and not (thin & ~thick).any()
        assert thin.sum() < 0.85 * thick.sum()


def test_segment_and_circle_crossings():
    img = np.zeros((10, 10), bool)
    mark_segments(img, [1.0], [2.0], [7.0], [2.0])  # horizontal at a row's centre line: columns 1..6
    assert np.argwhere(img).tolist() == [[2, c] for c in range(1, 7)]
    img[:] = False
    mark_circle(img, 4.5, 4.5, 3.0)
    # 4-fold symmetric about (4.5, 4.5), one pixel per crossing of each line
    assert (img == img[::-1]).all() and (img == img[:, ::-1]).all() and (img == img.T).all()
    # row 4: x = 4.5 -+ sqrt(9 - 0.25) = 1.54, 7.46 -> columns 2 and 7
    assert np.flatnonzero(img[4]).tolist() == [2, 7]


def test_mesh_scene_is_refused():
    scene = load_scene("scenes/boxes_3d.toml")
    with pytest.raises(NotImplementedError, match="planar scenes only"):
        thin_edge_map(scene, 0.0)
