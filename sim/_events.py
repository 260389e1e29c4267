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
    n = 0
    n_moved = 0
    m = 0
    ratio = 1.0
    span = t1 - t0
    for j in range(n_cand if fill else i0.shape[0]):
        i = cand[j] if fill else j
        if not fill and i1[i] == i0[i]:
            # unchanged pixel: it was inside its thresholds at i0, so it still is (most pixels)
            continue
        a = i1[i] + eps
        if not fill:
            ratio = _widen_ratio(ratio, a, i0[i] + eps)
        # conservative pre-test; the decision itself is made on logarithms below
        if e_lo[i] * (1.0 + 1e-12) < a < e_hi[i] * (1.0 - 1e-12):
            continue
        if not fill:
            cand[m] = i
            m += 1
        l1 = math.log(a)
        l0 = math.log(i0[i] + eps)
        lr = lref[i]
        cp = cpos[i]
        cn = cneg[i]
        last = last_t[i]
        k = seq[i]
        # one loop for both polarities: ``lr + step`` is ``lr + cp`` (ON) or
        # ``lr - cn`` (OFF) to the bit, since a - b == a + (-b) in IEEE arithmetic
        if l1 >= lr + cp:
            on = True
            step = cp
        elif l1 <= lr - cn:
            on = False
            step = -cn
        else:
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
    return n, n_moved, m, math.log(ratio)


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
