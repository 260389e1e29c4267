"""Speed regions without an estimator: neighbour delays vs a slow reference, 2-means, bands."""

import numpy as np
import pytest

from evedge.bench.regions import (NoRegionsError, longest_run, neighbour_delays, regions_from_delays, regions_from_truth,
                                  row_agreement, two_means_1d)
from evedge.events import SensorSize, make_events


def _reference_delays(events, width):
    """Slow reference: per event, scan all earlier-or-equal events of its polarity at x-1 / x+1."""
    out = np.full(events.size, np.nan)
    for i, e in enumerate(events):
        best = np.inf
        for j in range(events.size):
            o = events[j]
            if o["t"] > e["t"]:
                break
            if o["y"] == e["y"] and o["p"] == e["p"] and abs(int(o["x"]) - int(e["x"])) == 1:
                best = min(best, int(e["t"]) - int(o["t"]))
        if np.isfinite(best):
            out[i] = best
    return out


def test_neighbour_delays_match_the_slow_reference():
    rng = np.random.default_rng(3)
    n, w, h = 400, 7, 3
    t = np.sort(rng.integers(0, 5000, n))
    ev = make_events(rng.integers(0, w, n), rng.integers(0, h, n), t, rng.random(n) < 0.5)
    got = neighbour_delays(ev, SensorSize(w, h))
    ref = _reference_delays(ev, w)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(ref))
    np.testing.assert_array_equal(got[~np.isnan(got)], ref[~np.isnan(ref)])


def test_neighbour_delays_of_a_moving_edge_are_its_lifetime():
    # an edge at 200 px/s along +x: pixel x fires at 5000 x us -> delay 5000 us after the first column
    x = np.arange(10)
    ev = make_events(x, np.zeros(10, int), 5000 * x, np.ones(10, bool))
    d = neighbour_delays(ev, SensorSize(10, 1))
    assert np.isnan(d[0]) and np.all(d[1:] == 5000)
    with pytest.raises(ValueError):
        neighbour_delays(make_events([20], [0], [0], [True]), SensorSize(10, 1))


def test_two_means_and_longest_run_known_answers():
    thr, upper = two_means_1d([5.0, 1.0, 1.1, 5.1, 1.2])
    assert thr == pytest.approx(3.1)
    assert upper.tolist() == [True, False, False, True, False]
    with pytest.raises(ValueError, match="equal"):
        two_means_1d([2.0, 2.0, 2.0])
    with pytest.raises(ValueError, match="at least 2"):
        two_means_1d([1.0])
    assert longest_run([3, 5, 6, 7, 9]).tolist() == [5, 6, 7]
    assert longest_run([]).size == 0


def test_regions_of_the_two_band_recording(two_bands):
    found = regions_from_delays(two_bands.events, two_bands.sensor_size)
    # the fixture's bands: rows 0-7 at 100 px/s, rows 8-15 at 250 px/s
    assert found["rows"] == {"slow": list(range(8)), "fast": list(range(8, 16))}
    assert found["median_delay_us"]["slow"] == pytest.approx(10_000, rel=0.01)
    assert found["median_delay_us"]["fast"] == pytest.approx(4_000, rel=0.01)
    known = regions_from_truth(two_bands.events, two_bands.truth["lifetime_us"], two_bands.sensor_size)
    assert known["rows"] == found["rows"]
    assert known["truth_lifetime_us"] == {"slow": 10_000.0, "fast": 4_000.0}
    assert row_agreement(known, found) == 1.0
    swapped = {"rows": {"slow": found["rows"]["fast"], "fast": found["rows"]["slow"]}}
    assert row_agreement(known, swapped) == 0.0


def test_sparse_rows_are_left_out(two_bands):
    # a few stray events in an extra row 16 (sensor 17 rows high): too few to be part of a band
    ev = two_bands.events
    extra = make_events([1, 2, 3], [16, 16, 16], [10, 20, 30], [True, True, True])
    allev = np.sort(np.concatenate([ev, extra]), order="t", kind="stable")
    found = regions_from_delays(allev, SensorSize(48, 17))
    assert 16 not in found["rows"]["slow"] + found["rows"]["fast"]
    assert found["row_median_delay_us"][16] == pytest.approx(10.0)


def test_no_bands_no_regions(moving_edge, two_bands):
    # one edge over all rows (its speed changes in time, not by row): the rows do not form bands
    with pytest.raises(NoRegionsError, match="equal"):
        regions_from_delays(moving_edge.events, moving_edge.sensor_size)
    # bands 10 ms vs 4 ms differ by 2.5x: not distinct when asking for 3x
    with pytest.raises(NoRegionsError, match="no distinct speed bands"):
        regions_from_delays(two_bands.events, two_bands.sensor_size, min_ratio=3.0)
    with pytest.raises(NoRegionsError, match="equal"):
        regions_from_truth(moving_edge.events, moving_edge.truth["lifetime_us"], moving_edge.sensor_size)


def test_only_a_data_finding_means_no_regions(moving_edge, two_bands):
    """Regression: the lifetime experiment took any ValueError (a wrong truth length, a bad argument) for
    'no speed bands' and silently switched the lifetime verdict to its fallback measure."""
    from evedge.bench.exp_lifetime import _regions

    assert _regions(moving_edge, moving_edge.truth["lifetime_us"]) is None  # no bands: a finding
    assert set(_regions(two_bands, two_bands.truth["lifetime_us"])["rows"]) == {"slow", "fast"}
    with pytest.raises(ValueError, match="differ") as info:  # a bug: surfaces
        _regions(two_bands, two_bands.truth["lifetime_us"][:-1])
    assert not isinstance(info.value, NoRegionsError)
    with pytest.raises(ValueError, match="min_row_share") as info:
        regions_from_delays(two_bands.events, two_bands.sensor_size, min_row_share=2.0)
    assert not isinstance(info.value, NoRegionsError)


def test_core_regions_drop_the_band_ends():
    from evedge.bench.exp_lifetime import core_regions

    reg = {"method": "m", "rows": {"slow": list(range(0, 20)), "fast": list(range(20, 25))}}
    core = core_regions(reg, margin=4)
    assert core["rows"]["slow"] == list(range(4, 16))
    assert core["rows"]["fast"] == [22]  # too thin for the margin: its middle row
    assert "without 4 rows" in core["method"]
