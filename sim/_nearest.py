"""numba kernel: unit normal of the nearest shape boundary (ground-truth gradient direction)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _nearest_outward_normal(qx, qy, poly_x, poly_y, poly_start, poly_orient, poly_flip,
                            circ_x, circ_y, circ_r, circ_flip, out_nx, out_ny):
    """For each point ``(qx[i], qy[i])``, the normal of the nearest boundary.

    Polygons are ``poly_x/y[poly_start[k]:poly_start[k + 1]]`` with orientation
    ``poly_orient[k]`` (sign of the shoelace area); circles have centre and
    radius. The outward normal is multiplied by ``poly_flip[k]`` or
    ``circ_flip[k]`` (+1: the shape is darker than what surrounds it, so the
    brightness gradient points outward; -1: inward).
    """
    n_poly = poly_start.shape[0] - 1
    # bounding boxes, grown by a margin far above rounding: a polygon whose box is not nearer
    # than the best edge so far cannot hold a nearer edge, and is skipped (same result)
    lo_x = np.empty(n_poly)
    hi_x = np.empty(n_poly)
    lo_y = np.empty(n_poly)
    hi_y = np.empty(n_poly)
    for k in range(n_poly):
        lo_x[k] = 1e300
        hi_x[k] = -1e300
        lo_y[k] = 1e300
        hi_y[k] = -1e300
        for m in range(poly_start[k], poly_start[k + 1]):
            lo_x[k] = min(lo_x[k], poly_x[m] - 1e-6)
            hi_x[k] = max(hi_x[k], poly_x[m] + 1e-6)
            lo_y[k] = min(lo_y[k], poly_y[m] - 1e-6)
            hi_y[k] = max(hi_y[k], poly_y[m] + 1e-6)
    for i in range(qx.shape[0]):
        x = qx[i]
        y = qy[i]
        best = 1e300
        bx = math.nan
        by = math.nan
        for k in range(n_poly):
            gx = max(lo_x[k] - x, 0.0, x - hi_x[k])
            gy = max(lo_y[k] - y, 0.0, y - hi_y[k])
            if gx * gx + gy * gy >= best:
                continue
            s0 = poly_start[k]
            s1 = poly_start[k + 1]
            j = s1 - 1
            for m in range(s0, s1):
                ax = poly_x[j]
                ay = poly_y[j]
                dx = poly_x[m] - ax
                dy = poly_y[m] - ay
                ll = dx * dx + dy * dy
                t = 0.0
                if ll > 0.0:
                    t = min(1.0, max(0.0, ((x - ax) * dx + (y - ay) * dy) / ll))
                ex = ax + t * dx - x
                ey = ay + t * dy - y
                d2 = ex * ex + ey * ey
                if d2 < best and ll > 0.0:
                    best = d2
                    inv = poly_orient[k] * poly_flip[k] / math.sqrt(ll)
                    bx = dy * inv
                    by = -dx * inv
                j = m
        for k in range(circ_x.shape[0]):
            dx = x - circ_x[k]
            dy = y - circ_y[k]
            d = math.sqrt(dx * dx + dy * dy)
            g = d - circ_r[k]
            if g * g < best and d > 0.0:
                best = g * g
                bx = circ_flip[k] * dx / d
                by = circ_flip[k] * dy / d
        out_nx[i] = bx
        out_ny[i] = by
