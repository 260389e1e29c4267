"""numba kernel: first box face hit by each ray (the exact 3-D renderer's visibility test)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _cast_rays_kernel(origin, dirs, lo, hi, out):
    """Slab test of rays ``origin + t dirs[i]`` (t > 0) against boxes ``[lo[b], hi[b]]``.

    ``dirs`` (N, 3), ``lo``/``hi`` (B, 3), ``origin`` (3,) float64; writes to
    ``out[i]`` the face identifier ``1 + 6 b + f`` of the first face hit
    (``f = 2 axis`` entering through the -axis face, ``2 axis + 1`` through
    +axis) or 0. The arithmetic and tie-breaking are those of the vectorised
    form in :func:`evedge.sim.render3d._cast_rays` (first maximum of the
    entry times over the axes, first minimum over the boxes).
    """
    for i in range(dirs.shape[0]):
        d0 = dirs[i, 0]
        d1 = dirs[i, 1]
        d2 = dirs[i, 2]
        # no 0 * inf = NaN on axis-parallel rays
        if abs(d0) < 1e-300:
            d0 = 1e-300
        if abs(d1) < 1e-300:
            d1 = 1e-300
        if abs(d2) < 1e-300:
            d2 = 1e-300
        inv0 = 1.0 / d0
        inv1 = 1.0 / d1
        inv2 = 1.0 / d2
        best = np.inf
        best_box = 0
        best_axis = 0
        for b in range(lo.shape[0]):
            a0 = (lo[b, 0] - origin[0]) * inv0
            c0 = (hi[b, 0] - origin[0]) * inv0
            a1 = (lo[b, 1] - origin[1]) * inv1
            c1 = (hi[b, 1] - origin[1]) * inv1
            a2 = (lo[b, 2] - origin[2]) * inv2
            c2 = (hi[b, 2] - origin[2]) * inv2
            mn0, mx0 = min(a0, c0), max(a0, c0)
            mn1, mx1 = min(a1, c1), max(a1, c1)
            mn2, mx2 = min(a2, c2), max(a2, c2)
            axis = 0
            enter = mn0
            if mn1 > enter:
                axis = 1
                enter = mn1
            if mn2 > enter:
                axis = 2
                enter = mn2
            leave = min(mx0, min(mx1, mx2))
            if not (enter < leave and enter > 0.0):
                enter = np.inf
            if b == 0 or enter < best:  # first minimum over the boxes, as argmin
                best = enter
                best_box = b
                best_axis = axis
        if best < np.inf:
            d_axis = d0 if best_axis == 0 else (d1 if best_axis == 1 else d2)
            out[i] = 1 + 6 * best_box + 2 * best_axis + (1 if d_axis < 0 else 0)
        else:
            out[i] = 0
