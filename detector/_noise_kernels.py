"""numba helpers of the intra-pixel estimator's noise rules (see :mod:`evedge.detector.intra`, "noise").

The rules take the parameters packed in one float64 array, ``noise``
(:func:`evedge.detector.intra.noise_args`), so a new rule adds a slot here
instead of an argument to every kernel (the stream kernel, its strips in
:mod:`evedge.detector._tiles`, the window kernel). Slots:

``_NEWER`` (``IntraParams.newer_share_max``; 1 = off)
    Largest share of the window points newer than the fitted plane (beyond
    its inlier band) among those newer than it or on it (:func:`_newer_count`).
"""

import math

from numba import njit

#: Slot of ``newer_share_max`` in the ``noise`` array.
_NEWER = 0
#: Length of the ``noise`` array.
N_NOISE = 1


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
