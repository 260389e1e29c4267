"""Analytic renderers of planar scenes: shapes on a background, and moving stripes.

Both render the exact area coverage of every pixel square (see
:mod:`evedge.sim._coverage`), give the exact edge map from the same geometry
and the exact per-point ground truth (:class:`evedge.sim.renderer.GeometricTruth`).

Edge map definition: pixel ``(x, y)`` is an edge pixel at time ``t`` when a
shape boundary passes through the interior of its square
``[x - 0.5, x + 0.5] x [y - 0.5, y + 0.5]``, decided as
``1e-9 < coverage < 1 - 1e-9`` for some shape (a boundary through the open
square leaves area on both sides; one lying on the square's border does not
count).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._coverage import _draw_shapes, _fill_boxes, _render_disk, _render_polygons, _render_stripes
from ._coverage import _HALF_DIAG
from ._exact import (_nonmonotone_pixels, _shapes_at, _shapes_translating, _shapes_truth_points, _stripes_at,
                     _stripes_truth)
from ._nearest import _nearest_outward_normal
from .motion import PlanarMotion
from .thin_edges import mark_circle, mark_segments, mark_stripes

#: Coverage tolerance of the edge-map definition (px^2).
EDGE_AREA_TOL = 1e-9


@dataclass(frozen=True)
class Polygon:
    """A filled simple polygon (object coordinates in px at t = 0) of one intensity."""

    vertices_px: np.ndarray
    intensity: float

    def __post_init__(self) -> None:
        v = np.ascontiguousarray(self.vertices_px, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 2 or v.shape[0] < 3 or not np.all(np.isfinite(v)):
            raise ValueError(f"Polygon.vertices_px must be a finite (n >= 3, 2) array, got shape {v.shape}")
        if not 0.0 <= self.intensity <= 1.0:
            raise ValueError(f"Polygon.intensity must be in [0, 1], got {self.intensity}")
        object.__setattr__(self, "vertices_px", v)

    @property
    def orientation(self) -> float:
        x, y = self.vertices_px[:, 0], self.vertices_px[:, 1]
        return float(np.sign(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)))


@dataclass(frozen=True)
class Circle:
    """A filled disk (centre in object px at t = 0)."""

    center_px: tuple[float, float]
    radius_px: float
    intensity: float

    def __post_init__(self) -> None:
        if not (self.radius_px > 0 and math.isfinite(self.radius_px)):
            raise ValueError(f"Circle.radius_px must be > 0, got {self.radius_px}")
        if not 0.0 <= self.intensity <= 1.0:
            raise ValueError(f"Circle.intensity must be in [0, 1], got {self.intensity}")


def regular_polygon(center, radius_px: float, sides: int, rotation_rad: float = 0.0) -> np.ndarray:
    """Vertices of a regular polygon with circumradius ``radius_px``."""
    a = rotation_rad + 2 * np.pi * np.arange(sides) / sides - np.pi / 2
    return np.stack([center[0] + radius_px * np.cos(a), center[1] + radius_px * np.sin(a)], axis=1)


def star_polygon(center, radius_px: float, points: int, inner_ratio: float, rotation_rad: float = 0.0) -> np.ndarray:
    """Vertices of a star with ``points`` tips (outer radius ``radius_px``)."""
    k = np.arange(2 * points)
    r = np.where(k % 2 == 0, radius_px, radius_px * inner_ratio)
    a = rotation_rad + np.pi * k / points - np.pi / 2
    return np.stack([center[0] + r * np.cos(a), center[1] + r * np.sin(a)], axis=1)


class _CoverageRenderer:
    """Base of the planar renderers: one coverage pass gives intensity and exact edges together.

    Subclasses set ``width``, ``height``, ``background`` and implement
    ``_draw(t_s, out, edge)``, which adds the scene into the flat row-major
    buffers (``out`` starts at the background, ``edge`` all False).
    """

    width: int
    height: int
    background: float
    _edge_scratch: np.ndarray | None = None

    def _draw(self, t_s: float, out: np.ndarray, edge: np.ndarray) -> np.ndarray:
        """Draw into ``out``/``edge``; return the boxes (flat int64, 4 per box) outside which nothing was written."""
        raise NotImplementedError

    def _render(self, t_s: float):
        w, h = self.width, self.height
        out = np.full(w * h, self.background)
        edge = np.zeros(w * h, dtype=np.bool_)
        self._draw(t_s, out, edge)
        return out.reshape(h, w), edge.reshape(h, w)

    def intensity_into(self, t_s: float, out: np.ndarray, dirty: np.ndarray | None) -> np.ndarray:
        """Render the intensity at ``t_s`` into the flat float64 buffer ``out``, reusing it.

        Parameters
        ----------
        t_s : float
        out : numpy.ndarray
            Flat (H * W) float64 buffer, overwritten.
        dirty : numpy.ndarray or None
            What the previous ``intensity_into`` into ``out`` returned (only
            those boxes are reset to the background), or None when ``out``
            holds anything else (it is filled).

        Returns
        -------
        numpy.ndarray
            Boxes (flat int64, ``r0, r1, c0, c1`` half-open per box) outside
            which ``out`` equals the background exactly. ``out`` holds the
            same bytes as :meth:`intensity` (same kernels, same order).
        """
        if dirty is None:
            out.fill(self.background)
        else:
            _fill_boxes(out, self.width, dirty, dirty.shape[0] // 4, self.background)
        return self._draw(t_s, out, self._edge_buffer())

    def _edge_buffer(self) -> np.ndarray:
        # edge output of intensity_into, never read: the kernels only set pixels to True, so it
        # needs no reset
        if self._edge_scratch is None:
            self._edge_scratch = np.zeros(self.width * self.height, dtype=np.bool_)
        return self._edge_scratch

    def intensity(self, t_s: float) -> np.ndarray:
        return self._render(t_s)[0]

    def edges(self, t_s: float) -> np.ndarray:
        return self._render(t_s)[1]


class ShapesRenderer(_CoverageRenderer):
    """Non-overlapping shapes of flat intensity on a flat background, moving rigidly.

    Parameters
    ----------
    width, height : int
        Sensor size.
    shapes : list of Polygon or Circle
        Shapes in object coordinates (their image position at ``t = 0``).
        Intensities are composed as ``bg + sum_k coverage_k (I_k - bg)``, exact
        for non-overlapping shapes.
    motion : PlanarMotion
        The rigid image-plane motion shared by all shapes.
    background : float
        Background intensity in [0, 1].
    """

    def __init__(self, width: int, height: int, shapes, motion: PlanarMotion, background: float = 0.8):
        self.width = int(width)
        self.height = int(height)
        self.motion = motion
        self.background = float(background)
        self.polygons = [s for s in shapes if isinstance(s, Polygon)]
        self.circles = [s for s in shapes if isinstance(s, Circle)]
        if len(self.polygons) + len(self.circles) != len(shapes):
            raise TypeError("ShapesRenderer: shapes must be Polygon or Circle instances")
        self._acc = np.zeros(self.width * self.height)  # scratch of the polygon rasteriser
        # flattened geometry for the truth kernel
        verts = [p.vertices_px for p in self.polygons]
        self._px = np.ascontiguousarray(np.concatenate([v[:, 0] for v in verts]) if verts else np.empty(0))
        self._py = np.ascontiguousarray(np.concatenate([v[:, 1] for v in verts]) if verts else np.empty(0))
        self._pstart = np.concatenate([[0], np.cumsum([v.shape[0] for v in verts])]).astype(np.int64)
        self._porient = np.array([p.orientation for p in self.polygons], dtype=np.float64)
        self._pvalue = np.array([p.intensity for p in self.polygons], dtype=np.float64)
        self._pflip = np.array([1.0 if p.intensity < self.background else -1.0 for p in self.polygons])
        self._cx = np.array([c.center_px[0] for c in self.circles], dtype=np.float64)
        self._cy = np.array([c.center_px[1] for c in self.circles], dtype=np.float64)
        self._cr = np.array([c.radius_px for c in self.circles], dtype=np.float64)
        self._cflip = np.array([1.0 if c.intensity < self.background else -1.0 for c in self.circles])
        # the composition stays in [0, 1] unless shapes overlap (bounding circles as a cheap test;
        # the motion is rigid, so it does not change this)
        centres = [(p.vertices_px.mean(axis=0), np.max(np.hypot(*(p.vertices_px - p.vertices_px.mean(axis=0)).T)))
                   for p in self.polygons] + [(np.asarray(c.center_px), c.radius_px) for c in self.circles]
        self._may_overlap = any(np.hypot(*(a[0] - b[0])) < a[1] + b[1]
                                for k, a in enumerate(centres) for b in centres[:k])
        self._allx = np.concatenate([self._px, self._cx])
        self._ally = np.concatenate([self._py, self._cy])
        self._cvalue = np.array([c.intensity for c in self.circles], dtype=np.float64)
        # bounding circles of the polygons (object coordinates): pixel_intensity skips far polygons
        self._bcx = np.array([p.vertices_px[:, 0].mean() for p in self.polygons], dtype=np.float64)
        self._bcy = np.array([p.vertices_px[:, 1].mean() for p in self.polygons], dtype=np.float64)
        self._br = np.array([np.max(np.hypot(p.vertices_px[:, 0] - a, p.vertices_px[:, 1] - b))
                             for p, a, b in zip(self.polygons, self._bcx, self._bcy)], dtype=np.float64)
        self._motion_array = None  # the motion's parameters for the pixel_intensity kernel
        self._nm_stamp = None  # scratch of nonmonotone_pixels
        self._translating = None  # pixel_intensity's geometry when the motion does not rotate
        self._qx = np.empty_like(self._allx)  # scratch: image positions of the points
        self._qy = np.empty_like(self._allx)

    def _draw(self, t_s: float, out: np.ndarray, edge: np.ndarray) -> np.ndarray:
        # one motion evaluation for all vertices and circle centres, then one kernel call
        theta, _, sx, sy, _, _ = self.motion.state(float(t_s))
        cx, cy = self.motion.center_px
        boxes = np.empty(4 * (len(self.polygons) + len(self.circles)), dtype=np.int64)
        _draw_shapes(out, edge, self._acc, self.width, self.height, self._allx, self._ally, self._px.shape[0],
                     self._pstart, self._pvalue, self._cr, self._cvalue, self.background, EDGE_AREA_TOL,
                     self._may_overlap, cx, cy, math.cos(theta), math.sin(theta), sx, sy, self._qx, self._qy, boxes)
        return boxes

    def thin_edges(self, t_s: float) -> np.ndarray:
        """Thin exact edge map at ``t_s``: one pixel per boundary crossing of each row and column
        (:mod:`evedge.sim.thin_edges`)."""
        img = np.zeros((self.height, self.width), dtype=bool)
        for poly in self.polygons:
            px, py = self.motion.to_image(poly.vertices_px[:, 0], poly.vertices_px[:, 1], float(t_s))
            mark_segments(img, px, py, np.roll(px, -1), np.roll(py, -1))
        for c in self.circles:
            cx, cy = self.motion.to_image(np.array([c.center_px[0]]), np.array([c.center_px[1]]), float(t_s))
            mark_circle(img, float(cx[0]), float(cy[0]), c.radius_px)
        return img
    def pixel_intensity(self, pix: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Exact intensity of flat pixels ``pix`` at times ``t_s`` (one time per pixel).

        Parameters
        ----------
        pix : numpy.ndarray
            int64 flat pixel indices ``y * width + x``.
        t_s : numpy.ndarray
            float64 times (s), the shape of ``pix``.

        Returns
        -------
        numpy.ndarray
            float64 intensities: the pixel-area coverage of every shape at its
            time (the values of :meth:`intensity`, from clipping against the
            pixel square rather than row accumulation: equal to ~1e-15).
        """
        cx, cy = self.motion.center_px
        out = np.empty(pix.shape[0])
        if self._translation_geometry() is not None:
            bx, by, bcx, bcy, reach2, ccx, ccy = self._translating
            _shapes_translating(pix, np.ascontiguousarray(t_s, dtype=np.float64), False, self._motion_params(),
                                self.width, bx, by, self._pstart, self._pvalue, bcx, bcy, reach2, ccx, ccy, self._cr,
                                self._cvalue, self.background, self._may_overlap, out)
            return out
        _shapes_at(pix, np.ascontiguousarray(t_s, dtype=np.float64), self._motion_params(), self.width, cx, cy,
                   self._px, self._py, self._pstart,
                   self._pvalue, self._bcx, self._bcy, self._br, self._cx, self._cy, self._cr, self._cvalue,
                   self.background, self._may_overlap, out)
        return out

    def _translation_geometry(self):
        """For a motion without rotation: the geometry rotated by its constant angle (image positions at
        ``s = 0``) for the translating kernels; None when the motion rotates."""
        m = self.motion
        if m.angular_velocity_rad_s != 0.0 or m.angular_acceleration_rad_s2 != 0.0 or m.angle_amplitude_rad != 0.0:
            return None
        if self._translating is None:
            cx, cy = m.center_px
            c, sn = math.cos(m.angle_rad), math.sin(m.angle_rad)
            rot = lambda x, y: (np.ascontiguousarray(cx + c * (x - cx) - sn * (y - cy)),  # noqa: E731
                                np.ascontiguousarray(cy + sn * (x - cx) + c * (y - cy)))
            self._translating = (*rot(self._px, self._py), *rot(self._bcx, self._bcy),
                                 (self._br + _HALF_DIAG) ** 2, *rot(self._cx, self._cy))
        return self._translating

    def pixel_intensity_grid(self, pix: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Exact intensity of every flat pixel ``pix[j]`` at every time ``t_s[q]``, as ``out[j, q]``.

        The values of :meth:`pixel_intensity` on the repeated pixels and tiled
        times (up to rounding, ~1e-15), the motion evaluated once per time
        when it does not rotate.

        Examples
        --------
        >>> import numpy as np
        >>> from evedge.sim.motion import PlanarMotion
        >>> r = ShapesRenderer(8, 8, [Circle((3.5, 3.5), 2.0, 0.2)], PlanarMotion(velocity_px_s=(10.0, 0.0)))
        >>> r.pixel_intensity_grid(np.array([27, 28]), np.array([0.0, 0.05])).shape
        (2, 2)
        """
        pix = np.ascontiguousarray(pix, dtype=np.int64)
        t_s = np.ascontiguousarray(t_s, dtype=np.float64)
        geo = self._translation_geometry()
        if geo is None:
            return self.pixel_intensity(np.repeat(pix, t_s.shape[0]), np.tile(t_s, pix.shape[0])).reshape(
                pix.shape[0], t_s.shape[0])
        out = np.empty(pix.shape[0] * t_s.shape[0])
        bx, by, bcx, bcy, reach2, ccx, ccy = geo
        _shapes_translating(pix, t_s, True, self._motion_params(), self.width, bx, by, self._pstart, self._pvalue,
                            bcx, bcy, reach2, ccx, ccy, self._cr, self._cvalue, self.background, self._may_overlap,
                            out)
        return out.reshape(pix.shape[0], t_s.shape[0])

    def nonmonotone_pixels(self, t0_s: float, t1_s: float, reach_px: float) -> np.ndarray:
        """Pixels whose intensity may not be monotone in time over ``[t0_s, t1_s]``.

        Every other pixel's intensity is monotone over the step, so its
        crossings are exactly those its end values show (the converter's
        geometric steps rely on this, see :mod:`evedge.sim.converter`). The
        rule (:func:`~evedge.sim._exact._nonmonotone_pixels`): the sign of the
        boundary's normal speed ``v.n`` on every polygon edge and disk arc
        that comes within ``reach_px`` of the pixel centre; a pixel reached
        by pieces of both signs (a vertex moving sideways, the two sides of a
        thin part, a disk's flank, any edge as the motion turns) is returned.

        Parameters
        ----------
        t0_s, t1_s : float
            The step (s), ``t0_s <= t1_s``.
        reach_px : float
            Half the pixel diagonal plus the largest image displacement of
            any point during the step (px).

        Returns
        -------
        numpy.ndarray
            int64 flat pixel indices, each once (a fresh array).

        Examples
        --------
        >>> import numpy as np
        >>> from evedge.sim.motion import PlanarMotion
        >>> bar = Polygon(np.array([[3.0, -5.0], [3.3, -5.0], [3.3, 9.0], [3.0, 9.0]]), 0.1)
        >>> r = ShapesRenderer(8, 3, [bar], PlanarMotion(velocity_px_s=(100.0, 0.0)))
        >>> sorted(int(p) for p in r.nonmonotone_pixels(0.0, 0.005, 0.71 + 0.5) if p < 8)  # row 0: both sides
        [3, 4]
        """
        npix = self.width * self.height
        if self._nm_stamp is None:
            self._nm_stamp = np.full(npix, -1, dtype=np.int64)
            self._nm_bits = np.zeros(npix, dtype=np.uint8)
            self._nm_out = np.empty(npix, dtype=np.int64)
            self._nm_step = 0
        self._nm_step += 1
        cx, cy = self.motion.center_px
        n = _nonmonotone_pixels(self._motion_params(), float(t0_s), float(t1_s), float(reach_px), self.width,
                                self.height, cx, cy, self._px, self._py, self._pstart, self._porient, self._pvalue,
                                self._cx, self._cy, self._cr, self._cvalue, self.background, self._nm_stamp,
                                self._nm_bits, self._nm_step, self._nm_out)
        return self._nm_out[:n].copy()

    def _motion_params(self) -> np.ndarray:
        """The motion's parameters as one float64 array (for the kernels)."""
        if self._motion_array is None:
            m = self.motion
            self._motion_array = np.array([m.angle_rad, m.angular_velocity_rad_s, m.angular_acceleration_rad_s2,
                                           m.angle_amplitude_rad, m.frequency_hz, m.chirp_hz_s, *m.velocity_px_s,
                                           *m.acceleration_px_s2, *m.amplitude_px], dtype=np.float64)
        return self._motion_array

    def flow(self, t_s: float) -> np.ndarray:
        yy, xx = np.mgrid[0:self.height, 0:self.width].astype(np.float64)
        vx, vy = self.motion.flow_at(xx, yy, t_s)
        return np.stack([np.broadcast_to(vx, xx.shape), np.broadcast_to(vy, xx.shape)]).astype(np.float64)

    def max_speed_px_s(self, t0_s: float, t1_s: float) -> float:
        return self.motion.max_speed_px_s(t0_s, t1_s, self.width, self.height)

    def point_truth(self, x, y, t_s):
        x, y, t_s = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (x, y, t_s)))
        shape = x.shape
        x, y, t_s = (np.ascontiguousarray(a).ravel() for a in (x, y, t_s))
        m = self.motion
        cx, cy = m.center_px
        # the motion field and the point in object coordinates, R(-theta) (PlanarMotion's formulas, one pass)
        qx, qy, vx, vy, c, s = (np.empty_like(x) for _ in range(6))
        _shapes_truth_points(x, y, t_s, self._motion_params(), cx, cy, self._translation_geometry() is None,
                             qx, qy, vx, vy, c, s)
        onx = np.empty_like(qx)
        ony = np.empty_like(qx)
        _nearest_outward_normal(qx, qy, self._px, self._py, self._pstart, self._porient, self._pflip,
                                self._cx, self._cy, self._cr, self._cflip, onx, ony)
        nx = c * onx - s * ony  # back to the image frame: R(theta)
        ny = s * onx + c * ony
        return vx.reshape(shape), vy.reshape(shape), nx.reshape(shape), ny.reshape(shape)

    def close(self) -> None:
        pass


@dataclass(frozen=True)
class StripeLayer:
    """Parallel stripes filling the rows ``rows[0] <= y < rows[1]``.

    The stripe coordinate is ``u = n . (p - v t) - phase_px`` with the unit
    normal ``n = (cos angle, sin angle)``; the pixel is dark where
    ``u mod period_px < duty * period_px``. The stripes move with velocity
    ``velocity_px_s`` (any direction: the normal speed is ``v . n``).
    """

    rows: tuple[int, int]
    period_px: float
    angle_rad: float
    velocity_px_s: tuple[float, float]
    dark: float = 0.2
    light: float = 0.8
    duty: float = 0.5
    phase_px: float = 0.0

    def __post_init__(self) -> None:
        if not (0 <= self.rows[0] < self.rows[1]):
            raise ValueError(f"StripeLayer.rows must satisfy 0 <= start < end, got {self.rows}")
        if not self.period_px > 0:
            raise ValueError(f"StripeLayer.period_px must be > 0, got {self.period_px}")
        if not 0 < self.duty < 1:
            raise ValueError(f"StripeLayer.duty must be in (0, 1), got {self.duty}")
        for name in ("dark", "light"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"StripeLayer.{name} must be in [0, 1]")

    @property
    def normal(self) -> tuple[float, float]:
        return (math.cos(self.angle_rad), math.sin(self.angle_rad))


class StripesRenderer(_CoverageRenderer):
    """Horizontal bands of moving stripes (one :class:`StripeLayer` per band) over a background."""

    def __init__(self, width: int, height: int, layers, background: float = 0.5):
        self.width = int(width)
        self.height = int(height)
        self.layers = list(layers)
        self.background = float(background)
        self._layer_of_row = np.full(self.height, -1, dtype=np.int64)
        for k, layer in enumerate(self.layers):
            r0, r1 = layer.rows[0], min(layer.rows[1], self.height)
            if np.any(self._layer_of_row[r0:r1] >= 0):
                raise ValueError(f"StripesRenderer: layer {k} rows {layer.rows} overlap another layer")
            self._layer_of_row[r0:r1] = k
        self._layer_arrays = None

    def _draw(self, t_s: float, out: np.ndarray, edge: np.ndarray) -> np.ndarray:
        w, h = self.width, self.height
        for layer in self.layers:
            nx, ny = layer.normal
            offset = nx * layer.velocity_px_s[0] * t_s + ny * layer.velocity_px_s[1] * t_s + layer.phase_px
            _render_stripes(out, edge, w, layer.rows[0], min(layer.rows[1], h), nx, ny, offset,
                            layer.period_px, layer.duty, layer.dark, layer.light, EDGE_AREA_TOL)
        return np.array([0, h, 0, w], dtype=np.int64)  # stripes change everywhere

    def thin_edges(self, t_s: float) -> np.ndarray:
        """Thin exact edge map at ``t_s``: one pixel per stripe-boundary crossing of each row and column
        (:mod:`evedge.sim.thin_edges`)."""
        img = np.zeros((self.height, self.width), dtype=bool)
        for layer in self.layers:
            nx, ny = layer.normal
            offset = nx * layer.velocity_px_s[0] * t_s + ny * layer.velocity_px_s[1] * t_s + layer.phase_px
            mark_stripes(img, layer.rows[0], layer.rows[1], nx, ny, offset, layer.period_px, layer.duty)
        return img

    def intensity_into(self, t_s: float, out: np.ndarray, dirty: np.ndarray | None) -> np.ndarray:
        """As :meth:`_CoverageRenderer.intensity_into`; the stripes overwrite their rows, so no reset."""
        if dirty is None:
            out.fill(self.background)
        # rows of no layer are never written: they keep the background of the first fill
        return self._draw(t_s, out, self._edge_buffer())

    @property
    def monotone_step_px(self) -> float:
        """Largest image displacement over which every pixel's intensity is monotone in time.

        Each layer's edges are straight and move at a constant velocity, so a
        pixel whose square meets one edge only sees its coverage change one
        way. The square spans at most ``|nx| + |ny|`` along the normal; with
        stripes and gaps at least ``w`` wide, a displacement below
        ``w - (|nx| + |ny|)`` never brings a second edge into it. The
        converter samples such renderers by ``max_step_px`` alone when exact
        crossing times are on (see :mod:`evedge.sim.converter`).
        """
        out = math.inf
        for layer in self.layers:
            nx, ny = layer.normal
            width = min(layer.duty, 1.0 - layer.duty) * layer.period_px
            out = min(out, width - (abs(nx) + abs(ny)))
        return max(0.0, out)

    def pixel_intensity(self, pix: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Exact intensity of flat pixels ``pix`` at times ``t_s`` (as :meth:`ShapesRenderer.pixel_intensity`).

        The arithmetic is the renderer's, so at a sample time the values are
        those of :meth:`intensity` to the bit.
        """
        out = np.empty(pix.shape[0])
        _stripes_at(pix, np.asarray(t_s, dtype=np.float64), self.width, self._layer_of_row, *self._layers(),
                    self.background, out)
        return out

    def flow(self, t_s: float) -> np.ndarray:
        out = np.zeros((2, self.height, self.width))
        for layer in self.layers:
            r0, r1 = layer.rows[0], min(layer.rows[1], self.height)
            out[0, r0:r1] = layer.velocity_px_s[0]
            out[1, r0:r1] = layer.velocity_px_s[1]
        return out

    def max_speed_px_s(self, t0_s: float, t1_s: float) -> float:
        return max([math.hypot(*layer.velocity_px_s) for layer in self.layers], default=0.0)

    def _layers(self):
        """Per-layer parameters as float64 arrays (for the kernels)."""
        if self._layer_arrays is None:
            cols = [[layer.normal[0] for layer in self.layers], [layer.normal[1] for layer in self.layers],
                    [layer.velocity_px_s[0] for layer in self.layers], [layer.velocity_px_s[1] for layer in self.layers],
                    [layer.phase_px for layer in self.layers], [layer.period_px for layer in self.layers],
                    [layer.duty for layer in self.layers], [layer.dark for layer in self.layers],
                    [layer.light for layer in self.layers]]
            self._layer_arrays = [np.array(c, dtype=np.float64) for c in cols]
        return self._layer_arrays

    def point_truth(self, x, y, t_s):
        x = np.ascontiguousarray(x, dtype=np.float64)
        y = np.ascontiguousarray(y, dtype=np.float64)
        t_s = np.ascontiguousarray(np.broadcast_to(np.asarray(t_s, dtype=np.float64), x.shape))
        vx, vy, nx, ny = (np.empty_like(x) for _ in range(4))
        # the stripe coordinate u = n . (p - v t) - phase; boundaries at r = 0 and r = period (light -> dark
        # along +n) and r = duty * period (dark -> light); the normal of the nearer one, towards brighter
        _stripes_truth(x.ravel(), y.ravel(), t_s.ravel(), self.height, self._layer_of_row, *self._layers(),
                       vx.ravel(), vy.ravel(), nx.ravel(), ny.ravel())
        return vx, vy, nx, ny

    def close(self) -> None:
        pass
