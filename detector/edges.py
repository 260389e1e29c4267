"""Edge image at any instant from per-event lifetimes (paper section 2.3, Mueggler 2015).

A pixel is an edge at time ``T`` when its newest event ``e`` with ``t_e <= T``
satisfies ``T < t_e + tau_e``: every event keeps its pixel alive for its lifetime.

Events without an estimate (``valid`` False) do not count by default: they do
not change their pixel, whose newest *estimated* event decides
(``invalid="ignore"``). With ``invalid="clear"`` they end the pixel's life
instead (the pixel's newest event is then one with no edge evidence).

``clear_behind=True`` mimics Mueggler et al.'s display: a valid event also ends
the life of the 8-neighbour behind it, opposite its normal flow rounded to 45
degrees, which thins edges left behind by fast motion.

``burst_lifetimes > 0`` (our addition, burst-aware display): an edge crossing a
pixel fires a *burst* of events (one per threshold its contrast spans), and with
expiry counted from each event's own time the pixel stays alive for the
lifetime after the burst's *last* event, so a moving edge leaves a trail about
two pixels thick. With it, a valid event continues its pixel's burst when the
pixel's newest valid event has the same polarity and fired at most
``burst_lifetimes`` times its lifetime before (the estimator's rule,
:class:`~evedge.detector.intra.IntraParams` ``burst_lifetimes``), and the pixel
expires one lifetime after the burst's *first* event. 0 is the paper's
display: the default, except under the ``lifetime_only`` display policy
(:data:`DISPLAY_BURST_LIFETIMES`), whose edge maps are burst-aware.

References
----------
.. [1] S. Lee, H. Kim, H. J. Kim, BMVC 2019, section 2.3.
.. [2] E. Mueggler et al., "Lifetime Estimation of Events from Dynamic Vision
       Sensors", ICRA 2015 (display: pixel alive for its lifetime, neighbour behind cleared).
"""

from __future__ import annotations

import numpy as np

from ._checks import (NEVER_US, check_events, check_lifetimes, check_not_before, check_positive, check_sensor_size,
                      columns)
from ._edges_kernels import _DX, _DY, _edge_update
from ._stream_kernels import (_lifetime_columns_into, _lifetime_columns_par_into, _record_columns_into,
                              _record_columns_par_into)
from ._tiles import check_n_tiles, edge_frames_tiled
from ._workspace import WORKSPACE

_INT64_MAX = np.iinfo(np.int64).max

__all__ = ["DISPLAYS", "DISPLAY_BURST_LIFETIMES", "PRIMARY_DISPLAY", "EdgeImage", "display_clear_behind",
           "edge_frames"]

_INVALID = ("ignore", "clear")

#: Display policies: how an estimator's lifetimes become an edge image (a parameter of the
#: image, never part of a method's name) -> ``clear_behind``. ``predecessor``: Mueggler et
#: al.'s display, each event also clears the pixel behind it; ``lifetime_only``: nothing cleared.
DISPLAYS = {"predecessor": True, "lifetime_only": False}

#: ``burst_lifetimes`` of each display policy when :class:`EdgeImage` is given ``display`` and no
#: ``burst_lifetimes`` (issue 11): the lifetime-only policy counts expiry from the burst's first
#: event (without it a burst's trail is about twice as thick as the edge: lifetime-only CDM on
#: stripes at 200 px/s 63 -> 88, ``benchmarks/display_cdm.py``); the predecessor's display keeps
#: Mueggler et al.'s rule (each event alive from its own time; its clearing already thins the trail).
DISPLAY_BURST_LIFETIMES = {"predecessor": 0.0, "lifetime_only": 1.0}

#: The display of ``evedge detect`` by default and of the report's primary comparison: the
#: authors' code is a fork of Mueggler et al.'s and inherits its display.
PRIMARY_DISPLAY = "predecessor"


def display_clear_behind(display: str) -> bool:
    """``clear_behind`` of a display policy; ``ValueError`` naming the policies otherwise."""
    if display not in DISPLAYS:
        raise ValueError(f"display must be one of {tuple(DISPLAYS)}, got {display!r}")
    return DISPLAYS[display]


class EdgeImage:
    """Streaming edge image.

    Parameters
    ----------
    sensor_size : SensorSize or (width, height)
    clear_behind : bool
        Clear the neighbour behind each valid event (Mueggler's display).
    invalid : {"ignore", "clear"}
        What an event without estimate does to its pixel.
    burst_lifetimes : float, optional
        >= 0; expiry counted from the burst's first event (module notes); 0 = from each event.
        Default: the display policy's (:data:`DISPLAY_BURST_LIFETIMES`), else 0.
    display : {"predecessor", "lifetime_only"}, optional
        A display policy of :data:`DISPLAYS`; sets ``clear_behind`` (then leave it unset) and,
        unless given, ``burst_lifetimes``.

    Notes
    -----
    :meth:`image_at` answers for any ``T`` not before the newest processed event,
    so an edge map is available between any two events.
    """

    def __init__(self, sensor_size, clear_behind: bool = False, invalid: str = "ignore",
                 burst_lifetimes: float | None = None, *, display: str | None = None) -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        if display is not None:
            clear_behind = display_clear_behind(display)
        if burst_lifetimes is None:
            burst_lifetimes = DISPLAY_BURST_LIFETIMES[display] if display is not None else 0.0
        check_positive("EdgeImage", "burst_lifetimes", burst_lifetimes, allow_zero=True)
        self.burst_lifetimes = float(burst_lifetimes)
        if not isinstance(clear_behind, (bool, np.bool_)):
            raise TypeError(f"clear_behind must be a bool, got {clear_behind!r}")
        if invalid not in _INVALID:
            raise ValueError(f"invalid must be one of {_INVALID}, got {invalid!r}")
        self.clear_behind = bool(clear_behind)
        self.invalid = invalid
        self.reset()

    def reset(self) -> None:
        """Every pixel back to 'no event'."""
        n = self.sensor_size.width * self.sensor_size.height
        self._last_t = np.full(n, NEVER_US, dtype=np.int64)
        self._expiry = np.full(n, -np.inf)
        self._start_t = np.full(n, NEVER_US, dtype=np.int64)
        self._prev_lt = np.full(n, np.nan)
        self._prev_pol = np.full(n, -1, dtype=np.int8)
        self._last_time: int | None = None

    @property
    def last_time_us(self) -> int | None:
        """Time of the newest processed event (None before any)."""
        return self._last_time

    def process(self, events: np.ndarray, lifetimes: np.ndarray) -> None:
        """Apply a time-sorted chunk of events with their lifetimes (aligned)."""
        events = check_events(events, self.sensor_size)
        check_lifetimes(lifetimes, events.shape[0])
        check_not_before(events, self._last_time)
        if events.size == 0:
            return
        self._apply(*columns(events), np.ascontiguousarray(lifetimes["lifetime_us"]),
                    np.ascontiguousarray(lifetimes["vx_px_s"]), np.ascontiguousarray(lifetimes["vy_px_s"]),
                    np.ascontiguousarray(lifetimes["valid"]))

    def _apply(self, x, y, t, p, lt, vx, vy, valid) -> None:
        """:meth:`process` on plain columns: the events' (:func:`columns`) and their lifetimes' fields.

        A checked, non-empty chunk not before the newest processed event, with
        contiguous float64 ``lt, vx, vy`` and bool ``valid`` (for a pipeline that
        holds them already: :class:`~evedge.detector.pipeline.Detector`).
        """
        _edge_update(x, y, t, lt, vx, vy, valid, self._last_t, self._expiry, self.sensor_size.width,
                     self.sensor_size.height, self.clear_behind, self.invalid == "clear", _DX, _DY, p,
                     self.burst_lifetimes, self._start_t, self._prev_lt, self._prev_pol)
        self._last_time = int(t[-1])

    def image_at(self, t_us) -> np.ndarray:
        """Boolean (height, width) edge map at time ``t_us`` (>= the newest processed event)."""
        if isinstance(t_us, bool) or not isinstance(t_us, (int, np.integer, float, np.floating)):
            raise TypeError(f"t_us must be a number, got {t_us!r}")
        if isinstance(t_us, (float, np.floating)) and not np.isfinite(t_us):
            raise ValueError(f"t_us must be finite, got {t_us!r}")  # nan would give an empty map silently
        if self._last_time is not None and t_us < self._last_time:
            raise ValueError(
                f"t_us={t_us} is before the newest processed event (t={self._last_time} us); "
                "the state no longer holds older instants"
            )
        img = np.empty(self._last_t.shape[0], dtype=bool)
        self._render(t_us, img, np.empty_like(img))
        return img.reshape(self.sensor_size.shape)

    def _render(self, t_us, out: np.ndarray, scratch: np.ndarray) -> None:
        """:meth:`image_at` (flat) written into ``out`` with no temporary (``scratch``: a bool array as ``out``)."""
        np.less_equal(self._last_t, t_us, out=out)
        np.less(t_us, self._expiry, out=scratch)
        np.logical_and(out, scratch, out=out)


def edge_frames(events: np.ndarray, lifetimes: np.ndarray, sensor_size, times_us, clear_behind: bool = False,
                invalid: str = "ignore", burst_lifetimes: float | None = None, *,
                display: str | None = None, n_tiles: int = 1) -> np.ndarray:
    """Edge maps at the given instants (one-shot form of :class:`EdgeImage`).

    Parameters
    ----------
    events : numpy.ndarray
        Time-sorted events of dtype :data:`evedge.events.EVENT_DTYPE`.
    lifetimes : numpy.ndarray
        :data:`~evedge.detector.result.LIFETIME_DTYPE`, aligned with ``events``.
    sensor_size : SensorSize or (width, height)
    times_us : array_like of int
        Instants in us, any order; events with ``t <= T`` count for instant ``T``.
    clear_behind, invalid, burst_lifetimes, display
        As in :class:`EdgeImage`.
    n_tiles : int
        Row strips run in parallel (numba threads; :func:`evedge.detector._tiles.edge_frames_tiled`):
        the same frames, byte for byte, for any count. 1 = serial.

    Returns
    -------
    numpy.ndarray
        bool, shape ``(len(times_us), height, width)``, in the order of ``times_us``.
    """
    sensor_size = check_sensor_size(sensor_size)
    events = check_events(events, sensor_size)
    check_lifetimes(lifetimes, events.shape[0])
    times = np.asarray(times_us)
    if times.ndim != 1 or (times.size and times.dtype.kind not in "iuf"):
        raise ValueError(f"times_us: expected a 1-D array of numbers, got shape {times.shape} dtype {times.dtype}")
    if times.size and not np.all(np.isfinite(times)):
        raise ValueError("times_us: non-finite instant")
    n_tiles = check_n_tiles(n_tiles, sensor_size.height)
    out = np.zeros((times.size, *sensor_size.shape), dtype=bool)
    image = EdgeImage(sensor_size, clear_behind=clear_behind, invalid=invalid, burst_lifetimes=burst_lifetimes,
                      display=display)
    order = np.argsort(times, kind="stable")
    if not times.size:
        return out
    # the checked events' and lifetimes' columns once (one pass over each record array; with strips over chunks
    # in parallel), as scratch the workspace keeps mapped between calls (:mod:`._workspace`)
    n = events.shape[0]
    par = n_tiles > 1 and n > 0
    with WORKSPACE.scope() as take:
        ev_cols, lt_cols, valid = take.empty((4, n), np.int64), take.empty((3, n), np.float64), take.empty(n, bool)
        (_record_columns_par_into if par else _record_columns_into)(events, ev_cols)
        (_lifetime_columns_par_into if par else _lifetime_columns_into)(lifetimes, lt_cols, valid)
        x, y, t, p = ev_cols
        lt, vx, vy = lt_cols
        if par:
            # the instants as the serial comparisons see them (int64 / float64 against the int64 times)
            sorted_t = times[order].astype(np.float64 if times.dtype.kind == "f" or times.max() > _INT64_MAX
                                           else np.int64)
            edge_frames_tiled(x, y, t, lt, vx, vy, valid, p, sensor_size.width, sensor_size.height,
                              image.clear_behind, image.invalid == "clear", image.burst_lifetimes, sorted_t, order,
                              n_tiles, out)
            return out
        # slices of the columns (contiguous) per frame; each frame rendered into its own memory (the image_at
        # comparisons, no temporaries)
        cols = (x, y, t, p, lt, vx, vy, valid)
        ends = np.searchsorted(t, times[order], side="right")  # the contiguous time column, not the field
        scratch = np.empty(sensor_size.width * sensor_size.height, dtype=bool)
        flat = out.reshape(times.size, -1)
        start = 0
        for i, end in zip(order, ends):
            if end > start:
                image._apply(*(c[start:end] for c in cols))
                start = end
            image._render(times[i], flat[i], scratch)
    return out
