"""Accumulation baselines: edge images from a fixed time window or event count.

The simplest edge maps from events, which the paper compares against
(fixed windows of 1 ms and 30 ms, and a fixed number of events): a pixel is
"on" at time ``T`` when at least one event (of either polarity) fell on it in
the accumulation set.

Interval conventions
--------------------
- Time window: events with ``T - window_us < t <= T`` (half-open, the end
  ``T`` included), so consecutive windows tile the time axis without overlap.
- Event count: the last ``n_events`` events with ``t <= T`` (fewer when the
  stream holds fewer); among events sharing a timestamp, the later ones in
  the array count as later.

Each has a one-shot function over a whole event array and a streaming class
(``process(chunk)``, ``image_at(T)``, ``reset()``) that gives the same
images when every query ``T`` is at or after the events processed so far.

References
----------
.. [1] METHOD.md, section 5; Lee, Kim & Kim, BMVC 2019, section 3.
"""

from __future__ import annotations

import numpy as np

from evedge.events import SensorSize, find_time_decrease, validate_events

from .protocols import METHODS

__all__ = [
    "accumulate_time",
    "accumulate_count",
    "TimeWindowAccumulator",
    "CountWindowAccumulator",
]

_NEVER = np.iinfo(np.int64).min


def _check_sensor(sensor_size) -> SensorSize:
    if not isinstance(sensor_size, SensorSize):
        raise TypeError(f"sensor_size must be an evedge.events.SensorSize, got {type(sensor_size).__name__}")
    return sensor_size


def _check_positive_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be a positive integer, got {value!r}")
    if value <= 0:
        raise ValueError(f"{name} must be > 0, got {value}")
    return int(value)


def _check_times(times_us) -> np.ndarray:
    arr = np.asarray(times_us)
    if arr.ndim != 1:
        raise ValueError(f"times_us must be 1-D, got shape {arr.shape}")
    if arr.size and arr.dtype.kind not in "iu":
        if arr.dtype.kind != "f" or not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
            raise TypeError(f"times_us must hold integers (microseconds), got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    decrease = find_time_decrease(arr)
    if decrease is not None:
        i = decrease[0]
        raise ValueError(f"times_us must be non-decreasing: times_us[{i}]={arr[i]} < times_us[{i - 1}]={arr[i - 1]}")
    return arr


def _check_query_time(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an integer time in microseconds, got {value!r}")
    return int(value)


def _check_one_shot(events, sensor_size, times_us, size_name: str, size) -> tuple[np.ndarray, SensorSize, int, np.ndarray]:
    """Checks shared by the one-shot functions: events (converted), sensor, the window size ``size_name``, query times."""
    sensor_size = _check_sensor(sensor_size)
    events = validate_events(events, sensor_size, name="events")
    size = _check_positive_int(size_name, size)
    return events, sensor_size, size, _check_times(times_us)


def accumulate_time(events: np.ndarray, sensor_size: SensorSize, times_us, window_us: int) -> np.ndarray:
    """Images of the pixels that fired in a fixed time window before each time.

    Parameters
    ----------
    events : numpy.ndarray
        Time-sorted events of :data:`evedge.events.EVENT_DTYPE`.
    sensor_size : SensorSize
    times_us : array_like of int, shape (n,)
        Query times ``T`` (us), non-decreasing.
    window_us : int
        Window length (us), > 0 (the paper uses 1000 and 30000).

    Returns
    -------
    numpy.ndarray
        Boolean, shape ``(n, height, width)``: pixel on at ``T`` when an event
        fell on it with ``T - window_us < t <= T``.
    """
    events, sensor_size, window_us, times = _check_one_shot(events, sensor_size, times_us, "window_us", window_us)
    t = events["t"]
    lo = np.searchsorted(t, times - window_us, side="right")
    hi = np.searchsorted(t, times, side="right")
    return _images_from_ranges(events, sensor_size, lo, hi)


def accumulate_count(events: np.ndarray, sensor_size: SensorSize, times_us, n_events: int) -> np.ndarray:
    """Images of the pixels hit by the last ``n_events`` events before each time.

    Parameters
    ----------
    events : numpy.ndarray
        Time-sorted events of :data:`evedge.events.EVENT_DTYPE`.
    sensor_size : SensorSize
    times_us : array_like of int, shape (n,)
        Query times ``T`` (us), non-decreasing.
    n_events : int
        Number of events accumulated, > 0.

    Returns
    -------
    numpy.ndarray
        Boolean, shape ``(n, height, width)``: pixel on at ``T`` when one of the
        last ``n_events`` events with ``t <= T`` fell on it (all of them when
        fewer exist).
    """
    events, sensor_size, n_events, times = _check_one_shot(events, sensor_size, times_us, "n_events", n_events)
    hi = np.searchsorted(events["t"], times, side="right")
    lo = np.maximum(hi - n_events, 0)
    return _images_from_ranges(events, sensor_size, lo, hi)


def _images_from_ranges(events, sensor_size, lo, hi) -> np.ndarray:
    images = np.zeros((lo.shape[0], *sensor_size.shape), dtype=bool)
    x = events["x"]
    y = events["y"]
    for k in range(lo.shape[0]):
        images[k, y[lo[k] : hi[k]], x[lo[k] : hi[k]]] = True
    return images


class _Streaming:
    """Shared chunk bookkeeping: sensor check, time order across chunks."""

    def __init__(self, sensor_size: SensorSize) -> None:
        self.sensor_size = _check_sensor(sensor_size)
        self._last_t: int | None = None

    def _accept(self, chunk: np.ndarray) -> np.ndarray:
        chunk = validate_events(chunk, self.sensor_size, name="chunk")
        if chunk.size:
            if self._last_t is not None and chunk["t"][0] < self._last_t:
                raise ValueError(
                    f"chunk: first event has t={int(chunk['t'][0])} us, earlier than the previous "
                    f"chunk's last event (t={self._last_t} us); chunks must be time-ordered"
                )
            self._last_t = int(chunk["t"][-1])
        return chunk

    def _check_query(self, t_us) -> int:
        t_us = _check_query_time("t_us", t_us)
        if self._last_t is not None and t_us < self._last_t:
            raise ValueError(
                f"t_us={t_us} is before the last processed event (t={self._last_t} us); "
                "query times must not precede the events already processed"
            )
        return t_us


class TimeWindowAccumulator(_Streaming):
    """Streaming fixed-time-window accumulation (see :func:`accumulate_time`).

    Keeps the latest event time of every pixel, so memory does not grow with
    the window.

    Parameters
    ----------
    sensor_size : SensorSize
    window_us : int
        Window length (us), > 0.
    """

    def __init__(self, sensor_size: SensorSize, window_us: int) -> None:
        super().__init__(sensor_size)
        self.window_us = _check_positive_int("window_us", window_us)
        self.reset()

    def reset(self) -> None:
        """Forget all events."""
        self._last_t = None
        self._latest = np.full(self.sensor_size.shape, _NEVER, dtype=np.int64)

    def process(self, chunk: np.ndarray) -> None:
        """Add a time-ordered chunk of events."""
        chunk = self._accept(chunk)
        if chunk.size:
            np.maximum.at(self._latest, (chunk["y"], chunk["x"]), chunk["t"])

    def image_at(self, t_us: int) -> np.ndarray:
        """Boolean image of the pixels with an event in ``(t_us - window_us, t_us]``.

        ``t_us`` must not precede the events processed so far (their later
        history is unknown to an earlier query).
        """
        t_us = self._check_query(t_us)
        return (self._latest != _NEVER) & (self._latest > t_us - self.window_us)


class CountWindowAccumulator(_Streaming):
    """Streaming fixed-event-count accumulation (see :func:`accumulate_count`).

    Parameters
    ----------
    sensor_size : SensorSize
    n_events : int
        Number of most recent events accumulated, > 0.
    """

    def __init__(self, sensor_size: SensorSize, n_events: int) -> None:
        super().__init__(sensor_size)
        self.n_events = _check_positive_int("n_events", n_events)
        self.reset()

    def reset(self) -> None:
        """Forget all events."""
        self._last_t = None
        self._x = np.empty(0, dtype=np.int16)
        self._y = np.empty(0, dtype=np.int16)

    def process(self, chunk: np.ndarray) -> None:
        """Add a time-ordered chunk of events (only the last ``n_events`` are kept)."""
        chunk = self._accept(chunk)
        if chunk.size:
            self._x = np.concatenate([self._x, chunk["x"]])[-self.n_events :]
            self._y = np.concatenate([self._y, chunk["y"]])[-self.n_events :]

    def image_at(self, t_us: int) -> np.ndarray:
        """Boolean image of the pixels hit by the last ``n_events`` events.

        ``t_us`` must not precede the events processed so far; it then only
        checks the stream order, since every kept event is at or before it.
        """
        self._check_query(t_us)
        image = np.zeros(self.sensor_size.shape, dtype=bool)
        image[self._y, self._x] = True
        return image


def _time_registered(sensor_size, *, window_us: int = 30_000) -> TimeWindowAccumulator:
    """Factory of the method registry: ``TimeWindowAccumulator(sensor_size, window_us)``."""
    return TimeWindowAccumulator(sensor_size, window_us)


def _count_registered(sensor_size, *, n_events: int = 2000) -> CountWindowAccumulator:
    """Factory of the method registry: ``CountWindowAccumulator(sensor_size, n_events)``."""
    return CountWindowAccumulator(sensor_size, n_events)


def _time_frames(events, sensor_size, times_us, *, window_us: int = 30_000) -> np.ndarray:
    """One-shot frames of the registry entry ``time``: :func:`accumulate_time`."""
    return accumulate_time(events, sensor_size, times_us, window_us)


def _count_frames(events, sensor_size, times_us, *, n_events: int = 2000) -> np.ndarray:
    """One-shot frames of the registry entry ``count``: :func:`accumulate_count`."""
    return accumulate_count(events, sensor_size, times_us, n_events)


METHODS.register("time", _time_registered, kind="edges", display_name="fixed-time accumulation", colour="#2ca02c",
                 frames=_time_frames)
METHODS.register("count", _count_registered, kind="edges", display_name="fixed-count accumulation",
                 colour="#7f7f7f", frames=_count_frames)
