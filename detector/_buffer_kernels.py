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
from numba import njit, prange

from ._chunks import chunk_bounds, n_chunks
from ._prefetch import _prefetch

NEVER = np.iinfo(np.int64).min
FOREVER = np.iinfo(np.int64).max  # the backward pass's "never fires"


@njit(cache=True)
def new_state(width, height):
    """Empty per-pixel state of the kernels (no event seen), flat: ``2 * (height + 2) * (width + 2) * 2`` int64."""
    state = np.empty(4 * (height + 2) * (width + 2), dtype=np.int64)
    for i in range(0, state.shape[0], 2):
        state[i] = NEVER
        state[i + 1] = -1
    return state


def empty_state(width, height):
    """:func:`new_state` in plain numpy, for callers outside numba (the same bytes, no compilation)."""
    state = np.empty(4 * (height + 2) * (width + 2), dtype=np.int64)
    state[0::2] = NEVER
    state[1::2] = -1
    return state


#: The scans ask for the state cells of the event this many places ahead (:mod:`._prefetch`).
_AHEAD = 16


@njit(cache=True, inline="always")
def _walk(state, c, g, base_g, t, prev, supported, lo):
    """Mark the unwalked events of the pixel at ``c``, newest ``g``, no older than ``lo``; then none is left unwalked.

    ``g`` is unreleased and within the window (the caller checked ``last_t >= lo``).
    An unwalked event older than ``lo`` can no longer be supported by a later event
    (time-sorted stream): dropping it from the walk changes no decision.
    """
    state[c + 1] = -1
    j = g - base_g
    supported[j] = True
    g = prev[j]
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
        if k + _AHEAD < n:  # a hint: the three state rows of the event _AHEAD on, 48 bytes each (:mod:`._prefetch`)
            c2 = p[k + _AHEAD] * plane + (y[k + _AHEAD] + 1) * row + 2 * x[k + _AHEAD]
            for r2 in (c2 - row, c2, c2 + row):
                _prefetch(state, r2)
                _prefetch(state, r2 + 5)
        tk = t[k]
        lo = tk - tau_us
        # "fired within tau" is last_t >= lo and last_t != NEVER: one comparison with lo_n
        lo_n = lo + (lo == NEVER)
        c = p[k] * plane + (y[k] + 1) * row + 2 * (x[k] + 1)
        # the 8 neighbours (not the pixel itself)
        a0 = c - row - 2
        a1 = c - row
        a2 = c - row + 2
        a3 = c - 2
        a4 = c + 2
        a5 = c + row - 2
        a6 = c + row
        a7 = c + row + 2
        n0 = state[a0] >= lo_n
        n1 = state[a1] >= lo_n
        n2 = state[a2] >= lo_n
        n3 = state[a3] >= lo_n
        n4 = state[a4] >= lo_n
        n5 = state[a5] >= lo_n
        n6 = state[a6] >= lo_n
        n7 = state[a7] >= lo_n
        supported[k] = n0 | n1 | n2 | n3 | n4 | n5 | n6 | n7
        if not causal:
            # ...and this event supports the unwalked events of those neighbours within tau
            # (rare: each event is walked at most once, so test all eight before branching)
            h0 = state[a0 + 1]
            h1 = state[a1 + 1]
            h2 = state[a2 + 1]
            h3 = state[a3 + 1]
            h4 = state[a4 + 1]
            h5 = state[a5 + 1]
            h6 = state[a6 + 1]
            h7 = state[a7 + 1]
            w0 = n0 & (h0 >= base_g)
            w1 = n1 & (h1 >= base_g)
            w2 = n2 & (h2 >= base_g)
            w3 = n3 & (h3 >= base_g)
            w4 = n4 & (h4 >= base_g)
            w5 = n5 & (h5 >= base_g)
            w6 = n6 & (h6 >= base_g)
            w7 = n7 & (h7 >= base_g)
            if w0 | w1 | w2 | w3 | w4 | w5 | w6 | w7:
                if w0:
                    _walk(state, a0, h0, base_g, t, prev, supported, lo)
                if w1:
                    _walk(state, a1, h1, base_g, t, prev, supported, lo)
                if w2:
                    _walk(state, a2, h2, base_g, t, prev, supported, lo)
                if w3:
                    _walk(state, a3, h3, base_g, t, prev, supported, lo)
                if w4:
                    _walk(state, a4, h4, base_g, t, prev, supported, lo)
                if w5:
                    _walk(state, a5, h5, base_g, t, prev, supported, lo)
                if w6:
                    _walk(state, a6, h6, base_g, t, prev, supported, lo)
                if w7:
                    _walk(state, a7, h7, base_g, t, prev, supported, lo)
        prev[k] = state[c + 1]
        state[c + 1] = base_g + k
        state[c] = tk


# ---------------------------------------------------------------- one shot: two passes, no chains
#
# With the whole stream at hand the buffered rule splits in two: event ``k`` is
# supported when the *latest* same-polarity event before it (stream order) at one of
# its 8 neighbours is at most ``tau`` earlier (a forward pass, the causal rule), or
# the *earliest* one after it is at most ``tau`` later (the same pass backwards): the
# latest before and the earliest after are the nearest in time on each side (the
# stream is time-sorted), so this is ``|t_j - t_k| <= tau`` for some neighbour event
# ``j``, the rule :func:`_buffer_scan` implements with its walks. State: one time per
# pixel and polarity, ``(2, height + 2, width + 2)`` with a border that never fires;
# no chain, no per-event array but the mask. The time is ``t - t0``: int64 with
# ``t0 = 0`` (exact everywhere for the forward pass), or int32 with ``t0 = t[0]``
# when the span and the window fit (:func:`narrow_exact`; half the memory, which
# counts on large sensors).

I32_MIN = np.iinfo(np.int32).min  # the narrow state's "never fired" (forward pass)
I32_MAX = np.iinfo(np.int32).max  # and "never fires" (backward pass)


@njit(cache=True)
def _support_before(x, y, t, p, supported, state, t0, width, height, tau_us):
    """Set ``supported[k]``: a neighbour's latest event before ``k`` (stream order) is at most ``tau_us`` earlier.

    ``state``: :func:`_two_passes`' array, filled with its "never fired" (the dtype's
    minimum), holding ``t - t0``. With int64 and ``t0 = 0`` the causal rule exactly as
    :func:`_buffer_scan` decides it (``last_t >= lo``, the same treatment of a window
    starting at the int64 floor). Checks the events on the way (the input checks of
    :func:`evedge.events.validate_events`, in the same pass): returns -1, or the
    index of the first event outside the sensor or earlier than the one before it,
    where it stops (the mask is then incomplete).
    """
    row = width + 2
    plane = (height + 2) * row
    n = x.shape[0]
    t_prev = t[0] if n else 0
    for k in range(n):
        if k + _AHEAD < n:  # a hint: the state rows of the event _AHEAD on (no value changes, never faults)
            c = p[k + _AHEAD] * plane + (y[k + _AHEAD] + 1) * row + x[k + _AHEAD]
            _prefetch(state, c - row)
            _prefetch(state, c)
            _prefetch(state, c + row)
        xk = x[k]
        yk = y[k]
        tk = t[k]
        if xk < 0 or xk >= width or yk < 0 or yk >= height or tk < t_prev:
            return k
        t_prev = tk
        rel = tk - t0
        lo = rel - tau_us
        lo_n = lo + (lo == NEVER)  # a window starting at the floor does not count "never fired"
        c = p[k] * plane + (yk + 1) * row + (xk + 1)
        supported[k] = ((state[c - row - 1] >= lo_n) | (state[c - row] >= lo_n) | (state[c - row + 1] >= lo_n)
                        | (state[c - 1] >= lo_n) | (state[c + 1] >= lo_n)
                        | (state[c + row - 1] >= lo_n) | (state[c + row] >= lo_n) | (state[c + row + 1] >= lo_n))
        state[c] = rel
    return -1


@njit(cache=True)
def _support_after(x, y, t, p, supported, state, t0, width, height, tau_us):
    """Or into ``supported[k]``: a neighbour's earliest event after ``k`` (stream order) is at most ``tau_us`` later.

    After :func:`_support_before` on the same (checked) events, this gives the
    buffered rule; ``state`` filled with its "never fires" (the dtype's maximum).
    Exact when no event lies within ``tau_us`` of the int64 range's ends (no
    wrap-around, and the sentinel is later than every window): :func:`one_shot_exact`.
    Checks the coordinates (the state's bounds) on its way: returns -1, or the index
    of the last event outside the sensor, where it stops.
    """
    row = width + 2
    plane = (height + 2) * row
    for k in range(x.shape[0] - 1, -1, -1):
        if k >= _AHEAD:  # a hint, as in the forward pass
            c = p[k - _AHEAD] * plane + (y[k - _AHEAD] + 1) * row + x[k - _AHEAD]
            _prefetch(state, c - row)
            _prefetch(state, c)
            _prefetch(state, c + row)
        xk = x[k]
        yk = y[k]
        if xk < 0 or xk >= width or yk < 0 or yk >= height:
            return k  # (only unchecked events, :func:`_passes_both`: the forward pass names the error)
        rel = t[k] - t0
        hi = rel + tau_us
        c = p[k] * plane + (yk + 1) * row + (xk + 1)
        supported[k] |= ((state[c - row - 1] <= hi) | (state[c - row] <= hi) | (state[c - row + 1] <= hi)
                         | (state[c - 1] <= hi) | (state[c + 1] <= hi)
                         | (state[c + row - 1] <= hi) | (state[c + row] <= hi) | (state[c + row + 1] <= hi))
        state[c] = rel
    return -1


@njit(cache=True)
def _passes(x, y, t, p, supported, state, forever, t0, width, height, tau_us, forward_only):
    bad = _support_before(x, y, t, p, supported, state, t0, width, height, tau_us)
    if bad >= 0 or forward_only:
        return bad
    state[:] = forever
    _support_after(x, y, t, p, supported, state, t0, width, height, tau_us)
    return -1


@njit(cache=True)
def _two_passes(x, y, t, p, supported, width, height, tau_us, forward_only, narrow):
    """The one-shot buffer: :func:`_support_before`, then (unless ``forward_only``) :func:`_support_after`.

    ``narrow``: int32 state, times relative to ``t[0]`` (only when :func:`narrow_exact`);
    else int64, absolute. Returns :func:`_support_before`'s result (-1: events fine).
    """
    size = 2 * (height + 2) * (width + 2)
    if narrow:
        t0 = t[0] if t.shape[0] else 0
        return _passes(x, y, t, p, supported, np.full(size, I32_MIN, np.int32), I32_MAX, t0, width, height, tau_us,
                       forward_only)
    return _passes(x, y, t, p, supported, np.full(size, NEVER, np.int64), FOREVER, 0, width, height, tau_us,
                   forward_only)


@njit(parallel=True, cache=True)
def _passes_both(x, y, t, p, supported, state_before, state_after, t0, width, height, tau_us):
    """:func:`_passes` (both passes) with the two passes at once on two threads, each on its own state and
    mask, then or-ed: the same bytes. The backward pass may run on events the forward pass finds bad (it
    checks their coordinates itself); the forward pass's result is returned as :func:`_passes`'."""
    n = x.shape[0]
    after = np.zeros(n, np.bool_)
    bad = np.full(2, -1, np.int64)
    for i in prange(2):
        if i == 0:
            bad[0] = _support_before(x, y, t, p, supported, state_before, t0, width, height, tau_us)
        else:
            bad[1] = _support_after(x, y, t, p, after, state_after, t0, width, height, tau_us)
    if bad[0] >= 0:
        return bad[0]
    for c in prange(n_chunks(n)):
        lo, hi = chunk_bounds(c, n)
        for k in range(lo, hi):
            supported[k] |= after[k]
    return -1


def run_passes(x, y, t, p, supported, width, height, tau_us, forward_only, narrow, threads=1):
    """:func:`_two_passes` from Python, with the state made in numpy: only the state type used is compiled.

    (:func:`_two_passes` compiles both, a second or more on a cold start; the strips call it.)
    ``threads > 1`` with both passes: :func:`_passes_both` (the passes at once, the same bytes).
    """
    size = 2 * (height + 2) * (width + 2)
    if narrow:
        state, forever, t0 = np.full(size, I32_MIN, np.int32), int(I32_MAX), int(t[0]) if t.shape[0] else 0
    else:
        state, forever, t0 = np.full(size, NEVER, np.int64), int(FOREVER), 0
    if threads > 1 and not forward_only:
        return _passes_both(x, y, t, p, supported, state, np.full(size, forever, state.dtype), t0, width, height,
                            tau_us)
    return _passes(x, y, t, p, supported, state, forever, t0, width, height, tau_us, forward_only)


def one_shot_exact(t_first: int, t_last: int, tau_us: int) -> bool:
    """Whether :func:`_support_after` is exact for a stream from ``t_first`` to ``t_last`` (int64 state).

    No event within ``tau_us`` of the int64 range's ends: ``t_first - tau_us > min``
    and ``t_last + tau_us < max``. Else the one-shot buffer takes :func:`_buffer_scan`.
    """
    return int(t_first) - int(NEVER) > tau_us and int(FOREVER) - int(t_last) > tau_us


def narrow_exact(t_first: int, t_last: int, tau_us: int) -> bool:
    """Whether both passes give the same bytes with the int32 state (times relative to ``t_first``).

    :func:`one_shot_exact` (so the int64 passes do not wrap around either), and
    ``t_last - t_first + tau_us < 2**31 - 1``: every relative time and window bound
    (``>= -tau_us``, ``<= span + tau_us``) fits strictly between the sentinels.
    """
    return one_shot_exact(t_first, t_last, tau_us) and int(t_last) - int(t_first) + tau_us < int(I32_MAX)


#: The int32 state pays when the int64 one would not fit a core's L2 cache (512 KiB here): on a
#: Gen4-sized sensor 1.7x faster, on a DVS128 (270 KiB in int64) 7 % slower (``benchmarks/bench_buffer.py``).
NARROW_FROM_BYTES = 2**19


def narrow_state(t_first: int, t_last: int, tau_us: int, width: int, height: int) -> bool:
    """Whether the one-shot passes take the int32 state: exact (:func:`narrow_exact`) and large enough to pay."""
    return 16 * (width + 2) * (height + 2) > NARROW_FROM_BYTES and narrow_exact(t_first, t_last, tau_us)


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


# ---------------------------------------------------------------- the line rule (option, off by default)
#
# Its own per-pixel state, flat int64 laid out as ``(2, height + 4, width + 4, 3)``
# (:func:`new_line_state`): a border of two pixels that never fire, so the rule's
# reads two pixels out need no bounds checks. ``[..., 0]`` is the pixel's latest
# timestamp (:data:`NEVER`: none), ``[..., 1]`` the global index of that event
# (-1: none, or it needs no mark: supported when it came or marked since; marking is
# idempotent, so skipping those changes no decision),
# ``[..., 2]`` the timestamp of the pixel's event before it (:data:`NEVER`: none).

LINE_FIELDS = 3


@njit(cache=True)
def new_line_state(width, height):
    """Empty state of :func:`_line_scan` (no event seen), flat: ``2 * (height + 4) * (width + 4) * 3`` int64."""
    state = np.empty(2 * LINE_FIELDS * (height + 4) * (width + 4), dtype=np.int64)
    for i in range(0, state.shape[0], LINE_FIELDS):
        state[i] = NEVER
        state[i + 1] = -1
        state[i + 2] = NEVER
    return state


def empty_line_state(width, height):
    """:func:`new_line_state` in plain numpy (the same bytes, no compilation)."""
    state = np.empty(2 * LINE_FIELDS * (height + 4) * (width + 4), dtype=np.int64)
    state[0::LINE_FIELDS] = NEVER
    state[1::LINE_FIELDS] = -1
    state[2::LINE_FIELDS] = NEVER
    return state


@njit(cache=True, inline="always")
def _midway(t1, tc, t2, line_us, line_tol):
    """Whether ``tc`` lies between ``t1`` and ``t2`` (either order), each at most ``line_us`` away, and about midway."""
    if t1 == NEVER or t2 == NEVER:
        return False
    if t1 > t2:
        t1, t2 = t2, t1
    if t1 > tc or tc > t2:
        return False
    d1 = t2 - tc
    d2 = tc - t1
    return d1 <= line_us and d2 <= line_us and abs(d1 - d2) <= line_tol * max(d1, d2)


@njit(cache=True)
def _line_scan(x, y, t, p, supported, n_old, base_g, state, width, height, line_us, line_tol, line_quiet,
               line_count):
    """The line rule for events ``n_old..`` (after :func:`_buffer_scan` on the same arrays): or-s into ``supported``.

    When event ``k`` (pixel ``u``) arrives, for each of the 8 directions ``a``, let
    ``c = u + a`` and ``e = u + 2a`` (same polarity), with their latest events
    before ``k`` at ``t_c`` and ``t_e``, and ``c``'s event before its latest at
    ``t_c0``. The event at ``c`` is supported when ``t_e <= t_c <= t_k``,
    ``d1 = t_k - t_c <= line_us``, ``d2 = t_c - t_e <= line_us``,
    ``|d1 - d2| <= line_tol * max(d1, d2)`` (:func:`_midway`),
    ``t_c - t_c0 >= line_quiet * (d1 + d2)`` (never fired before counts as quiet)
    and, with ``line_count = 2``, one of the three other pairs of opposite
    neighbours of ``c`` is midway too (their latest events before ``k``, either
    order): ``c``'s event lies midway in time between neighbours on opposite
    sides, as on an edge crossing the three pixels at a steady speed, however
    slowly, and its own pixel was quiet for longer than that edge took to cross
    the three (on an active pixel a chance midpoint is likely). Every pixel read
    is within one of ``c``, the supported one, so a one-row halo keeps strips
    exact. Only events still held are marked (the caller holds an unsupported
    event ``line_us`` long).
    """
    row = LINE_FIELDS * (width + 4)
    plane = (height + 4) * row
    n = x.shape[0]
    for k in range(n_old, n):
        if k + _AHEAD < n:  # a hint: the five state rows the event _AHEAD on reads, both ends (:mod:`._prefetch`)
            u2 = p[k + _AHEAD] * plane + (y[k + _AHEAD] + 2) * row + LINE_FIELDS * x[k + _AHEAD]
            for r2 in (u2 - 2 * row, u2 - row, u2, u2 + row, u2 + 2 * row):
                _prefetch(state, r2)
                _prefetch(state, r2 + 5 * LINE_FIELDS - 1)
        tk = t[k]
        lo = tk - line_us
        lo_n = lo + (lo == NEVER)
        u = p[k] * plane + (y[k] + 2) * row + LINE_FIELDS * (x[k] + 2)
        for dy in range(-1, 2):
            for dx in range(-1, 2):
                if dx == 0 and dy == 0:
                    continue
                step = dy * row + LINE_FIELDS * dx
                c = u + step
                gc = state[c + 1]
                if gc < base_g:  # no event to mark there (most often: supported when it came, or marked since)
                    continue
                tc = state[c]
                if tc < lo_n:
                    continue
                if supported[gc - base_g]:  # supported since (streaming: a later chunk's walk)
                    state[c + 1] = -1
                    continue
                te = state[c + step]
                if not _midway(te, tc, tk, line_us, line_tol):
                    continue
                tc0 = state[c + 2]
                if tc0 != NEVER and tc - tc0 < line_quiet * (tk - te):
                    continue
                if line_count >= 2:
                    found = False
                    for b in range(4):  # the pairs (1, 0), (0, 1), (1, 1), (1, -1), but the one along a
                        bx = 1 if b != 1 else 0
                        by = 0 if b == 0 else (1 if b != 3 else -1)
                        if (bx == dx and by == dy) or (bx == -dx and by == -dy):
                            continue
                        sb = by * row + LINE_FIELDS * bx
                        if _midway(state[c + sb], tc, state[c - sb], line_us, line_tol):
                            found = True
                            break
                    if not found:
                        continue
                supported[gc - base_g] = True
                state[c + 1] = -1
        state[u + 2] = state[u]
        state[u] = tk
        state[u + 1] = -1 if supported[k] else base_g + k
