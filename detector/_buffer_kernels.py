"""numba kernels of the event buffer (see :mod:`evedge.detector.buffer`)."""

import numpy as np
from numba import njit

_NEVER = np.iinfo(np.int64).min


@njit(cache=True)
def _buffer_scan(x, y, t, p, prev, supported, n_old, base_g, last_t, head_g, covered_g, width, height, tau_us,
                 causal):
    """Mark support for events ``n_old..`` of the arrays (events ``0..n_old`` are carried over).

    Arrays ``x, y, t, p, prev, supported`` hold the unreleased events, the first of which
    has global index ``base_g``. ``last_t`` and ``head_g`` are per pixel and polarity
    (index ``(p * height + y) * width + x``): the latest timestamp and the global index of
    the latest event there. ``prev`` chains the events of one pixel and polarity.
    ``covered_g`` (per pixel and polarity, -1 = none) is the global index of the newest
    event of that pixel reached by an earlier backward walk: that walk marked every
    event of the pixel up to it no older than its own ``t - tau``, which is no later
    than the present walk's (time-sorted stream), so the present walk stops there
    (the marks are the same; on dense edges most of the walking is saved).
    Returns nothing; updates ``supported``, ``prev``, ``last_t``, ``head_g``, ``covered_g`` in place.
    """
    n = x.shape[0]
    for k in range(n_old, n):
        xk = x[k]
        yk = y[k]
        tk = t[k]
        plane = p[k] * height
        lo = tk - tau_us
        n_support = 0
        x0 = max(xk - 1, 0)
        x1 = min(xk + 1, width - 1)
        # the 3x3 neighbourhood over clipped ranges; the support test is branch-free
        # (whether a neighbour fired within tau is unpredictable), the walk is not
        for yy in range(max(yk - 1, 0), min(yk + 1, height - 1) + 1):
            row = (plane + yy) * width
            for xx in range(x0, x1 + 1):
                q = row + xx
                lt = last_t[q]
                # a neighbour (not the pixel itself) fired within tau before (or at) this event
                near = (lt >= lo) & (lt != _NEVER) & ((xx != xk) | (yy != yk))
                n_support += near
                if near and not causal:
                    # ...and this event supports every unreleased event of that
                    # neighbour within tau before it
                    g = head_g[q]
                    stop = max(covered_g[q], base_g - 1)
                    covered_g[q] = g
                    while g > stop:
                        j = g - base_g
                        if t[j] < lo:
                            break
                        supported[j] = True
                        g = prev[j]
        if n_support > 0:
            supported[k] = True
        pix = (plane + yk) * width + xk
        prev[k] = head_g[pix]
        head_g[pix] = base_g + k
        last_t[pix] = tk


@njit(cache=True)
def _n_decided(t, supported, t_latest, tau_us, causal):
    """Length of the leading run of events whose fate is known by time ``t_latest``."""
    n = t.shape[0]
    if causal:
        return n
    k = 0
    while k < n:
        # an unsupported event may still be supported by an event up to t + tau
        if not supported[k] and t[k] + tau_us >= t_latest:
            break
        k += 1
    return k
