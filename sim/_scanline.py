"""numba kernel: scanline accumulation of the jumps across straight discontinuities (exact 3-D intensity)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _psi(z):
    """Antiderivative of ``clamp(z, 0, 1)``."""
    if z <= 0:
        return 0.0
    if z >= 1:
        return z - 0.5
    return 0.5 * z * z


@njit(cache=True)
def _row_coverage_1(c, xa, xb, h):
    """``h`` times the mean over the straight crossing from ``xa`` to ``xb`` of ``clamp(c - x, 0, 1)``.

    For a pixel row cut by a piece of discontinuity running from ``u = xa`` to ``u = xb``
    over a height ``h``, this is the area of the strip ``u < c`` (a column's right border)
    lying right of the piece, integrated exactly (the crossing is linear in v).
    """
    span = xb - xa
    if abs(span) < 1e-12:
        return h * min(max(c - 0.5 * (xa + xb), 0.0), 1.0)
    return h * ((_psi(c - xa) - _psi(c - xb)) / span)


@njit(cache=True)
def _accumulate_pieces(acc, width, height, u0s, v0s, u1s, v1s, jumps):
    """Add the jump of every piece ``(u0, v0) -> (u1, v1)`` (``v0 < v1``) to ``acc`` (H, W + 1).

    For each pixel row the piece crosses, each column from one left of the crossing to one
    right of it receives ``jump`` times the area of the row band right of the piece inside
    the column (exact, the crossing being straight); a prefix sum along the row then gives
    each pixel's mean. Visits rows and columns in increasing order, piece by piece.
    """
    for k in range(u0s.shape[0]):
        u0 = u0s[k]
        v0 = v0s[k]
        u1 = u1s[k]
        v1 = v1s[k]
        jump = jumps[k]
        slope = (u1 - u0) / (v1 - v0)
        for row in range(max(math.floor(v0 + 0.5), 0), min(math.ceil(v1 + 0.5), height)):
            ya = max(row - 0.5, v0)
            yb = min(row + 0.5, v1)
            if not yb > ya:
                continue
            xa = u0 + (ya - v0) * slope
            xb = u0 + (yb - v0) * slope
            h = yb - ya
            first = max(int(math.floor(min(xa, xb) - 0.5)), 0)
            last = min(int(math.ceil(max(xa, xb) + 0.5)), width - 1)
            for col in range(first, last + 1):
                cover = _row_coverage_1(col + 0.5, xa, xb, h) - _row_coverage_1(col - 0.5, xa, xb, h)
                acc[row, col] += jump * cover


@njit(cache=True)
def _prefix_rows(acc, left, width, out):
    """``out[i, j] = clip(left[i] + sum(acc[i, :j + 1]), 0, 1)``: the image from the accumulated jumps.

    Sums along each row in order (the same additions as ``numpy.cumsum``), then clips to [0, 1].
    """
    for i in range(out.shape[0]):
        s = 0.0
        for j in range(width):
            s += acc[i, j]
            v = left[i] + s
            out[i, j] = min(max(v, 0.0), 1.0)


def _piece_jumps(p, q, left, right, values, width, height):
    """Accumulator (H, W + 1) of the intensity jumps of visible pieces ``p -> q`` along each row.

    ``left`` and ``right`` index ``values`` (the intensity on each side of a piece); the
    image is the left border's value plus the prefix sum of a row's accumulator. Horizontal
    pieces are crossed by no scanline and are skipped.
    """
    acc = np.zeros((height, width + 1))
    u0, v0, u1, v1 = p[:, 0], p[:, 1], q[:, 0], q[:, 1]
    sloped = v0 != v1  # horizontal pieces are crossed by no scanline
    # jump met when moving along +u; the left side (normal (-dv, du)) is ahead if dv < 0
    up = v1 < v0
    jump = np.where(up, values[left] - values[right], values[right] - values[left])
    # each piece from its upper end (smaller v) to its lower end
    su0, sv0 = np.where(up, u1, u0)[sloped], np.where(up, v1, v0)[sloped]
    su1, sv1 = np.where(up, u0, u1)[sloped], np.where(up, v0, v1)[sloped]
    _accumulate_pieces(acc, width, height, np.ascontiguousarray(su0), np.ascontiguousarray(sv0),
                       np.ascontiguousarray(su1), np.ascontiguousarray(sv1),
                       np.ascontiguousarray(jump[sloped], dtype=np.float64))
    return acc
