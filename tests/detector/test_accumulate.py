"""Tests of the accumulation baselines (evedge.detector.accumulate)."""

from __future__ import annotations

import numpy as np
import pytest

from evedge.detector.accumulate import (
    CountWindowAccumulator,
    TimeWindowAccumulator,
    accumulate_count,
    accumulate_time,
)
from evedge.events import SensorSize, make_events, sort_events

SENSOR = SensorSize(7, 5)


def random_events(rng, n, t_max=10_000):
    ev = make_events(
        rng.integers(0, SENSOR.width, n),
        rng.integers(0, SENSOR.height, n),
        rng.integers(0, t_max, n),
        rng.integers(0, 2, n),
    )
    return sort_events(ev)


def brute_time(events, times, window):
    out = np.zeros((len(times), *SENSOR.shape), dtype=bool)
    for k, T in enumerate(times):
        for e in events:
            if T - window < e["t"] <= T:
                out[k, e["y"], e["x"]] = True
    return out


def brute_count(events, times, n):
    out = np.zeros((len(times), *SENSOR.shape), dtype=bool)
    for k, T in enumerate(times):
        before = [e for e in events if e["t"] <= T]
        for e in before[max(0, len(before) - n) :]:
            out[k, e["y"], e["x"]] = True
    return out


def query_times(rng, events):
    # Before, on, between and after event times, with repeats.
    t = events["t"]
    times = np.concatenate([[t[0] - 5, t[0], t[-1], t[-1] + 3000], rng.choice(t, 6), rng.integers(t[0], t[-1], 6)])
    return np.sort(np.concatenate([times, times[:3]]))


@pytest.mark.parametrize(
    "accumulate, brute, size",
    [(accumulate_time, brute_time, w) for w in (1, 37, 1000, 30_000)]
    + [(accumulate_count, brute_count, n) for n in (1, 5, 40, 1000)],
    ids=[f"time_window_us={w}" for w in (1, 37, 1000, 30_000)] + [f"count_n_events={n}" for n in (1, 5, 40, 1000)],
)
def test_matches_brute_force(accumulate, brute, size):
    rng = np.random.default_rng(size)
    ev = random_events(rng, 300)
    times = query_times(rng, ev)
    got = accumulate(ev, SENSOR, times, size)
    assert got.shape == (times.size, SENSOR.height, SENSOR.width) and got.dtype == bool
    np.testing.assert_array_equal(got, brute(ev, times, size))


def test_interval_conventions():
    ev = make_events([1, 2, 3], [0, 0, 0], [100, 200, 300], [1, 0, 1])
    img = accumulate_time(ev, SENSOR, [300], 200)[0]
    # (100, 300]: the event at 100 is out, 200 and 300 (either polarity) are in.
    assert (img[0, 1], img[0, 2], img[0, 3]) == (False, True, True)
    assert img.sum() == 2
    assert not accumulate_time(ev, SENSOR, [99], 1000).any()
    cnt = accumulate_count(ev, SENSOR, [250, 250, 1000], 2)
    assert cnt[0].sum() == 2 and cnt[0][0, 1] and cnt[0][0, 2]
    assert cnt[2][0, 2] and cnt[2][0, 3] and not cnt[2][0, 1]
    stream = TimeWindowAccumulator(SENSOR, 200)
    stream.process(ev)
    np.testing.assert_array_equal(stream.image_at(300), img)
    assert stream.image_at(400).sum() == 1  # (200, 400]: only the event at 300 is left
    # Ties: the later event in the array counts as later.
    tie = make_events([4, 5], [1, 1], [500, 500], [1, 1])
    assert accumulate_count(tie, SENSOR, [500], 1)[0][1, 5]
    assert not accumulate_count(tie, SENSOR, [500], 1)[0][1, 4]


def test_empty_inputs():
    ev = make_events([], [], [], [])
    assert accumulate_time(ev, SENSOR, [0, 10], 5).shape == (2, 5, 7)
    assert not accumulate_count(ev, SENSOR, [0], 3).any()
    assert accumulate_time(random_events(np.random.default_rng(0), 10), SENSOR, [], 5).shape == (0, 5, 7)


@pytest.mark.parametrize(
    "call, exc, word",
    [
        (lambda ev: accumulate_time(ev, SENSOR, [1], 0), ValueError, "window_us"),
        (lambda ev: accumulate_time(ev, SENSOR, [1], -5), ValueError, "window_us"),
        (lambda ev: accumulate_time(ev, SENSOR, [1], 2.5), TypeError, "window_us"),
        (lambda ev: accumulate_count(ev, SENSOR, [1], 0), ValueError, "n_events"),
        (lambda ev: accumulate_count(ev, SENSOR, [1], True), TypeError, "n_events"),
        (lambda ev: accumulate_time(ev, SENSOR, [5, 3], 10), ValueError, "times_us"),
        (lambda ev: accumulate_time(ev, SENSOR, [[5]], 10), ValueError, "times_us"),
        (lambda ev: accumulate_time(ev, SENSOR, [1.5], 10), TypeError, "times_us"),
        (lambda ev: accumulate_time(ev, (7, 5), [1], 10), TypeError, "sensor_size"),
        (lambda ev: accumulate_time(ev[::-1], SENSOR, [1], 10), ValueError, "not sorted"),
        (lambda ev: accumulate_count(ev, SensorSize(3, 3), [1], 10), ValueError, "outside the sensor"),
        (lambda ev: accumulate_count(np.zeros(3), SENSOR, [1], 10), TypeError, "events"),
        (lambda ev: TimeWindowAccumulator(SENSOR, 0), ValueError, "window_us"),
        (lambda ev: CountWindowAccumulator(SENSOR, -1), ValueError, "n_events"),
    ],
)
def test_validation(call, exc, word):
    ev = random_events(np.random.default_rng(1), 20)
    with pytest.raises(exc, match=word):
        call(ev)


def _stream(acc, ev, times, rng):
    """Feed events up to each query time (cut at random inside), then query."""
    images, start = [], 0
    for T in times:
        stop = int(np.searchsorted(ev["t"], T, side="right"))
        part = ev[start:stop]
        cuts = np.sort(rng.integers(0, part.size + 1, 2))
        for chunk in np.split(part, cuts):
            acc.process(chunk)
        start = stop
        images.append(acc.image_at(int(T)))
    return np.stack(images)


def test_streaming_equals_one_shot():
    rng = np.random.default_rng(4)
    ev = random_events(rng, 400)
    times = query_times(rng, ev)
    tw = TimeWindowAccumulator(SENSOR, 700)
    np.testing.assert_array_equal(_stream(tw, ev, times, rng), accumulate_time(ev, SENSOR, times, 700))
    cw = CountWindowAccumulator(SENSOR, 25)
    np.testing.assert_array_equal(_stream(cw, ev, times, rng), accumulate_count(ev, SENSOR, times, 25))
    for acc in (tw, cw):
        acc.reset()
        assert not acc.image_at(int(times[0])).any()


def test_streaming_order_checks():
    ev = make_events([1, 2], [1, 1], [100, 200], [1, 1])
    for acc in (TimeWindowAccumulator(SENSOR, 50), CountWindowAccumulator(SENSOR, 3)):
        acc.process(ev)
        with pytest.raises(ValueError, match="t_us"):
            acc.image_at(150)
        with pytest.raises(ValueError, match="time-ordered"):
            acc.process(make_events([3], [1], [150], [1]))
        with pytest.raises(TypeError, match="t_us"):
            acc.image_at(250.0)
        assert acc.image_at(200)[1, 2]
