"""numba kernels: exact visibility of box scenes (ray casting, visible discontinuities).

The image of a scene of flat polyhedra is piecewise constant in the face seen; its
discontinuities lie on the projected edges. Along one projected edge the pair of faces seen on
either side can only change where the image of another edge meets it (a crossing, a T-junction
or the end of a collinear edge), so the visible pieces follow from 2-D segment intersections and
one pair of ray casts per interval between consecutive break points, without any sampling.
The public, validating wrappers live in :mod:`evedge.sim.render3d`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Side offset (px) at which the faces either side of an edge are probed.
SIDE_PX = 1e-8
#: Two projected edges closer than this (px) along their whole common part are one line.
COLLINEAR_PX = 1e-6


@njit(cache=True, inline="always")
def _first_face(o0, o1, o2, d0, d1, d2, lo, hi):
    """Face identifier ``1 + 6 b + f`` of the first box face hit by the ray ``o + t d`` (t > 0), or 0.

    ``f = 2 axis`` entering through the -axis face, ``2 axis + 1`` through +axis; ties: the
    first maximum of the entry times over the axes, the first minimum over the boxes (as the
    vectorised slab test this replaced, see ``tests/sim/test_raycast.py``).
    """
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
        a0 = (lo[b, 0] - o0) * inv0
        c0 = (hi[b, 0] - o0) * inv0
        a1 = (lo[b, 1] - o1) * inv1
        c1 = (hi[b, 1] - o1) * inv1
        a2 = (lo[b, 2] - o2) * inv2
        c2 = (hi[b, 2] - o2) * inv2
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
        return 1 + 6 * best_box + 2 * best_axis + (1 if d_axis < 0 else 0)
    return 0


@njit(cache=True)
def _cast_rays_kernel(origin, dirs, lo, hi, out):
    """``out[i]``: face identifier of the first face hit by ray ``origin + t dirs[i]`` (see :func:`_first_face`)."""
    for i in range(dirs.shape[0]):
        out[i] = _first_face(origin[0], origin[1], origin[2], dirs[i, 0], dirs[i, 1], dirs[i, 2], lo, hi)


@njit(cache=True, inline="always")
def _pixel_face(u, v, rot, centre, fx, fy, cx, cy, lo, hi):
    """Face seen at image point ``(u, v)``: the ray ``R ((u - cx) / fx, (v - cy) / fy, 1)`` from ``centre``."""
    x = (u - cx) / fx
    y = (v - cy) / fy
    d0 = rot[0, 0] * x + rot[0, 1] * y + rot[0, 2]
    d1 = rot[1, 0] * x + rot[1, 1] * y + rot[1, 2]
    d2 = rot[2, 0] * x + rot[2, 1] * y + rot[2, 2]
    return _first_face(centre[0], centre[1], centre[2], d0, d1, d2, lo, hi)


@njit(cache=True)
def _clip_range(p0, p1, lo, hi):
    """Liang-Barsky on one coordinate: ``(a, b)`` narrowed to where ``lo <= p0 + s (p1 - p0) <= hi``."""
    delta = p1 - p0
    if abs(delta) < 1e-15:
        if p0 < lo or p0 > hi:
            return 1.0, 0.0
        return 0.0, 1.0
    s_lo = (lo - p0) / delta
    s_hi = (hi - p0) / delta
    if s_lo > s_hi:
        s_lo, s_hi = s_hi, s_lo
    return s_lo, s_hi


@njit(cache=True)
def _project_edges(edges, rot, centre, fx, fy, cx, cy, znear, u_lo, v_lo, u_hi, v_hi, seg):
    """Clip every world edge (E, 2, 3) to ``z >= znear`` (camera frame), project it and clip
    it to the view ``[u_lo, u_hi] x [v_lo, v_hi]``; writes ``(u0, v0, u1, v1)`` rows to ``seg``
    and returns their count (edges seen end-on, shorter than 1e-9 px, are dropped)."""
    n = 0
    a = np.empty(3)
    b = np.empty(3)
    for e in range(edges.shape[0]):
        for k in range(3):  # camera coordinates: (P - c) @ R
            a[k] = ((edges[e, 0, 0] - centre[0]) * rot[0, k] + (edges[e, 0, 1] - centre[1]) * rot[1, k]
                    + (edges[e, 0, 2] - centre[2]) * rot[2, k])
            b[k] = ((edges[e, 1, 0] - centre[0]) * rot[0, k] + (edges[e, 1, 1] - centre[1]) * rot[1, k]
                    + (edges[e, 1, 2] - centre[2]) * rot[2, k])
        s0, s1 = _clip_range(a[2], b[2], znear, np.inf)
        s0, s1 = max(0.0, s0), min(1.0, s1)
        if s0 > s1:
            continue
        p = a + s0 * (b - a)
        q = a + s1 * (b - a)
        pu, pv = p[0] / p[2] * fx + cx, p[1] / p[2] * fy + cy
        qu, qv = q[0] / q[2] * fx + cx, q[1] / q[2] * fy + cy
        r0, r1 = _clip_range(pu, qu, u_lo, u_hi)
        t0, t1 = _clip_range(pv, qv, v_lo, v_hi)
        s0, s1 = max(0.0, max(r0, t0)), min(1.0, min(r1, t1))
        if s0 > s1:
            continue
        du, dv = qu - pu, qv - pv
        u0, v0, u1, v1 = pu + s0 * du, pv + s0 * dv, pu + s1 * du, pv + s1 * dv
        if math.hypot(u1 - u0, v1 - v0) > 1e-9:
            seg[n, 0], seg[n, 1], seg[n, 2], seg[n, 3] = u0, v0, u1, v1
            n += 1
    return n


@njit(cache=True)
def _visible_pieces_kernel(edges, rot, centre, fx, fy, cx, cy, znear, u_lo, v_lo, u_hi, v_hi, lo, hi):
    """Visible discontinuities of a box scene as straight pieces ``(K, 4)`` and their sides.

    Returns ``(pieces, left, right)``: rows ``(u0, v0, u1, v1)`` and the faces seen either side
    (left = side of the normal ``(-dv, du)``), constant along each piece, which differ. Every
    part of the image where edges are collinear is returned once (by the first such edge).
    """
    seg = np.empty((edges.shape[0], 4))
    n = _project_edges(edges, rot, centre, fx, fy, cx, cy, znear, u_lo, v_lo, u_hi, v_hi, seg)
    length = np.empty(n)
    for i in range(n):
        length[i] = math.hypot(seg[i, 2] - seg[i, 0], seg[i, 3] - seg[i, 1])
    cap = 16 + 4 * n * (n + 2)
    out = np.empty((cap, 4))
    left_out = np.empty(cap, dtype=np.int64)
    right_out = np.empty(cap, dtype=np.int64)
    breaks = np.empty(2 * n + 2)
    collinear = np.zeros(n, dtype=np.bool_)
    k = 0
    for i in range(n):
        pu, pv = seg[i, 0], seg[i, 1]
        du, dv = seg[i, 2] - pu, seg[i, 3] - pv
        li = length[i]
        eu, ev = du / li, dv / li  # unit direction
        nb = 0
        breaks[nb] = 0.0
        breaks[nb + 1] = 1.0
        nb = 2
        for j in range(n):
            collinear[j] = False
            if j == i:
                continue
            qu, qv = seg[j, 0], seg[j, 1]
            fu, fv = seg[j, 2] - qu, seg[j, 3] - qv
            lj = length[j]
            wu, wv = qu - pu, qv - pv
            if abs(eu * fv - ev * fu) < 1e-9 * lj:  # parallel
                if abs(eu * wv - ev * wu) < COLLINEAR_PX:  # and on one line: its ends break this one
                    collinear[j] = True
                    for lam in ((wu * du + wv * dv) / (li * li), ((wu + fu) * du + (wv + fv) * dv) / (li * li)):
                        if 0.0 < lam < 1.0:
                            breaks[nb] = lam
                            nb += 1
                continue
            denom = du * fv - dv * fu
            lam = (wu * fv - wv * fu) / denom
            mu = (wu * dv - wv * du) / denom
            if 0.0 < lam < 1.0 and -1e-9 <= mu * lj <= lj + 1e-9:
                breaks[nb] = lam
                nb += 1
        b = np.sort(breaks[:nb])
        last_end = -1.0
        for m in range(nb - 1):
            a0, a1 = b[m], b[m + 1]
            if (a1 - a0) * li < 1e-10:
                continue
            mid = 0.5 * (a0 + a1)
            mu_, mv_ = pu + mid * du, pv + mid * dv
            # covered by an earlier collinear edge: that edge returns this part
            covered = False
            for j in range(i):
                if collinear[j]:
                    fu, fv = seg[j, 2] - seg[j, 0], seg[j, 3] - seg[j, 1]
                    mu_j = ((mu_ - seg[j, 0]) * fu + (mv_ - seg[j, 1]) * fv) / (length[j] * length[j])
                    if 0.0 <= mu_j <= 1.0:
                        covered = True
                        break
            if covered:
                continue
            left = _pixel_face(mu_ - SIDE_PX * ev, mv_ + SIDE_PX * eu, rot, centre, fx, fy, cx, cy, lo, hi)
            right = _pixel_face(mu_ + SIDE_PX * ev, mv_ - SIDE_PX * eu, rot, centre, fx, fy, cx, cy, lo, hi)
            if left == right:
                continue
            if k > 0 and last_end == a0 and left_out[k - 1] == left and right_out[k - 1] == right:
                out[k - 1, 2], out[k - 1, 3] = pu + a1 * du, pv + a1 * dv  # extends the previous piece
            else:
                out[k, 0], out[k, 1] = pu + a0 * du, pv + a0 * dv
                out[k, 2], out[k, 3] = pu + a1 * du, pv + a1 * dv
                left_out[k] = left
                right_out[k] = right
                k += 1
            last_end = a1
    return out[:k].copy(), left_out[:k].copy(), right_out[:k].copy()


@njit(cache=True, inline="always")
def _pose_ray(rot, centre, i, x, y):
    """Camera centre ``(c0, c1, c2)`` and world direction ``(d0, d1, d2) = R (x, y, 1)`` of point ``i``'s ray.

    ``rot`` (M, 3, 3) and ``centre`` (M, 3) are one pose for all points (M = 1) or one per
    point. Inlined into its callers (the ray casting kernels of both 3-D renderers).
    """
    m = i if rot.shape[0] > 1 else 0
    d0 = rot[m, 0, 0] * x + rot[m, 0, 1] * y + rot[m, 0, 2]
    d1 = rot[m, 1, 0] * x + rot[m, 1, 1] * y + rot[m, 1, 2]
    d2 = rot[m, 2, 0] * x + rot[m, 2, 1] * y + rot[m, 2, 2]
    return centre[m, 0], centre[m, 1], centre[m, 2], d0, d1, d2


@njit(cache=True)
def _point_depth_kernel(x, y, rot, centre, lo, hi, normals, offsets, out_id, out_z):
    """Face seen at normalised image points ``(x, y)`` (camera ray ``(x, y, 1)``) and its z-depth.

    ``rot`` (M, 3, 3) and ``centre`` (M, 3) are one pose for all points (M = 1) or one per
    point. ``Z = (d - n . c) / (n . R q)`` on the plane ``n . X = d`` of the face seen;
    ``inf`` for the background (identifier 0).
    """
    for i in range(x.shape[0]):
        c0, c1, c2, d0, d1, d2 = _pose_ray(rot, centre, i, x[i], y[i])
        f = _first_face(c0, c1, c2, d0, d1, d2, lo, hi)
        out_id[i] = f
        if f == 0:
            out_z[i] = np.inf
        else:
            n0, n1, n2 = normals[f, 0], normals[f, 1], normals[f, 2]
            out_z[i] = (offsets[f] - (n0 * c0 + n1 * c1 + n2 * c2)) / (n0 * d0 + n1 * d1 + n2 * d2)


@njit(cache=True)
def _left_border_kernel(cuts, height, rot, centre, fx, fy, cx, cy, lo, hi, lut, out):
    """Mean intensity along the left image border ``u = -0.5`` over each pixel row, ``out`` (H,).

    The border is cut at the row borders and at ``cuts`` (sorted: where visible pieces end on
    it); each part shows one face, found by a ray 1e-7 px inside the image at its midpoint.
    """
    for i in range(height):
        out[i] = 0.0
    n = cuts.shape[0]
    k = 0
    prev = -0.5
    row = 0
    while row < height:
        top = row + 0.5
        # the next break: a cut inside (prev, top), else the row border
        while k < n and cuts[k] <= prev:
            k += 1
        nxt = cuts[k] if (k < n and cuts[k] < top) else top
        mid = 0.5 * (nxt + prev)
        f = _pixel_face(-0.5 + 1e-7, mid, rot, centre, fx, fy, cx, cy, lo, hi)
        r = min(max(int(math.floor(mid + 0.5)), 0), height - 1)
        out[r] += lut[f] * (nxt - prev)
        prev = nxt
        if nxt == top:
            row += 1
