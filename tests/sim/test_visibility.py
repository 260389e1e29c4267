"""The analytic (numba) visibility of the exact 3-D renderer against the sampled implementation it replaced.

The reference (``tests/sim/_render3d_reference.py``) samples each projected edge every 1/8 px
and bisects visibility changes to ~7e-9 px; the analytic kernel finds them as segment
intersections. Both must give the same edge maps and intensities within 1e-7 (the reference's
bisection tolerance times the largest jump, plus rounding).
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from evedge.sim.render3d import Box3D, CameraTrajectory, MeshRenderer
from evedge.sim.build import build_trajectory
from evedge.sim.scene import load_scene

sys.path.insert(0, str(Path(__file__).parent))
from _render3d_reference import ReferenceRenderer  # noqa: E402

SCENES = Path(__file__).resolve().parents[2] / "scenes"

LAYOUTS = {
    "apart": (CameraTrajectory((0.6, -0.7, 0.0), (0.3, 0.0, 0.2), (0.1, -0.12, -0.1), (0.1, 0.2, 0.1)),
              [Box3D((0.0, 0.0, 5.0), (1.0, 1.2, 1.4), (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)),
               Box3D((0.8, 0.3, 7.0), (1.0, 1.2, 1.4), (0.9, 0.2, 0.7, 0.4, 0.95, 0.6)),
               Box3D((-1.5, -0.6, 4.0), (1.0, 1.2, 1.4), (0.9, 0.2, 0.7, 0.4, 0.95, 0.6))]),
    # aligned faces seen from their common plane: box edges project onto common lines
    "stacked": (CameraTrajectory((0.4, 0.0, 0.0), (0.0, 0.0, 0.3), (0.0, 0.0, 0.08), (0.0, 0.0, 0.0)),
                [Box3D((0.0, -0.5, 5.0), (1.0, 1.0, 1.0), (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)),
                 Box3D((0.0, 0.5, 5.0), (1.0, 1.0, 1.0), (0.9, 0.8, 0.7, 0.6, 0.95, 0.4)),
                 Box3D((1.0, 0.5, 5.0), (1.0, 1.0, 1.0), (0.3, 0.8, 0.7, 0.6, 0.05, 0.4))]),
    # a floor reaching behind the camera (near-plane clipping), a wall through it, interpenetrating boxes
    "overlapping": (CameraTrajectory((0, 0, 0), (0.3, 0, 0.5), (0.05, 0.1, -0.2), (0.1, 0.2, 0.0)),
                    [Box3D((0, 1.5, 10), (20, 1.0, 40), (0.2, 0.2, 0.35, 0.6, 0.25, 0.25)),
                     Box3D((0, 0, 12), (30, 30, 0.5), (0.8,) * 6),
                     Box3D((0.5, 0.5, 4), (1, 1, 1), (0.1, 0.9, 0.3, 0.6, 0.7, 0.2)),
                     Box3D((0.9, 0.7, 4.2), (1, 0.5, 1.2), (0.5, 0.1, 0.95, 0.6, 0.05, 0.2))]),
}


def _pair(trajectory, boxes, **kw):
    args = dict(width=120, height=90, fx=100.0, fy=104.0, cx=59.7, cy=44.2)
    args.update(kw)
    fast = MeshRenderer(args["width"], args["height"], args["fx"], args["fy"], args["cx"], args["cy"], boxes,
                        trajectory, background=0.55)
    slow = ReferenceRenderer(args["width"], args["height"], args["fx"], args["fy"], args["cx"], args["cy"], boxes,
                             trajectory, background=0.55)
    return fast, slow


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_analytic_visibility_matches_sampled_reference(layout):
    fast, slow = _pair(*LAYOUTS[layout])
    for t in (0.0, 0.13, 0.4):
        a, b = fast.intensity(t), slow.intensity(t)
        assert np.unique(a).size > 20
        assert np.abs(a - b).max() <= 1e-7, (layout, t)
        for contrast_only in (False, True):
            np.testing.assert_array_equal(fast.edges(t, contrast_only), slow.edges(t, contrast_only))
    assert fast._renderer is None  # no GL for the exact path


def test_boxes_3d_matches_reference_along_the_scene():
    scene = load_scene(SCENES / "boxes_3d.toml")
    s = scene.sensor
    boxes, tr = [Box3D(**b) for b in scene.objects], build_trajectory(scene.motion)
    fast, slow = _pair(tr, boxes, width=s.width, height=s.height, fx=s.fx, fy=s.fy, cx=s.cx, cy=s.cy)
    for t in np.linspace(0.0, scene.duration_s, 6):
        assert np.abs(fast.intensity(t) - slow.intensity(t)).max() <= 1e-7
        np.testing.assert_array_equal(fast.edges(t), slow.edges(t))


def test_flow_at_equals_the_flow_field_on_the_grid():
    tr, boxes = LAYOUTS["overlapping"]
    r = MeshRenderer(80, 60, 70.0, 72.0, 39.6, 30.2, boxes, tr)
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0.0, 0.5, 400))
    x, y = rng.integers(0, 80, t.size), rng.integers(0, 60, t.size)
    vx, vy = r.flow_at(x, y, t)
    want = np.array([r.flow(tk)[:, yk, xk] for tk, xk, yk in zip(t, x, y)])
    np.testing.assert_allclose(vx, want[:, 0], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(vy, want[:, 1], rtol=1e-12, atol=1e-9)
    with pytest.raises(ValueError, match="one length"):
        r.flow_at([1, 2], [1], [0.0, 0.1])
    assert r._renderer is None
