"""The stripes recording (Mueggler et al. 2015, DVS128): share with estimate and the two speed peaks.

Measured with the defaults (2026-11-23, burst grouping on): the buffer keeps
93.2 % of the 340,394 events; 96.0 % of the kept events get a lifetime; the
median lifetime is 6.9 ms in the lower half of the image (y >= 64) and 12.1 ms
in rows 32-63; the flow is horizontal. A model-free check agrees within 5 %:
the delay between the first events of neighbouring pixels' bursts has its mode
at 6.6 ms (rows 64-127) and 11.6 ms (rows 32-63).
"""

import numpy as np

from evedge.detector import detect
from evedge.events import SensorSize

SIZE = SensorSize(128, 128)




def test_stripes_lifetimes(stripes_events):
    ev = stripes_events
    res = detect(ev, SIZE)
    lt, kept = res.lifetimes, res.kept
    v = lt["valid"]
    assert 0.90 < kept.mean() < 0.96
    assert v[kept].mean() > 0.93
    tau = lt["lifetime_us"]
    # two speed regions: the lower half moves about twice as fast as rows 32-63
    fast = np.median(tau[v & (ev["y"] >= 64)])
    slow = np.median(tau[v & (ev["y"] >= 32) & (ev["y"] < 64)])
    assert 4_500 < fast < 7_000
    assert 8_500 < slow < 12_500
    # ... which the histogram of all lifetimes shows as two peaks
    h, edges = np.histogram(np.log10(tau[v]), bins=40, range=(2.5, 4.5))
    centres = 10 ** ((edges[:-1] + edges[1:]) / 2)
    i1 = np.argmax(np.where((centres > 4_500) & (centres < 7_000), h, 0))
    i2 = np.argmax(np.where((centres > 8_500) & (centres < 12_500), h, 0))
    dip = h[i1:i2 + 1].min()
    assert h[i1] == h.max()
    assert dip < 0.95 * h[i2] and h[i2] > 0.4 * h[i1]
    # horizontal motion: flow within 30 degrees of the x axis for most estimates
    ang = np.degrees(np.arctan2(np.abs(lt["vy_px_s"][v]), np.abs(lt["vx_px_s"][v])))
    assert np.mean(ang < 30) > 0.75


def _neighbour_delay_mode(ev, rows, quiet_us=3_000):
    """Mode of the delay between the first events of neighbouring pixels' bursts (0.25 ms bins).

    An edge passing a pixel fires a burst of events (same-pixel gaps of 1-2.5 ms
    on this recording). The first event of a burst (the pixel was quiet for
    more than ``quiet_us`` in that polarity) marks the same phase of the edge
    at every pixel, so the delay from the right-hand neighbour's first event to
    this pixel's first event is the time the edge takes to move one pixel:
    a model-free lifetime. (Comparing an event with the neighbour's *newest*
    event mixes phases of the burst and comes out short.)
    """
    x, y, t, p = (ev[k].astype(np.int64) for k in ("x", "y", "t", "p"))
    last = np.full((2, 128, 128), np.iinfo(np.int64).min // 2, np.int64)
    first_of_burst = np.full((2, 128, 128), np.iinfo(np.int64).min // 2, np.int64)
    d = []
    for i in range(ev.size):
        quiet = t[i] - last[p[i], y[i], x[i]] > quiet_us
        last[p[i], y[i], x[i]] = t[i]
        if not quiet:
            continue
        if rows[0] <= y[i] < rows[1] and x[i] + 1 < 128:
            d.append(t[i] - first_of_burst[p[i], y[i], x[i] + 1])
        first_of_burst[p[i], y[i], x[i]] = t[i]
    h, edges = np.histogram(np.array(d), bins=158, range=(500, 40_000))
    return (edges[np.argmax(h)] + edges[np.argmax(h) + 1]) / 2


def test_stripes_lifetimes_match_neighbour_delays(stripes_events):
    ev = stripes_events
    lt = detect(ev, SIZE).lifetimes
    v = lt["valid"]
    for rows in ((32, 64), (64, 128)):
        sel = v & (ev["y"] >= rows[0]) & (ev["y"] < rows[1])
        median = np.median(lt["lifetime_us"][sel])
        mode = _neighbour_delay_mode(ev, rows)
        assert abs(median / mode - 1) < 0.1, (rows, median, mode)
