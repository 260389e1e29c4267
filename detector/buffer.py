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

One shot (:func:`filter_events`): two passes instead of walks
    With the whole stream at hand, the buffered rule needs no chains: an event
    is supported when the latest same-polarity event before it (stream order)
    at one of its neighbours is at most ``tau_min_us`` earlier (a forward pass,
    the causal rule), or the earliest one after it at most ``tau_min_us`` later
    (the same pass backwards): those two are the nearest in time on each side,
    the stream being time-sorted. The streaming kernel (:class:`EventBuffer`)
    walks each neighbour's chain of waiting events instead, with an int64 link
    per event and 16 bytes of state per pixel; the passes keep one time per
    pixel and no per-event array but the mask, and the forward pass checks the
    events (range, order: :func:`evedge.events.validate_events`' checks) on its
    way, so the events are read twice, not four times. The time is int64, or
    int32 relative to the first event where that is exact (span + window <
    2**31 us, 36 min) and the int64 state would not fit a core's L2 cache
    (512 KiB: larger than a DVS128's; ``_buffer_kernels.narrow_state``; only
    the state type used is compiled: ~1.3 s CPU on a cold start, the chain
    kernel's ~1.5). Same bytes as the chain kernel, serial and on strips, either
    state (``tests/detector/test_buffer_one_shot.py``); a stream within
    ``tau_min_us`` of the int64 range's ends (where the chain kernel's window
    wraps around) takes the chain kernel. Measured (``benchmarks/bench_buffer.py
    --gen4``, 2026-12-03, load 3.4 -> 4.8 on the 2 CPUs, thread CPU, least of
    5; the load inflates both, compare the ratios), previous -> today, ns per
    event: paper defaults 44.1 -> 18.1 on ``stripes.mat`` (2.4x), 50.1 -> 17.9
    on it repeated 30 times (10.2 M events, 2.8x), 156.2 -> 48.7 on the
    Gen4-sized input (1280x720, 1.6 M events, 3.2x; the passes in its int32
    state 47.7, in int64 87.8); causal 20.1 -> 8.8, 24.4 -> 8.9, 74.4 -> 30.5;
    ``line_params()`` 95.7 -> 53.7, 102.6 -> 54.8, 262.4 -> 142.0 (its kernel
    also skips the neighbours whose latest event is supported already). On a
    DVS128 the int32 state costs 7 % more (19.1 against 17.8), hence the size
    rule; of the 17.9 on the 10 M file the forward pass with the checks is ~9.4
    (the previous path's ``check_events`` alone 6.7).
    ``benchmarks/bench_cli.py`` (load 4.3): "buffer alone (filter_events,
    checks included)" 17 ns/event on the 10 M file (least of 3; the first 18),
    18 on ``stripes.mat`` (issue 12 item 4's target <= 40; it was 40-43 / 32-35
    at load ~1.2).

Streaming (:class:`EventBuffer`)
    Keeps the chain kernel (an unsupported event's later neighbours are not
    known yet); a chunk is checked while it is copied into the slots and the
    decided events are released with their int64 columns by the kernels of
    :mod:`evedge.detector._stream_kernels` (the streaming Detector passes those
    columns on, see :mod:`evedge.detector.pipeline`). ``benchmarks/bench_buffer.py``
    prints its ns per event beside the one-shot passes'.

Line rule (``line_window_us``, a departure from the paper, off by default; :func:`line_params`)
    The 10 ms window removes slow oblique edges: at 10 px/s and 20 degrees the
    nearest neighbour along the edge fires 34 ms away (0.34 lifetimes; 0.45 at
    the worst angle, 26.6 degrees), so at low contrast, one event per pixel and
    passage, 0.7 % of the signal survived (robustness grid, issue 11). An edge
    crossing pixels ``q - a``, ``q``, ``q + a`` at a steady speed, however
    slowly, fires ``q`` midway in time between the other two; isolated noise
    rarely does. The rule keeps an event that lies about midway
    (``line_tolerance``) between the latest same-polarity events of two
    opposite neighbours, one before and one after it, each within
    ``line_window_us``, when its pixel was quiet before (``line_quiet`` times
    the span) and, with ``line_count = 2``, midway between a second pair of
    opposite neighbours too. Every pixel it reads is within one of the event
    it keeps, so strips with a one-row halo stay exact (``n_tiles > 1`` runs it
    on the strips; tests compare the decisions with the serial ones). Measured (``benchmarks/robustness_grid.py
    --quick``, ``noise_params()``, README "Robustness"): one pair, 100 ms:
    noise kept by the buffer 37.3 -> 41.8 %, noise given a lifetime 6.2 ->
    7.0 %; two pairs (the preset: 150 ms, tolerance 0.7): 38.9 % and 6.7 %,
    slow oblique signal kept 66 -> 79 % (median of those cells). Cost: a further
    pass with its own state (the default path is unchanged), on
    ``benchmarks/bench_buffer_rules.py`` (2026-12-03, load 3.6, after the two
    passes above made the default path ~3x cheaper): ``stripes.mat`` 18.0 ->
    52.0 ns/event (2.9x the default's), the slow oblique noisy cell 16.2 ->
    101.6 (6.3x; many unsupported events there, each a candidate).

References
----------
.. [1] S. Lee, H. Kim, H. J. Kim, "Edge Detection for Event Cameras using
       Intra-pixel-area Events", BMVC 2019, section 2.2 (tau_min = 0.01 s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evedge.events import EVENT_DTYPE

from ._buffer_kernels import (NEVER, _buffer_scan, _line_scan, _n_decided, empty_line_state, empty_state,
                              narrow_state, one_shot_exact, run_passes)
from ._stream_kernels import _fill_slots, _release_slots
from ._tiles import check_n_tiles, filter_tiled
from ._checks import check_events, check_not_before, check_positive, check_sensor_size, columns
from evedge._validate import check_real

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
    line_window_us : int
        The line rule (a departure from the paper, 0 = off, the default; buffered
        form only): an event is also kept when same-polarity events fired at two
        opposite neighbours (``q - a`` and ``q + a``) one before and one after it,
        each within ``line_window_us``, and it lies about midway in time between
        them (see ``line_tolerance``). A slow edge crossing three pixels in a row
        does this whatever its speed; isolated noise rarely does. Latency: an
        unsupported event waits ``max(tau_min_us, line_window_us)``.
    line_tolerance : float
        How far from midway: ``|d1 - d2| <= line_tolerance * max(d1, d2)`` for the
        delays ``d1, d2`` to the two neighbours, in ``[0, 1]`` (default 0.5).
    line_quiet : float
        And the event's pixel fired no event of that polarity in the
        ``line_quiet * (d1 + d2)`` before it (default 2; 0: no such condition).
    line_count : int
        Pairs of opposite neighbours the event must lie midway between: 1
        (default) or 2 (a second pair, in another direction, at the same time).
    """

    tau_min_us: int = 10_000
    mode: str = "buffered"
    line_window_us: int = 0
    line_tolerance: float = 0.5
    line_quiet: float = 2.0
    line_count: int = 1

    def __post_init__(self) -> None:
        check_positive("BufferParams", "tau_min_us", self.tau_min_us, integer=True)
        object.__setattr__(self, "tau_min_us", int(self.tau_min_us))
        if self.mode not in _MODES:
            raise ValueError(f"BufferParams.mode must be one of {_MODES}, got {self.mode!r}")
        check_positive("BufferParams", "line_window_us", self.line_window_us, integer=True, allow_zero=True)
        object.__setattr__(self, "line_window_us", int(self.line_window_us))
        lt = check_real("BufferParams", "line_tolerance", self.line_tolerance, 0.0, 1.0, low_open=False,
                        high_open=False)
        object.__setattr__(self, "line_tolerance", lt)
        check_positive("BufferParams", "line_quiet", self.line_quiet, allow_zero=True)
        object.__setattr__(self, "line_quiet", float(self.line_quiet))
        if isinstance(self.line_count, bool) or self.line_count not in (1, 2):
            raise ValueError(f"BufferParams.line_count must be 1 or 2, got {self.line_count!r}")
        object.__setattr__(self, "line_count", int(self.line_count))
        lw = self.line_window_us
        if lw and self.mode != "buffered":
            raise ValueError("BufferParams.line_window_us needs mode='buffered' (the rule supports an event from a "
                             f"later neighbour), got mode={self.mode!r}")

    @property
    def hold_us(self) -> int:
        """How long an unsupported event may wait for support: ``max(tau_min_us, line_window_us)``."""
        return max(self.tau_min_us, self.line_window_us)


#: The line rule as measured on ``benchmarks/robustness_grid.py`` (module notes, "line rule"): :func:`line_params`.
LINE_RULE = {"line_window_us": 150_000, "line_count": 2, "line_tolerance": 0.7, "line_quiet": 2.0}


def line_params(**overrides) -> BufferParams:
    """:class:`BufferParams` with the line rule on (:data:`LINE_RULE`), plus any ``overrides``.

    Examples
    --------
    >>> p = line_params()
    >>> (p.tau_min_us, p.line_window_us, p.line_count, p.hold_us)
    (10000, 150000, 2, 150000)
    """
    return BufferParams(**{**LINE_RULE, **overrides})


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
        self._line_state = empty_line_state(w, h) if self.params.line_window_us else None
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
            # the same capacity: moved within the arrays (no fresh memory to fault in at every move;
            # nothing outside holds a view of them: released events and columns are copies)
            out = arr if cap == self._cap else np.empty(cap, dtype=arr.dtype)
            out[:pending] = arr[sl]  # (numpy buffers an overlapping copy)
            new.append(out)
        self._ev, self._cols, self._prev, self._supported = new[0], new[1:5], new[5], new[6]
        self._cap, self._start, self._end = cap, 0, pending

    def process(self, events: np.ndarray) -> np.ndarray:
        """Take a time-sorted chunk; return the kept events whose fate is now known."""
        if type(events) is np.ndarray and events.ndim == 1 and events.dtype == EVENT_DTYPE:
            taken = self._take(events, None, columns=False)  # checked in the pass that copies it
            if taken is not None:
                return taken[0]
            # refused (nothing changed): the full checks below raise with their messages
        events = check_events(events, self.sensor_size)
        check_not_before(events, self._last_time)
        if events.size == 0:
            return events[:0].copy()
        self._scan(events)
        return self._release(self._n_ready())

    def _scan(self, events: np.ndarray) -> None:
        """Append a checked, non-empty chunk (not before the newest event) and run the rules on it."""
        m = events.shape[0]
        self._make_room(m)
        a, b = self._end, self._end + m
        self._ev[a:b] = events
        for col, field in zip(self._cols, "xytp"):
            col[a:b] = events[field]  # converted to int64 in place (no temporary column)
        self._end = b  # prev and supported of the new slots are set by the kernel
        self._scan_slots(a)

    def _scan_slots(self, a: int) -> None:
        """Run the rules on the new slots ``[a, _end)`` (filled) with the pending ones before them."""
        b = self._end
        sl = slice(self._start, b)
        x, y, t, p = (col[sl] for col in self._cols)
        tau = self.params.tau_min_us
        causal = self.params.mode == "causal"
        _buffer_scan(x, y, t, p, self._prev[sl], self._supported[sl], a - self._start, self._base_g, self._state,
                     self.sensor_size.width, self.sensor_size.height, tau, causal)
        if self._line_state is not None:
            _line_scan(x, y, t, p, self._supported[sl], a - self._start, self._base_g, self._line_state,
                       self.sensor_size.width, self.sensor_size.height, self.params.line_window_us,
                       self.params.line_tolerance, self.params.line_quiet, self.params.line_count)
        self._last_time = int(t[-1])

    def _n_ready(self) -> int:
        """How many of the pending slots are decided by ``_last_time`` (a leading run)."""
        sl = slice(self._start, self._end)
        return _n_decided(self._cols[2][sl], self._supported[sl], self._last_time, self.params.hold_us,
                          self.params.mode == "causal")

    def _take(self, events: np.ndarray | None, until_us: int | None, columns: bool = True):
        """:meth:`process` then :meth:`advance_to` in one release, with the released events' columns.

        ``events``: a chunk of :data:`~evedge.events.EVENT_DTYPE`, checked here in the
        pass that copies it (None: none). Returns the released events and their
        x, y, t, p (int64, as :func:`columns`; None with ``columns`` False), the same events as the two calls
        (the decided run only grows with the time); or None, changing nothing,
        when the chunk or ``until_us`` fails a check (the caller then runs the
        full checks for their messages).
        """
        has_until = until_us is not None
        if has_until and (isinstance(until_us, bool) or not isinstance(until_us, (int, np.integer))):
            return None
        until = int(until_us) if has_until else 0
        if events is None:
            if has_until and self._last_time is not None and until < self._last_time:
                return None
        else:
            m = events.shape[0]
            self._make_room(m)
            a = self._end
            if not _fill_slots(events, self.sensor_size.width, self.sensor_size.height,
                               NEVER if self._last_time is None else self._last_time, has_until, until, self._ev,
                               *self._cols, a):
                return None
            if m:
                self._end = a + m
                self._scan_slots(a)
        if has_until:
            self._last_time = until
        if self._last_time is None:
            return self._release(0, True)
        r = self._n_ready()
        if not columns:  # (for process: the records only)
            return self._release(r), None
        out, cols = _release_slots(self._ev, *self._cols, self._supported, self._start, r)
        self._advance(r)
        return out, (cols[0], cols[1], cols[2], cols[3])

    @staticmethod
    def _check_until(t_us, newest: int | None) -> None:
        if isinstance(t_us, bool) or not isinstance(t_us, (int, np.integer)):
            raise TypeError(f"t_us must be an integer (microseconds), got {t_us!r}")
        if newest is not None and t_us < newest:
            raise ValueError(f"t_us={t_us} is before the newest processed event (t={newest} us)")

    def advance_to(self, t_us: int) -> np.ndarray:
        """Declare that no event earlier than ``t_us`` will come; return the kept events now decided.

        Without it an unsupported event waits for the next event later than its
        ``t + tau_min_us``; a caller with a clock can bound the latency in wall time.
        Later chunks must not start before ``t_us``.
        """
        self._check_until(t_us, self._last_time)
        self._last_time = int(t_us)
        return self._release(self._n_ready())

    def _release(self, r: int, with_columns: bool = False):
        """The kept events of the next ``r`` slots (and, ``with_columns``, their x, y, t, p columns)."""
        sl = slice(self._start, self._start + r)
        keep = self._supported[sl]
        out = self._ev[sl].compress(keep)  # (faster than boolean indexing on records)
        self._advance(r)
        if with_columns:
            return out, tuple(col[sl].compress(keep) for col in self._cols)
        return out

    def _advance(self, r: int) -> None:
        """The next ``r`` slots are released."""
        self._start += r
        self._base_g += r

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
        Parallel work (numba threads; default 1): the buffered rule's two
        one-shot passes at once on two threads, or, for the causal rule, the
        line rule and streams near the int64 range's ends, row strips
        (:mod:`evedge.detector._tiles`). Any value gives the same decisions.

    Returns
    -------
    numpy.ndarray
        Boolean mask, True for the events kept.
    """
    sensor_size = check_sensor_size(sensor_size)
    params = _check_params(params)
    plain = isinstance(events, np.ndarray) and events.dtype == EVENT_DTYPE and events.ndim == 1
    if not plain:  # converted and checked here; plain events are checked by the serial kernel on its way
        events = check_events(events, sensor_size)
    try:
        n_tiles = check_n_tiles(n_tiles, sensor_size.height)
    except (TypeError, ValueError):
        check_events(events, sensor_size)  # the events' error first, as their checks come first
        raise
    if _strips(events, sensor_size, params, n_tiles) and plain:
        events = check_events(events, sensor_size)
    return _filter(events, sensor_size, params, n_tiles)


def _strips(events: np.ndarray, sensor_size, params: BufferParams, n_tiles: int) -> bool:
    """Whether :func:`_filter` runs the strips (:func:`~evedge.detector._tiles.filter_tiled`).

    With ``n_tiles > 1`` the buffered rule, when the one-shot passes are exact and no
    line rule follows, runs its two passes at once on two threads instead
    (:func:`~evedge.detector._buffer_kernels._passes_both`): no column copies, no
    strips' gathering (the same bytes either way).
    """
    if n_tiles == 1:
        return False
    if params.mode == "causal" or params.line_window_us or events.shape[0] == 0:
        return True
    return not one_shot_exact(events["t"][0], events["t"][-1], params.tau_min_us)


def _filter(events: np.ndarray, sensor_size, params: BufferParams, n_tiles: int) -> np.ndarray:
    """:func:`filter_events` on checked parameters and events of :data:`EVENT_DTYPE`.

    Without strips (``n_tiles == 1``, or the two passes at once, :func:`_strips`) the
    events need not be checked: the first pass checks them (range and order, in the same
    pass) and, on a bad event, :func:`check_events` raises its error.
    """
    w, h = sensor_size.width, sensor_size.height
    n = events.shape[0]
    causal = params.mode == "causal"
    if _strips(events, sensor_size, params, n_tiles):
        x, y, t, p = columns(events)
        return filter_tiled(x, y, t, p, w, h, params.tau_min_us, causal, n_tiles,
                            params.line_window_us, params.line_tolerance, params.line_quiet, params.line_count)
    supported = np.empty(n, dtype=bool)
    if n == 0:
        return supported
    # the kernels read the event fields in place (strided views: no int64 copies, which on a
    # 10 M-event file cost as much as a pass, most of it first touches of fresh memory)
    x, y, t, p = events["x"], events["y"], events["t"], events["p"]
    tau = params.tau_min_us
    exact = one_shot_exact(t[0], t[-1], tau)  # (t[-1] may not be the last time yet: then the checks fail)
    bad = run_passes(x, y, t, p, supported, w, h, tau, causal or not exact, narrow_state(t[0], t[-1], tau, w, h),
                     threads=n_tiles)
    if bad >= 0:
        check_events(events, sensor_size)  # raises, naming the first bad event
        raise RuntimeError(f"events: event {bad} failed the buffer's checks but passed check_events (a bug)")
    if not (causal or exact):  # times within tau of the int64 range's ends: the chain kernel
        _buffer_scan(x, y, t, p, np.empty(n, dtype=np.int64), supported, 0, 0, empty_state(w, h), w, h, tau, False)
    if params.line_window_us:
        _line_scan(x, y, t, p, supported, 0, 0, empty_line_state(w, h), w, h, params.line_window_us,
                   params.line_tolerance, params.line_quiet, params.line_count)
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
