"""Per-event ground truth: its dtype and how it is computed.

``TRUTH_DTYPE`` rows are aligned with the events (row ``i`` describes event ``i``):

- ``vx_px_s``, ``vy_px_s``: optical flow (motion field) at the event's pixel
  centre and exact (pre-jitter) crossing time, from the known motion;
- ``nx``, ``ny``: unit brightness-gradient direction (towards brighter);
  planar scenes: the normal of the nearest shape/stripe boundary, from the
  geometry; other renderers: central differences of the log intensity,
  interpolated linearly in time between the two samples around the event;
- ``lifetime_us = 1e6 / |v . n|``: time for the edge to move one pixel along
  its normal (``inf`` when the edge does not move along its normal);
- ``is_signal``: False for background-activity noise events, whose other
  fields are NaN;
- ``t_ns``: the event's time in int64 nanoseconds, the same instant as the
  event's ``t`` (us, rounded) at sub-microsecond precision (exact crossing
  times on the analytic scenes; see :mod:`evedge.sim.converter`).
"""

from __future__ import annotations

import numpy as np

TRUTH_DTYPE = np.dtype([
    ("vx_px_s", np.float64),
    ("vy_px_s", np.float64),
    ("nx", np.float64),
    ("ny", np.float64),
    ("lifetime_us", np.float64),
    ("is_signal", np.bool_),
    ("t_ns", np.int64),
])


def empty_truth(n: int) -> np.ndarray:
    """``n`` rows of :data:`TRUTH_DTYPE` describing noise (NaN values, ``is_signal`` False)."""
    out = np.empty(n, dtype=TRUTH_DTYPE)
    for name in ("vx_px_s", "vy_px_s", "nx", "ny", "lifetime_us"):
        out[name] = np.nan
    out["is_signal"] = False
    out["t_ns"] = 0  # set by the caller
    return out


def lifetime_us(vx, vy, nx, ny) -> np.ndarray:
    """``1e6 / |v . n|`` in microseconds (``inf`` where ``v . n == 0``)."""
    dot = np.abs(np.asarray(vx) * nx + np.asarray(vy) * ny)
    with np.errstate(divide="ignore"):
        return np.where(dot > 0, 1e6 / np.where(dot > 0, dot, 1.0), np.inf)


def gradient_direction(log_image: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit direction of the central-difference gradient of ``log_image`` at pixels ``(x, y)``.

    One-sided differences at the border; NaN where the gradient is zero.
    """
    h, w = log_image.shape
    xp = np.minimum(x + 1, w - 1)
    xm = np.maximum(x - 1, 0)
    yp = np.minimum(y + 1, h - 1)
    ym = np.maximum(y - 1, 0)
    gx = (log_image[y, xp] - log_image[y, xm]) / np.maximum(xp - xm, 1)
    gy = (log_image[yp, x] - log_image[ym, x]) / np.maximum(yp - ym, 1)
    norm = np.hypot(gx, gy)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(norm > 0, gx / norm, np.nan), np.where(norm > 0, gy / norm, np.nan)


def log_gradient_direction_at(image_flat: np.ndarray, eps: float, x: np.ndarray, y: np.ndarray,
                              width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`gradient_direction` of ``log(image + eps)`` at pixels ``(x, y)``, taking only the logs it needs.

    ``image_flat`` is the row-major linear image. The same arithmetic as
    ``gradient_direction(np.log(image + eps), x, y)`` element by element (the
    same bytes), without the full-frame logarithm.
    """
    xp = np.minimum(x + 1, width - 1)
    xm = np.maximum(x - 1, 0)
    yp = np.minimum(y + 1, height - 1)
    ym = np.maximum(y - 1, 0)
    at = lambda yy, xx: np.log(image_flat[yy * width + xx] + eps)  # noqa: E731
    gx = (at(y, xp) - at(y, xm)) / np.maximum(xp - xm, 1)
    gy = (at(yp, x) - at(ym, x)) / np.maximum(yp - ym, 1)
    norm = np.hypot(gx, gy)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(norm > 0, gx / norm, np.nan), np.where(norm > 0, gy / norm, np.nan)
