"""The ray/box kernel of the exact 3-D renderer against the vectorised numpy form it replaced."""

import numpy as np
import pytest

from evedge.sim.render3d import _cast_rays


def ref_cast_rays(origin, dirs, lo, hi):
    """Vectorised slab test (the renderer's former implementation)."""
    n = len(dirs)
    if n == 0 or len(lo) == 0:
        return np.zeros(n, dtype=np.int64)
    d = np.where(np.abs(dirs) < 1e-300, 1e-300, dirs)
    inv = 1.0 / d
    t1 = (lo[None, :, :] - origin) * inv[:, None, :]
    t2 = (hi[None, :, :] - origin) * inv[:, None, :]
    t_min, t_max = np.minimum(t1, t2), np.maximum(t1, t2)
    axis = t_min.argmax(axis=2)
    t_enter = np.take_along_axis(t_min, axis[..., None], axis=2)[..., 0]
    t_exit = t_max.min(axis=2)
    t_enter = np.where((t_enter < t_exit) & (t_enter > 0.0), t_enter, np.inf)
    box = t_enter.argmin(axis=1)
    rows = np.arange(n)
    ax = axis[rows, box]
    face = 2 * ax + (d[rows, ax] < 0)
    return np.where(np.isfinite(t_enter[rows, box]), 1 + 6 * box + face, 0)


@pytest.mark.parametrize("seed", range(4))
def test_cast_rays_kernel_matches_reference(seed):
    rng = np.random.default_rng(seed)
    centres = rng.uniform([-2, -2, 3], [2, 2, 8], (4, 3))
    half = rng.uniform(0.2, 1.0, (4, 3))
    lo, hi = centres - half, centres + half
    origin = rng.uniform(-0.5, 0.5, 3)
    dirs = np.column_stack([rng.uniform(-0.6, 0.6, (3000, 2)), np.ones(3000)])
    dirs[:50, 0] = 0.0  # axis-parallel components
    dirs[50:100, :2] = 0.0
    dirs[100:150] *= -1.0  # away from the boxes
    got = _cast_rays(origin, dirs, lo, hi)
    want = ref_cast_rays(origin, dirs, lo, hi)
    np.testing.assert_array_equal(got, want)
    assert np.count_nonzero(got) > 300 and np.count_nonzero(got == 0) > 100
    assert len(np.unique(got[got > 0] % 6)) >= 2  # several face kinds seen


def test_cast_rays_from_inside_and_empty():
    lo, hi = np.array([[-1.0, -1, -1]]), np.array([[1.0, 1, 1]])
    dirs = np.array([[0.0, 0, 1], [1.0, 0, 0]])
    # from inside a box the entry time is negative: no hit (same as the reference)
    np.testing.assert_array_equal(_cast_rays(np.zeros(3), dirs, lo, hi), ref_cast_rays(np.zeros(3), dirs, lo, hi))
    assert _cast_rays(np.zeros(3), np.empty((0, 3)), lo, hi).shape == (0,)
    origin = np.array([0.0, 0, -5])
    assert _cast_rays(origin, dirs[:1], lo, hi)[0] == 1 + 4  # enters through the -z face (f = 4)
