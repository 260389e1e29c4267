"""Offscreen 3-D renderer of box scenes seen by a moving camera, with exact ground truth.

A scene is a set of axis-aligned boxes (:class:`~evedge.sim.boxes.Box3D`) whose six faces each
have one flat linear intensity, seen by a pinhole camera moving along a trajectory
(:mod:`evedge.sim.trajectory`: constant velocity or keyframed splines). The renderer gives, at
any time:

- ``intensity``: the flat-shaded image in linear units, box-filtered exactly (the area average
  over each pixel square, from the visible outline found analytically), so it is continuous in
  time; or, ``method="raster"``, the mean of supersampled rasterised samples (pyrender);
- ``depth``: exact z-depth, the pixel ray intersected with the plane of the visible face;
- ``flow``: the exact motion field of the static scene (Longuet-Higgins & Prazdny), on the
  pixel grid or, :meth:`MeshRenderer.flow_at`, at given points and times (per-event truth);
- ``edges``: the pixels whose square a visible discontinuity (silhouette, occlusion boundary,
  crease between faces) crosses, exactly; or from the rasterised face identifiers.

Conventions
-----------
World and camera frames follow OpenCV: x right, y down, z forward (the camera looks along +z
of its own frame). At ``rotation_rpy_rad = (0, 0, 0)`` the camera frame is the world frame, so
boxes at positive world z lie in front of a camera at the origin, and world -y is "up".
Pixel ``(row i, column j)`` has its centre at image coordinates ``(u, v) = (j, i)`` and covers
``[j - 0.5, j + 0.5] x [i - 0.5, i + 0.5]``; a point ``(X, Y, Z)`` in the camera frame projects
to ``u = fx X / Z + cx``, ``v = fy Y / Z + cy`` (OpenCV's pixel-centre convention).

pyrender (OpenGL) looks along -z with y up and places pixel centres at half-integers; the
renderer converts both (a flip of the camera y and z axes, and ``cx + 0.5``, ``cy + 0.5``).
pyrender is imported lazily, by the first raster render (:mod:`evedge.sim._gl`), so importing
this module, and the exact methods, never touch OpenGL.

References
----------
H. C. Longuet-Higgins and K. Prazdny, "The interpretation of a moving retinal image",
Proc. R. Soc. Lond. B 208, 385-397, 1980 (the instantaneous motion field).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ._gl import ZNEAR_M, _import_pyrender, _offscreen, _PinholeRenderer, _single_sample_renderer_class
from ._motion_field import image_speed_bound, motion_field
from ._scanline import _piece_jumps, _prefix_rows
from ._visibility import _cast_rays_kernel, _left_border_kernel, _point_depth_kernel, _visible_pieces_kernel
from .boxes import FACE_ORDER, Box3D, box_edges, box_faces
from .trajectory import CameraTrajectory, KeyframeTrajectory, _finite, rotation_from_rpy

__all__ = ["Box3D", "CameraTrajectory", "KeyframeTrajectory", "MeshRenderer", "FACE_ORDER", "rotation_from_rpy"]


def _cast_rays(origin: np.ndarray, dirs: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Face identifier (N,) int64 of the first box face hit by each ray (0: none).

    Slab test of rays ``origin + t dirs`` (t > 0) against axis-aligned boxes ``[lo, hi]``
    (B, 3); identifiers follow the renderer: ``1 + 6 b + f`` with ``f`` in :data:`FACE_ORDER`.
    """
    n = len(dirs)
    if n == 0 or len(lo) == 0:
        return np.zeros(n, dtype=np.int64)
    out = np.empty(n, dtype=np.int64)
    _cast_rays_kernel(np.ascontiguousarray(origin, dtype=np.float64), np.ascontiguousarray(dirs, dtype=np.float64),
                      np.ascontiguousarray(lo, dtype=np.float64), np.ascontiguousarray(hi, dtype=np.float64), out)
    return out


def _mark_segment(mask: np.ndarray, u0: float, v0: float, u1: float, v1: float) -> None:
    """Set ``mask`` on every pixel whose closed square ``[j-.5, j+.5] x [i-.5, i+.5]`` the
    segment ``(u0, v0)-(u1, v1)`` meets (an exact supercover, column by column)."""
    height, width = mask.shape
    if u0 > u1:
        u0, v0, u1, v1 = u1, v1, u0, v0
    j = np.arange(max(math.ceil(u0 - 0.5), 0), min(math.floor(u1 + 0.5), width - 1) + 1)
    if j.size == 0:
        return
    if u1 - u0 > 1e-12:
        slope = (v1 - v0) / (u1 - u0)
        ua, ub = np.maximum(j - 0.5, u0), np.minimum(j + 0.5, u1)
        va, vb = v0 + (ua - u0) * slope, v0 + (ub - u0) * slope
    else:
        va, vb = np.full(j.size, v0), np.full(j.size, v1)
    first = np.maximum(np.ceil(np.minimum(va, vb) - 0.5), 0).astype(np.int64)
    last = np.minimum(np.floor(np.maximum(va, vb) + 0.5), height - 1).astype(np.int64)
    count = np.maximum(last - first + 1, 0)
    cols = np.repeat(j, count)
    rows = np.repeat(first, count) + (np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count))
    mask[rows, cols] = True


class MeshRenderer(_PinholeRenderer):
    """Render intensity, depth, motion field and edges of a box scene for a moving camera.

    Parameters
    ----------
    width, height : int
        Image size in pixels, > 0.
    fx, fy : float
        Focal lengths in pixels, > 0.
    cx, cy : float
        Principal point in pixels (OpenCV convention: pixel centres at integer coordinates).
    boxes : sequence of Box3D
        The static scene.
    trajectory : CameraTrajectory or KeyframeTrajectory
        The camera motion (:mod:`evedge.sim.trajectory`).
    background : float, default 0.5
        Linear intensity in [0, 1] where no geometry is seen.
    supersample : int, default 1
        Odd factor ``s >= 1``: the scene is rasterised at ``s`` times the resolution
        (``s**2`` samples per pixel on a regular grid centred in the pixel). Only the
        ``method="raster"`` variants of :meth:`intensity` and :meth:`edges` use more than the
        centre sample; 3 is a good value for them.

    Notes
    -----
    A rasterisation per time stamp (pyrender, the last one is cached) draws every face in a
    unique flat colour (its identifier; 0 = background) without multisampling, so every
    sample names exactly one face:

    - depth, flow: at the pixel centre (the centre sample, ``s`` odd), from the exact plane of
      the face seen there, so they are exact up to float64 rounding;
    - intensity and edges, ``method="raster"``: from the ``s x s`` samples of each pixel.

    The default ``method="exact"`` of :meth:`intensity` and :meth:`edges` needs no raster:
    the visible discontinuities are found analytically (box edges, exact ray casting against
    the boxes), then the exact pixel-area average and the pixels they cross follow.
    Both methods agree (tested); the exact ones are continuous in time and sub-pixel exact.

    The OpenGL context is created on the first use of a ``method="raster"`` variant only (the
    exact methods, depth, flow and :meth:`flow_at` need none); call :meth:`close` (or use the
    renderer as a context manager) to free it.

    Examples
    --------
    >>> from evedge.sim.render3d import Box3D, CameraTrajectory, MeshRenderer
    >>> tr = CameraTrajectory((0, 0, 0), (0.5, 0, 0), (0, 0, 0), (0, 0, 0))
    >>> with MeshRenderer(64, 48, 50.0, 50.0, 31.5, 23.5, [Box3D((0, 0, 4), (1, 1, 1), (0.2,) * 6)], tr) as r:
    ...     image = r.intensity(0.0)
    >>> image.shape, float(image[24, 32]), float(image[0, 0])
    ((48, 64), 0.2, 0.5)
    """

    def __init__(self, width, height, fx, fy, cx, cy, boxes, trajectory, background=0.5,
                 supersample=1):
        self._set_camera(width, height, fx, fy, cx, cy, background, trajectory, supersample, odd_supersample=True)
        background = self.background
        if isinstance(boxes, Box3D) or not isinstance(boxes, Sequence):
            raise TypeError("boxes must be a sequence of Box3D")
        for k, box in enumerate(boxes):
            if not isinstance(box, Box3D):
                raise TypeError(f"boxes[{k}] must be a Box3D, got {type(box).__name__}")
        if 6 * len(boxes) + 1 >= 2**24:
            raise ValueError(f"too many boxes ({len(boxes)}): face identifiers need 24 bits")
        self.boxes = tuple(boxes)

        # Face table; index 0 is the background (no plane, intensity = background).
        normals, offsets, lut, quads = [np.full(3, np.nan)], [np.nan], [background], []
        for box in self.boxes:
            for (n, d, corners), value in zip(box_faces(box), box.face_intensities):
                normals.append(n)
                offsets.append(d)
                lut.append(value)
                quads.append(corners)
        self._normals = np.array(normals)
        self._offsets = np.array(offsets)
        self._normals_k = np.nan_to_num(self._normals)  # the kernels' copies (background row unused)
        self._offsets_k = np.nan_to_num(self._offsets)
        self._lut = np.array(lut, dtype=np.float64)
        # Box bounds and the 12 edges of every box (world frame) for the analytic edge map.
        half = np.array([b.size_m for b in self.boxes]).reshape(-1, 3) / 2.0
        centres = np.array([b.center_m for b in self.boxes]).reshape(-1, 3)
        self._lo, self._hi = centres - half, centres + half
        self._box_edges = box_edges(centres, half)

        self._cache_t = None
        self._cache_ids = None
        self._center_t = None
        self._center_cache = None
        self._pieces_t = None
        self._pieces = None
        self._quads = quads  # OpenGL: the renderer is created by the first raster render

    # -- OpenGL ---------------------------------------------------------------------------
    def _build_gl(self):
        quads = self._quads
        pyrender, GL = _import_pyrender()
        import trimesh

        s = self.supersample
        self._flags = pyrender.RenderFlags.FLAT
        scene = pyrender.Scene(bg_color=[0.0, 0.0, 0.0, 1.0], ambient_light=[0.0, 0.0, 0.0])
        for face_id, corners in enumerate(quads, start=1):
            # The identifier is the face colour: 8 bits per channel, exact in FLAT mode.
            rgb = [(face_id >> shift & 255) / 255.0 for shift in (0, 8, 16)]
            material = pyrender.MetallicRoughnessMaterial(
                baseColorFactor=rgb + [1.0], metallicFactor=0.0, doubleSided=True
            )
            mesh = trimesh.Trimesh(vertices=corners, faces=[[0, 1, 2], [0, 2, 3]], process=False)
            scene.add(pyrender.Mesh.from_trimesh(mesh, material=material, smooth=False))
        self._add_camera(pyrender, scene)
        self._renderer = _offscreen(pyrender, _single_sample_renderer_class(pyrender, GL), s * self.width,
                                    s * self.height)

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("MeshRenderer is closed")

    def _face_ids(self, t_s: float) -> np.ndarray:
        """Face identifiers (s*H, s*W) (uint8 or int32) of the supersampled image at ``t_s`` (cached)."""
        t_s = _finite(t_s, "t_s")
        self._check_open()
        if self._cache_t != t_s:
            color = self._draw(t_s)
            if len(self._lut) <= 256:  # up to 42 boxes: the red channel holds the identifier
                ids = np.ascontiguousarray(color[..., 0])
            else:
                color = color.astype(np.int32)
                ids = color[..., 0] | (color[..., 1] << 8) | (color[..., 2] << 16)
            if ids.max() >= len(self._lut):
                raise RuntimeError("rendered an unknown face colour (multisampling active?)")
            self._cache_t, self._cache_ids = t_s, ids
        return self._cache_ids

    def _center_ids(self, t_s: float) -> np.ndarray:
        """Face identifiers (H, W) int64 seen at the pixel centres at ``t_s`` (cached).

        Exact ray casting of the pixel-centre rays (the visibility test of the exact
        intensity), not the GL raster: several times cheaper than a render and read-back,
        and exact on the pixels an edge passes near.
        """
        t_s = _finite(t_s, "t_s")
        self._check_open()
        if self._center_t != t_s:
            ids, depth = self._points(self._x.ravel(), self._y.ravel(), t_s)
            self._center_t = t_s
            self._center_cache = ids.reshape(self.height, self.width), depth.reshape(self.height, self.width)
        return self._center_cache[0]

    def _points(self, x, y, t_s):
        """Face seen (N,) int64 and z-depth (N,) (inf: background) at normalised points ``(x, y)``.

        ``t_s`` is one time, one per point (N,), or the poses ``(rotations, centres)`` per point.
        """
        x = np.ascontiguousarray(x, dtype=np.float64)
        y = np.ascontiguousarray(y, dtype=np.float64)
        if isinstance(t_s, tuple):  # (rotations, centres) already evaluated, one per point
            rot, centre = t_s
        elif np.ndim(t_s) == 0:
            rot = self.trajectory.rotation(t_s)[None]
            centre = self.trajectory.position(t_s)[None]
        else:
            rot, centre, _, _ = self.trajectory.kinematics(t_s)
        ids = np.empty(x.size, dtype=np.int64)
        depth = np.empty(x.size)
        _point_depth_kernel(x, y, np.ascontiguousarray(rot), np.ascontiguousarray(centre),
                            self._lo, self._hi, self._normals_k, self._offsets_k, ids, depth)
        return ids, depth

    # -- public ---------------------------------------------------------------------------
    def intensity(self, t_s: float, method: str = "exact") -> np.ndarray:
        """Linear intensity image (H, W) float64 in [0, 1] at time ``t_s``.

        Flat shading: a pixel wholly on one face has exactly that face's intensity.

        Parameters
        ----------
        t_s : float
            Time in seconds.
        method : {"exact", "raster"}, default "exact"
            ``"exact"``: the exact area average (box filter) of the intensity over each pixel
            square, computed from the visible discontinuities (see :meth:`edges`) by scanline
            accumulation; pixels on one face are exact to 1e-7, others agree with a
            400 x 400-sample brute force to its own accuracy (1e-4), and
            continuous in time, which an event simulator needs (a rasterised image jumps when
            an edge crosses a sample). ``"raster"``: the mean over the ``s x s`` rasterised
            samples of the pixel (``s = supersample``; ``s = 1`` is aliased).
        """
        if method == "exact":
            self._check_open()
            return self._exact_intensity(_finite(t_s, "t_s"))
        if method != "raster":
            raise ValueError(f"method must be 'exact' or 'raster', got {method!r}")
        s = self.supersample
        values = self._lut[self._face_ids(t_s)]
        if s == 1:
            return values
        return values.reshape(self.height, s, self.width, s).sum(axis=3).sum(axis=1) / (s * s)

    def depth(self, t_s: float) -> np.ndarray:
        """Z-depth (H, W) float64 in metres at the pixel centres; ``inf`` where no geometry.

        The depth is the intersection of the pixel ray with the plane of the face visible at
        the pixel centre: ``Z = (d - n.c) / (n.R q)`` with ``q = (x, y, 1)``.
        """
        self._center_ids(t_s)
        return self._center_cache[1].copy()

    def flow(self, t_s: float) -> np.ndarray:
        """Motion field (2, H, W) float64 ``(vx, vy)`` in px/s at the pixel centres.

        Notes
        -----
        The exact instantaneous field of the static scene (:func:`evedge.sim._motion_field.motion_field`)
        from the exact depth; background pixels are points at infinity (``1/Z = 0``):
        rotational flow only.
        """
        t_s = _finite(t_s, "t_s")
        inv_z = 1.0 / self.depth(t_s)  # 0 for the background (inf depth)
        rot = self.trajectory.rotation(t_s)
        v_cam = rot.T @ self.trajectory.linear_velocity(t_s)
        w = self.trajectory.angular_velocity(t_s)
        return np.stack(motion_field(self._x, self._y, inv_z, v_cam, w, self.fx, self.fy))

    def flow_at(self, x, y, t_s) -> tuple[np.ndarray, np.ndarray]:
        """Motion field ``(vx, vy)`` (N,) in px/s at pixel centres ``(x, y)`` (N,), each at its own time.

        Parameters
        ----------
        x, y : array_like
            Pixel columns and rows (integers or any image coordinates).
        t_s : array_like
            Times (N,), seconds.

        Returns
        -------
        vx, vy : (N,) float64

        Notes
        -----
        Per point: the face seen and its depth by exact ray casting at the point's own time,
        then the exact motion field (as :meth:`flow`, which equals this on the pixel grid): the
        per-event truth of the converter, computed only where events occur.
        """
        self._check_open()
        x, y, t = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (x, y, t_s))
        if not (x.size == y.size == t.size):
            raise ValueError(f"flow_at: x, y and t_s must have one length, got {x.size}, {y.size}, {t.size}")
        if t.size and not np.all(np.isfinite(t)):
            raise ValueError("flow_at: t_s must be finite")
        xn, yn = (x - self.cx) / self.fx, (y - self.cy) / self.fy
        rot, centre, vel, w = self.trajectory.kinematics(t)
        _, depth = self._points(xn, yn, (rot, centre))
        v_cam = np.einsum("nji,nj->ni", rot, vel)
        return motion_field(xn, yn, 1.0 / depth, v_cam, w, self.fx, self.fy)

    def edges(self, t_s: float, contrast_only: bool = False, method: str = "exact") -> np.ndarray:
        """Edge map (H, W) bool at time ``t_s``: pixels whose square a visible discontinuity crosses.

        Parameters
        ----------
        t_s : float
            Time in seconds.
        contrast_only : bool, default False
            If True, only discontinuities across which the intensity changes count (faces of
            equal intensity, and the background, merge): the edges an event camera can see.
        method : {"exact", "raster"}, default "exact"
            How to find them, see Notes.

        Returns
        -------
        (H, W) bool

        Notes
        -----
        The discontinuities are the visible parts of the image of the face-identifier function:
        silhouettes, occlusion boundaries and the creases between two visible faces of a box,
        whatever their contrast unless ``contrast_only``.

        ``method="exact"`` (analytic, independent of the rasteriser): every box edge is clipped
        to the near plane and projected; along it the faces seen either side can only change
        where the image of another edge meets it (crossing, T-junction, end of a collinear
        edge), so the break points are 2-D segment intersections and each interval between
        them is one piece, whose sides are the faces seen 1e-8 px to either side of its
        midpoint (exact slab ray casting); a piece is a discontinuity when they differ
        (:mod:`evedge.sim._visibility`, numba). Every pixel whose closed square meets a visible
        piece is marked (exact supercover). Where boxes overlap, the face-face intersection
        lines are candidates too, so the outline of their union is exact as well.

        ``method="raster"``: in the ``s``-times supersampled face-identifier image, a sample is marked
        when one of its 8 neighbours shows another face (or the background); a pixel is an edge
        pixel when any of its ``s x s`` samples is marked. Every face is its own region, so
        silhouettes, occlusion boundaries and the creases between two visible faces of a box
        are edges, whatever their contrast. This equals "a visible discontinuity crosses the
        closed pixel square" up to about ``1/s`` px (the sample spacing): a discontinuity on
        the border of two pixels marks both, one within ``1/(2s)`` px of the border may mark
        both, and one that clips a pixel corner by less than about ``1/s`` px may be missed.
        With ``s = 1`` it is the classic 8-neighbour definition (both sides of an edge marked).
        """
        if method == "exact":
            self._check_open()
            return self._exact_edges(_finite(t_s, "t_s"), bool(contrast_only))
        if method != "raster":
            raise ValueError(f"method must be 'exact' or 'raster', got {method!r}")
        s = self.supersample
        ids = self._face_ids(t_s)
        if contrast_only:
            ids = self._lut[ids]
        marked = np.zeros(ids.shape, dtype=bool)
        diff_x = ids[:, 1:] != ids[:, :-1]
        diff_y = ids[1:, :] != ids[:-1, :]
        marked[:, 1:] |= diff_x
        marked[:, :-1] |= diff_x
        marked[1:, :] |= diff_y
        marked[:-1, :] |= diff_y
        # diagonal neighbours: an outline that only touches a pixel's corner crosses its square
        diff_d = ids[1:, 1:] != ids[:-1, :-1]
        marked[1:, 1:] |= diff_d
        marked[:-1, :-1] |= diff_d
        diff_a = ids[1:, :-1] != ids[:-1, 1:]
        marked[1:, :-1] |= diff_a
        marked[:-1, 1:] |= diff_a
        return marked.reshape(self.height, s, self.width, s).any(axis=(1, 3))

    def _pieces_at(self, t_s: float, contrast_only: bool):
        """Visible discontinuities in the image at ``t_s`` (cached), each part of a line once."""
        if self._pieces_t != t_s:
            self._pieces = self._visible_pieces(t_s)
            self._pieces_t = t_s
        p, q, left, right = self._pieces
        if contrast_only:
            keep = self._lut[left] != self._lut[right]
            return p[keep], q[keep], left[keep], right[keep]
        return p, q, left, right

    def _visible_pieces(self, t_s: float):
        """Visible discontinuities at ``t_s`` as straight pieces, clipped to the image.

        Returns ``(start (K, 2), end (K, 2), left (K,), right (K,))``: image coordinates of the
        ends and the face identifiers on either side of each piece (left = side of the normal
        ``(-dv, du)``), constant along it (see :meth:`edges` and :mod:`evedge.sim._visibility`).
        """
        rot = np.ascontiguousarray(self.trajectory.rotation(t_s))
        centre = np.ascontiguousarray(self.trajectory.position(t_s))
        pieces, left, right = _visible_pieces_kernel(
            self._box_edges, rot, centre, self.fx, self.fy, self.cx, self.cy, ZNEAR_M,
            -0.5, -0.5, self.width - 0.5, self.height - 0.5, self._lo, self._hi)
        return pieces[:, :2], pieces[:, 2:], left, right

    def _exact_edges(self, t_s: float, contrast_only: bool) -> np.ndarray:
        mask = np.zeros((self.height, self.width), dtype=bool)
        p, q, _, _ = self._pieces_at(t_s, contrast_only)
        for (u0, v0), (u1, v1) in zip(p.tolist(), q.tolist()):
            _mark_segment(mask, u0, v0, u1, v1)
        return mask

    def _exact_intensity(self, t_s: float) -> np.ndarray:
        """Exact box-filtered (area-averaged) intensity, by scanline accumulation of jumps.

        Along a row, the image is the value at its left border plus the jumps across the
        visible discontinuities crossed so far; integrating over the pixel square gives each
        piece's exact contribution in closed form (as font rasterisers accumulate coverage).
        """
        height, width = self.height, self.width
        p, q, left, right = self._pieces_at(t_s, True)
        acc = _piece_jumps(p, q, left, right, self._lut, width, height)
        out = np.empty((height, width))
        _prefix_rows(acc, self._left_border(t_s, p, q), width, out)  # clipped to [0, 1]
        return out

    def _left_border(self, t_s: float, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Mean intensity along the left image border ``u = -0.5`` over each row (H,)."""
        ends = np.concatenate([p, q])
        cuts = np.sort(np.clip(ends[np.abs(ends[:, 0] + 0.5) < 1e-9, 1], -0.5, self.height - 0.5))
        out = np.empty(self.height)
        _left_border_kernel(cuts, self.height, np.ascontiguousarray(self.trajectory.rotation(t_s)),
                            np.ascontiguousarray(self.trajectory.position(t_s)), self.fx, self.fy, self.cx, self.cy,
                            self._lo, self._hi, self._lut, out)
        return out

    def max_speed_px_s(self, t0_s: float, t1_s: float) -> float:
        """Upper bound on the image speed ``|flow|`` over all pixels for ``t`` in ``[t0_s, t1_s]``.

        Analytic and rigorous, without rendering (so it is cheap and leaves the image cache
        alone); typically 1.3-2x the true maximum.

        Notes
        -----
        With ``q = (x, y, 1)`` and ``r = max |q|`` over the image corners, the translational
        part of the field is ``f M V / Z`` with ``||M|| = |q|``, so it is at most
        ``max(fx, fy) |V| r / Z``; any visible point has ``Z >= D / r`` where ``D`` is the
        Euclidean distance from the camera centre to the nearest box (bounded over the interval
        by its value at the midpoint minus ``|v| (t1 - t0) / 2``; never below the 5 cm near
        plane); ``|V|`` and the rates ``|w|`` are the trajectory's bounds over the interval
        (:func:`evedge.sim._motion_field.image_speed_bound`).
        """
        return image_speed_bound(self, t0_s, t1_s, self._lo, self._hi)

    def _drop_caches(self) -> None:
        self._cache_t = self._cache_ids = self._pieces_t = self._pieces = None
        self._center_t = self._center_cache = None
