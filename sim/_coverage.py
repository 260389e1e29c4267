"""numba kernels: exact area of a shape inside a pixel square.

Pixel ``(x, y)`` is the square ``[x - 0.5, x + 0.5] x [y - 0.5, y + 0.5]``
(pixel centres on integer coordinates, x right, y down). Every coverage is the
exact area of the intersection (no supersampling): polygons, for a single
box, by Sutherland-Hodgman clipping against the square and the shoelace
formula, and for whole images by exact signed-area accumulation along rows
(each edge adds, per row band, the exact area to its right cell by cell; a
prefix sum along the row gives the coverage, as in font-rs' rasteriser),
circles by the signed circle/triangle decomposition, stripes by the exact CDF
of the pixel square projected on the stripe normal. The public, validating
wrappers are in :mod:`evedge.sim.coverage`.
"""

from __future__ import annotations

import math

from numba import njit

#: Half the diagonal of the unit pixel square, slightly enlarged: a boundary
#: farther than this from the pixel centre cannot touch the square.
_HALF_DIAG = 0.7072


@njit(cache=True)
def _clip_axis(ix, iy, n, ox, oy, axis, value, keep_ge):
    """Clip polygon ``(ix, iy)[:n]`` to the half-plane ``coord >= value`` (or ``<=``)."""
    if n == 0:
        return 0
    m = 0
    sx = ix[n - 1]
    sy = iy[n - 1]
    sc = sx if axis == 0 else sy
    s_in = sc >= value if keep_ge else sc <= value
    for i in range(n):
        ex = ix[i]
        ey = iy[i]
        ec = ex if axis == 0 else ey
        e_in = ec >= value if keep_ge else ec <= value
        if e_in != s_in:
            # the edge crosses the clip line: add the crossing point
            f = (value - sc) / (ec - sc)
            if axis == 0:
                ox[m] = value
                oy[m] = sy + f * (ey - sy)
            else:
                ox[m] = sx + f * (ex - sx)
                oy[m] = value
            m += 1
        if e_in:
            ox[m] = ex
            oy[m] = ey
            m += 1
        sx = ex
        sy = ey
        sc = ec
        s_in = e_in
    return m


@njit(cache=True)
def _shoelace(xs, ys, n):
    a = 0.0
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        a += xs[i] * ys[j] - xs[j] * ys[i]
    return 0.5 * a


@njit(cache=True)
def _polygon_box_area(px, py, n, x0, y0, x1, y1, ax, ay, bx, by):
    """Exact area of polygon ``(px, py)[:n]`` inside the box ``[x0, x1] x [y0, y1]``.

    Sutherland-Hodgman against a convex clip window is exact in area also for
    a concave (simple) subject polygon: the degenerate edges it may create run
    along the window border and enclose no area. ``ax..by`` are scratch
    buffers of length >= 6 n + 16.
    """
    for i in range(n):
        ax[i] = px[i]
        ay[i] = py[i]
    m = _clip_axis(ax, ay, n, bx, by, 0, x0, True)
    m = _clip_axis(bx, by, m, ax, ay, 0, x1, False)
    m = _clip_axis(ax, ay, m, bx, by, 1, y0, True)
    m = _clip_axis(bx, by, m, ax, ay, 1, y1, False)
    return abs(_shoelace(ax, ay, m))


@njit(cache=True)
def _sector(ux, uy, vx, vy, r):
    return 0.5 * r * r * math.atan2(ux * vy - uy * vx, ux * vx + uy * vy)


@njit(cache=True)
def _disk_triangle_signed(ax, ay, bx, by, r):
    """Signed area of disk(0, r) intersected with triangle (0, a, b)."""
    dx = bx - ax
    dy = by - ay
    qa = dx * dx + dy * dy
    if qa == 0.0:
        return 0.0
    qb = ax * dx + ay * dy
    qc = ax * ax + ay * ay - r * r
    disc = qb * qb - qa * qc
    if disc <= 0.0:
        return _sector(ax, ay, bx, by, r)
    sq = math.sqrt(disc)
    t1 = (-qb - sq) / qa
    t2 = (-qb + sq) / qa
    if t2 <= 0.0 or t1 >= 1.0:
        return _sector(ax, ay, bx, by, r)
    t1 = max(t1, 0.0)
    t2 = min(t2, 1.0)
    px = ax + t1 * dx
    py = ay + t1 * dy
    qx = ax + t2 * dx
    qy = ay + t2 * dy
    return _sector(ax, ay, px, py, r) + 0.5 * (px * qy - py * qx) + _sector(qx, qy, bx, by, r)


@njit(cache=True)
def _disk_box_area(cx, cy, r, x0, y0, x1, y1):
    """Exact area of disk((cx, cy), r) inside the box ``[x0, x1] x [y0, y1]``."""
    a = _disk_triangle_signed(x0 - cx, y0 - cy, x1 - cx, y0 - cy, r)
    a += _disk_triangle_signed(x1 - cx, y0 - cy, x1 - cx, y1 - cy, r)
    a += _disk_triangle_signed(x1 - cx, y1 - cy, x0 - cx, y1 - cy, r)
    a += _disk_triangle_signed(x0 - cx, y1 - cy, x0 - cx, y0 - cy, r)
    return abs(a)


@njit(cache=True)
def _ramp2(z):
    return 0.5 * z * z if z > 0.0 else 0.0


@njit(cache=True)
def _square_projection_cdf(s, a, b):
    """CDF at ``s`` of ``U(-a/2, a/2) + U(-b/2, b/2)`` (unit square projected on a unit normal).

    ``a = |nx|`` and ``b = |ny|``: the pixel square's coordinate along the
    normal is this trapezoidal distribution around the pixel centre.
    """
    if a < b:
        a, b = b, a
    if b < 1e-12:
        f = s / a + 0.5
        return min(1.0, max(0.0, f))
    h = 0.5 * (a + b)
    g = 0.5 * (a - b)
    f = (_ramp2(s + h) - _ramp2(s + g) - _ramp2(s - g) + _ramp2(s - h)) / (a * b)
    return min(1.0, max(0.0, f))


@njit(cache=True)
def _stripe_dark_fraction(uc, nx, ny, period, duty):
    """Exact fraction of the pixel square whose stripe coordinate ``u`` is dark.

    ``uc`` is ``u`` at the pixel centre; dark means ``u mod period < duty * period``.
    """
    a = abs(nx)
    b = abs(ny)
    h = 0.5 * (a + b)
    k0 = math.floor((uc - h) / period)
    k1 = math.floor((uc + h) / period)
    total = 0.0
    for k in range(k0, k1 + 1):
        lo = k * period - uc
        hi = lo + duty * period
        total += _square_projection_cdf(hi, a, b) - _square_projection_cdf(lo, a, b)
    return min(1.0, max(0.0, total))


@njit(cache=True, inline="always")
def _disk_pixel_coverage(x, y, cx, cy, r):
    """Exact fraction (clipped to [0, 1]) of pixel ``(x, y)``'s square inside the disk ``(cx, cy, r)``;
    the area is computed only for pixels the circle may cross. Inlined into its callers."""
    d = math.sqrt((x - cx) ** 2 + (y - cy) ** 2)
    if d + _HALF_DIAG <= r:
        return 1.0
    if d - _HALF_DIAG >= r:
        return 0.0
    return min(1.0, max(0.0, _disk_box_area(cx, cy, r, x - 0.5, y - 0.5, x + 0.5, y + 0.5)))


@njit(cache=True)
def _render_disk(out, edge, width, height, cx, cy, r, value, background, edge_tol):
    """Add disk ``(cx, cy, r)`` of ``value`` over ``background`` to ``out``; mark on ``edge`` the pixels
    it covers partly (coverage strictly between ``edge_tol`` and ``1 - edge_tol``, ``edge_tol >= 0``)."""
    c0 = max(0, int(math.floor(cx - r + 0.5)))
    c1 = min(width - 1, int(math.floor(cx + r + 0.5)))
    r0 = max(0, int(math.floor(cy - r + 0.5)))
    r1 = min(height - 1, int(math.floor(cy + r + 0.5)))
    for y in range(r0, r1 + 1):
        for x in range(c0, c1 + 1):
            cov = _disk_pixel_coverage(x, y, cx, cy, r)
            if edge_tol < cov < 1.0 - edge_tol:
                edge[y * width + x] = True
            if cov > 0.0:
                out[y * width + x] += cov * (value - background)


@njit(cache=True)
def _render_stripes(out, edge, width, row0, row1, nx, ny, offset, period, duty, dark, light, edge_tol):
    """Write stripes into rows ``row0 <= y < row1``.

    ``u = nx x + ny y - offset``; dark where ``u mod period < duty period``.
    """
    for y in range(row0, row1):
        if ny == 0.0 and y > row0:
            # stripes parallel to the y axis: every row equals the first one
            base = row0 * width
            for x in range(width):
                out[y * width + x] = out[base + x]
                edge[y * width + x] = edge[base + x]
            continue
        for x in range(width):
            uc = nx * x + ny * y - offset
            r = uc - period * math.floor(uc / period)
            h = 0.5 * (abs(nx) + abs(ny))
            # fast path: the pixel's footprint on the normal lies inside one stripe
            if h < r < duty * period - h:
                f = 1.0
            elif duty * period + h < r < period - h:
                f = 0.0
            else:
                f = _stripe_dark_fraction(uc, nx, ny, period, duty)
            out[y * width + x] = light + f * (dark - light)
            if edge_tol < f < 1.0 - edge_tol:
                edge[y * width + x] = True


@njit(cache=True)
def _ramp_integral(s):
    """P(s) = integral_0^s clamp(1 - u, 0, 1) du, extended by P(s) = s for s < 0."""
    if s <= 0.0:
        return s
    if s >= 1.0:
        return 0.5
    return s - 0.5 * s * s


@njit(cache=True)
def _accumulate_edge(acc, width, height, x0, y0, x1, y1):
    """Add edge (x0, y0) -> (x1, y1) (pixel-corner coordinates: pixel c spans [c, c + 1]) to ``acc``.

    For each row band it crosses, the edge adds to cell ``c`` the difference
    ``g(c) - g(c - 1)`` with ``g(c) = dir * integral over the band of
    clamp(c + 1 - x_edge(Y), 0, 1) dY`` (the band area to the right of the
    edge inside columns <= c); summing the cells of a row left to right gives
    the signed area of the polygon inside each pixel. Columns left of the
    image fold into column 0, columns right of it are dropped.
    """
    if y0 == y1:
        return
    direction = 1.0
    if y0 > y1:
        x0, y0, x1, y1 = x1, y1, x0, y0
        direction = -1.0
    dxdy = (x1 - x0) / (y1 - y0)
    r0 = max(0, int(math.floor(y0)))
    r1 = min(height, int(math.ceil(y1)))
    for r in range(r0, r1):
        ya = max(float(r), y0)
        yb = min(float(r + 1), y1)
        if yb <= ya:
            continue
        xa = x0 + (ya - y0) * dxdy
        xb = x0 + (yb - y0) * dxdy
        if xa > xb:
            xa, xb = xb, xa
        d = direction * (yb - ya)
        c0 = int(math.floor(xa))
        c1 = int(math.ceil(xb))
        row = r * width
        prev = 0.0
        span = xb - xa
        for c in range(c0, c1 + 1):
            if span > 1e-12:
                g = d * (_ramp_integral(xb - c) - _ramp_integral(xa - c)) / span
            else:
                g = d * min(1.0, max(0.0, c + 1.0 - 0.5 * (xa + xb)))
            if c >= width:
                break
            acc[row + max(c, 0)] += g - prev
            prev = g


@njit(cache=True)
def _render_polygons(out, edge, acc, width, height, px, py, starts, values, background, edge_tol):
    """Add every polygon ``k`` (vertices ``px/py[starts[k]:starts[k + 1]]``, intensity ``values[k]``).

    ``acc`` is a zeroed (height * width) scratch buffer, zeroed again on return.
    """
    for k in range(values.shape[0]):
        s0 = starts[k]
        s1 = starts[k + 1]
        xmin = 1e300
        xmax = -1e300
        ymin = 1e300
        ymax = -1e300
        j = s1 - 1
        for i in range(s0, s1):
            # shift to pixel-corner coordinates: pixel c spans [c, c + 1]
            xa = px[j] + 0.5
            ya = py[j] + 0.5
            xb = px[i] + 0.5
            yb = py[i] + 0.5
            _accumulate_edge(acc, width, height, xa, ya, xb, yb)
            xmin = min(xmin, xb)
            xmax = max(xmax, xb)
            ymin = min(ymin, yb)
            ymax = max(ymax, yb)
            j = i
        r0 = max(0, int(math.floor(ymin)))
        r1 = min(height, int(math.ceil(ymax)))
        c0 = max(0, int(math.floor(xmin)))
        c1 = min(width, int(math.ceil(xmax)) + 1)
        delta = values[k] - background
        for r in range(r0, r1):
            run = 0.0
            row = r * width
            for c in range(c0, c1):
                run += acc[row + c]
                acc[row + c] = 0.0
                cov = min(1.0, abs(run))
                if cov > 0.0:
                    out[row + c] += cov * delta
                    if edge_tol < cov < 1.0 - edge_tol:
                        edge[row + c] = True


@njit(cache=True)
def _shape_boxes(width, height, px, py, starts, cx, cy, cr, boxes):
    """Boxes ``(r0, r1, c0, c1)`` (half-open, clipped) outside which the shapes write nothing.

    One box per polygon (vertices ``px/py[starts[k]:starts[k + 1]]``, image
    coordinates) then one per disk; each encloses, with a margin of one pixel,
    what :func:`_render_polygons` and :func:`_render_disk` touch (their loops
    stay inside the shape's bounding box in pixel-corner coordinates).
    Written flattened into ``boxes``; returns the number of boxes.
    """
    n = 0
    for k in range(starts.shape[0] - 1):
        xmin = 1e300
        xmax = -1e300
        ymin = 1e300
        ymax = -1e300
        for i in range(starts[k], starts[k + 1]):
            xmin = min(xmin, px[i])
            xmax = max(xmax, px[i])
            ymin = min(ymin, py[i])
            ymax = max(ymax, py[i])
        _put_box(boxes, n, width, height, xmin, xmax, ymin, ymax)
        n += 1
    for k in range(cx.shape[0]):
        _put_box(boxes, n, width, height, cx[k] - cr[k], cx[k] + cr[k], cy[k] - cr[k], cy[k] + cr[k])
        n += 1
    return n


@njit(cache=True)
def _put_box(boxes, n, width, height, xmin, xmax, ymin, ymax):
    # pixel c spans [c - 0.5, c + 0.5]; one pixel of margin on every side
    r0 = max(0, min(height, int(math.floor(ymin + 0.5)) - 1))
    r1 = max(0, min(height, int(math.ceil(ymax + 0.5)) + 2))
    c0 = max(0, min(width, int(math.floor(xmin + 0.5)) - 1))
    c1 = max(0, min(width, int(math.ceil(xmax + 0.5)) + 2))
    if r0 >= r1 or c0 >= c1:
        r0 = r1 = c0 = c1 = 0
    boxes[4 * n] = r0
    boxes[4 * n + 1] = r1
    boxes[4 * n + 2] = c0
    boxes[4 * n + 3] = c1


@njit(cache=True)
def _fill_boxes(out, width, boxes, n_boxes, value):
    """Set every pixel of the first ``n_boxes`` boxes (as :func:`_shape_boxes`) of flat ``out`` to ``value``."""
    for k in range(n_boxes):
        c0 = boxes[4 * k + 2]
        c1 = boxes[4 * k + 3]
        for r in range(boxes[4 * k], boxes[4 * k + 1]):
            out[r * width + c0:r * width + c1] = value


@njit(cache=True)
def _draw_shapes(out, edge, acc, width, height, qx, qy, n_poly_vertices, starts, values, radii, circle_values,
                 background, edge_tol, clip, center_x, center_y, cos_t, sin_t, shift_x, shift_y, px, py, boxes):
    """All shapes of a :class:`~evedge.sim.planar.ShapesRenderer` in one call (the per-sample path).

    Moves the object points ``(qx, qy)`` (polygon vertices, then circle
    centres) to the image by ``c + R(theta) (q - c) + s`` (the arithmetic of
    :meth:`~evedge.sim.motion.PlanarMotion.to_image`, term by term), draws the
    polygons (:func:`_render_polygons`) then the disks (:func:`_render_disk`),
    clips to [0, 1] when ``clip`` and writes the boxes of :func:`_shape_boxes`.
    ``px``/``py`` are scratch of the length of ``qx``. Returns the number of boxes.
    """
    for i in range(qx.shape[0]):
        dx = qx[i] - center_x
        dy = qy[i] - center_y
        px[i] = center_x + cos_t * dx - sin_t * dy + shift_x
        py[i] = center_y + sin_t * dx + cos_t * dy + shift_y
    vx = px[:n_poly_vertices]
    vy = py[:n_poly_vertices]
    cx = px[n_poly_vertices:]
    cy = py[n_poly_vertices:]
    if values.shape[0] > 0:
        _render_polygons(out, edge, acc, width, height, vx, vy, starts, values, background, edge_tol)
    for k in range(radii.shape[0]):
        _render_disk(out, edge, width, height, cx[k], cy[k], radii[k], circle_values[k], background, edge_tol)
    n = _shape_boxes(width, height, vx, vy, starts, cx, cy, radii, boxes)
    if clip:
        for k in range(n):
            for r in range(boxes[4 * k], boxes[4 * k + 1]):
                for c in range(boxes[4 * k + 2], boxes[4 * k + 3]):
                    v = out[r * width + c]
                    out[r * width + c] = min(1.0, max(0.0, v))
    return n
