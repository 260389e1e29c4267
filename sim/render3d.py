"""Offscreen 3-D renderer of box scenes seen by a moving camera, with exact ground truth.

A scene is a set of axis-aligned boxes whose six faces each have one flat linear intensity,
seen by a pinhole camera that moves with constant linear and angular velocity. The renderer
gives, at any time:

- ``intensity``: the flat-shaded image in linear units, box-filtered exactly (the area average
  over each pixel square, from the visible outline found analytically), so it is continuous in
  time; or, ``method="raster"``, the mean of supersampled rasterised samples;
- ``depth``: exact z-depth, the pixel ray intersected with the plane of the visible face
  (the face at the pixel centre comes from one pyrender rasterisation, EGL, Mesa llvmpipe);
- ``flow``: the exact motion field of the static scene (Longuet-Higgins & Prazdny);
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
pyrender is imported lazily, in the constructor, after setting ``PYOPENGL_PLATFORM=egl`` and
``PYGLET_HEADLESS=1`` (only if unset), so importing this module never touches OpenGL.

References
----------
H. C. Longuet-Higgins and K. Prazdny, "The interpretation of a moving retinal image",
Proc. R. Soc. Lond. B 208, 385-397, 1980 (the instantaneous motion field).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ._raycast import _cast_rays_kernel
from ._scanline import _accumulate_pieces

__all__ = ["Box3D", "CameraTrajectory", "MeshRenderer", "FACE_ORDER", "rotation_from_rpy"]

#: Order of ``Box3D.face_intensities``: the face whose outward normal is -x, +x, -y, +y, -z, +z
#: (world frame; -y is the top face, -z the face towards a camera at the origin looking at +z).
FACE_ORDER = ("-x", "+x", "-y", "+y", "-z", "+z")

# Clip planes of the OpenGL camera. The near plane clips geometry closer than 5 cm; a 24-bit
# depth buffer with these planes resolves 0.1 mm at 5 m, ample for the occlusion test (depth
# values themselves are computed analytically, not read back).
_ZNEAR_M = 0.05
_ZFAR_M = 1000.0


def _vector(value, name: str, length: int = 3) -> tuple[float, ...]:
    """Return ``value`` as a tuple of ``length`` finite floats or raise naming ``name``."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a sequence of {length} numbers, got {value!r}") from exc
    if arr.shape != (length,):
        raise ValueError(f"{name} must have {length} elements, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return tuple(float(x) for x in arr)


def _finite(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    return value


def _skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _so3_exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrix ``exp([w]x)`` (Rodrigues' formula)."""
    theta = float(np.linalg.norm(w))
    k = _skew(w)
    if theta < 1e-12:
        return np.eye(3) + k
    return np.eye(3) + (math.sin(theta) / theta) * k + ((1.0 - math.cos(theta)) / theta**2) * (k @ k)


def rotation_from_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Camera-to-world rotation of roll/pitch/yaw angles in OpenCV axes.

    ``R = Ry(yaw) @ Rx(pitch) @ Rz(roll)``: yaw about the (down) y axis, then pitch about the
    (right) x axis, then roll about the (forward, optical) z axis; the aerospace z-y-x sequence
    mapped onto OpenCV axes (forward z, right x, down y). Positive yaw turns the view towards +x.
    """
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rz = np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    return ry @ rx @ rz


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


@dataclass(frozen=True)
class CameraTrajectory:
    """Constant-velocity 6-DOF camera motion.

    Parameters
    ----------
    position_m : tuple of 3 float
        Camera centre at t = 0, world frame, metres.
    velocity_m_s : tuple of 3 float
        Constant linear velocity of the camera centre, world frame, m/s.
    rotation_rpy_rad : tuple of 3 float
        Orientation at t = 0 as (roll, pitch, yaw), see :func:`rotation_from_rpy`
        (roll about the optical axis z, pitch about x, yaw about y).
    angular_velocity_rad_s : tuple of 3 float
        Constant angular velocity ``(wx, wy, wz)`` in the camera's own frame (OpenCV axes), rad/s:
        ``wy`` is the yaw rate, ``wx`` the pitch rate, ``wz`` the roll rate.

    Notes
    -----
    ``R(t) = R0 @ expm([w]x t)`` and ``c(t) = c0 + v t``; the camera-to-world pose is
    ``[[R(t), c(t)], [0, 1]]``. A body-frame angular velocity keeps the motion a true
    constant-velocity screw motion (roll/pitch/yaw rates would not be constant in general).
    """

    position_m: tuple[float, float, float]
    velocity_m_s: tuple[float, float, float]
    rotation_rpy_rad: tuple[float, float, float]
    angular_velocity_rad_s: tuple[float, float, float]

    def __post_init__(self):
        for name in ("position_m", "velocity_m_s", "rotation_rpy_rad", "angular_velocity_rad_s"):
            object.__setattr__(self, name, _vector(getattr(self, name), f"CameraTrajectory.{name}"))

    def rotation(self, t_s: float) -> np.ndarray:
        """Camera-to-world rotation (3, 3) at time ``t_s``."""
        t_s = _finite(t_s, "t_s")
        r0 = rotation_from_rpy(*self.rotation_rpy_rad)
        return r0 @ _so3_exp(np.asarray(self.angular_velocity_rad_s) * t_s)

    def position(self, t_s: float) -> np.ndarray:
        """Camera centre (3,) in the world frame at time ``t_s``, metres."""
        t_s = _finite(t_s, "t_s")
        return np.asarray(self.position_m) + np.asarray(self.velocity_m_s) * t_s

    def pose(self, t_s: float) -> np.ndarray:
        """Camera-to-world 4x4 matrix at time ``t_s`` (OpenCV camera axes)."""
        pose = np.eye(4)
        pose[:3, :3] = self.rotation(t_s)
        pose[:3, 3] = self.position(t_s)
        return pose


def _import_pyrender():
    """Import pyrender for headless EGL rendering (lazily: importing OpenGL has side effects)."""
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    os.environ.setdefault("PYGLET_HEADLESS", "1")
    if not hasattr(np, "infty"):
        # numpy 2 removed np.infty, which pyrender.mesh still uses (bounds, centroid)
        np.infty = np.inf
    import pyrender
    from OpenGL import GL

    return pyrender, GL


def _single_sample_renderer_class(pyrender, GL):
    """A pyrender Renderer whose main framebuffer has one sample per pixel.

    pyrender always draws into a 4x multisampled framebuffer and resolves it, which blends
    the colours of the faces meeting in a pixel; face identifiers encoded as colours must not
    be blended, so the multisampled renderbuffers are re-allocated with 0 samples (which
    OpenGL defines as single-sample storage) right after pyrender creates them.
    """

    class _SingleSampleRenderer(pyrender.Renderer):
        _respecified = None

        def _configure_main_framebuffer(self):
            super()._configure_main_framebuffer()
            if self._main_cb_ms is not self._respecified:
                w, h = self.viewport_width, self.viewport_height
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_cb_ms)
                GL.glRenderbufferStorageMultisample(GL.GL_RENDERBUFFER, 0, GL.GL_RGBA, w, h)
                GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, self._main_db_ms)
                GL.glRenderbufferStorageMultisample(
                    GL.GL_RENDERBUFFER, 0, GL.GL_DEPTH_COMPONENT24, w, h
                )
                self._respecified = self._main_cb_ms

    return _SingleSampleRenderer


def _delete_offscreen(renderer) -> None:
    """Free an OffscreenRenderer's GL objects and context without terminating the EGL display.

    pyrender's ``OffscreenRenderer.delete`` calls ``eglTerminate`` on the display, which is one
    per device and shared by every renderer of the process: it would invalidate the contexts of
    all other live renderers. Here only this renderer's context is destroyed.
    """
    platform = renderer._platform
    try:
        platform.make_current()
        renderer._renderer.delete()
    finally:
        display = getattr(platform, "_egl_display", None)
        context = getattr(platform, "_egl_context", None)
        if display is not None and context is not None:
            from OpenGL.EGL import EGL_NO_CONTEXT, EGL_NO_SURFACE, eglDestroyContext, eglMakeCurrent

            eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT)
            eglDestroyContext(display, context)
            platform._egl_context = None
            platform._egl_display = None
        else:  # other platforms (OSMesa, pyglet) own their context alone
            platform.delete_context()
        # OffscreenRenderer.__del__ calls delete(), which then fails harmlessly (and silently)
        renderer._renderer = None
        renderer._platform = None


def _box_faces(box: Box3D):
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


def _merge_collinear(p, q, left, right, tol_px=1e-6):
    """Merge pieces lying on one image line (each part of the line kept once).

    Box edges project onto one line when the camera lies in their common plane (a face seen
    edge-on, stacked boxes with aligned faces); the scanline accumulation must count each
    discontinuity once. Sides are re-expressed for the common orientation of the line.
    """
    d = q - p
    length = np.hypot(d[:, 0], d[:, 1])
    unit = d / length[:, None]
    flip = (unit[:, 0] < 0) | ((unit[:, 0] == 0) & (unit[:, 1] < 0))
    unit[flip] *= -1
    left, right = np.where(flip, right, left), np.where(flip, left, right)
    offset = unit[:, 0] * p[:, 1] - unit[:, 1] * p[:, 0]  # n . p with n = (-d_v, d_u)
    group = -np.ones(len(p), dtype=np.int64)
    n_groups = 0
    for k in range(len(p)):
        if group[k] < 0:
            same = ((group < 0) & (np.abs(unit - unit[k]).max(axis=1) < 1e-9)
                    & (np.abs(offset - offset[k]) < tol_px))
            group[same] = n_groups
            n_groups += 1
    out_p, out_q, out_l, out_r = [], [], [], []
    for g in range(n_groups):
        members = np.flatnonzero(group == g)
        k0 = members[0]
        # positions along the common line of every member's ends
        sp = p[members] @ unit[k0]
        sq = q[members] @ unit[k0]
        lo, hi = np.minimum(sp, sq), np.maximum(sp, sq)
        if members.size == 1:
            spans = [(lo[0], hi[0], k0)]
        else:
            ends = np.unique(np.concatenate([lo, hi]))
            spans = []
            for a, b in zip(ends[:-1], ends[1:]):
                cover = np.flatnonzero((lo <= 0.5 * (a + b)) & (hi >= 0.5 * (a + b)))
                if cover.size:
                    spans.append((a, b, members[cover[0]]))
        base = offset[k0] * np.array([-unit[k0, 1], unit[k0, 0]])  # foot of the line's normal
        for a, b, k in spans:
            out_p.append(base + a * unit[k0])
            out_q.append(base + b * unit[k0])
            out_l.append(left[k])
            out_r.append(right[k])
    if not out_p:
        return p[:0], q[:0], left[:0], right[:0]
    return np.array(out_p), np.array(out_q), np.array(out_l), np.array(out_r)


def _clip_segment(p0: np.ndarray, p1: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Liang-Barsky: parameters (a, b) of the part of ``p0 + s (p1 - p0)`` inside ``[lo, hi]``,
    or None."""
    a, b = 0.0, 1.0
    delta = p1 - p0
    for k in range(len(p0)):
        if abs(delta[k]) < 1e-15:
            if p0[k] < lo[k] or p0[k] > hi[k]:
                return None
            continue
        s_lo, s_hi = (lo[k] - p0[k]) / delta[k], (hi[k] - p0[k]) / delta[k]
        if s_lo > s_hi:
            s_lo, s_hi = s_hi, s_lo
        a, b = max(a, s_lo), min(b, s_hi)
        if a > b:
            return None
    return a, b


class MeshRenderer:
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
    trajectory : CameraTrajectory
        The camera motion.
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

    The renderer owns an OpenGL context: call :meth:`close` (or use it as a context manager).
    """

    def __init__(self, width, height, fx, fy, cx, cy, boxes, trajectory, background=0.5,
                 supersample=1):
        for name, value in (("width", width), ("height", height), ("supersample", supersample)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise TypeError(f"{name} must be an int, got {type(value).__name__}")
            if value <= 0:
                raise ValueError(f"{name} must be > 0, got {value}")
        if supersample % 2 == 0:
            raise ValueError(f"supersample must be odd (a sample at the pixel centre), got {supersample}")
        fx, fy = _finite(fx, "fx"), _finite(fy, "fy")
        if fx <= 0 or fy <= 0:
            raise ValueError(f"fx and fy must be > 0, got fx={fx}, fy={fy}")
        cx, cy = _finite(cx, "cx"), _finite(cy, "cy")
        background = _finite(background, "background")
        if not 0.0 <= background <= 1.0:
            raise ValueError(f"background must lie in [0, 1], got {background}")
        if not isinstance(trajectory, CameraTrajectory):
            raise TypeError(f"trajectory must be a CameraTrajectory, got {type(trajectory).__name__}")
        if isinstance(boxes, Box3D) or not isinstance(boxes, Sequence):
            raise TypeError("boxes must be a sequence of Box3D")
        for k, box in enumerate(boxes):
            if not isinstance(box, Box3D):
                raise TypeError(f"boxes[{k}] must be a Box3D, got {type(box).__name__}")
        if 6 * len(boxes) + 1 >= 2**24:
            raise ValueError(f"too many boxes ({len(boxes)}): face identifiers need 24 bits")

        self.width, self.height = int(width), int(height)
        self.fx, self.fy, self.cx, self.cy = fx, fy, cx, cy
        self.background = background
        self.supersample = int(supersample)
        self.boxes = tuple(boxes)
        self.trajectory = trajectory

        # Face table; index 0 is the background (no plane, intensity = background).
        normals, offsets, lut, quads = [np.full(3, np.nan)], [np.nan], [background], []
        for box in self.boxes:
            for (n, d, corners), value in zip(_box_faces(box), box.face_intensities):
                normals.append(n)
                offsets.append(d)
                lut.append(value)
                quads.append(corners)
        self._normals = np.array(normals)
        self._offsets = np.array(offsets)
        self._lut = np.array(lut, dtype=np.float64)
        # Box bounds and the 12 edges of every box (world frame) for the analytic edge map.
        half = np.array([b.size_m for b in self.boxes]).reshape(-1, 3) / 2.0
        centres = np.array([b.center_m for b in self.boxes]).reshape(-1, 3)
        self._lo, self._hi = centres - half, centres + half
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
        pairs = [(a, b) for a in range(8) for b in range(a + 1, 8)
                 if np.count_nonzero(signs[a] != signs[b]) == 1]
        edges = [[c + signs[a] * h, c + signs[b] * h] for c, h in zip(centres, half) for a, b in pairs]
        # where boxes overlap, the visible outline also follows face-face intersection lines
        edges += _intersection_segments(self._lo, self._hi)
        self._box_edges = np.array(edges).reshape(-1, 2, 3)

        # Normalised image coordinates of the pixel centres (x = X/Z, y = Y/Z).
        self._x = ((np.arange(self.width, dtype=np.float64) - cx) / fx)[None, :].repeat(self.height, 0)
        self._y = ((np.arange(self.height, dtype=np.float64) - cy) / fy)[:, None].repeat(self.width, 1)

        self._cache_t = None
        self._cache_ids = None
        self._center_rays = np.stack([self._x.ravel(), self._y.ravel(), np.ones(self._x.size)], axis=1)
        self._center_t = None
        self._center_cache = None
        self._pieces_t = None
        self._pieces = None
        self._renderer = None
        self._build_gl(quads)

    # -- OpenGL ---------------------------------------------------------------------------
    def _build_gl(self, quads):
        pyrender, GL = _import_pyrender()
        import trimesh

        s = self.supersample
        self._flat = pyrender.RenderFlags.FLAT
        scene = pyrender.Scene(bg_color=[0.0, 0.0, 0.0, 1.0], ambient_light=[0.0, 0.0, 0.0])
        for face_id, corners in enumerate(quads, start=1):
            # The identifier is the face colour: 8 bits per channel, exact in FLAT mode.
            rgb = [(face_id >> shift & 255) / 255.0 for shift in (0, 8, 16)]
            material = pyrender.MetallicRoughnessMaterial(
                baseColorFactor=rgb + [1.0], metallicFactor=0.0, doubleSided=True
            )
            mesh = trimesh.Trimesh(vertices=corners, faces=[[0, 1, 2], [0, 2, 3]], process=False)
            scene.add(pyrender.Mesh.from_trimesh(mesh, material=material, smooth=False))
        camera = pyrender.IntrinsicsCamera(
            fx=s * self.fx, fy=s * self.fy,
            cx=s * (self.cx + 0.5), cy=s * (self.cy + 0.5),
            znear=_ZNEAR_M, zfar=_ZFAR_M,
        )
        self._camera_node = scene.add(camera, pose=np.eye(4))
        self._scene = scene
        renderer = pyrender.OffscreenRenderer(s * self.width, s * self.height)
        try:
            renderer._renderer.delete()
            renderer._renderer = _single_sample_renderer_class(pyrender, GL)(
                s * self.width, s * self.height
            )
        except Exception:
            _delete_offscreen(renderer)
            raise
        self._renderer = renderer

    def _check_open(self) -> None:
        if self._renderer is None:
            raise RuntimeError("MeshRenderer is closed")

    def _face_ids(self, t_s: float) -> np.ndarray:
        """Face identifiers (s*H, s*W) (uint8 or int32) of the supersampled image at ``t_s`` (cached)."""
        t_s = _finite(t_s, "t_s")
        self._check_open()
        if self._cache_t != t_s:
            pose = self.trajectory.pose(t_s)
            pose[:3, 1:3] *= -1.0  # OpenCV camera (y down, looks +z) -> OpenGL (y up, looks -z)
            self._scene.set_pose(self._camera_node, pose)
            color, _ = self._renderer.render(self._scene, flags=self._flat)
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
            rays = self._center_rays @ self.trajectory.rotation(t_s).T  # camera -> world directions
            ids = _cast_rays(self.trajectory.position(t_s), rays, self._lo, self._hi)
            self._center_t, self._center_cache = t_s, ids.reshape(self.height, self.width)
        return self._center_cache

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
            return np.clip(self._exact_intensity(_finite(t_s, "t_s")), 0.0, 1.0)
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
        ids = self._center_ids(t_s)
        rot = self.trajectory.rotation(t_s)
        centre = self.trajectory.position(t_s)
        n = self._normals[ids]  # (H, W, 3); NaN for the background
        nr = n @ rot  # n^T R, so (n^T R) q = n . (R q)
        denom = nr[..., 0] * self._x + nr[..., 1] * self._y + nr[..., 2]
        with np.errstate(invalid="ignore", divide="ignore"):
            z = (self._offsets[ids] - n @ centre) / denom
        return np.where(ids == 0, np.inf, z)

    def flow(self, t_s: float) -> np.ndarray:
        """Motion field (2, H, W) float64 ``(vx, vy)`` in px/s at the pixel centres.

        Notes
        -----
        A static point ``P`` in the frame of a camera moving with linear velocity ``V`` and
        angular velocity ``w`` (both in the camera frame) moves as ``dP/dt = -V - w x P``.
        Differentiating ``u = fx X/Z + cx``, ``v = fy Y/Z + cy`` with ``a = (dP/dt) / Z``:
        ``du/dt = fx (a_x - x a_z)``, ``dv/dt = fy (a_y - y a_z)`` (Longuet-Higgins & Prazdny
        1980). Background pixels are points at infinity (``1/Z = 0``): rotational flow only.
        """
        inv_z = 1.0 / self.depth(t_s)  # 0 for the background (inf depth)
        rot = self.trajectory.rotation(t_s)
        v_cam = rot.T @ np.asarray(self.trajectory.velocity_m_s)
        wx, wy, wz = self.trajectory.angular_velocity_rad_s
        x, y = self._x, self._y
        # a = -V/Z - w x q with q = (x, y, 1)
        ax = -v_cam[0] * inv_z - (wy - wz * y)
        ay = -v_cam[1] * inv_z - (wz * x - wx)
        az = -v_cam[2] * inv_z - (wx * y - wy * x)
        return np.stack([self.fx * (ax - x * az), self.fy * (ay - y * az)])

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
        to the near plane, projected, and sampled every 1/8 px; a sample is a discontinuity
        when the faces seen 1e-8 px to either side of it (exact slab ray casting) differ.
        Visibility transitions are refined by bisection to 1e-8 px, and every pixel
        whose closed square meets a visible piece is marked (exact supercover). Limits: a
        visible piece shorter than 1/8 px between two hidden samples is missed. Where boxes
        overlap, the face-face intersection lines are candidates too, so the outline of their
        union is exact as well.

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
        """Visible discontinuities in the image at ``t_s`` (cached), merged where collinear."""
        if self._pieces_t != t_s:
            lo, hi = (-0.5, -0.5), (self.width - 0.5, self.height - 0.5)
            self._pieces = _merge_collinear(*self._visible_pieces(t_s, lo, hi))
            self._pieces_t = t_s
        p, q, left, right = self._pieces
        if contrast_only:
            keep = self._lut[left] != self._lut[right]
            return p[keep], q[keep], left[keep], right[keep]
        return p, q, left, right

    def _visible_pieces(self, t_s: float, view_lo, view_hi):
        """Visible discontinuities at ``t_s`` as straight pieces, clipped to ``[view_lo, view_hi]``.

        Returns ``(start (K, 2), end (K, 2), left (K,), right (K,))``: image coordinates of the
        ends and the face identifiers on either side of each piece (left = side of the normal
        ``(-dv, du)``), constant along it. Every box edge is clipped to the near plane,
        projected, clipped to the view and sampled every 1/8 px; at each sample the faces seen
        1e-8 px to either side are found by exact ray casting; pieces are maximal runs of
        samples with one (left, right) pair that differ, their ends refined by bisection.
        """
        # bisection to 0.125 / 2**24 = 7e-9 px, matching the 1e-8 px side offset
        step_px, side_px, iterations = 0.125, 1e-8, 24
        rot = self.trajectory.rotation(t_s)
        centre = self.trajectory.position(t_s)
        focal, principal = np.array([self.fx, self.fy]), np.array([self.cx, self.cy])
        near_lo, near_hi = np.array([-np.inf, -np.inf, _ZNEAR_M]), np.full(3, np.inf)
        view_lo, view_hi = np.asarray(view_lo, float), np.asarray(view_hi, float)
        starts, ends = [], []
        for a_w, b_w in self._box_edges:
            a_c, b_c = (a_w - centre) @ rot, (b_w - centre) @ rot
            part = _clip_segment(a_c, b_c, near_lo, near_hi)
            if part is None:
                continue
            p, q = a_c + part[0] * (b_c - a_c), a_c + part[1] * (b_c - a_c)
            p, q = p[:2] / p[2] * focal + principal, q[:2] / q[2] * focal + principal
            part = _clip_segment(p, q, view_lo, view_hi)
            if part is None:
                continue
            p, q = p + part[0] * (q - p), p + part[1] * (q - p)
            if np.hypot(*(q - p)) > 1e-9:  # an edge seen end-on is a point of its neighbours
                starts.append(p)
                ends.append(q)
        none = (np.empty((0, 2)), np.empty((0, 2)), np.empty(0, np.int64), np.empty(0, np.int64))
        if not starts:
            return none
        starts, ends = np.array(starts), np.array(ends)
        delta = ends - starts
        length = np.hypot(delta[:, 0], delta[:, 1])
        normal = np.stack([-delta[:, 1], delta[:, 0]], axis=1) / length[:, None]
        values = self._lut

        def sides(seg, lam):
            """Key per sample: left * K + right when a discontinuity, else -1."""
            points = starts[seg] + lam[:, None] * delta[seg]
            both = np.concatenate([points + side_px * normal[seg], points - side_px * normal[seg]])
            rays = np.column_stack([(both - principal) / focal, np.ones(len(both))]) @ rot.T
            ids = _cast_rays(centre, rays, self._lo, self._hi)
            left, right = ids[: len(points)], ids[len(points):]
            return np.where(left != right, left * len(values) + right, -1)

        counts = np.maximum(np.ceil(length / step_px).astype(np.int64) + 1, 2)
        seg = np.repeat(np.arange(len(starts)), counts)
        offsets = np.cumsum(counts) - counts
        lam = (np.arange(seg.size) - offsets[seg]) / (counts[seg] - 1)
        key = sides(seg, lam)
        # changes of key between consecutive samples of one segment, refined by bisection
        same_seg = seg[:-1] == seg[1:]
        k = np.flatnonzero((key[:-1] != key[1:]) & same_seg)
        lo_lam, hi_lam, lo_key = lam[k].copy(), lam[k + 1].copy(), key[k]
        for _ in range(iterations):
            mid = 0.5 * (lo_lam + hi_lam)
            same = sides(seg[k], mid) == lo_key
            lo_lam, hi_lam = np.where(same, mid, lo_lam), np.where(same, hi_lam, mid)
        crossing = dict(zip(k.tolist(), (0.5 * (lo_lam + hi_lam)).tolist()))
        # pieces: maximal runs of one key >= 0 within a segment
        new_run = np.r_[True, (key[1:] != key[:-1]) | ~same_seg]
        end_run = np.r_[(key[1:] != key[:-1]) | ~same_seg, True]
        run_start = np.flatnonzero(new_run & (key >= 0))
        run_end = np.flatnonzero(end_run & (key >= 0))
        if run_start.size == 0:
            return none
        sid = seg[run_start]
        lam0 = np.array([crossing.get(f - 1, lam[f]) for f in run_start.tolist()])
        lam1 = np.array([crossing.get(e, lam[e]) for e in run_end.tolist()])
        p = starts[sid] + lam0[:, None] * delta[sid]
        q = starts[sid] + lam1[:, None] * delta[sid]
        return p, q, key[run_start] // len(values), key[run_start] % len(values)

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
        values = self._lut
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
        return self._left_border(t_s, p, q)[:, None] + np.cumsum(acc, axis=1)[:, :width]

    def _left_border(self, t_s: float, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Mean intensity along the left image border ``u = -0.5`` over each row (H,)."""
        height = self.height
        ends = np.concatenate([p, q])
        cuts = ends[np.abs(ends[:, 0] + 0.5) < 1e-9, 1]
        breaks = np.unique(np.concatenate([np.arange(height + 1) - 0.5, np.clip(cuts, -0.5, height - 0.5)]))
        mids = 0.5 * (breaks[1:] + breaks[:-1])
        u = np.full(mids.size, -0.5 + 1e-7)
        rays = np.column_stack([(u - self.cx) / self.fx, (mids - self.cy) / self.fy, np.ones(mids.size)])
        ids = _cast_rays(self.trajectory.position(t_s), rays @ self.trajectory.rotation(t_s).T,
                         self._lo, self._hi)
        row = np.clip(np.floor(mids + 0.5).astype(np.int64), 0, height - 1)
        return np.bincount(row, weights=self._lut[ids] * np.diff(breaks), minlength=height)

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
        plane). The rotational part is bounded term by term with ``|x| <= xm``, ``|y| <= ym``:
        ``|vx| <= fx (|wy| (1 + xm^2) + |wz| ym + |wx| xm ym)`` and
        ``|vy| <= fy (|wx| (1 + ym^2) + |wz| xm + |wy| xm ym)``. The bound is the sum of both.
        """
        t0_s, t1_s = _finite(t0_s, "t0_s"), _finite(t1_s, "t1_s")
        if t1_s < t0_s:
            raise ValueError(f"t1_s must be >= t0_s, got t0_s={t0_s}, t1_s={t1_s}")
        xm = max(abs(-0.5 - self.cx), abs(self.width - 0.5 - self.cx)) / self.fx
        ym = max(abs(-0.5 - self.cy), abs(self.height - 0.5 - self.cy)) / self.fy
        wx, wy, wz = (abs(w) for w in self.trajectory.angular_velocity_rad_s)
        rot_x = self.fx * (wy * (1 + xm * xm) + wz * ym + wx * xm * ym)
        rot_y = self.fy * (wx * (1 + ym * ym) + wz * xm + wy * xm * ym)
        bound = math.hypot(rot_x, rot_y)
        speed = float(np.linalg.norm(self.trajectory.velocity_m_s))
        if speed > 0 and len(self.boxes):
            r = math.sqrt(1 + xm * xm + ym * ym)
            centre = self.trajectory.position(0.5 * (t0_s + t1_s))
            gap = np.maximum(np.maximum(self._lo - centre, centre - self._hi), 0.0)
            distance = float(np.sqrt((gap * gap).sum(axis=1)).min()) - 0.5 * speed * (t1_s - t0_s)
            z_min = max(distance / r, _ZNEAR_M)
            bound += max(self.fx, self.fy) * speed * r / z_min
        return bound

    def close(self) -> None:
        """Free the OpenGL context (idempotent); the renderer cannot render afterwards."""
        if self._renderer is not None:
            renderer, self._renderer = self._renderer, None
            self._cache_t = self._cache_ids = self._pieces_t = self._pieces = None
            _delete_offscreen(renderer)

    @property
    def closed(self) -> bool:
        return self._renderer is None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
