"""numba kernels of the event converter (ESIM-style) and its noise and hash RNG.

Counter-based randomness: every random number is a hash (splitmix64) of a
seed, a pixel index and a per-pixel counter, so results do not depend on how
the run is cut into time chunks.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from evedge._splitmix import _splitmix64

_K_PIX = np.uint64(0xD1B54A32D192ED03)


@njit(cache=True)
def _hash_uniform(seed, a, b):
    """Uniform in (0, 1) from (seed, a, b); never 0 or 1."""
    h = _splitmix64(np.uint64(seed) ^ _splitmix64(np.uint64(a) * _K_PIX + np.uint64(b)))
    return (float(h >> np.uint64(11)) + 0.5) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _half_normal(seed, a, b):
    """|N(0, 1)| by Box-Muller from two hashed uniforms."""
    u1 = _hash_uniform(seed, a, 2 * b)
    u2 = _hash_uniform(seed, a, 2 * b + 1)
    return abs(math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2))


@njit(cache=True)
def _widen_ratio(r, a, b):
    """``max(r, a / b, b / a)`` for positive ``a``, ``b`` and ``r >= 1``.

    Compares by multiplication and divides only when the maximum grows.
    """
    if a > r * b:
        return a / b
    if b > r * a:
        return b / a
    return r


@njit(cache=True)
def _max_log_change(i0, i1, eps):
    """max over pixels of |log(i1 + eps) - log(i0 + eps)| (one log, not one per pixel)."""
    r = 1.0
    for i in range(i0.shape[0]):
        r = _widen_ratio(r, i0[i] + eps, i1[i] + eps)
    return math.log(r)


@njit(cache=True)
def _max_log_gradient(img, width, height, eps):
    """max over pixels of |grad L| (forward differences, px^-1) of ``L = log(img + eps)``."""
    g = 0.0
    for y in range(height):
        for x in range(width):
            i = y * width + x
            li = math.log(img[i] + eps)
            gx = math.log(img[i + 1] + eps) - li if x + 1 < width else 0.0
            gy = math.log(img[i + width] + eps) - li if y + 1 < height else 0.0
            m = math.sqrt(gx * gx + gy * gy)
            if m > g:
                g = m
    return g


@njit(cache=True)
def _box_spans(boxes, n_boxes, width, height, out):
    """Row-major flat index ranges covering the union of boxes; returns the number of ranges.

    ``boxes`` is ``(r0, r1, c0, c1)`` (half-open, clipped to the image) per
    box, flattened; ``out`` receives ``(start, stop)`` pairs, flattened, and
    needs room for ``2 * height * n_boxes`` values. The ranges are disjoint and
    in increasing order (the pixel visiting order of a full scan).
    """
    lo = np.empty(n_boxes, dtype=np.int64)
    hi = np.empty(n_boxes, dtype=np.int64)
    n = 0
    for r in range(height):
        m = 0
        for k in range(n_boxes):
            if boxes[4 * k] <= r < boxes[4 * k + 1] and boxes[4 * k + 2] < boxes[4 * k + 3]:
                # insertion sort by start column (a handful of boxes)
                j = m
                while j > 0 and lo[j - 1] > boxes[4 * k + 2]:
                    lo[j] = lo[j - 1]
                    hi[j] = hi[j - 1]
                    j -= 1
                lo[j] = boxes[4 * k + 2]
                hi[j] = boxes[4 * k + 3]
                m += 1
        j = 0
        while j < m:
            a = lo[j]
            b = hi[j]
            j += 1
            while j < m and lo[j] <= b:
                b = max(b, hi[j])
                j += 1
            if n > 0 and out[2 * n - 1] == r * width + a:
                out[2 * n - 1] = r * width + b  # contiguous with the previous range (full rows)
            else:
                out[2 * n] = r * width + a
                out[2 * n + 1] = r * width + b
                n += 1
    return n


@njit(cache=True)
def _scan(i0, i1, eps, e_hi, e_lo, spans, n_spans, cand):
    """Pre-test of the pixels in ``spans`` (flat ranges, as :func:`_box_spans`).

    Writes to ``cand`` the pixels whose new intensity may cross a threshold
    and returns ``(n_cand, max_dl)``: their number and the largest
    ``|Delta L|`` over the scanned pixels. Pixels outside the spans must have
    ``i1 == i0`` (unchanged pixels cannot cross and do not change ``max_dl``).
    """
    m = 0
    ratio = 1.0
    for s in range(n_spans):
        for i in range(spans[2 * s], spans[2 * s + 1]):
            if i1[i] == i0[i]:
                # unchanged pixel: it was inside its thresholds at i0, so it still is (most pixels)
                continue
            a = i1[i] + eps
            ratio = _widen_ratio(ratio, a, i0[i] + eps)
            # conservative pre-test; the decision itself is made on logarithms in _crossings
            if e_lo[i] * (1.0 + 1e-12) < a < e_hi[i] * (1.0 - 1e-12):
                continue
            cand[m] = i
            m += 1
    return m, math.log(ratio)


@njit(cache=True, inline="always")
def _first_step(l1, lr, cp, cn):
    """``(on, step)`` of the first level ``l1`` reaches from the reference ``lr``: ``lr + cp`` (ON),
    ``lr - cn`` (OFF), or ``step = 0.0`` for none (thresholds are > 0). Inlined into its callers.

    One loop serves both polarities: ``lr + step`` is ``lr + cp`` (ON) or ``lr - cn`` (OFF) to
    the bit, since a - b == a + (-b) in IEEE arithmetic.
    """
    if l1 >= lr + cp:
        return True, cp
    if l1 <= lr - cn:
        return False, -cn
    return False, 0.0


@njit(cache=True)
def _crossings(i0, i1, t0, t1, eps, lref, e_hi, e_lo, cpos, cneg, last_t, refractory_s,
               seq, jitter_s, jitter_seed, fill, cand, n_cand, out_pix, out_t_true, out_t, out_p):
    """Events of the candidate pixels ``cand[:n_cand]`` (see :func:`_convert`); returns ``(n_events, n_moved)``.

    With ``fill`` False nothing is written (count pass); with ``fill`` True
    the events are written and the pixel state is updated.
    """
    n = 0
    n_moved = 0
    span = t1 - t0
    for j in range(n_cand):
        i = cand[j]
        a = i1[i] + eps
        l1 = math.log(a)
        l0 = math.log(i0[i] + eps)
        lr = lref[i]
        cp = cpos[i]
        cn = cneg[i]
        last = last_t[i]
        k = seq[i]
        on, step = _first_step(l1, lr, cp, cn)
        if step == 0.0:
            continue  # no crossing: reference level unchanged
        while (l1 >= lr + step) if on else (l1 <= lr + step):
            lr += step
            tc = t0 + (lr - l0) / (l1 - l0) * span
            if tc - last >= refractory_s:
                if fill:
                    out_pix[n] = i
                    out_t_true[n] = tc
                    out_t[n] = tc + jitter_s * _half_normal(jitter_seed, i, k) if jitter_s > 0 else tc
                    out_p[n] = on
                n += 1
                k += 1
                last = tc
        # the loop ran at least once (its first test is the branch test above)
        n_moved += 1
        if fill:
            lref[i] = lr
            e_hi[i] = math.exp(lr + cp)
            e_lo[i] = math.exp(lr - cn)
            last_t[i] = last
            seq[i] = k
    return n, n_moved


@njit(cache=True)
def _convert(i0, i1, t0, t1, eps, lref, e_hi, e_lo, cpos, cneg, last_t, refractory_s,
             seq, jitter_s, jitter_seed, fill, cand, n_cand, out_pix, out_t_true, out_t, out_p):
    """Events of every pixel between samples ``(t0, i0)`` and ``(t1, i1)`` (linear intensity).

    The log intensity ``L = log(I + eps)`` is interpolated linearly in time
    between the samples; each crossing of ``lref + cpos`` (ON) or
    ``lref - cneg`` (OFF) is an event at the interpolated crossing time, and
    moves ``lref`` by one threshold (several crossings per interval allowed).
    A crossing less than ``refractory_s`` after the pixel's last emitted event
    is dropped (``lref`` still moves). The emitted time adds a half-normal
    latency ``jitter_s |N(0, 1)|`` hashed from (pixel, per-pixel event count).

    ``e_hi = exp(lref + cpos)`` and ``e_lo = exp(lref - cneg)`` let most pixels
    be skipped without a logarithm. With ``fill`` False nothing is written or
    mutated except the scratch ``cand``, which receives the indices of the
    pixels passing the pre-test; the fill pass (``fill`` True) then visits only
    ``cand[:n_cand]`` (two-pass sizing: count, then fill).

    Returns ``(n_events, n_moved, n_cand, max_dl)``: the events emitted, the
    pixels whose reference level moved (non-zero ``n_moved`` with
    ``n_events == 0`` when all crossings fell in refractory periods: the fill
    pass must still run), the candidates written to ``cand`` and the largest
    ``|Delta L|`` over the image (the last two from the count pass only; the
    sampler uses ``max_dl`` to accept or reject the step, as
    :func:`_max_log_change`).
    """
    if fill:
        n, n_moved = _crossings(i0, i1, t0, t1, eps, lref, e_hi, e_lo, cpos, cneg, last_t, refractory_s, seq,
                                jitter_s, jitter_seed, True, cand, n_cand, out_pix, out_t_true, out_t, out_p)
        return n, n_moved, 0, 0.0
    spans = np.empty(2, dtype=np.int64)
    spans[0] = 0
    spans[1] = i0.shape[0]
    m, max_dl = _scan(i0, i1, eps, e_hi, e_lo, spans, 1, cand)
    n, n_moved = _crossings(i0, i1, t0, t1, eps, lref, e_hi, e_lo, cpos, cneg, last_t, refractory_s, seq,
                            jitter_s, jitter_seed, False, cand, m, out_pix, out_t_true, out_t, out_p)
    return n, n_moved, m, max_dl


@njit(cache=True)
def _noise(t1, rate_hz, time_seed, pol_seed, next_t, count, fill, out_pix, out_t, out_p):
    """Background-activity events before ``t1``: a Poisson process per pixel.

    Arrival ``k`` of pixel ``i`` is ``sum_{j <= k} E_j`` with exponential gaps
    ``E_j = -log(u(time_seed, i, j)) / rate_hz``; its polarity is ON when
    ``u(pol_seed, i, k) < 0.5``. ``next_t[i]`` holds arrival ``count[i]``.
    """
    n = 0
    for i in range(next_t.shape[0]):
        tn = next_t[i]
        k = count[i]
        while tn < t1:
            if fill:
                out_pix[n] = i
                out_t[n] = tn
                out_p[n] = _hash_uniform(pol_seed, i, k) < 0.5
            n += 1
            k += 1
            tn += -math.log(_hash_uniform(time_seed, i, k)) / rate_hz
        if fill:
            next_t[i] = tn
            count[i] = k
    return n


@njit(cache=True)
def _noise_first_arrivals(rate_hz, time_seed, out):
    for i in range(out.shape[0]):
        out[i] = -math.log(_hash_uniform(time_seed, i, 0)) / rate_hz


@njit(cache=True)
def _scan_frame(i0, i1, eps, e_hi, e_lo, cand):
    """:func:`_scan` over a whole frame that also counts non-finite values of ``i1``.

    Frames input is checked here, in the pass that reads every pixel anyway,
    instead of by a separate reduction per frame. Returns ``(n_cand, n_bad)``.
    """
    m = 0
    bad = 0
    for i in range(i1.shape[0]):
        v = i1[i]
        if v == i0[i]:
            continue
        if not math.isfinite(v):
            bad += 1
            continue
        a = v + eps
        if e_lo[i] * (1.0 + 1e-12) < a < e_hi[i] * (1.0 - 1e-12):
            continue
        cand[m] = i
        m += 1
    return m, bad




@njit(cache=True)
def _grow(pix, t_true, t_emit, pol, need):
    """The event buffers of :func:`_frames_batch` with room for at least ``need`` events (contents kept)."""
    m = max(need, 2 * pix.shape[0])
    a = np.empty(m, dtype=np.int64)
    b = np.empty(m)
    c = np.empty(m)
    d = np.empty(m, dtype=np.bool_)
    a[:pix.shape[0]] = pix
    b[:pix.shape[0]] = t_true
    c[:pix.shape[0]] = t_emit
    d[:pix.shape[0]] = pol
    return a, b, c, d


@njit(cache=True)
def _frames_batch(frames, n_frames, times, i_prev, t_prev, eps, lref, e_hi, e_lo, cpos, cneg, last_t,
                  refractory_s, seq, jitter_s, jitter_seed, bad, cand, out_pix, out_t_true, out_t, out_p):
    """Events of a batch of frames in one call: :func:`_scan_frame` and :func:`_crossings` per frame.

    ``frames`` holds ``n_frames`` flat images one after the other (frame
    ``k`` at ``frames[k * npix:(k + 1) * npix]``, sample time ``times[k]``);
    the batch follows the sample ``(t_prev, i_prev)``. Per frame the pixels
    get :func:`_scan_frame`'s test (inlined) and the candidates
    :func:`_crossings` (count, then fill): the arithmetic of the
    frame-by-frame path, so the same events, in the same order. Non-finite
    values of frame ``k`` (among the pixels that changed) are counted in
    ``bad[k]``; the caller raises on the first such frame. ``cand`` is
    scratch (``npix`` int64).

    The pre-test stays a plain branch per pixel: measured on this project's
    frames (3 % of the pixels change per 5 kHz frame), vectorised versions
    (a chunk's pixels all unchanged? by float or bit comparison) and pixel
    tiles through the batch were 1.2-3x slower on the development machine.

    The event buffers grow inside as needed. Returns ``(n_events, out_pix,
    out_t_true, out_t, out_p)``.
    """
    npix = i_prev.shape[0]
    n = 0
    for f in range(n_frames):
        base = f * npix
        i1 = frames[base:base + npix]
        i0 = i_prev if f == 0 else frames[base - npix:base]
        m = 0
        for i in range(npix):  # _scan_frame's test
            v = i1[i]
            if v == i0[i]:
                continue  # unchanged pixel (most of them)
            if not math.isfinite(v):
                bad[f] += 1
                continue
            a = v + eps
            if e_lo[i] * (1.0 + 1e-12) < a < e_hi[i] * (1.0 - 1e-12):
                continue
            cand[m] = i
            m += 1
        if bad[f]:
            break  # the caller raises: no events of this frame or later ones
        if m == 0:
            continue
        t0 = t_prev if f == 0 else times[f - 1]
        k, moved = _crossings(i0, i1, t0, times[f], eps, lref, e_hi, e_lo, cpos, cneg, last_t, refractory_s,
                              seq, jitter_s, jitter_seed, False, cand, m, out_pix, out_t_true, out_t, out_p)
        if moved == 0:
            continue
        if n + k > out_pix.shape[0]:
            out_pix, out_t_true, out_t, out_p = _grow(out_pix[:n], out_t_true[:n], out_t[:n], out_p[:n], n + k)
        _crossings(i0, i1, t0, times[f], eps, lref, e_hi, e_lo, cpos, cneg, last_t, refractory_s, seq,
                   jitter_s, jitter_seed, True, cand, m, out_pix[n:], out_t_true[n:], out_t[n:], out_p[n:])
        n += k
    return n, out_pix, out_t_true, out_t, out_p


@njit(cache=True)
def _log_interval(l0, l1, a_prev, alphas, t_prev, times, n_samples, lref, e_hi, e_lo, cpos, cneg, last_t,
                  refractory_s, seq, jitter_s, jitter_seed, cand, out_pix, out_t_true, out_t, out_p):
    """Events of samples interpolated in log intensity inside one frame interval, without building them.

    ``l0`` and ``l1`` are the log frames ``L = log(I + eps)`` at the ends of
    the interval; the sample at fraction ``a`` of it is
    ``L_a = (1 - a) * l0 + a * l1`` (``l0`` itself at ``a = 0``, ``l1`` at
    ``a = 1``), the expression :class:`~evedge.sim.frames.FramesRenderer`
    evaluates in numpy, evaluated here per pixel. The batch starts at the
    sample ``(t_prev, a_prev)`` and has ``n_samples`` more, at ``times`` and
    fractions ``alphas``.

    The pixels with ``l0 != l1`` are the only ones that change; each is
    followed through all the samples at once (the output is ordered later,
    by time and pixel), with :func:`_crossings`' decision and crossing
    instant on ``L`` directly. The frame-by-frame path takes
    ``log(exp(L_a) - eps + eps)`` instead, which may differ from ``L_a`` in
    its last bits: the events are the same up to crossings within an ulp of
    a level, and their times agree to about 1e-15 s (tested).

    Returns ``(n_events, out_pix, out_t_true, out_t, out_p)`` (the buffers
    grow as needed), or ``n_events = -1`` with nothing changed when a
    changing pixel of ``l0`` or ``l1`` is not finite (the caller then takes
    the frame-by-frame path, which names the sample).
    """
    m = 0
    for i in range(l0.shape[0]):
        if l0[i] == l1[i]:
            continue  # unchanged over the whole interval (most pixels)
        if not (math.isfinite(l0[i]) and math.isfinite(l1[i])):
            return -1, out_pix, out_t_true, out_t, out_p
        cand[m] = i
        m += 1
    n = 0
    for c in range(m):
        i = cand[c]
        x0 = l0[i]
        x1 = l1[i]
        lr = lref[i]
        cp = cpos[i]
        cn = cneg[i]
        last = last_t[i]
        k = seq[i]
        moved = False
        lb = x0 if a_prev == 0.0 else (1.0 - a_prev) * x0 + a_prev * x1
        tb = t_prev
        for s in range(n_samples):
            la = lb
            ta = tb
            a = alphas[s]
            lb = x1 if a == 1.0 else (1.0 - a) * x0 + a * x1
            tb = times[s]
            on, step = _first_step(lb, lr, cp, cn)
            if step == 0.0:
                continue
            moved = True
            span = tb - ta
            while (lb >= lr + step) if on else (lb <= lr + step):
                lr += step
                tc = ta + (lr - la) / (lb - la) * span
                if tc - last >= refractory_s:
                    if n == out_pix.shape[0]:
                        out_pix, out_t_true, out_t, out_p = _grow(out_pix, out_t_true, out_t, out_p, n + 1)
                    out_pix[n] = i
                    out_t_true[n] = tc
                    out_t[n] = tc + jitter_s * _half_normal(jitter_seed, i, k) if jitter_s > 0 else tc
                    out_p[n] = on
                    n += 1
                    k += 1
                    last = tc
        if moved:
            lref[i] = lr
            e_hi[i] = math.exp(lr + cp)
            e_lo[i] = math.exp(lr - cn)
            last_t[i] = last
            seq[i] = k
    return n, out_pix, out_t_true, out_t, out_p
