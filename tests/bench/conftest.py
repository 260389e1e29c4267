"""Shared fixtures for the bench tests: a tiny analytic recording with truth, frames and edges."""

from pathlib import Path

import numpy as np
import pytest

from evedge.events import Frames, Recording, SensorSize, make_events

REALDATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "realdata"

#: Piecewise speeds of the test edge: slow then fast.
SLOW_PX_S, FAST_PX_S, SWITCH_US, END_US = 100.0, 300.0, 200_000, 300_000
X0_PX = 4.0


def edge_x(t_us):
    """Sub-pixel position of the moving vertical edge at time t."""
    t = np.asarray(t_us, dtype=np.float64)
    slow = X0_PX + SLOW_PX_S * np.minimum(t, SWITCH_US) / 1e6
    return slow + FAST_PX_S * np.clip(t - SWITCH_US, 0, None) / 1e6


def make_moving_edge_recording(width=64, height=24, frame_step_us=10_000, seed=0):
    """A vertical edge moving right, slowly then fast; exact events, truth, frames, edges.

    Each pixel fires one ON event when the edge crosses its centre (x + 0.5);
    a few random noise events are added (is_signal False, NaN lifetime).
    """
    rng = np.random.default_rng(seed)
    xs, ys, ts, lts = [], [], [], []
    x_switch = edge_x(SWITCH_US)
    for x in range(width):
        c = x + 0.5
        if c < X0_PX:
            continue
        if c <= x_switch:
            t = (c - X0_PX) / SLOW_PX_S * 1e6
            lt = 1e6 / SLOW_PX_S
        else:
            t = SWITCH_US + (c - x_switch) / FAST_PX_S * 1e6
            lt = 1e6 / FAST_PX_S
        if t > END_US:
            break
        for y in range(height):
            xs.append(x)
            ys.append(y)
            ts.append(int(round(t)))
            lts.append(lt)
    n_noise = 30
    xs += list(rng.integers(0, width, n_noise))
    ys += list(rng.integers(0, height, n_noise))
    ts += list(rng.integers(0, END_US, n_noise))
    lts += [np.nan] * n_noise
    signal = np.r_[np.ones(len(xs) - n_noise, bool), np.zeros(n_noise, bool)]
    order = np.argsort(np.asarray(ts), kind="stable")
    events = make_events(np.asarray(xs)[order], np.asarray(ys)[order], np.asarray(ts)[order],
                         np.ones(len(xs), bool))
    truth = np.zeros(len(xs), dtype=[("lifetime_us", "f8"), ("vx_px_s", "f8"), ("vy_px_s", "f8"),
                                     ("is_signal", "?")])
    truth["lifetime_us"] = np.asarray(lts)[order]
    truth["vx_px_s"] = np.where(signal[order], 1e6 / truth["lifetime_us"], np.nan)
    truth["vy_px_s"] = np.where(signal[order], 0.0, np.nan)
    truth["is_signal"] = signal[order]
    ft = np.arange(0, END_US + 1, frame_step_us, dtype=np.int64)
    cols = np.arange(width) + 0.5
    frames = np.where(cols[None, None, :] < edge_x(ft)[:, None, None], 0.8, 0.2) * np.ones((1, height, 1))
    edges = np.zeros((ft.size, height, width), bool)
    for k, xe in enumerate(edge_x(ft)):
        col = int(np.floor(xe))
        if 0 <= col < width:
            edges[k, :, col] = True
    meta = {"sections": [{"name": "slow", "start_us": 0, "end_us": SWITCH_US},
                         {"name": "fast", "start_us": SWITCH_US, "end_us": END_US + 1}],
            "scene": "test_moving_edge"}
    return Recording(events, SensorSize(width, height), frames=Frames(ft, frames.astype(np.float32)),
                     truth=truth, edges=Frames(ft, edges), metadata=meta)


@pytest.fixture(scope="session")
def moving_edge():
    return make_moving_edge_recording()


@pytest.fixture(scope="session")
def realdata_dir():
    return REALDATA


#: Two bands of rows moving along +x at different speeds (a tiny stripes recording).
BAND_SPEEDS_PX_S = {"slow": 100.0, "fast": 250.0}
BAND_ROWS = {"slow": range(0, 8), "fast": range(8, 16)}


def make_two_band_recording(width=48, period_px=12, end_us=400_000):
    """Stripes of period ``period_px`` moving along +x: rows 0-7 at 100 px/s, rows 8-15 at 250 px/s.

    Each pixel fires one event each time a stripe boundary crosses its centre:
    ON at a dark-to-light boundary, OFF at the other (half a period later).
    Truth: lifetime 1/v (10 ms and 4 ms), ``is_signal`` True.
    """
    xs, ys, ts, ps, lts = [], [], [], [], []
    for band, rows in BAND_ROWS.items():
        v = BAND_SPEEDS_PX_S[band]
        for x in range(width):
            c = x + 0.5
            # boundaries at positions k * period/2 + v t; they cross c at t = (c - k * period / 2) / v
            for k in range(-int(v * end_us / 1e6 / (period_px / 2)) - 2, int(width / (period_px / 2)) + 2):
                t = (c - k * period_px / 2) / v * 1e6
                if 0 <= t <= end_us:
                    for y in rows:
                        xs.append(x)
                        ys.append(y)
                        ts.append(int(round(t)))
                        ps.append(k % 2 == 0)
                        lts.append(1e6 / v)
    order = np.lexsort((np.asarray(xs), np.asarray(ys), np.asarray(ts)))
    events = make_events(np.asarray(xs)[order], np.asarray(ys)[order], np.asarray(ts)[order],
                         np.asarray(ps)[order])
    truth = np.zeros(events.size, dtype=[("lifetime_us", "f8"), ("vx_px_s", "f8"), ("vy_px_s", "f8"),
                                         ("is_signal", "?")])
    truth["lifetime_us"] = np.asarray(lts)[order]
    truth["vx_px_s"] = 1e6 / truth["lifetime_us"]
    truth["is_signal"] = True
    return Recording(events, SensorSize(width, 16), truth=truth, metadata={"scene": "test_two_bands"})


@pytest.fixture(scope="session")
def two_bands():
    return make_two_band_recording()
