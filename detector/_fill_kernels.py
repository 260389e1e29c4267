"""numba kernel of the neighbour fill of missing lifetimes (see :mod:`evedge.detector.fill`).

One pass over the events in stream order with per-pixel state (per polarity
plane when the estimator runs per polarity): the newest *estimated* event's time,
lifetime and normal flow. Everything an event's decision reads was written by
earlier events of the stream, so any chunking gives the same bytes.
"""

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _sorted_median(v, m):
    """Median of ``v[:m]`` (sorts ``v[:m]`` in place; insertion sort, ``m <= 8``)."""
    for i in range(1, m):
        key = v[i]
        j = i - 1
        while j >= 0 and v[j] > key:
            v[j + 1] = v[j]
            j -= 1
        v[j + 1] = key
    h = m // 2
    if m % 2:
        return v[h]
    return (v[h - 1] + v[h]) / 2.0


@njit(cache=True)
def _fill_stream(x, y, t, p, lt, vx, vy, valid, state_t, state_lt, state_vx, state_vy, width, height, per_pol,
                 neighbours, tolerance, agreement, border, arrival):
    """Fill, in place, the events of ``lt, vx, vy, valid`` that have no estimate; returns how many were filled.

    ``state_*`` are per pixel and plane (index ``(p * height + y) * width + x`` when
    ``per_pol``, else ``y * width + x``): time, lifetime (NaN: never estimated) and
    flow of the pixel's newest event that the *estimator* gave a lifetime. An event
    with an estimate writes it there; a filled event does not (no chain reaction).
    An event without estimate, at least ``border`` px inside the sensor, is filled
    when at least ``neighbours`` of its 8 neighbours (same plane) hold a recent
    estimate (``t - state_t <= agreement * state_lt``) whose plane predicts the edge
    at the event's pixel within ``arrival`` lifetimes of the event (``arrival > 0``;
    prediction ``state_t + 1e6 (d . v) / |v|^2`` for the offset ``d`` from the
    neighbour to the event and its flow ``v``) and those estimates
    agree (``max - min <= tolerance * median``): lifetime = their median, flow = the
    component-wise median of their flows rescaled to speed ``1e6 / lifetime`` px/s
    (not filled when that median flow is zero).
    """
    n = x.shape[0]
    nb_lt = np.empty(8)
    nb_vx = np.empty(8)
    nb_vy = np.empty(8)
    plane_size = width * height
    filled = 0
    for i in range(n):
        xi = x[i]
        yi = y[i]
        base = p[i] * plane_size if per_pol else 0
        if valid[i]:
            q = base + yi * width + xi
            state_t[q] = t[i]
            state_lt[q] = lt[i]
            state_vx[q] = vx[i]
            state_vy[q] = vy[i]
            continue
        if border > 0 and (xi < border or yi < border or xi >= width - border or yi >= height - border):
            continue
        ti = t[i]
        m = 0
        lo = math.inf
        hi = -math.inf
        for yy in range(max(yi - 1, 0), min(yi + 1, height - 1) + 1):
            row = base + yy * width
            for xx in range(max(xi - 1, 0), min(xi + 1, width - 1) + 1):
                if xx == xi and yy == yi:
                    continue
                q = row + xx
                life = state_lt[q]
                if not (life > 0):  # NaN: never estimated
                    continue
                dt = float(ti - state_t[q])
                if dt > agreement * life:
                    continue
                if arrival > 0.0:
                    gx = state_vx[q]
                    gy = state_vy[q]
                    v2 = gx * gx + gy * gy
                    if not (v2 > 0.0) or abs(dt - ((xi - xx) * gx + (yi - yy) * gy) / v2 * 1e6) > arrival * life:
                        continue
                nb_lt[m] = life
                nb_vx[m] = state_vx[q]
                nb_vy[m] = state_vy[q]
                lo = min(lo, life)
                hi = max(hi, life)
                m += 1
        if m < neighbours:
            continue
        med = _sorted_median(nb_lt, m)
        if hi - lo > tolerance * med:
            continue
        mvx = _sorted_median(nb_vx, m)
        mvy = _sorted_median(nb_vy, m)
        norm = math.sqrt(mvx * mvx + mvy * mvy)  # not hypot: the reference must give the same bits
        if not norm > 0.0:
            continue
        scale = 1e6 / med / norm
        lt[i] = med
        vx[i] = mvx * scale
        vy[i] = mvy * scale
        valid[i] = True
        filled += 1
    return filled
