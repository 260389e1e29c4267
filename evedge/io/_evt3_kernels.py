"""numba kernels of the EVT 3.0 codec (plain 1-D arrays and scalars only; see prophesee.py)."""

from __future__ import annotations

import numpy as np
from numba import njit

# 4-bit word types of EVT 3.0 (Prophesee, "EVT 3.0 format")
ADDR_Y, ADDR_X, VECT_BASE_X, VECT_12, VECT_8, TIME_LOW, CONTINUED_4, TIME_HIGH = 0x0, 0x2, 0x3, 0x4, 0x5, 0x6, 0x7, 0x8
EXT_TRIGGER, OTHERS, CONTINUED_12 = 0xA, 0xE, 0xF


@njit(cache=True)
def evt3_max_events(words):
    """Upper bound of the CD events in ``words``: one per ADDR_X, one per set bit of a vector."""
    n = 0
    for w in words:
        kind = w >> 12
        if kind == ADDR_X:
            n += 1
        elif kind == VECT_12 or kind == VECT_8:
            bits = w & (0xFFF if kind == VECT_12 else 0xFF)
            while bits:
                n += bits & 1
                bits >>= 1
    return n


@njit(cache=True)
def evt3_decode(words, t_base, x_out, y_out, t_out, p_out):
    """Decode CD events; returns ``(n_events, n_triggers, n_other, bad_word_index or -1)``.

    A TIME_HIGH smaller than the previous one is a wrap of the 24-bit time
    (every 2**24 us = 16.78 s). Reserved word types stop decoding.
    """
    y = 0
    x_base = 0
    pol = 0
    t_high = 0
    t_low = 0
    wraps = 0
    have_high = False
    n = 0
    n_trig = 0
    n_other = 0
    for i in range(words.shape[0]):
        w = np.int64(words[i])
        kind = w >> 12
        if kind == ADDR_Y:
            y = w & 0x7FF
        elif kind == ADDR_X:
            x_out[n] = w & 0x7FF
            y_out[n] = y
            t_out[n] = t_base + (wraps << 24) + (t_high << 12) + t_low
            p_out[n] = (w >> 11) & 1
            n += 1
        elif kind == VECT_BASE_X:
            x_base = w & 0x7FF
            pol = (w >> 11) & 1
        elif kind == VECT_12 or kind == VECT_8:
            width = 12 if kind == VECT_12 else 8
            t = t_base + (wraps << 24) + (t_high << 12) + t_low
            for b in range(width):
                if (w >> b) & 1:
                    x_out[n] = x_base + b
                    y_out[n] = y
                    t_out[n] = t
                    p_out[n] = pol
                    n += 1
            x_base += width
        elif kind == TIME_LOW:
            t_low = w & 0xFFF
        elif kind == TIME_HIGH:
            new = w & 0xFFF
            if have_high and new < t_high:
                wraps += 1
            t_high = new
            have_high = True
        elif kind == EXT_TRIGGER:
            n_trig += 1
        elif kind == OTHERS or kind == CONTINUED_4 or kind == CONTINUED_12:
            n_other += 1
        else:
            return n, n_trig, n_other, i
    return n, n_trig, n_other, -1


@njit(cache=True)
def _evt3_words(x, y, t_rel, p, out, fill):
    """Count (``fill`` False) or write the words of the events; returns the word count.

    Between two TIME_HIGH words the 24-bit time moves by at most half a wrap
    (2048 x 4096 us), so a decoder sees every wrap, even over a long silence.
    """
    k = 0
    prev_high = np.int64(-1)
    prev_low = np.int64(-1)
    prev_y = np.int64(-1)
    for i in range(x.shape[0]):
        high = t_rel[i] >> 12
        low = t_rel[i] & 0xFFF
        new_time = False
        if high != prev_high:
            if prev_high >= 0:
                cur = prev_high
                while high - cur > 2048:
                    cur += 2048
                    if fill:
                        out[k] = (TIME_HIGH << 12) | (cur & 0xFFF)
                    k += 1
            if fill:
                out[k] = (TIME_HIGH << 12) | (high & 0xFFF)
            k += 1
            prev_high = high
            new_time = True
        if new_time or low != prev_low:
            if fill:
                out[k] = (TIME_LOW << 12) | low
            k += 1
            prev_low = low
        if y[i] != prev_y:
            if fill:
                out[k] = (ADDR_Y << 12) | y[i]
            k += 1
            prev_y = y[i]
        if fill:
            out[k] = (ADDR_X << 12) | (p[i] << 11) | x[i]
        k += 1
    return k


def evt3_encode(x, y, t_rel, p):
    """EVT 3.0 words (uint16) of events with ``0 <= t_rel``, coordinates < 2048, sorted by time."""
    dummy = np.empty(0, dtype=np.uint16)
    n = _evt3_words(x, y, t_rel, p, dummy, False)
    out = np.empty(n, dtype=np.uint16)
    _evt3_words(x, y, t_rel, p, out, True)
    return out
