"""numba kernel of the lifetime edge image (see :mod:`evedge.detector.edges`)."""

import math

import numpy as np
from numba import njit

# 8 directions, index = round(angle / 45 degrees) mod 8, image axes (x right, y down)
_DX = np.array([1, 1, 0, -1, -1, -1, 0, 1], dtype=np.int64)
_DY = np.array([0, 1, 1, 1, 0, -1, -1, -1], dtype=np.int64)


@njit(cache=True)
def _edge_update(x, y, t, lt, vx, vy, valid, last_t, expiry, width, height, clear_behind, invalid_clears,
                 dirx, diry, p, burst, start_t, prev_lt, prev_pol, sel=None, a=0, b=0, row0=0):
    """Apply events in order to the per-pixel state (flat ``y * width + x``).

    ``last_t`` (int64) is the time of the pixel's newest counted event and
    ``expiry`` (float64) the end of its life ``t + lifetime``. An event without
    estimate is skipped, or with ``invalid_clears`` sets its pixel dead
    (``expiry = t``). With ``clear_behind`` a valid event also ends the life of
    the 8-neighbour behind it, opposite its flow rounded to 45 degrees.

    Burst-aware expiry (``burst > 0``): ``start_t`` (int64), ``prev_lt`` (float,
    NaN = none) and ``prev_pol`` (int8, -1 = none) hold, per pixel, the start of
    its current burst and the lifetime and polarity of its newest valid event. A
    valid event of the same polarity at most ``burst * prev_lt`` after that
    event continues the burst, and its life is counted from the burst's start:
    ``expiry = start + lifetime``. Otherwise it starts a burst (``expiry = t +
    lifetime``, as with ``burst = 0``).

    ``sel`` (None: every event, in order): the events ``sel[a:b]`` instead, read
    in place, on a state whose row 0 is sensor row ``row0`` (a strip,
    :mod:`evedge.detector._tiles`; ``height`` is then its rows).
    """
    j1 = x.shape[0] if sel is None else b
    for j in range(0 if sel is None else a, j1):
        # unsigned: the columns are read with no negative-index wraparound test (8 per event; a strip reading its
        # events through its index ran 1.4x slower than the serial loop with them)
        k = np.uint64(j) if sel is None else np.uint64(sel[j])
        yk = y[k] - row0
        pix = yk * width + x[k]
        if not valid[k]:
            if invalid_clears:
                last_t[pix] = t[k]
                expiry[pix] = float(t[k])
            continue
        start = t[k]
        if burst > 0.0:
            pk = np.int8(1) if p[k] else np.int8(0)
            # prev_lt NaN (no valid event yet): the comparison is False
            if prev_pol[pix] == pk and t[k] - last_t[pix] <= burst * prev_lt[pix]:
                start = start_t[pix]
            start_t[pix] = start
            prev_lt[pix] = lt[k]
            prev_pol[pix] = pk
        last_t[pix] = t[k]
        expiry[pix] = start + lt[k]
        if clear_behind:
            ang = math.atan2(-vy[k], -vx[k])
            # nearest of 8 directions; half-way angles round up (counter-clockwise)
            d = int(math.floor(ang / (math.pi / 4.0) + 0.5)) % 8
            xx = x[k] + dirx[d]
            yy = yk + diry[d]
            if 0 <= xx < width and 0 <= yy < height:
                q = yy * width + xx
                if expiry[q] > t[k]:
                    expiry[q] = float(t[k])
