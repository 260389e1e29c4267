"""Synthetic straight moving edges with exact lifetimes (no evedge.sim needed).

A family of parallel straight edges, ``spacing_px`` apart, moves along the unit
normal ``(cos angle, sin angle)`` at ``speed_px_s``. Pixel (x, y) fires one
event per edge, when the edge passes its centre, shifted by a sub-pixel
position error uniform in +-``subpixel_px`` and a Gaussian time jitter of
``jitter_frac`` lifetimes; a share ``outlier_frac`` of the events gets an extra
time offset uniform in +-5 lifetimes (scattered noise). With ``events_per_edge``
``n > 1`` a pixel fires a burst of ``n`` events per edge instead, the ``k``-th when
the edge is at ``(k + 0.5) / n - 0.5`` px from its centre (the edge sweeps the
pixel's area, as on a real sensor when the edge contrast spans several
thresholds), each with its own position error and jitter. The true lifetime of
every event is ``1e6 / speed_px_s`` us and its normal flow is
``speed * (cos angle, sin angle)`` px/s.
"""

from __future__ import annotations

import numpy as np

from evedge.events import make_events


def edge_events(width, height, speed_px_s, angle_rad, *, n_edges=3, spacing_px=16.0, jitter_frac=0.0,
                subpixel_px=0.0, outlier_frac=0.0, events_per_edge=1, rng=None, t0_us=1000):
    """Return ``(events, true_lifetime_us)`` sorted by time."""
    rng = np.random.default_rng(rng)
    ys, xs = np.mgrid[0:height, 0:width]
    d = np.array([np.cos(angle_rad), np.sin(angle_rad)])
    s = (xs * d[0] + ys * d[1]).ravel()
    s = s - s.min()
    lifetime = 1e6 / speed_px_s
    ts, xx, yy = [], [], []
    phases = [0.0] if events_per_edge == 1 else [(j + 0.5) / events_per_edge - 0.5 for j in range(events_per_edge)]
    for k, phase in ((k, ph) for k in range(n_edges) for ph in phases):
        pos = s + k * spacing_px + phase
        pos = pos + rng.uniform(-subpixel_px, subpixel_px, pos.size) if subpixel_px else pos
        t = pos * lifetime + rng.normal(0.0, jitter_frac * lifetime, pos.size)
        out = rng.random(pos.size) < outlier_frac
        t[out] += rng.uniform(-5 * lifetime, 5 * lifetime, int(out.sum()))
        ts.append(t)
        xx.append(xs.ravel())
        yy.append(ys.ravel())
    t = np.concatenate(ts)
    t = np.rint(t - t.min()).astype(np.int64) + t0_us
    order = np.argsort(t, kind="stable")
    x = np.concatenate(xx)[order]
    y = np.concatenate(yy)[order]
    ev = make_events(x, y, t[order], np.ones(t.size, bool))
    return ev, lifetime
