"""Event buffer: the paper's noise filter (Lee, Kim & Kim 2019, section 2.2).

An event is kept when an event of the same polarity fired at one of its 8
neighbouring pixels (radius 1; the pixel itself does not count) within
``tau_min_us`` of it. Isolated events are noise.

Two forms:

``buffered`` (default)
    Support may come from before *or after* the event (``|t_j - t_i| <= tau_min``),
    so the first event of an edge, which has no past neighbour yet, is kept once
    its neighbours fire. An event therefore waits at most ``tau_min_us`` before
    its fate is known; the output stays in time order and its latency is bounded
    by ``tau_min_us`` (the buffer the paper's name refers to).
``causal``
    Support from earlier events of the stream only (``t_i - tau_min <= t_j``,
    ``j`` before ``i``); no latency.

Equal timestamps: two events with the same timestamp at neighbouring pixels
support each other in the buffered form; in the causal form only the one later
in the stream is supported by the other (stream order decides).

References
----------
.. [1] S. Lee, H. Kim, H. J. Kim, "Edge Detection for Event Cameras using
       Intra-pixel-area Events", BMVC 2019, section 2.2 (tau_min = 0.01 s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evedge.events import EVENT_DTYPE

from ._buffer_kernels import _buffer_scan, _n_decided, empty_state
from ._tiles import check_n_tiles, filter_tiled
from ._checks import check_events, check_not_before, check_positive, check_sensor_size, columns
from .protocols import METHODS

_MODES = ("buffered", "causal")


@dataclass(frozen=True)
class BufferParams:
    """Parameters of the event buffer.

    Parameters
    ----------
    tau_min_us : int
        Support window in microseconds (paper: 0.01 s).
    mode : {"buffered", "causal"}
        Support from past and future (default, latency <= ``tau_min_us``) or past only.
    """

    tau_min_us: int = 10_000
    mode: str = "buffered"

    def __post_init__(self) -> None:
        check_positive("BufferParams", "tau_min_us", self.tau_min_us, integer=True)
        object.__setattr__(self, "tau_min_us", int(self.tau_min_us))
        if self.mode not in _MODES:
            raise ValueError(f"BufferParams.mode must be one of {_MODES}, got {self.mode!r}")


def _check_params(params) -> BufferParams:
    if params is None:
        return BufferParams()
    if not isinstance(params, BufferParams):
        raise TypeError(f"params: expected BufferParams, got {type(params).__name__}")
    return params


class EventBuffer:
    """Streaming event buffer.

    Parameters
    ----------
    sensor_size : SensorSize or (width, height)
    params : BufferParams, optional

    Notes
    -----
    :meth:`process` returns the events whose fate is known, kept ones only, in
    time order; in the buffered form an event is held until it is supported or
    until an event later than ``t + tau_min_us`` arrives (or :meth:`advance_to`
    says the stream has passed that time). :meth:`flush` releases
    the rest at the end of the stream. The concatenation of all outputs equals
    ``events[filter_events(events, ...)]`` whatever the chunking.
    """

    def __init__(self, sensor_size, params: BufferParams | None = None) -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        self.params = _check_params(params)
        self.reset()

    def reset(self) -> None:
        """Forget every event seen."""
        w, h = self.sensor_size.width, self.sensor_size.height
        self._state = empty_state(w, h)  # per pixel and polarity, padded border (see _buffer_kernels)
        # the unreleased events are slots [_start, _end) of growable arrays (the events
        # and their plain columns, converted once on arrival): a chunk costs O(chunk),
        # not O(events waiting), however long the support window keeps them
        self._cap = 0
        self._ev = np.empty(0, dtype=EVENT_DTYPE)
        self._cols = [np.empty(0, dtype=np.int64) for _ in range(4)]  # x, y, t, p
        self._prev = np.empty(0, dtype=np.int64)
        self._supported = np.empty(0, dtype=bool)
        self._start = 0
        self._end = 0
        self._base_g = 0  # global index of slot _start
        self._last_time: int | None = None

    @property
    def n_pending(self) -> int:
        """Events received but not yet released or dropped."""
        return self._end - self._start

    def _make_room(self, m: int) -> None:
        """Room for ``m`` more slots: move the pending slots to the front, grow when needed."""
        pending = self._end - self._start
        if self._end + m <= self._cap:
            return
        cap = max(self._cap, 1024)
        while pending + m > cap // 2:  # at least half free after the move: amortised O(1) per event
            cap *= 2
        sl = slice(self._start, self._end)
        arrays = [self._ev, *self._cols, self._prev, self._supported]
        new = []
        for arr in arrays:
            out = np.empty(cap, dtype=arr.dtype)
            out[:pending] = arr[sl]
            new.append(out)
        self._ev, self._cols, self._prev, self._supported = new[0], new[1:5], new[5], new[6]
        self._cap, self._start, self._end = cap, 0, pending

    def process(self, events: np.ndarray) -> np.ndarray:
        """Take a time-sorted chunk; return the kept events whose fate is now known."""
        events = check_events(events, self.sensor_size)
        check_not_before(events, self._last_time)
        if events.size == 0:
            return events[:0].copy()
        m = events.shape[0]
        self._make_room(m)
        a, b = self._end, self._end + m
        self._ev[a:b] = events
        for col, field in zip(self._cols, "xytp"):
            col[a:b] = events[field]  # converted to int64 in place (no temporary column)
        self._end = b  # prev and supported of the new slots are set by the kernel
        sl = slice(self._start, b)
        x, y, t, p = (col[sl] for col in self._cols)
        tau = self.params.tau_min_us
        causal = self.params.mode == "causal"
        _buffer_scan(x, y, t, p, self._prev[sl], self._supported[sl], a - self._start, self._base_g, self._state,
                     self.sensor_size.width, self.sensor_size.height, tau, causal)
        self._last_time = int(t[-1])
        return self._release(_n_decided(t, self._supported[sl], self._last_time, tau, causal))

    def advance_to(self, t_us: int) -> np.ndarray:
        """Declare that no event earlier than ``t_us`` will come; return the kept events now decided.

        Without it an unsupported event waits for the next event later than its
        ``t + tau_min_us``; a caller with a clock can bound the latency in wall time.
        Later chunks must not start before ``t_us``.
        """
        if isinstance(t_us, bool) or not isinstance(t_us, (int, np.integer)):
            raise TypeError(f"t_us must be an integer (microseconds), got {t_us!r}")
        if self._last_time is not None and t_us < self._last_time:
            raise ValueError(f"t_us={t_us} is before the newest processed event (t={self._last_time} us)")
        self._last_time = int(t_us)
        sl = slice(self._start, self._end)
        r = _n_decided(self._cols[2][sl], self._supported[sl], self._last_time, self.params.tau_min_us,
                       self.params.mode == "causal")
        return self._release(r)

    def _release(self, r: int) -> np.ndarray:
        sl = slice(self._start, self._start + r)
        out = self._ev[sl].compress(self._supported[sl])  # (faster than boolean indexing on records)
        self._start += r
        self._base_g += r
        return out

    def flush(self) -> np.ndarray:
        """End of stream: release the kept events still waiting for support."""
        return self._release(self._end - self._start)


def filter_events(events: np.ndarray, sensor_size, params: BufferParams | None = None, *, n_tiles: int = 1) -> np.ndarray:
    """One-shot event buffer.

    Parameters
    ----------
    events : numpy.ndarray
        Time-sorted events of dtype :data:`evedge.events.EVENT_DTYPE`.
    sensor_size : SensorSize or (width, height)
    params : BufferParams, optional
        Defaults: ``tau_min_us=10_000``, buffered form.
    n_tiles : int
        Row strips processed in parallel (numba threads; default 1). Any value
        gives the same decisions (:mod:`evedge.detector._tiles`).

    Returns
    -------
    numpy.ndarray
        Boolean mask, True for the events kept.
    """
    sensor_size = check_sensor_size(sensor_size)
    params = _check_params(params)
    events = check_events(events, sensor_size)
    return _filter(events, sensor_size, params, check_n_tiles(n_tiles, sensor_size.height))


def _filter(events: np.ndarray, sensor_size, params: BufferParams, n_tiles: int) -> np.ndarray:
    """:func:`filter_events` on validated events and parameters."""
    w, h = sensor_size.width, sensor_size.height
    x, y, t, p = columns(events)
    n = events.shape[0]
    if n_tiles > 1:
        return filter_tiled(x, y, t, p, w, h, params.tau_min_us, params.mode == "causal", n_tiles)
    supported = np.empty(n, dtype=bool)  # every entry set by the kernel, as is prev
    _buffer_scan(x, y, t, p, np.empty(n, dtype=np.int64), supported, 0, 0, empty_state(w, h), w, h,
                 params.tau_min_us, params.mode == "causal")
    return supported


def _registered(sensor_size, n_tiles: int = 1, **params) -> EventBuffer:
    """Factory of the method registry: ``EventBuffer(sensor_size, BufferParams(**params))``.

    ``n_tiles`` is for the one-shot keep mask (strips); the streaming buffer is serial.
    """
    return EventBuffer(sensor_size, BufferParams(**params))


def _keep_mask(events: np.ndarray, sensor_size, n_tiles: int = 1, **params) -> np.ndarray:
    """One-shot keep mask of the registry entry: :func:`filter_events`."""
    return filter_events(events, sensor_size, BufferParams(**params), n_tiles=n_tiles)


METHODS.register("buffer", _registered, kind="filter", display_name="event buffer (noise filter)", colour="#8c564b",
                 params=BufferParams, keep_mask=_keep_mask, extra_params=("n_tiles",))
