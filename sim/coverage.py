"""Exact area of a polygon, a disk or a stripe pattern inside an axis-aligned box.

Validating wrappers around the numba kernels of :mod:`evedge.sim._coverage`
(which the renderers call directly on their own checked data).
"""

from __future__ import annotations

import math

import numpy as np

from ._coverage import _disk_box_area, _polygon_box_area, _stripe_dark_fraction


def _box(box) -> tuple[float, float, float, float]:
    b = np.asarray(box, dtype=np.float64)
    if b.shape != (4,) or not np.all(np.isfinite(b)) or not (b[0] < b[2] and b[1] < b[3]):
        raise ValueError(f"box must be finite (x0, y0, x1, y1) with x0 < x1 and y0 < y1, got {box!r}")
    return tuple(float(v) for v in b)


def _finite(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a number, got {type(value).__name__}")
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    return float(value)


def polygon_box_area(vx, vy, box) -> float:
    """Exact area of the simple polygon ``(vx, vy)`` inside ``box = (x0, y0, x1, y1)``."""
    vx = np.ascontiguousarray(vx, dtype=np.float64)
    vy = np.ascontiguousarray(vy, dtype=np.float64)
    if vx.ndim != 1 or vx.shape != vy.shape or vx.shape[0] < 3:
        raise ValueError(f"vx, vy must be 1-D of the same length >= 3, got {vx.shape} and {vy.shape}")
    if not (np.all(np.isfinite(vx)) and np.all(np.isfinite(vy))):
        raise ValueError("vx, vy must be finite")
    x0, y0, x1, y1 = _box(box)
    n = vx.shape[0]
    bufs = [np.empty(6 * n + 16) for _ in range(4)]
    return float(_polygon_box_area(vx, vy, n, x0, y0, x1, y1, *bufs))


def disk_box_area(cx, cy, radius_px, box) -> float:
    """Exact area of the disk of centre ``(cx, cy)`` and radius ``radius_px`` inside ``box``."""
    cx, cy, r = _finite(cx, "cx"), _finite(cy, "cy"), _finite(radius_px, "radius_px")
    if r <= 0:
        raise ValueError(f"radius_px must be > 0, got {r}")
    return float(_disk_box_area(cx, cy, r, *_box(box)))


def stripe_dark_fraction(x, y, nx, ny, offset_px, period_px, duty) -> float:
    """Exact dark fraction of pixel ``(x, y)`` for stripes ``u = nx X + ny Y - offset_px``.

    Dark where ``u mod period_px < duty * period_px``; ``(nx, ny)`` is normalised.
    """
    x, y, nx, ny = (_finite(v, n) for v, n in ((x, "x"), (y, "y"), (nx, "nx"), (ny, "ny")))
    offset, period, duty = _finite(offset_px, "offset_px"), _finite(period_px, "period_px"), _finite(duty, "duty")
    norm = math.hypot(nx, ny)
    if norm == 0:
        raise ValueError("(nx, ny) must not be zero")
    if period <= 0:
        raise ValueError(f"period_px must be > 0, got {period}")
    if not 0 < duty < 1:
        raise ValueError(f"duty must be in (0, 1), got {duty}")
    return float(_stripe_dark_fraction(nx / norm * x + ny / norm * y - offset, nx / norm, ny / norm, period, duty))
