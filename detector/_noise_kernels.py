"""numba helpers of the intra-pixel estimator's noise rules (see :mod:`evedge.detector.intra`, "noise").

The rules take the parameters packed in one float64 array, ``noise``
(:func:`evedge.detector.intra.noise_args`), so a new rule adds a slot here
instead of an argument to every kernel (the stream kernel, its strips in
:mod:`evedge.detector._tiles`, the window kernel). With every rule off the
array is None: numba then compiles none of the rules' code (as
``off_as_none`` does for the other options). Slots:

``_NEWER`` (``IntraParams.newer_share_max``; 1 = off)
    Largest share of the window points newer than the fitted plane (beyond
    its inlier band) among those newer than it or on it (:func:`_newer_count`).
``_BURST_SPAN`` (``IntraParams.burst_span_lifetimes``; 0 = off)
    An event continues its pixel's burst only if it fired at most this many
    lifetimes (the previous event's estimate) after the burst's *first* event
    (``burst_lifetimes`` alone bounds the gap to the previous event, so a chain
    of events, a background event right after a burst among them, can extend
    a burst without end). Applied in the stream kernel.
``_AGREE`` (``IntraParams.lifetime_agreement``; 0 = off)
    Largest ratio between the event's lifetime and the median of its inlier
    pixels' own latest estimates (:func:`_lifetime_agrees`). Stream kernel.
``_PASSAGE_GAP`` (``IntraParams.passage_gap``; 0 = off)
    Largest ratio between the lifetime of an event that starts a new burst and
    the time since its pixel's previous event of the same polarity (two passages
    closer than one lifetime are closer than one pixel). Stream kernel.
"""

import math

import numpy as np
from numba import njit

#: Slot of ``newer_share_max`` in the ``noise`` array.
_NEWER = 0
#: Slot of ``burst_span_lifetimes`` in the ``noise`` array.
_BURST_SPAN = 1
#: Slot of ``lifetime_agreement`` in the ``noise`` array.
_AGREE = 2
#: Slot of ``passage_gap`` in the ``noise`` array.
_PASSAGE_GAP = 3
#: Length of the ``noise`` array.
N_NOISE = 4


#: Inlier pixels with an estimate needed before ``lifetime_agreement`` judges (fewer: the event is kept).
AGREE_MIN_KNOWN = 3


@njit(cache=True)
def _newer_count(wf, dx_row, dy_row, dt_row, n, a, b, delta, thr_us, thr_rel):
    """Window points newer than the plane ``dt = a dx + b dy`` through the current event, beyond its inlier band.

    Points are ``wf[dx_row / dy_row / dt_row, :n]``. A point is newer when
    ``dt - (a dx + b dy) - delta (|a| + |b|) > thr_us + thr_rel sqrt(a^2 + b^2)``
    (the inlier residual of the kernels, on the newer side only). An edge
    passing the event leaves the pixels behind it at the plane's times and the
    pixels ahead older (they hold an earlier passage): none newer, except a
    pixel that fired again after the edge passed it (noise). A background
    event that RANSAC fits to a steep plane of older points (a long lifetime:
    the relative threshold and the intra-pixel slack grow with it) leaves the
    window's recent events above that plane.
    """
    slack = delta * (abs(a) + abs(b))
    thr = thr_us + thr_rel * math.sqrt(a * a + b * b)
    c = 0
    for i in range(n):
        r = wf[dt_row, i] - (a * wf[dx_row, i] + b * wf[dy_row, i]) - slack
        c += 1 if r > thr else 0
    return c


@njit(cache=True)
def _lifetime_agrees(wf, wi, n, dx_row, dy_row, inl_row, tmp_row, prev_lt, base, xk, yk, width, lifetime, ratio):
    """Whether ``lifetime`` is within a factor ``ratio`` of the median of the inlier pixels' latest estimates.

    The inliers are the window points with ``wi[inl_row, i] == 1`` (offsets
    ``wf[dx_row / dy_row, i]`` from pixel ``(xk, yk)``); a pixel's latest
    estimate is ``prev_lt`` at ``base + row * width + column`` (the stream
    kernel's layout; NaN: none). With fewer than :data:`AGREE_MIN_KNOWN`
    known, True (start-up, sparse scenes: nothing to compare with).
    ``wf[tmp_row]`` is scratch. An edge's event fits the plane its inlier
    neighbours were fitted on moments before (their lifetimes agree); a
    background event fitted to a steep plane of stale or noise points gets a
    lifetime several times theirs.
    """
    m = 0
    for i in range(n):
        if wi[inl_row, i] == 1:
            v = prev_lt[base + (yk + np.int64(wf[dy_row, i])) * width + xk + np.int64(wf[dx_row, i])]
            if not math.isnan(v):
                wf[tmp_row, m] = v
                m += 1
    if m < AGREE_MIN_KNOWN:
        return True
    med = np.median(wf[tmp_row, :m])
    return lifetime <= ratio * med and lifetime * ratio >= med
