"""numba kernel: depth of the first triangle hit by each ray (per-event truth of the raster mesh renderer)."""

from __future__ import annotations

import numpy as np
from numba import njit

from ._visibility import _pose_ray


@njit(cache=True)
def _first_hit_depth_kernel(x, y, rot, centre, v0, e1, e2, znear, out_z):
    """z-depth of the first triangle hit by the camera ray ``(x[i], y[i], 1)`` (inf: none).

    ``rot`` (M, 3, 3) and ``centre`` (M, 3) are one pose (M = 1) or one per point; triangles
    are ``v0 + a e1 + b e2`` (T, 3) in the world frame. Moller-Trumbore intersection; the ray
    parameter along ``R (x, y, 1)`` is the z-depth itself; hits nearer than ``znear`` are
    ignored, as the OpenGL near plane clips them. Brute force over the triangles.
    """
    for i in range(x.shape[0]):
        o0, o1, o2, d0, d1, d2 = _pose_ray(rot, centre, i, x[i], y[i])
        best = np.inf
        for k in range(v0.shape[0]):
            a0, a1, a2 = e1[k, 0], e1[k, 1], e1[k, 2]
            b0, b1, b2 = e2[k, 0], e2[k, 1], e2[k, 2]
            p0 = d1 * b2 - d2 * b1
            p1 = d2 * b0 - d0 * b2
            p2 = d0 * b1 - d1 * b0
            det = a0 * p0 + a1 * p1 + a2 * p2
            if abs(det) < 1e-300:
                continue
            inv = 1.0 / det
            s0, s1, s2 = o0 - v0[k, 0], o1 - v0[k, 1], o2 - v0[k, 2]
            u = (s0 * p0 + s1 * p1 + s2 * p2) * inv
            if u < 0.0 or u > 1.0:
                continue
            q0 = s1 * a2 - s2 * a1
            q1 = s2 * a0 - s0 * a2
            q2 = s0 * a1 - s1 * a0
            v = (d0 * q0 + d1 * q1 + d2 * q2) * inv
            if v < 0.0 or u + v > 1.0:
                continue
            t = (b0 * q0 + b1 * q1 + b2 * q2) * inv
            if znear <= t < best:
                best = t
        out_z[i] = best
