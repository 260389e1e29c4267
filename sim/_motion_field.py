"""The instantaneous motion field of a static scene seen by a moving pinhole camera (Longuet-Higgins & Prazdny)."""

from __future__ import annotations

import math

import numpy as np

from .trajectory import _finite

#: The OpenGL near plane (m): no visible point is nearer (see :mod:`evedge.sim._gl`).
_ZNEAR_M = 0.05


def motion_field(x, y, inv_z, v_cam, w, fx: float, fy: float) -> tuple[np.ndarray, np.ndarray]:
    """Image velocity ``(du/dt, dv/dt)`` in px/s of static points at normalised coordinates ``(x, y)``.

    Parameters
    ----------
    x, y : array_like
        ``X / Z`` and ``Y / Z`` of the points in the camera frame.
    inv_z : array_like
        ``1 / Z`` (0 for points at infinity, e.g. the background: rotational flow only).
    v_cam, w : array_like, (..., 3)
        Camera linear velocity and angular velocity, both in the camera frame (broadcast).
    fx, fy : float
        Focal lengths, px.

    Returns
    -------
    vx, vy : numpy.ndarray

    Notes
    -----
    A static point ``P`` in the frame of a camera moving with linear velocity ``V`` and angular
    velocity ``w`` (camera frame) moves as ``dP/dt = -V - w x P``. Differentiating
    ``u = fx X/Z + cx``, ``v = fy Y/Z + cy`` with ``a = (dP/dt) / Z``:
    ``du/dt = fx (a_x - x a_z)``, ``dv/dt = fy (a_y - y a_z)`` (H. C. Longuet-Higgins and
    K. Prazdny, Proc. R. Soc. Lond. B 208, 1980).

    Examples
    --------
    >>> vx, vy = motion_field(0.0, 0.0, 0.5, [1.0, 0, 0], [0, 0, 0], 100.0, 100.0)
    >>> float(vx), float(vy)
    (-50.0, 0.0)
    """
    v_cam, w = np.asarray(v_cam, dtype=np.float64), np.asarray(w, dtype=np.float64)
    wx, wy, wz = w[..., 0], w[..., 1], w[..., 2]
    # a = -V/Z - w x q with q = (x, y, 1)
    ax = -v_cam[..., 0] * inv_z - (wy - wz * y)
    ay = -v_cam[..., 1] * inv_z - (wz * x - wx)
    az = -v_cam[..., 2] * inv_z - (wx * y - wy * x)
    return fx * (ax - x * az), fy * (ay - y * az)


def image_speed_bound(camera, t0_s: float, t1_s: float, lo: np.ndarray, hi: np.ndarray) -> float:
    """Upper bound of the image speed (px/s) over all pixels and ``t`` in ``[t0_s, t1_s]``.

    ``camera`` has ``width, height, fx, fy, cx, cy`` and a ``trajectory``; the scene lies inside
    the world boxes ``[lo, hi]`` (B, 3) (boxes, or meshes' bounding boxes).

    Notes
    -----
    With ``q = (x, y, 1)`` and ``r = max |q|`` over the image corners, the translational part of
    the field is ``f M V / Z`` with ``||M|| = |q|``, so it is at most ``max(fx, fy) |V| r / Z``;
    any visible point has ``Z >= D / r`` where ``D`` is the Euclidean distance from the camera
    centre to the nearest box (bounded over the interval by its value at the midpoint minus
    ``|v| (t1 - t0) / 2``; never below the 5 cm near plane). The rotational part is bounded term
    by term with ``|x| <= xm``, ``|y| <= ym``: ``|vx| <= fx (|wy| (1 + xm^2) + |wz| ym + |wx| xm ym)``
    and ``|vy| <= fy (|wx| (1 + ym^2) + |wz| xm + |wy| xm ym)``. The bound is the sum of both;
    ``|V|`` and ``|w|`` are the trajectory's bounds over the interval.
    """
    t0_s, t1_s = _finite(t0_s, "t0_s"), _finite(t1_s, "t1_s")
    if t1_s < t0_s:
        raise ValueError(f"t1_s must be >= t0_s, got t0_s={t0_s}, t1_s={t1_s}")
    c = camera
    xm = max(abs(-0.5 - c.cx), abs(c.width - 0.5 - c.cx)) / c.fx
    ym = max(abs(-0.5 - c.cy), abs(c.height - 0.5 - c.cy)) / c.fy
    wx, wy, wz = (float(w) for w in c.trajectory.angular_rate_bound_rad_s(t0_s, t1_s))
    rot_x = c.fx * (wy * (1 + xm * xm) + wz * ym + wx * xm * ym)
    rot_y = c.fy * (wx * (1 + ym * ym) + wz * xm + wy * xm * ym)
    bound = math.hypot(rot_x, rot_y)
    speed = float(c.trajectory.speed_bound_m_s(t0_s, t1_s))
    if speed > 0 and len(lo):
        r = math.sqrt(1 + xm * xm + ym * ym)
        centre = c.trajectory.position(0.5 * (t0_s + t1_s))
        gap = np.maximum(np.maximum(lo - centre, centre - hi), 0.0)
        distance = float(np.sqrt((gap * gap).sum(axis=1)).min()) - 0.5 * speed * (t1_s - t0_s)
        z_min = max(distance / r, _ZNEAR_M)
        bound += max(c.fx, c.fy) * speed * r / z_min
    return bound
