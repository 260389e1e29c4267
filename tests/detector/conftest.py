"""Fixtures of the detector tests: synthetic event generators and the real-data path."""

from pathlib import Path

import numpy as np
import pytest

from evedge.events import make_events

REALDATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "realdata"


def _edge_events(width, height, speed_px_s, angle_rad, *, n_edges=1, spacing_px=16.0, jitter_frac=0.0,
                 subpixel_px=0.0, rng=None, t0_us=1000, polarity=True):
    """Straight parallel edges moving along (cos a, sin a) at ``speed_px_s``.

    Each pixel fires one event per edge when the edge crosses its centre (plus
    optional sub-pixel position error and Gaussian time jitter, both in units of
    the lifetime). Returns ``(events, lifetime_us)``.
    """
    rng = np.random.default_rng(rng)
    ys, xs = np.mgrid[0:height, 0:width]
    s = (xs * np.cos(angle_rad) + ys * np.sin(angle_rad)).ravel()
    s = s - s.min()
    lifetime = 1e6 / speed_px_s
    ts = []
    for k in range(n_edges):
        pos = s + k * spacing_px + (rng.uniform(-subpixel_px, subpixel_px, s.size) if subpixel_px else 0.0)
        ts.append(pos * lifetime + (rng.normal(0.0, jitter_frac * lifetime, s.size) if jitter_frac else 0.0))
    t = np.concatenate(ts)
    t = np.rint(t - t.min()).astype(np.int64) + t0_us
    x = np.tile(xs.ravel(), n_edges)
    y = np.tile(ys.ravel(), n_edges)
    order = np.argsort(t, kind="stable")
    return make_events(x[order], y[order], t[order], np.full(t.size, polarity)), lifetime


def _random_events(n, width, height, *, duration_us=50_000, rng=None):
    """Uniform random events (both polarities), time-sorted, with some equal timestamps."""
    rng = np.random.default_rng(rng)
    t = np.sort(rng.integers(0, duration_us, n))
    return make_events(rng.integers(0, width, n), rng.integers(0, height, n), t, rng.random(n) < 0.5)


@pytest.fixture
def edge_events():
    return _edge_events


@pytest.fixture
def random_events():
    return _random_events


@pytest.fixture
def stripes_events():
    path = REALDATA / "rpg_event_lifetime" / "stripes.mat"
    if not path.exists():
        pytest.skip(f"real recording absent: {path}")
    from scipy.io import loadmat

    e = loadmat(str(path))["events"]
    return make_events(e[:, 0], e[:, 1], e[:, 3], e[:, 2])
