"""numba kernels: exact pixel intensities at arbitrary times, and the root finder of the crossing times.

The planar renderers draw whole images at the sample times; between two
samples the converter needs a pixel's intensity at any instant to solve for
the exact moment its log intensity crosses a threshold. These kernels
evaluate the closed-form pixel-area intensity of one pixel at one time per
entry (the same coverage formulas as :mod:`evedge.sim._coverage`: stripes by
the projected-square CDF, polygons by the signed area of each edge in the pixel's row band,
disks by the circle/triangle decomposition), and :func:`_root_step`
advances a bracketed regula falsi (Anderson-Bjorck variant) on
``f(t) = I(t) - (exp(level) - eps)`` for many crossings at once.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._coverage import _HALF_DIAG, _disk_pixel_coverage, _stripe_dark_fraction
from ._events import _first_step, _half_normal


@njit(cache=True)
def _stripes_at(pix, t, width, layer_of_row, nx, ny, vx, vy, phase, period, duty, dark, light, background, out):
    """Intensity of flat pixel ``pix[j]`` at time ``t[j]`` for a :class:`~evedge.sim.planar.StripesRenderer`.

    Per layer ``k``: unit normal ``(nx, ny)[k]``, velocity ``(vx, vy)[k]``
    and the stripe parameters; ``layer_of_row[y]`` is the layer of row ``y``
    (-1: background). The arithmetic is that of
    :func:`~evedge.sim._coverage._render_stripes` term by term, so at a sample
    time the value is the rendered one.
    """
    for j in range(pix.shape[0]):
        i = pix[j]
        y = i // width
        x = i - y * width
        k = layer_of_row[y]
        if k < 0:
            out[j] = background
            continue
        offset = nx[k] * vx[k] * t[j] + ny[k] * vy[k] * t[j] + phase[k]
        uc = nx[k] * x + ny[k] * y - offset
        p = period[k]
        r = uc - p * math.floor(uc / p)
        h = 0.5 * (abs(nx[k]) + abs(ny[k]))
        dp = duty[k] * p
        if h < r < dp - h:
            f = 1.0
        elif dp + h < r < p - h:
            f = 0.0
        else:
            f = _stripe_dark_fraction(uc, nx[k], ny[k], p, duty[k])
        out[j] = light[k] + f * (dark[k] - light[k])


@njit(cache=True)
def _polygon_pixel_coverage(vx, vy, n, x, y):
    """Exact area of the polygon ``(vx, vy)[:n]`` inside pixel ``(x, y)``: :func:`_polygon_pixel_coverage_from`."""
    return _polygon_pixel_coverage_from(vx, vy, 0, n, x, y)


@njit(cache=True)
def _polygon_pixel_coverage_from(vx, vy, s0, n, x, y):
    """Exact area of the polygon ``(vx, vy)[s0:s0 + n]`` inside pixel ``(x, y)`` (its square ``[x-0.5, x+0.5]^2``).

    The rasteriser's decomposition (:func:`~evedge.sim._coverage._accumulate_edge`)
    for one cell: each edge crossing the pixel's row band adds
    ``dir * mean_Y clamp(x + 0.5 - x_edge(Y), 0, 1)`` over the band (the part
    of the pixel's row right of the edge); edges left of the pixel add the full
    band, edges right of it nothing; the absolute sum is the coverage. One
    pass over the edges, no clipping buffers.
    """
    total = 0.0
    # pixel-corner coordinates: the pixel spans [c, c + 1] x [r, r + 1]
    c = float(x)
    r = float(y)
    j = s0 + n - 1
    for i in range(s0, s0 + n):
        x0 = vx[j] + 0.5
        y0 = vy[j] + 0.5
        x1 = vx[i] + 0.5
        y1 = vy[i] + 0.5
        j = i
        if y0 == y1:
            continue
        direction = 1.0
        if y0 > y1:
            x0, y0, x1, y1 = x1, y1, x0, y0
            direction = -1.0
        ya = max(r, y0)
        yb = min(r + 1.0, y1)
        if yb <= ya:
            continue
        dxdy = (x1 - x0) / (y1 - y0)
        xa = x0 + (ya - y0) * dxdy
        xb = x0 + (yb - y0) * dxdy
        if xa > xb:
            xa, xb = xb, xa
        d = direction * (yb - ya)
        span = xb - xa
        if span > 0.0:
            # mean over x in [xa, xb] of clamp(c + 1 - x, 0, 1), piece by piece (1 left of c, the ramp on
            # [c, c + 1], 0 beyond): lengths over span, no cancellation for short spans
            left = max(0.0, min(xb, c) - xa)
            a2 = max(xa, c)
            b2 = min(xb, c + 1.0)
            ramp = (b2 - a2) * (c + 1.0 - 0.5 * (a2 + b2)) if b2 > a2 else 0.0
            total += d * (left + ramp) / span
        else:
            total += d * min(1.0, max(0.0, c + 1.0 - xa))
    return min(1.0, abs(total))


@njit(cache=True)
def _motion_state(m, t):
    """``theta, sx, sy`` of :meth:`~evedge.sim.motion.PlanarMotion._state_scalar` at ``t`` (same formulas, same order).

    ``m`` holds ``angle, angular_velocity, angular_acceleration, angle_amplitude,
    frequency, chirp, v0x, v0y, ax, ay, amx, amy``.
    """
    ph = 2.0 * math.pi * (m[4] * t + 0.5 * m[5] * t * t)
    sph = math.sin(ph)
    theta = m[0] + m[1] * t + 0.5 * m[2] * t * t + m[3] * sph
    return theta, m[6] * t + 0.5 * m[8] * t * t + m[10] * sph, m[7] * t + 0.5 * m[9] * t * t + m[11] * sph


@njit(cache=True)
def _shapes_at(pix, t, motion, width, center_x, center_y, qx, qy, starts, values,
               poly_cx, poly_cy, poly_r, ccx, ccy, radii, circle_values, background, clip, out):
    """Intensity of flat pixel ``pix[j]`` at time ``t[j]`` for a :class:`~evedge.sim.planar.ShapesRenderer`.

    Entry ``j`` sees the object points moved by ``c + R(theta) (q - c) + s``
    with the motion state at ``t[j]`` (:func:`_motion_state`; the arithmetic
    of :func:`~evedge.sim._coverage._draw_shapes`). Polygon ``k`` has vertices
    ``qx/qy[starts[k]:starts[k + 1]]`` and a bounding circle
    ``(poly_cx, poly_cy, poly_r)[k]`` (object coordinates) used to skip it;
    disks have centres ``ccx/ccy`` and ``radii``. Intensity
    ``bg + sum_k coverage_k (value_k - bg)``, clipped to [0, 1] when ``clip``.
    """
    nmax = 0
    for k in range(values.shape[0]):
        nmax = max(nmax, starts[k + 1] - starts[k])
    vx = np.empty(nmax)
    vy = np.empty(nmax)
    for j in range(pix.shape[0]):
        i = pix[j]
        y = i // width
        x = i - y * width
        theta, sx, sy = _motion_state(motion, t[j])
        c = math.cos(theta)
        sn = math.sin(theta)
        value = background
        for k in range(values.shape[0]):
            dx = poly_cx[k] - center_x
            dy = poly_cy[k] - center_y
            mx = center_x + c * dx - sn * dy + sx
            my = center_y + sn * dx + c * dy + sy
            if math.hypot(x - mx, y - my) > poly_r[k] + _HALF_DIAG:
                continue
            n = starts[k + 1] - starts[k]
            for v in range(n):
                dx = qx[starts[k] + v] - center_x
                dy = qy[starts[k] + v] - center_y
                vx[v] = center_x + c * dx - sn * dy + sx
                vy[v] = center_y + sn * dx + c * dy + sy
            cov = _polygon_pixel_coverage(vx, vy, n, x, y)
            if cov > 0.0:
                value += cov * (values[k] - background)
        for k in range(radii.shape[0]):
            dx = ccx[k] - center_x
            dy = ccy[k] - center_y
            mx = center_x + c * dx - sn * dy + sx
            my = center_y + sn * dx + c * dy + sy
            r = radii[k]
            cov = _disk_pixel_coverage(x, y, mx, my, r)
            if cov > 0.0:
                value += cov * (circle_values[k] - background)
        if clip:
            value = min(1.0, max(0.0, value))
        out[j] = value


@njit(cache=True)
def _root_start(ia, ib, target, shift, ta, tb, fa, fb, tc, active):
    """Start the brackets: ``f = I - target`` at both ends; returns the number still active.

    ``target`` is first moved by ``shift`` towards the start value ``ia``
    (in place): the crossing instant is the *first* time the intensity
    reaches the level, which is then a transversal root even where the
    intensity only touches the level and stays there (a pixel returning to
    the plateau it started on: its last level is that plateau's value).
    Where the function shows no sign change over ``[ta, tb]`` the root is the
    end nearer in ``f`` (written to ``tc``; inactive).
    """
    m = 0
    for j in range(ta.shape[0]):
        target[j] += -shift if ib[j] > ia[j] else shift
        fa[j] = ia[j] - target[j]
        fb[j] = ib[j] - target[j]
        if fa[j] == 0.0:
            tc[j] = ta[j]
            active[j] = False
        elif fb[j] == 0.0 or (fa[j] > 0.0) == (fb[j] > 0.0):
            tc[j] = ta[j] if abs(fa[j]) < abs(fb[j]) else tb[j]
            active[j] = False
        else:
            tc[j] = ta[j] - fa[j] * (tb[j] - ta[j]) / (fb[j] - fa[j])
            active[j] = True
            m += 1
    return m


@njit(cache=True)
def _root_step(idx, ic, target, ta, tb, fa, fb, tc, tp, fp, side, tol_s, tol_i, tol_t, active):
    """One regula falsi step for the active crossings ``idx``, given ``ic = I(tc[idx])``; returns the number left.

    The bracket ``[ta, tb]`` keeps a sign change of ``f`` (``ta`` on the side
    of the start, where the level is not reached yet); the new point
    replaces the end of its sign, and when the same end is replaced twice in
    a row the other end's ``f`` is scaled by ``1 - f_new / f_old``
    (Anderson-Bjorck; by 1/2 when that is not positive: Illinois), and after
    three in a row the step is a bisection (a safeguard: never much slower
    than bisection). The function is the intensity, not its log (the same
    root: the log is monotone), because it is linear in time wherever an edge
    crosses a pixel along a row, where regula falsi is exact in one step.

    A crossing is done when its bracket is narrower than ``tol_s``, or
    ``|f(tc)| <= tol_i``, or ``tc`` has not reached the level and the secant
    through the last two evaluations (``tp``, ``fp``: the previous one) puts
    the root at most ``tol_t`` after it (then ``tc`` moves to that secant
    root, whose error is second order in ``tol_t``). Its time is ``tc``.
    """
    left = 0
    for q in range(idx.shape[0]):
        j = idx[q]
        fc = ic[q] - target[j]
        if abs(fc) <= tol_i:
            active[j] = False
            continue
        not_reached = (fc > 0.0) == (fa[j] > 0.0)
        if not_reached and fc != fp[j]:
            # the secant through the last two evaluations: the root is ``step`` after ``tc``
            step = -fc * (tc[j] - tp[j]) / (fc - fp[j])
            if 0.0 <= step <= tol_t and tc[j] + step < tb[j]:
                tc[j] += step  # second-order accurate: the error is far below tol_t
                active[j] = False
                continue
        tp[j] = tc[j]
        fp[j] = fc
        # side: -k / +k when the low / high end moved the last k times in a row
        if not_reached:
            if side[j] < 0:
                scale = 1.0 - fc / fa[j]
                fb[j] *= scale if scale > 0.0 else 0.5
                side[j] -= 1
            else:
                side[j] = -1
            ta[j] = tc[j]
            fa[j] = fc
        else:
            if side[j] > 0:
                scale = 1.0 - fc / fb[j]
                fa[j] *= scale if scale > 0.0 else 0.5
                side[j] += 1
            else:
                side[j] = 1
            tb[j] = tc[j]
            fb[j] = fc
        if tb[j] - ta[j] <= tol_s:
            tc[j] = ta[j] - fa[j] * (tb[j] - ta[j]) / (fb[j] - fa[j])
            active[j] = False
            continue
        t = ta[j] - fa[j] * (tb[j] - ta[j]) / (fb[j] - fa[j])
        # keep strictly inside the bracket (rounding), and bisect when one end has moved three times in a
        # row (a function flat on one side, e.g. touching a plateau, stalls regula falsi): the bracket then
        # at least halves every few steps
        if not (ta[j] < t < tb[j]) or abs(side[j]) >= 3:
            t = 0.5 * (ta[j] + tb[j])
            side[j] = 0
        tc[j] = t
        left += 1
    return left


@njit(cache=True)
def _crossing_levels(i0, i1, t0, t1, eps, lref, e_hi, e_lo, cpos, cneg, fill, cand, n_cand,
                     out_pix, out_level, out_t, out_p):
    """The threshold crossings of the candidates ``cand[:n_cand]`` between two samples; returns ``(n, n_moved)``.

    As :func:`~evedge.sim._events._crossings` without the refractory period
    and the jitter (applied later, on exact times): every crossing of
    ``lref + cpos`` (ON) or ``lref - cneg`` (OFF) is written with its level
    (the log intensity crossed) and its linearly interpolated time (a first
    guess). With ``fill`` False nothing is written (count pass); with ``fill``
    True the crossings are written and ``lref``, ``e_hi``, ``e_lo`` updated.
    """
    n = 0
    n_moved = 0
    span = t1 - t0
    for j in range(n_cand):
        i = cand[j]
        l1 = math.log(i1[i] + eps)
        l0 = math.log(i0[i] + eps)
        lr = lref[i]
        cp = cpos[i]
        cn = cneg[i]
        on, step = _first_step(l1, lr, cp, cn)
        if step == 0.0:
            continue
        while (l1 >= lr + step) if on else (l1 <= lr + step):
            lr += step
            if fill:
                out_pix[n] = i
                out_level[n] = lr
                out_t[n] = t0 + (lr - l0) / (l1 - l0) * span
                out_p[n] = on
            n += 1
        n_moved += 1
        if fill:
            lref[i] = lr
            e_hi[i] = math.exp(lr + cp)
            e_lo[i] = math.exp(lr - cn)
    return n, n_moved


@njit(cache=True)
def _refractory_jitter(pix, t, last_t, seq, refractory_s, jitter_s, jitter_seed, keep, t_emit):
    """Apply the refractory period and the latency jitter to crossings in generation order; returns the number kept.

    Crossing ``j`` of pixel ``pix[j]`` at exact time ``t[j]`` is kept when
    ``t[j] - last_t[pix[j]] >= refractory_s`` (``last_t``: the pixel's last
    kept crossing, updated); a kept one is emitted at
    ``t + jitter_s |N(0, 1)|`` hashed from (pixel, per-pixel event count
    ``seq``, updated), as :func:`~evedge.sim._events._crossings` does.
    """
    n = 0
    for j in range(pix.shape[0]):
        i = pix[j]
        if t[j] - last_t[i] >= refractory_s:
            keep[j] = True
            t_emit[j] = t[j] + jitter_s * _half_normal(jitter_seed, i, seq[i]) if jitter_s > 0 else t[j]
            seq[i] += 1
            last_t[i] = t[j]
            n += 1
        else:
            keep[j] = False
    return n


@njit(cache=True)
def _hidden_crossing(i0, im, i1, eps, lref, cpos, cneg, spans, n_spans):
    """Whether the midpoint sample ``im`` shows a level crossing the end samples ``i0``, ``i1`` do not.

    For each pixel of the spans (flat ranges, as :func:`~evedge.sim._events._box_spans`)
    whose midpoint intensity lies outside the range of its two end values, the
    levels ``lref + k cpos`` (above) or ``lref - k cneg`` (below) between the
    nearer end and the midpoint are counted; any such level means the step
    hides an excursion (up and back, or down and back) whose crossings the
    end values alone would miss. Returns True at the first one.
    """
    for s in range(n_spans):
        for i in range(spans[2 * s], spans[2 * s + 1]):
            a0 = i0[i] + eps
            am = im[i] + eps
            a1 = i1[i] + eps
            hi = max(a0, a1)
            lo = min(a0, a1)
            if am > hi:
                lr = lref[i]
                if math.floor((math.log(am) - lr) / cpos[i]) > max(0.0, math.floor((math.log(hi) - lr) / cpos[i])):
                    return True
            elif am < lo:
                lr = lref[i]
                if math.floor((lr - math.log(am)) / cneg[i]) > max(0.0, math.floor((lr - math.log(lo)) / cneg[i])):
                    return True
    return False


@njit(cache=True)
def _stripes_truth(x, y, t, height, layer_of_row, nx, ny, vx, vy, phase, period, duty, dark, light,
                   out_vx, out_vy, out_nx, out_ny):
    """:meth:`~evedge.sim.planar.StripesRenderer.point_truth` per point (the same arithmetic, in one pass).

    Rows of no layer: zero flow, NaN normal. The normal is that of the
    nearest stripe boundary, pointing towards the brighter side.
    """
    for j in range(x.shape[0]):
        row = min(max(int(y[j]), 0), height - 1)
        k = layer_of_row[row]
        if k < 0:
            out_vx[j] = 0.0
            out_vy[j] = 0.0
            out_nx[j] = np.nan
            out_ny[j] = np.nan
            continue
        out_vx[j] = vx[k]
        out_vy[j] = vy[k]
        u = nx[k] * (x[j] - vx[k] * t[j]) + ny[k] * (y[j] - vy[k] * t[j]) - phase[k]
        p = period[k]
        r = u - p * math.floor(u / p)
        d_start = min(r, p - r)
        d_end = abs(r - duty[k] * p)
        sign = 1.0 if d_end < d_start else -1.0
        if dark[k] > light[k]:
            sign = -sign
        out_nx[j] = sign * nx[k]
        out_ny[j] = sign * ny[k]


@njit(cache=True)
def _motion_full(m, t):
    """``theta, theta_dot, sx, sy, vx, vy`` of :meth:`~evedge.sim.motion.PlanarMotion._state_scalar` at ``t``
    (same formulas; ``m`` as in :func:`_motion_state`)."""
    ph = 2.0 * math.pi * (m[4] * t + 0.5 * m[5] * t * t)
    sph = math.sin(ph)
    cph = math.cos(ph) * 2.0 * math.pi * (m[4] + m[5] * t)
    theta = m[0] + m[1] * t + 0.5 * m[2] * t * t + m[3] * sph
    theta_dot = m[1] + m[2] * t + m[3] * cph
    return (theta, theta_dot, m[6] * t + 0.5 * m[8] * t * t + m[10] * sph, m[7] * t + 0.5 * m[9] * t * t + m[11] * sph,
            m[6] + m[8] * t + m[10] * cph, m[7] + m[9] * t + m[11] * cph)


@njit(cache=True)
def _nonmonotone_pixels(motion, t0, t1, reach, width, height, center_x, center_y, qx, qy, starts, orient,
                        values, ccx, ccy, radii, circle_values, background, stamp, bits, step_id, out):
    """Pixels whose intensity may not be monotone in time over ``[t0, t1]`` (written to ``out``; returns how many).

    The rate of a pixel's intensity is ``sum_k (I_k - bg) int v.n ds`` over the
    parts of shape ``k``'s boundary inside the pixel square (the transport of
    area: ``v`` the boundary's velocity, ``n`` its outward normal), so the
    intensity is monotone over the step when every boundary piece that meets
    the square during the step moves it the same way. Per polygon edge the
    sign of ``v.n`` over the step is that of its values at both ends of the
    edge (``v.n`` is affine along a straight edge of a rigid motion:
    ``s'.R n0 + theta' J (q - c).n0``) at ``t0``, the midpoint and ``t1``
    (0 when they differ: both signs); per disk, ``v_c . n`` (its centre's
    velocity) over the arc within ``reach`` of the pixel, mixed when that arc
    holds a point whose normal is perpendicular to ``v_c``. Each piece ORs bit 1
    (brightening) or 2 (darkening), or 3, into every pixel whose centre lies
    within ``reach`` (half the pixel diagonal plus the step's largest
    displacement) of its position at ``t0`` (a superset by row spans); pixels
    that end with both bits are the output. ``stamp``/``bits`` are per-pixel
    scratch (``stamp != step_id``: no bit yet), so nothing needs clearing.

    Assumes ``v.n`` does not change sign and back between the three times
    (steps far shorter than the motion's period).
    """
    n_out = 0
    # the motion at t0, the midpoint and t1: angle, angular velocity, translation velocity
    mc = np.empty(3)
    ms = np.empty(3)
    mw = np.empty(3)
    mvx = np.empty(3)
    mvy = np.empty(3)
    for q in range(3):
        th, mw[q], _, _, mvx[q], mvy[q] = _motion_full(motion, t0 + 0.5 * q * (t1 - t0))
        mc[q] = math.cos(th)
        ms[q] = math.sin(th)
    th0, _, sx0, sy0, _, _ = _motion_full(motion, t0)
    c0 = math.cos(th0)
    s0 = math.sin(th0)
    for k in range(values.shape[0]):
        dv = values[k] - background
        if dv == 0.0:
            continue
        n = starts[k + 1] - starts[k]
        for e in range(n):
            a = starts[k] + (e - 1 if e > 0 else n - 1)
            b = starts[k] + e
            ex = qx[b] - qx[a]
            ey = qy[b] - qy[a]
            norm = math.hypot(ex, ey)
            if norm == 0.0:
                continue
            # outward normal in object coordinates (orient: sign of the shoelace area)
            n0x = orient[k] * ey / norm
            n0y = -orient[k] * ex / norm
            sign = 0
            moving = False
            for q in range(3):
                c = mc[q]
                sn = ms[q]
                base = mvx[q] * (c * n0x - sn * n0y) + mvy[q] * (sn * n0x + c * n0y)
                for end in range(2):
                    px = qx[a] if end == 0 else qx[b]
                    py = qy[a] if end == 0 else qy[b]
                    g = base + mw[q] * (-(py - center_y) * n0x + (px - center_x) * n0y)
                    s = 1 if g > 0.0 else (-1 if g < 0.0 else 0)
                    moving = moving or s != 0
                    if q == 0 and end == 0:
                        sign = s
                    elif s != sign:
                        sign = 0
            if not moving:
                continue  # the edge slides along itself (v.n = 0 throughout): it changes no coverage
            sign = sign if dv > 0.0 else -sign
            bit = 1 if sign > 0 else (2 if sign < 0 else 3)
            # the edge at t0 in the image
            dx = qx[a] - center_x
            dy = qy[a] - center_y
            xa = center_x + c0 * dx - s0 * dy + sx0
            ya = center_y + s0 * dx + c0 * dy + sy0
            dx = qx[b] - center_x
            dy = qy[b] - center_y
            xb = center_x + c0 * dx - s0 * dy + sx0
            yb = center_y + s0 * dx + c0 * dy + sy0
            r0 = max(0, int(math.ceil(min(ya, yb) - reach)))
            r1 = min(height - 1, int(math.floor(max(ya, yb) + reach)))
            for y in range(r0, r1 + 1):
                # the part of the segment within reach of the row, then its x range widened by reach
                if ya == yb:
                    lo_x = min(xa, xb)
                    hi_x = max(xa, xb)
                else:
                    u0 = (y - reach - ya) / (yb - ya)
                    u1 = (y + reach - ya) / (yb - ya)
                    if u0 > u1:
                        u0, u1 = u1, u0
                    u0 = max(0.0, u0)
                    u1 = min(1.0, u1)
                    if u0 > u1:
                        continue
                    xu0 = xa + u0 * (xb - xa)
                    xu1 = xa + u1 * (xb - xa)
                    lo_x = min(xu0, xu1)
                    hi_x = max(xu0, xu1)
                x0 = max(0, int(math.ceil(lo_x - reach)))
                x1 = min(width - 1, int(math.floor(hi_x + reach)))
                for x in range(x0, x1 + 1):
                    pi = y * width + x
                    if stamp[pi] != step_id:
                        stamp[pi] = step_id
                        bits[pi] = bit
                        if bit == 3:
                            out[n_out] = pi
                            n_out += 1
                    elif bits[pi] != 3 and (bits[pi] | bit) == 3:
                        bits[pi] = 3
                        out[n_out] = pi
                        n_out += 1
    tx = np.empty((3, 2))
    ty = np.empty((3, 2))
    cvx = np.empty(3)
    cvy = np.empty(3)
    for k in range(radii.shape[0]):
        dv = circle_values[k] - background
        if dv == 0.0:
            continue
        r = radii[k]
        dx = ccx[k] - center_x
        dy = ccy[k] - center_y
        mx = center_x + c0 * dx - s0 * dy + sx0
        my = center_y + s0 * dx + c0 * dy + sy0
        # a disk's v.n at its boundary point of normal n is its centre's velocity . n (rotation about the
        # centre slides the boundary along itself); it changes sign at the two points whose normal is
        # perpendicular to that velocity (t*, on the disk at t0): the arc within reach of a pixel holds
        # both signs iff it holds one of them, else the sign is that of v_c . (pixel - centre)
        for q in range(3):
            rx = mc[q] * dx - ms[q] * dy
            ry = ms[q] * dx + mc[q] * dy
            cvx[q] = mvx[q] - mw[q] * ry
            cvy[q] = mvy[q] + mw[q] * rx
            speed = math.hypot(cvx[q], cvy[q])
            ux = -cvy[q] / speed if speed > 0.0 else 0.0
            uy = cvx[q] / speed if speed > 0.0 else 0.0
            tx[q, 0] = mx + r * ux
            ty[q, 0] = my + r * uy
            tx[q, 1] = mx - r * ux
            ty[q, 1] = my - r * uy
        if cvx[0] == 0.0 and cvy[0] == 0.0 and cvx[1] == 0.0 and cvy[1] == 0.0 and cvx[2] == 0.0 and cvy[2] == 0.0:
            continue  # a disk at rest changes no coverage
        reach2 = reach * reach
        out_r = r + reach
        in_r = r - reach
        r0 = max(0, int(math.ceil(my - out_r)))
        r1 = min(height - 1, int(math.floor(my + out_r)))
        for y in range(r0, r1 + 1):
            ddy = y - my
            wo = math.sqrt(max(0.0, out_r * out_r - ddy * ddy))
            wi = math.sqrt(in_r * in_r - ddy * ddy) if in_r > 0.0 and abs(ddy) < in_r else -1.0
            for side in range(2):
                if wi < 0.0:
                    if side == 1:
                        break
                    xa0, xb0 = mx - wo, mx + wo
                elif side == 0:
                    xa0, xb0 = mx - wo, mx - wi
                else:
                    xa0, xb0 = mx + wi, mx + wo
                for x in range(max(0, int(math.ceil(xa0))), min(width - 1, int(math.floor(xb0))) + 1):
                    ddx = x - mx
                    d2 = ddx * ddx + ddy * ddy
                    d = math.sqrt(d2)
                    if abs(d - r) > reach:
                        continue
                    sign = 0
                    for q in range(3):
                        if cvx[q] == 0.0 and cvy[q] == 0.0:
                            s = 0
                        elif ((x - tx[q, 0]) ** 2 + (y - ty[q, 0]) ** 2 <= reach2
                              or (x - tx[q, 1]) ** 2 + (y - ty[q, 1]) ** 2 <= reach2):
                            s = 0
                        else:
                            g = cvx[q] * ddx + cvy[q] * ddy
                            s = 1 if g > 0.0 else (-1 if g < 0.0 else 0)
                        if q == 0:
                            sign = s
                        elif s != sign:
                            sign = 0
                    sign = sign if dv > 0.0 else -sign
                    bit = 1 if sign > 0 else (2 if sign < 0 else 3)
                    pi = y * width + x
                    if stamp[pi] != step_id:
                        stamp[pi] = step_id
                        bits[pi] = bit
                        if bit == 3:
                            out[n_out] = pi
                            n_out += 1
                    elif bits[pi] != 3 and (bits[pi] | bit) == 3:
                        bits[pi] = 3
                        out[n_out] = pi
                        n_out += 1
    return n_out


@njit(cache=True)
def _drop_marked(cand, n_cand, marked):
    """Remove the pixels with ``marked[pix]`` from ``cand[:n_cand]`` in place (order kept); returns the new count."""
    m = 0
    for j in range(n_cand):
        if not marked[cand[j]]:
            cand[m] = cand[j]
            m += 1
    return m


@njit(cache=True)
def _advance_level(lr, l1, cp, cn):
    """The reference level after going to log intensity ``l1`` from reference ``lr``: ``(lr, n_crossings)``."""
    n = 0
    on, step = _first_step(l1, lr, cp, cn)
    if step != 0.0:
        while (l1 >= lr + step) if on else (l1 <= lr + step):
            lr += step
            n += 1
    return lr, n


@njit(cache=True)
def _extremum_flags(pix, vals, i0, i1, eps, lref, cpos, cneg, flags):
    """Sub-intervals of sub-sampled paths to sample more densely: around extrema that may reach a new level.

    Pixel ``j``'s path is ``i0``, ``vals[j, :]``, ``i1`` (``m + 1`` samples,
    ``m`` sub-intervals). At every sample that is a local minimum of the path
    (an end sample counts when the path moves away from it), the function
    may dip below it between the samples (a vertex passing the pixel: a V);
    the dip is taken to be at most twice the largest difference between
    consecutive samples over the two sub-intervals on either side. When the next OFF level below the reference (as
    it stands at that sample) lies within that reach, the sub-intervals on
    both sides are flagged (``flags[j, q]``); maxima and ON levels alike.
    Returns the number flagged.
    """
    m = vals.shape[1] + 1
    n = 0
    seq = np.empty(m + 1)
    for j in range(pix.shape[0]):
        i = pix[j]
        lr = lref[i]
        cp = cpos[i]
        cn = cneg[i]
        seq[0] = i0[i]
        for q in range(m - 1):
            seq[q + 1] = vals[j, q]
        seq[m] = i1[i]
        for q in range(m + 1):
            v = seq[q]
            if q > 0:
                lr, _ = _advance_level(lr, math.log(v + eps), cp, cn)
            vl = seq[q - 1] if q > 0 else v
            vr = seq[q + 1] if q < m else v
            lo = (vl > v and vr >= v) or (vl >= v and vr > v)
            hi = (vl < v and vr <= v) or (vl <= v and vr < v)
            if not (lo or hi):
                continue
            # the V's arms: the largest change over the two sub-intervals on either side (the tip may fall
            # between two samples of nearly equal value, so the outer ones count too)
            diff = 0.0
            for u in range(max(0, q - 2), min(m, q + 2)):
                diff = max(diff, abs(seq[u + 1] - seq[u]))
            diff *= 2.0
            if (lo and math.log(max(v - diff, 0.0) + eps) <= lr - cn) or (hi and math.log(v + diff + eps) >= lr + cp):
                if q > 0 and not flags[j, q - 1]:
                    flags[j, q - 1] = True
                    n += 1
                if q < m and not flags[j, q]:
                    flags[j, q] = True
                    n += 1
    return n


@njit(cache=True)
def _path_crossing_levels(pix, vals, tt, flags, rvals, rt, i0, i1, t0, t1, eps, lref, e_hi, e_lo, cpos, cneg, fill,
                          out_pix, out_level, out_pol, out_ta, out_tb, out_ia, out_ib):
    """:func:`_crossing_levels` along sub-sampled paths: pixel ``pix[j]`` seen at ``t0``, ``tt[:]``, ``t1``.

    ``vals[j, q]`` is its intensity at ``tt[q]``; a flagged sub-interval
    (``flags[j, q]``, row-major order) is walked through its extra samples
    ``rt[f, :]``, ``rvals[f, :]`` (``f`` counts the flagged ones). Every
    crossing is written with the sub-interval that brackets it
    (``out_ta``/``out_tb`` and the intensities there). Count pass (``fill``
    False: nothing written, the reference levels unchanged) or fill pass.
    Returns the number of crossings.
    """
    n = 0
    m = tt.shape[0] + 1
    nr = rt.shape[1]
    f = 0
    for j in range(pix.shape[0]):
        i = pix[j]
        lr = lref[i]
        cp = cpos[i]
        cn = cneg[i]
        ta = t0
        ia = i0[i]
        for q in range(m):
            end_t = tt[q] if q < m - 1 else t1
            end_i = vals[j, q] if q < m - 1 else i1[i]
            extra = nr if flags[j, q] else 0
            for r in range(extra + 1):
                tb = rt[f, r] if r < extra else end_t
                ib = rvals[f, r] if r < extra else end_i
                l1 = math.log(ib + eps)
                on, step = _first_step(l1, lr, cp, cn)
                if step != 0.0:
                    while (l1 >= lr + step) if on else (l1 <= lr + step):
                        lr += step
                        if fill:
                            out_pix[n] = i
                            out_level[n] = lr
                            out_pol[n] = on
                            out_ta[n] = ta
                            out_tb[n] = tb
                            out_ia[n] = ia
                            out_ib[n] = ib
                        n += 1
                ta = tb
                ia = ib
            if extra:
                f += 1
        if fill and lr != lref[i]:
            lref[i] = lr
            e_hi[i] = math.exp(lr + cp)
            e_lo[i] = math.exp(lr - cn)
    return n


@njit(cache=True)
def _shapes_translating(pix, t, grid, motion, width, bx, by, starts, values, bcx, bcy, reach2, ccx, ccy, radii,
                        circle_values, background, clip, out):
    """:func:`_shapes_at` for a motion without rotation (``theta`` constant): the pixel moves, not the shapes.

    ``bx/by`` are the polygons' vertices and ``bcx/bcy`` their bounding
    centres, ``ccx/ccy`` the disk centres, all already rotated by the
    constant angle (their image positions at ``s = 0``); an entry is the
    coverage of the pixel square shifted by ``-s(t)`` against them (one sine
    per time, no vertex transforms). ``reach2[k]`` is polygon ``k``'s squared
    skip distance ``(radius + half diagonal)^2``. Entries: pixel ``pix[j]``
    at time ``t[j]`` (``grid`` False, ``out[j]``), or every pixel at every
    time (``grid`` True, ``out[j * len(t) + q]``). Equal to
    :func:`_shapes_at` up to rounding (~1e-15).
    """
    nt = t.shape[0]
    sx = np.empty(nt)
    sy = np.empty(nt)
    if grid:
        for q in range(nt):
            tq = t[q]
            sph = math.sin(2.0 * math.pi * (motion[4] * tq + 0.5 * motion[5] * tq * tq))
            sx[q] = motion[6] * tq + 0.5 * motion[8] * tq * tq + motion[10] * sph
            sy[q] = motion[7] * tq + 0.5 * motion[9] * tq * tq + motion[11] * sph
    n = pix.shape[0] * nt if grid else pix.shape[0]
    for e in range(n):
        j = e // nt if grid else e
        i = pix[j]
        y = i // width
        x = i - y * width
        if grid:
            q = e - j * nt
            px = x - sx[q]
            py = y - sy[q]
        else:
            tj = t[j]
            sph = math.sin(2.0 * math.pi * (motion[4] * tj + 0.5 * motion[5] * tj * tj))
            px = x - (motion[6] * tj + 0.5 * motion[8] * tj * tj + motion[10] * sph)
            py = y - (motion[7] * tj + 0.5 * motion[9] * tj * tj + motion[11] * sph)
        value = background
        for k in range(values.shape[0]):
            dx = px - bcx[k]
            dy = py - bcy[k]
            if dx * dx + dy * dy > reach2[k]:
                continue
            cov = _polygon_pixel_coverage_from(bx, by, starts[k], starts[k + 1] - starts[k], px, py)
            if cov > 0.0:
                value += cov * (values[k] - background)
        for k in range(radii.shape[0]):
            cov = _disk_pixel_coverage(px, py, ccx[k], ccy[k], radii[k])
            if cov > 0.0:
                value += cov * (circle_values[k] - background)
        if clip:
            value = min(1.0, max(0.0, value))
        out[e] = value


@njit(cache=True)
def _shapes_truth_points(x, y, t, motion, center_x, center_y, rotating, qx, qy, vx, vy, cos_t, sin_t):
    """Per point of :meth:`~evedge.sim.planar.ShapesRenderer.point_truth`: the motion field and the object point.

    ``(vx, vy)`` is the motion field at image point ``(x, y)`` and time ``t``
    (:meth:`~evedge.sim.motion.PlanarMotion.flow_at`), ``(qx, qy)`` the point
    moved back to object coordinates (``R(-theta)``), ``cos_t``/``sin_t`` of
    the angle (for the normal's way back); the formulas of
    :func:`_motion_full`, one pass. Without rotation (``rotating`` False) the
    angle is the constant ``motion[0]``.
    """
    c0 = math.cos(motion[0])
    s0 = math.sin(motion[0])
    for j in range(x.shape[0]):
        th, w, sx, sy, v0x, v0y = _motion_full(motion, t[j])
        c = math.cos(th) if rotating else c0
        s = math.sin(th) if rotating else s0
        rx = x[j] - center_x - sx
        ry = y[j] - center_y - sy
        vx[j] = v0x - w * ry
        vy[j] = v0y + w * rx
        qx[j] = center_x + c * rx + s * ry
        qy[j] = center_y - s * rx + c * ry
        cos_t[j] = c
        sin_t[j] = s
