"""numba kernels of the sensor effects (v2e's pixel model [1]_): low-pass, leak, shot noise, resetting noise.

All work on log intensity ``L`` per pixel between two samples ``t0 < t1``.

References
----------
.. [1] Y. Hu, S.-C. Liu, T. Delbruck, "v2e: From video frames to realistic DVS
       events", CVPR Workshops 2021 (and its code, ``v2ecore/emulator.py``).
"""

from __future__ import annotations

import math

from numba import njit

from ._events import _first_step, _half_normal, _hash_uniform

#: v2e's floor of the intensity that sets the photoreceptor bandwidth: ``(255 I + 20) / 275``.
_V2E_INTENSITY_OFFSET = 20.0 / 255.0
#: v2e's ratio of the shot-noise rate at full intensity to the rate in the dark.
SHOT_NOISE_BRIGHT_FACTOR = 0.25


@njit(cache=True)
def _lowpass(l_lp, l_new, i_new, dt, cutoff_hz):
    """First-order photoreceptor low-pass, in place: ``L_lp += a (L_new - L_lp)``.

    ``a = 1 - exp(-2 pi f(I) dt)`` with the intensity-dependent cutoff
    ``f(I) = cutoff_hz (I + 20/255) / (1 + 20/255)`` (v2e: brighter pixels
    are faster; ``I`` clipped to [0, 1]): the exact step response of
    ``tau dL_lp/dt = L - L_lp``, ``tau = 1 / (2 pi f(I))``, for an input held
    at ``L_new`` over the step.
    """
    w = 2.0 * math.pi * cutoff_hz * dt / (1.0 + _V2E_INTENSITY_OFFSET)
    for i in range(l_lp.shape[0]):
        v = min(1.0, max(0.0, i_new[i]))
        a = 1.0 - math.exp(-w * (v + _V2E_INTENSITY_OFFSET))
        l_lp[i] += a * (l_new[i] - l_lp[i])


@njit(cache=True)
def _thin_shot(pix, t, pol, n, intensity, rate_seed, kind_ok):
    """Keep shot-noise candidates (drawn at the dark rate) with probability ``((0.25 - 1) I + 1)``.

    Thinning of a Poisson process: accepted candidates form one of rate
    ``R(I) = R_dark (1 - 0.75 I)`` (v2e's intensity dependence; ``I`` the
    pixel's linear intensity at the step's end, clipped to [0, 1]). Writes
    ``kind_ok``; returns the number kept.
    """
    m = 0
    for j in range(n):
        v = min(1.0, max(0.0, intensity[pix[j]]))
        keep = _hash_uniform(rate_seed, pix[j], int(t[j] * 1e9)) < (SHOT_NOISE_BRIGHT_FACTOR - 1.0) * v + 1.0
        kind_ok[j] = keep
        if keep:
            m += 1
    return m


@njit(cache=True)
def _sensor_interval(l0, l1, t0, t1, lref, cpos, cneg, last_t, refractory_s, seq, jitter_s, jitter_seed,
                     noise_pix, noise_t, noise_pol, n_noise, fill, out_pix, out_t_true, out_t, out_p, out_noise):
    """Events of every pixel between samples ``(t0, l0)`` and ``(t1, l1)`` (log intensities), noise included.

    ``L`` is interpolated linearly in time. The noise arrivals of the step
    (``noise_pix`` ascending, each pixel's times ascending) cut a pixel's
    interval into segments: the crossings of each segment are found as in
    :func:`~evedge.sim._events._crossings` (levels ``lref + cpos``,
    ``lref - cneg``, interpolated times, refractory, jitter), then the noise
    arrival at the segment's end is emitted when outside the refractory
    period, and then *resets* the pixel: ``lref = L(t_noise)``, the value the
    reset switch samples, and it starts a refractory period. An arrival
    inside the refractory period is dropped (a refractory pixel cannot fire).
    Returns the number of events. ``fill`` False: count only, nothing written.
    """
    n = 0
    q = 0
    span = t1 - t0
    for i in range(l0.shape[0]):
        a = l0[i]
        b = l1[i]
        lr = lref[i]
        last = last_t[i]
        k = seq[i]
        cp = cpos[i]
        cn = cneg[i]
        ta = t0
        la = a
        while True:
            noisy = q < n_noise and noise_pix[q] == i
            if noisy:
                tb = noise_t[q]
                lb = a + (b - a) * ((tb - t0) / span)
            else:
                tb = t1
                lb = b
            on, step = _first_step(lb, lr, cp, cn)
            if step != 0.0:
                while (lb >= lr + step) if on else (lb <= lr + step):
                    lr += step
                    tc = ta + (lr - la) / (lb - la) * (tb - ta)
                    if tc - last >= refractory_s:
                        if fill:
                            out_pix[n] = i
                            out_t_true[n] = tc
                            out_t[n] = tc + jitter_s * _half_normal(jitter_seed, i, k) if jitter_s > 0 else tc
                            out_p[n] = on
                            out_noise[n] = False
                        n += 1
                        k += 1
                        last = tc
            if not noisy:
                break
            if tb - last >= refractory_s:
                if fill:
                    out_pix[n] = i
                    out_t_true[n] = tb
                    out_t[n] = tb
                    out_p[n] = noise_pol[q]
                    out_noise[n] = True
                n += 1
                last = tb
                lr = lb  # the reset samples the present log intensity
            q += 1
            ta = tb
            la = lb
        if fill:
            lref[i] = lr
            last_t[i] = last
            seq[i] = k
    return n
