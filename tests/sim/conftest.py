"""Slow, obviously-correct pure-Python references of the simulator's numba kernels, and helpers."""

import math
import warnings

import numpy as np
import pytest
from scipy import integrate

MASK64 = (1 << 64) - 1


# ---------------------------------------------------------------- coverage references
def _interval_overlap(a0, a1, b0, b1):
    return max(0.0, min(a1, b1) - max(a0, b0))


def polygon_row_length(vx, vy, y, x0, x1):
    """Length of the horizontal line at height y inside the polygon, within [x0, x1] (even-odd)."""
    xs = []
    n = len(vx)
    for i in range(n):
        ax, ay, bx, by = vx[i - 1], vy[i - 1], vx[i], vy[i]
        if (ay > y) != (by > y):
            xs.append(ax + (y - ay) * (bx - ax) / (by - ay))
    xs.sort()
    return sum(_interval_overlap(xs[k], xs[k + 1], x0, x1) for k in range(0, len(xs) - 1, 2))


def ref_polygon_box_area(vx, vy, x0, y0, x1, y1):
    """Area by integrating the exact row length over y with adaptive quadrature (breaks at vertices)."""
    pts = sorted({float(v) for v in vy if y0 < v < y1})
    val, _ = integrate.quad(lambda y: polygon_row_length(vx, vy, y, x0, x1), y0, y1, points=pts or None,
                            epsabs=1e-13, epsrel=1e-10, limit=200)
    return val


def ref_disk_box_area(cx, cy, r, x0, y0, x1, y1):
    def length(y):
        d = r * r - (y - cy) ** 2
        if d <= 0:
            return 0.0
        h = math.sqrt(d)
        return _interval_overlap(cx - h, cx + h, x0, x1)

    pts = [v for v in (cy - r, cy + r) if y0 < v < y1]
    with warnings.catch_warnings():
        # sqrt-type endpoints of the chord length: quad converges but warns
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        val, _ = integrate.quad(length, y0, y1, points=pts or None, epsabs=1e-13, epsrel=1e-10, limit=200)
    return val


def ref_stripe_dark_fraction(x, y, nx, ny, offset, period, duty):
    """Dark fraction of pixel (x, y): u = nx X + ny Y - offset, dark where u mod period < duty period."""
    def dark_length(yy):
        # along x, u is linear: find the dark sub-intervals of [x - 0.5, x + 0.5]
        x0, x1 = x - 0.5, x + 0.5
        if abs(nx) < 1e-15:
            u = ny * yy - offset
            return (x1 - x0) if (u % period) < duty * period else 0.0
        u0 = nx * x0 + ny * yy - offset
        u1 = nx * x1 + ny * yy - offset
        lo, hi = min(u0, u1), max(u0, u1)
        total = 0.0
        k0 = math.floor(lo / period) - 1
        k1 = math.floor(hi / period) + 1
        for k in range(k0, k1 + 1):
            total += _interval_overlap(k * period, k * period + duty * period, lo, hi)
        return total / abs(nx)

    # the integrand is piecewise linear: break where a pixel corner's u meets a stripe boundary
    pts = []
    if abs(ny) > 1e-15:
        for xc in (x - 0.5, x + 0.5):
            lo_u = nx * xc + ny * (y - 0.5) - offset
            hi_u = nx * xc + ny * (y + 0.5) - offset
            lo_u, hi_u = min(lo_u, hi_u), max(lo_u, hi_u)
            for k in range(math.floor(lo_u / period) - 1, math.floor(hi_u / period) + 2):
                for b in (k * period, k * period + duty * period):
                    yy = (b + offset - nx * xc) / ny
                    if y - 0.5 < yy < y + 0.5:
                        pts.append(yy)
    val, _ = integrate.quad(dark_length, y - 0.5, y + 0.5, points=sorted(pts) or None, epsabs=1e-13,
                            epsrel=1e-10, limit=200)
    return val


# ---------------------------------------------------------------- RNG reference
def splitmix64(x):
    z = (x + 0x9E3779B97F4A7C15) & MASK64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK64
    return z ^ (z >> 31)


def hash_uniform(seed, a, b):
    h = splitmix64(int(seed) ^ splitmix64((int(a) * 0xD1B54A32D192ED03 + int(b)) & MASK64))
    return ((h >> 11) + 0.5) / 9007199254740992.0


def half_normal(seed, a, b):
    u1 = hash_uniform(seed, a, 2 * b)
    u2 = hash_uniform(seed, a, 2 * b + 1)
    return abs(math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2))


# ---------------------------------------------------------------- event generation references
def ref_convert(i0, i1, t0, t1, eps, lref, cpos, cneg, last_t, refractory_s, seq, jitter_s, jitter_seed):
    """ESIM-style conversion of one interval, pixel by pixel, in plain Python (log domain only).

    Returns the events as a list of (pixel, t_true, t_emitted, polarity) and the new state.
    """
    lref = list(lref)
    last_t = list(last_t)
    seq = list(seq)
    out = []
    for i in range(len(i0)):
        l0 = math.log(i0[i] + eps)
        l1 = math.log(i1[i] + eps)
        for sign, c in ((1, cpos[i]), (-1, cneg[i])):
            while sign * (l1 - lref[i]) >= c:
                lref[i] += sign * c
                tc = t0 + (lref[i] - l0) / (l1 - l0) * (t1 - t0)
                if tc - last_t[i] >= refractory_s:
                    jit = jitter_s * half_normal(jitter_seed, i, seq[i]) if jitter_s > 0 else 0.0
                    out.append((i, tc, tc + jit, sign > 0))
                    seq[i] += 1
                    last_t[i] = tc
    return out, lref, last_t, seq


def ref_noise(t1, rate_hz, time_seed, pol_seed, next_t, count):
    out = []
    next_t = list(next_t)
    count = list(count)
    for i in range(len(next_t)):
        while next_t[i] < t1:
            out.append((i, next_t[i], hash_uniform(pol_seed, i, count[i]) < 0.5))
            count[i] += 1
            next_t[i] += -math.log(hash_uniform(time_seed, i, count[i])) / rate_hz
    return out, next_t, count


# ---------------------------------------------------------------- helpers
def fit_plane(x, y, t):
    """Least-squares t = a x + b y + c; returns (a, b)."""
    a = np.column_stack([x, y, np.ones_like(x)]).astype(np.float64)
    coef, *_ = np.linalg.lstsq(a, t.astype(np.float64), rcond=None)
    return coef[0], coef[1]


def stripes_scene_dict(width=24, height=16, duration_s=0.1, **stripe):
    layer = dict(rows_fraction=[0.0, 1.0], period_px=12.0, angle_deg=0.0, velocity_px_s=[100.0, 0.0])
    layer.update(stripe)
    return {
        "scene": {"name": "test_stripes", "kind": "stripes", "duration_s": duration_s, "seed": 5,
                  "frame_rate_hz": 50.0},
        "sensor": {"width": width, "height": height},
        "events": {"contrast_pos": 0.2, "contrast_neg": 0.2},
        "stripes": [layer],
    }


@pytest.fixture
def stripes_dict():
    return stripes_scene_dict


@pytest.fixture(scope="session")
def ref():
    """The references and helpers above, as a namespace (test modules cannot import conftest)."""
    import types

    names = ["ref_polygon_box_area", "ref_disk_box_area", "ref_stripe_dark_fraction", "splitmix64",
             "hash_uniform", "half_normal", "ref_convert", "ref_noise", "fit_plane", "stripes_scene_dict"]
    return types.SimpleNamespace(**{n: globals()[n] for n in names})
