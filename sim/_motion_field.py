"""The instantaneous motion field of a static scene seen by a moving pinhole camera (Longuet-Higgins & Prazdny)."""

from __future__ import annotations

import numpy as np


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
