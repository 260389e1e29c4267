"""numba kernel: the output order of a flush's events (time in microseconds, then pixel), by counting sorts."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _time_pixel_order(t_us, pix, npix, order):
    """Stable order of the events by ``(t_us, pix)``, written to ``order``; returns whether a pair repeats.

    Two stable counting sorts (LSD radix): by pixel (``npix`` buckets), then
    by ``t_us - min(t_us)``. The result is ``np.argsort(t_us * npix + pix,
    kind="stable")`` (``0 <= pix < npix``) in ``O(n + npix + range)``
    instead of a comparison sort. The caller falls back to a comparison sort
    when the time range is much larger than the number of events.
    """
    n = t_us.shape[0]
    if n == 0:
        return False
    lo = t_us[0]
    hi = t_us[0]
    for j in range(n):
        lo = min(lo, t_us[j])
        hi = max(hi, t_us[j])
    tmp = np.empty(n, dtype=np.int64)
    count = np.zeros(npix + 1, dtype=np.int64)
    for j in range(n):
        count[pix[j] + 1] += 1
    for b in range(npix):
        count[b + 1] += count[b]
    for j in range(n):
        b = pix[j]
        tmp[count[b]] = j
        count[b] += 1
    span = hi - lo + 1
    count = np.zeros(span + 1, dtype=np.int64)
    for j in range(n):
        count[t_us[j] - lo + 1] += 1
    for b in range(span):
        count[b + 1] += count[b]
    for q in range(n):
        j = tmp[q]
        b = t_us[j] - lo
        order[count[b]] = j
        count[b] += 1
    for q in range(1, n):
        if t_us[order[q]] == t_us[order[q - 1]] and pix[order[q]] == pix[order[q - 1]]:
            return True
    return False
