"""numba kernels of the event buffer (see :mod:`evedge.detector.buffer`).

Per-pixel state: one flat int64 array ``state`` laid out as ``(2, height + 2, width + 2, 2)``
(:func:`new_state`): polarity plane by padded row by padded column, two fields per
pixel side by side (a row of three neighbours is 48 contiguous bytes):

``[..., 0]`` (``last_t``)
    timestamp of the pixel's latest event, :data:`NEVER` when none; the one-pixel
    border never fires, so the 8-neighbour test needs no bounds checks.
``[..., 1]`` (``head_g``)
    global index of the pixel's newest event not yet reached by a neighbour's
    backward walk, -1 when none (every event of the pixel has been walked).
"""

import numpy as np
from numba import njit

NEVER = np.iinfo(np.int64).min


@njit(cache=True)
def new_state(width, height):
    """Empty per-pixel state of the kernels (no event seen), flat: ``2 * (height + 2) * (width + 2) * 2`` int64."""
    state = np.empty(4 * (height + 2) * (width + 2), dtype=np.int64)
    for i in range(0, state.shape[0], 2):
        state[i] = NEVER
        state[i + 1] = -1
    return state


@njit(cache=True, inline="always")
def _walk(state, c, base_g, t, prev, supported, lo):
    """Mark the unwalked events of the pixel at ``c`` no older than ``lo``; then none is left unwalked.

    The pixel's latest event is within the window (the caller checked ``last_t >= lo``).
    An unwalked event older than ``lo`` can no longer be supported by a later event
    (time-sorted stream): dropping it from the walk changes no decision.
    """
    g = state[c + 1]
    state[c + 1] = -1
    while g >= base_g:
        j = g - base_g
        if t[j] < lo:
            break
        supported[j] = True
        g = prev[j]


@njit(cache=True)
def _buffer_scan(x, y, t, p, prev, supported, n_old, base_g, state, width, height, tau_us, causal):
    """Decide support for events ``n_old..`` of the arrays (events ``0..n_old`` are carried over).

    Arrays ``x, y, t, p, prev, supported`` hold the unreleased events, the first of which
    has global index ``base_g``; ``state`` is :func:`new_state`'s array.
    ``prev`` chains the unwalked events of one pixel and polarity (newest first).
    Event ``k`` is supported by a neighbour fired within tau before it (``supported[k]``
    is set, not or-ed: ``prev`` and ``supported`` of events ``n_old..`` need no
    initialisation) and, in the buffered form, it supports every unwalked event of
    each such neighbour within tau before it: a neighbour's events earlier than the
    last walk there were either marked by that walk or are older than its window,
    hence older than this event's (the stream is time-sorted).
    Returns nothing; updates ``supported``, ``prev`` and ``state`` in place.
    """
    row = 2 * (width + 2)  # one padded row of (last_t, head_g) pairs
    plane = (height + 2) * row
    n = x.shape[0]
    for k in range(n_old, n):
        tk = t[k]
        lo = tk - tau_us
        c = p[k] * plane + (y[k] + 1) * row + 2 * (x[k] + 1)
        # the 8 neighbours (not the pixel itself); NEVER < lo unless lo itself underflows
        a0 = c - row - 2
        a1 = c - row
        a2 = c - row + 2
        a3 = c - 2
        a4 = c + 2
        a5 = c + row - 2
        a6 = c + row
        a7 = c + row + 2
        n0 = (state[a0] >= lo) & (state[a0] != NEVER)
        n1 = (state[a1] >= lo) & (state[a1] != NEVER)
        n2 = (state[a2] >= lo) & (state[a2] != NEVER)
        n3 = (state[a3] >= lo) & (state[a3] != NEVER)
        n4 = (state[a4] >= lo) & (state[a4] != NEVER)
        n5 = (state[a5] >= lo) & (state[a5] != NEVER)
        n6 = (state[a6] >= lo) & (state[a6] != NEVER)
        n7 = (state[a7] >= lo) & (state[a7] != NEVER)
        any_near = n0 | n1 | n2 | n3 | n4 | n5 | n6 | n7
        supported[k] = any_near
        if any_near and not causal:
            # ...and this event supports the unwalked events of those neighbours within tau
            if n0 and state[a0 + 1] >= base_g:
                _walk(state, a0, base_g, t, prev, supported, lo)
            if n1 and state[a1 + 1] >= base_g:
                _walk(state, a1, base_g, t, prev, supported, lo)
            if n2 and state[a2 + 1] >= base_g:
                _walk(state, a2, base_g, t, prev, supported, lo)
            if n3 and state[a3 + 1] >= base_g:
                _walk(state, a3, base_g, t, prev, supported, lo)
            if n4 and state[a4 + 1] >= base_g:
                _walk(state, a4, base_g, t, prev, supported, lo)
            if n5 and state[a5 + 1] >= base_g:
                _walk(state, a5, base_g, t, prev, supported, lo)
            if n6 and state[a6 + 1] >= base_g:
                _walk(state, a6, base_g, t, prev, supported, lo)
            if n7 and state[a7 + 1] >= base_g:
                _walk(state, a7, base_g, t, prev, supported, lo)
        prev[k] = state[c + 1]
        state[c + 1] = base_g + k
        state[c] = tk


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
