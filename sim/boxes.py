"""Axis-aligned boxes with one flat intensity per face: the flat polyhedra of the exact 3-D renderer."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .trajectory import _vector

__all__ = ["Box3D", "FACE_ORDER"]

#: Order of ``Box3D.face_intensities``: the face whose outward normal is -x, +x, -y, +y, -z, +z
#: (world frame; -y is the top face, -z the face towards a camera at the origin looking at +z).
FACE_ORDER = ("-x", "+x", "-y", "+y", "-z", "+z")


@dataclass(frozen=True)
class Box3D:
    """An axis-aligned box with one flat linear intensity per face.

    Parameters
    ----------
    center_m : tuple of 3 float
        Centre in the world frame (OpenCV axes: x right, y down, z forward), metres.
    size_m : tuple of 3 float
        Extent along world x, y, z, metres; each > 0.
    face_intensities : tuple of 6 float
        Linear intensity in [0, 1] of the faces in :data:`FACE_ORDER` (-x, +x, -y, +y, -z, +z).

    Examples
    --------
    >>> Box3D((0, 0, 5), (1, 1, 1), (0.5,) * 6).size_m
    (1.0, 1.0, 1.0)
    """

    center_m: tuple[float, float, float]
    size_m: tuple[float, float, float]
    face_intensities: tuple[float, float, float, float, float, float]

    def __post_init__(self):
        object.__setattr__(self, "center_m", _vector(self.center_m, "Box3D.center_m"))
        size = _vector(self.size_m, "Box3D.size_m")
        if min(size) <= 0.0:
            raise ValueError(f"Box3D.size_m must be > 0 along every axis, got {size}")
        object.__setattr__(self, "size_m", size)
        faces = _vector(self.face_intensities, "Box3D.face_intensities", length=6)
        if min(faces) < 0.0 or max(faces) > 1.0:
            raise ValueError(f"Box3D.face_intensities must lie in [0, 1], got {faces}")
        object.__setattr__(self, "face_intensities", faces)


def box_edges(centres: np.ndarray, half: np.ndarray) -> np.ndarray:
    """World segments (E, 2, 3) on which the image of boxes ``centres +- half`` (B, 3) can be discontinuous.

    The 12 edges of every box, plus, where boxes overlap, the lines where a face of one crosses
    a face of another (the outline of their union).
    """
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    pairs = [(a, b) for a in range(8) for b in range(a + 1, 8) if np.count_nonzero(signs[a] != signs[b]) == 1]
    lo, hi = centres - half, centres + half
    edges = [[c + signs[a] * h, c + signs[b] * h] for c, h in zip(centres, half) for a, b in pairs]
    edges += _intersection_segments(lo, hi)
    return np.array(edges, dtype=np.float64).reshape(-1, 2, 3)


def box_faces(box: Box3D):
    """Yield (outward normal n, plane offset d with n.x = d on the face, 4 corners) per face."""
    c = np.asarray(box.center_m)
    h = np.asarray(box.size_m) / 2.0
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            a, b = (axis + 1) % 3, (axis + 2) % 3
            corners = []
            for sa, sb in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = c.copy()
                p[axis] += sign * h[axis]
                p[a] += sa * h[a]
                p[b] += sb * h[b]
                corners.append(p)
            corners = np.array(corners)  # in order around the quad (faces are double-sided)
            yield n, float(n @ c + h[axis]), corners


def _intersection_segments(lo: np.ndarray, hi: np.ndarray) -> list:
    """Segments where a face of one box crosses a face of another (overlapping boxes only).

    Two axis-aligned faces with normals along different axes ``a`` and ``b`` meet on a line
    along the third axis; the part lying on both face rectangles is a candidate discontinuity
    of the image (the outline of the union of the boxes), like the box edges themselves.
    """
    out = []
    n = len(lo)
    for i in range(n):
        for j in range(i + 1, n):
            if np.any(lo[i] >= hi[j]) or np.any(lo[j] >= hi[i]):
                continue  # interiors disjoint: the box edges are the whole outline
            for (p, q) in ((i, j), (j, i)):
                for a in range(3):
                    for ca in (lo[p, a], hi[p, a]):
                        for b in range(3):
                            if b == a:
                                continue
                            for cb in (lo[q, b], hi[q, b]):
                                k = 3 - a - b
                                # the line x_a = ca, x_b = cb must lie on both faces
                                if not (lo[p, b] <= cb <= hi[p, b] and lo[q, a] <= ca <= hi[q, a]):
                                    continue
                                k0, k1 = max(lo[p, k], lo[q, k]), min(hi[p, k], hi[q, k])
                                if k1 <= k0:
                                    continue
                                start, end = np.zeros(3), np.zeros(3)
                                start[a] = end[a] = ca
                                start[b] = end[b] = cb
                                start[k], end[k] = k0, k1
                                out.append([start, end])
    return out


