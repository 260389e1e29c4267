"""Thin exact edge maps: one pixel per boundary crossing of each pixel row and column.

The exact edge map of :mod:`evedge.sim.planar` marks every pixel whose open
square a boundary crosses: about ``|cos a| + |sin a|`` pixels per row for an edge
at angle ``a`` (1.36 at 20 degrees, 1.41 at 45), so any detector as thin as
Canny scores below 100 on oblique edges however well it places them. The thin
map keeps one pixel per crossing, the way a rasterised line is drawn:

* **row crossings**: where a boundary crosses the centre line ``y = r`` of pixel
  row ``r`` at ``x``, pixel ``(floor(x + 0.5), r)`` is an edge pixel;
* **column crossings**: where it crosses the centre line ``x = c`` of column
  ``c`` at ``y``, pixel ``(c, floor(y + 0.5))`` is an edge pixel.

A straight edge steeper than 45 degrees gets exactly one pixel per row (its
column crossings fall on the same pixels, up to ties), a flatter one exactly
one per column: an 8-connected line one pixel thick, like Canny's after
non-maximum suppression. A boundary that only touches a centre line (a vertex
at a local extremum) does not cross it; a boundary lying along a centre line
is counted by the crossings of the other direction. Every thin edge pixel is
an edge pixel of the exact map except where a crossing falls exactly on a
pixel border (the open-square rule then marks neither side).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["mark_circle", "mark_segments", "mark_stripes"]


def _mark(img: np.ndarray, cols: np.ndarray, rows: np.ndarray) -> None:
    h, w = img.shape
    ok = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    img[rows[ok], cols[ok]] = True


def mark_segments(img: np.ndarray, x0, y0, x1, y1) -> None:
    """Mark the row and column crossings of straight segments ``(x0, y0) -> (x1, y1)`` (image px).

    Parameters
    ----------
    img : numpy.ndarray
        (height, width) bool, updated in place.
    x0, y0, x1, y1 : array_like
        Segment end points (pixel centres at integers). A segment covers
        ``min <= r < max`` of its row range (and column range), so a vertex
        shared by two segments is counted once and a vertex at a local
        extremum (a touch, not a crossing) is not counted.
    """
    x0, y0, x1, y1 = (np.atleast_1d(np.asarray(v, dtype=np.float64)) for v in (x0, y0, x1, y1))
    for (a0, b0, a1, b1, by_rows) in ((x0, y0, x1, y1, True), (y0, x0, y1, x1, False)):
        # crossings of the lines b = integer: along rows (b = y) or along columns (b = x)
        lo = np.minimum(b0, b1)
        hi = np.maximum(b0, b1)
        for k in np.flatnonzero(hi > lo):
            lines = np.arange(math.ceil(lo[k]), math.ceil(hi[k]), dtype=np.int64)  # lo <= line < hi
            if lines.size == 0:
                continue
            pos = a0[k] + (lines - b0[k]) * (a1[k] - a0[k]) / (b1[k] - b0[k])
            cells = np.floor(pos + 0.5).astype(np.int64)
            if by_rows:
                _mark(img, cells, lines)
            else:
                _mark(img, lines, cells)


def mark_circle(img: np.ndarray, cx: float, cy: float, r: float) -> None:
    """Mark the row and column crossings of the circle of centre ``(cx, cy)`` and radius ``r`` (px)."""
    h, w = img.shape
    for by_rows, c_line, c_pos, n in ((True, cy, cx, h), (False, cx, cy, w)):
        lines = np.arange(max(0, math.floor(c_line - r)), min(n - 1, math.ceil(c_line + r)) + 1, dtype=np.int64)
        d2 = r * r - (lines - c_line) ** 2
        lines = lines[d2 > 0]  # a tangent line (d2 = 0) touches, it does not cross
        half = np.sqrt(d2[d2 > 0])
        for pos in (c_pos - half, c_pos + half):
            cells = np.floor(pos + 0.5).astype(np.int64)
            if by_rows:
                _mark(img, cells, lines)
            else:
                _mark(img, lines, cells)


def mark_stripes(img: np.ndarray, row0: int, row1: int, nx: float, ny: float, offset: float, period: float,
                 duty: float) -> None:
    """Mark the crossings of the stripe boundaries inside rows ``row0 <= y < row1``.

    The stripe coordinate is ``u = nx x + ny y - offset``; boundaries lie where
    ``u mod period`` is 0 or ``duty * period`` (as :func:`evedge.sim._coverage._render_stripes`).
    Column crossings count only inside the band's rows.
    """
    h, w = img.shape
    row1 = min(row1, h)
    for b in (0.0, duty * period):
        if nx != 0.0:
            # along rows: nx x = b + k period + offset - ny y
            ys = np.arange(row0, row1, dtype=np.float64)
            for y in ys:
                c = b + offset - ny * y
                xs = _solutions(c, nx, period, -0.5, w - 0.5)
                _mark(img, np.floor(xs + 0.5).astype(np.int64), np.full(xs.size, int(y), np.int64))
        if ny != 0.0:
            for x in range(w):
                c = b + offset - nx * x
                ys = _solutions(c, ny, period, row0 - 0.5, row1 - 0.5)
                rows = np.floor(ys + 0.5).astype(np.int64)
                keep = (rows >= row0) & (rows < row1)
                _mark(img, np.full(int(keep.sum()), x, np.int64), rows[keep])


def _solutions(c: float, slope: float, period: float, lo: float, hi: float) -> np.ndarray:
    """All ``s`` in ``[lo, hi)`` with ``slope * s = c + k * period`` for an integer ``k``."""
    a, b = sorted(((slope * lo - c) / period, (slope * hi - c) / period))
    ks = np.arange(math.floor(a) - 1, math.ceil(b) + 2, dtype=np.float64)
    s = (c + ks * period) / slope
    return s[(s >= lo) & (s < hi)]
