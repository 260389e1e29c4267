"""The whole detector: a noise filter, then a lifetime estimator (paper sections 2.2-2.4).

Both stages are looked up in the method registry
(:data:`evedge.detector.protocols.METHODS`), so any registered estimator and
filter compose, built-in or third-party. :func:`detect` is the one-shot form;
:class:`Detector` the streaming one (filter -> estimator -> edge image, with
``image_at(T)`` at any instant).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from evedge.events import EVENT_DTYPE

from ._checks import check_events, check_not_before, check_sensor_size, validated
from ._stream_kernels import (_expand_lifetimes, _expand_lifetimes_par, _kept_columns_into, _kept_columns_par_into,
                              _kept_offsets, _pack_lifetimes)
from ._tiles import check_n_tiles
from ._workspace import WORKSPACE
from .buffer import EventBuffer
from .buffer import _keep_mask as _buffer_keep_mask
from .edges import EdgeImage
from .intra import IntraPixelLifetime
from .protocols import METHODS
from .result import LIFETIME_DTYPE, empty_lifetimes

__all__ = ["DetectionResult", "Detector", "detect", "edge_frames_of", "keep_mask", "make_method", "method_params",
           "resolved_params"]


@dataclass
class DetectionResult:
    """Per-event output of :func:`detect`.

    Attributes
    ----------
    lifetimes : numpy.ndarray
        :data:`~evedge.detector.result.LIFETIME_DTYPE`, aligned with the input
        events; filtered events are invalid (NaN).
    kept : numpy.ndarray
        bool, True for events that passed the filter (all True without filter).
    """

    lifetimes: np.ndarray
    kept: np.ndarray


def method_params(name: str, params) -> dict:
    """Keyword parameters of the registered method ``name`` from ``params``.

    ``params`` is None (defaults), a mapping, or an instance of the entry's
    parameter dataclass (metadata ``params``, e.g. ``IntraParams``).

    Raises
    ------
    TypeError
        For anything else, naming the method and the class it takes.
    """
    entry = METHODS.get(name)
    cls = entry.metadata.get("params")
    if params is None:
        return {}
    if isinstance(params, Mapping):
        return dict(params)
    if cls is not None and isinstance(params, cls):
        return {f.name: getattr(params, f.name) for f in dataclasses.fields(cls)}
    takes = f"{cls.__name__} or a mapping" if cls is not None else "a mapping"
    raise TypeError(f"params: method {name!r} takes {takes}, got {type(params).__name__}")


def resolved_params(name: str, params=None) -> dict:
    """Every parameter of the registered method ``name`` with ``params`` applied (for the output's record).

    With a parameter dataclass: all its fields (validated by constructing it);
    otherwise the factory's keyword defaults updated by ``params``.

    Raises
    ------
    TypeError, ValueError
        An unknown parameter (naming it and the known ones) or an invalid value.
    """
    import inspect

    entry = METHODS.get(name)
    given = method_params(name, params)
    cls = entry.metadata.get("params")
    extra = set(entry.metadata.get("extra_params", ()))
    if cls is not None:
        fields = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(given) - fields - extra)
        if unknown:
            raise TypeError(f"method {name!r} has no parameter {', '.join(map(repr, unknown))}; "
                            f"its parameters: {', '.join(sorted(fields | extra))}")
        value = cls(**{k: v for k, v in given.items() if k in fields})
        out = {f: getattr(value, f) for f in sorted(fields)}
        out.update({k: given[k] for k in extra if k in given})
        return out
    try:
        sig = inspect.signature(entry.factory)
    except (TypeError, ValueError):
        return dict(given)
    known = {p.name: p.default for p in list(sig.parameters.values())[1:]
             if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)}
    if not any(p.kind == p.VAR_KEYWORD for p in sig.parameters.values()):
        unknown = sorted(set(given) - set(known))
        if unknown:
            raise TypeError(f"method {name!r} has no parameter {', '.join(map(repr, unknown))}; "
                            f"its parameters: {', '.join(sorted(known)) or 'none'}")
    out = {k: v for k, v in known.items() if v is not inspect.Parameter.empty}
    out.update(given)
    return out


def make_method(name: str, sensor_size, params=None, *, kind=None):
    """Build the registered method ``name`` (or ``package.module:factory``) for a sensor.

    Returns
    -------
    object
        ``factory(sensor_size, **params)``, following the protocol of its kind
        (:mod:`evedge.detector.protocols`).
    """
    entry = METHODS.get(name, kind=kind)
    return entry.factory(check_sensor_size(sensor_size), **method_params(name, params))


def keep_mask(filter_name: str, events: np.ndarray, sensor_size, params=None, n_tiles: int = 1) -> np.ndarray:
    """One-shot keep mask of a registered noise filter over a whole event array.

    Uses the entry's ``keep_mask`` metadata when it has one (with ``n_tiles`` when
    the entry takes it: the same mask, on more threads); otherwise streams
    the events through the filter and marks the released ones (a released
    event is matched to the earliest unmatched input with the same x, y, t, p;
    identical events are indistinguishable anyway).
    """
    sensor_size = check_sensor_size(sensor_size)
    entry = METHODS.get(filter_name, kind="filter")
    kw = method_params(filter_name, params)
    events = check_events(events, sensor_size)
    with validated(events, sensor_size):  # the filter's own check is then O(1)
        if "keep_mask" in entry.metadata:
            if n_tiles > 1 and "n_tiles" in entry.metadata.get("extra_params", ()):
                kw = {**kw, "n_tiles": n_tiles}
            return np.asarray(entry.metadata["keep_mask"](events, sensor_size, **kw), dtype=bool)
        flt = entry.factory(sensor_size, **kw)
        released = np.concatenate([np.asarray(flt.process(events), dtype=EVENT_DTYPE),
                                   np.asarray(flt.flush(), dtype=EVENT_DTYPE)])
    mask = np.zeros(events.shape[0], bool)
    j = 0
    for r in released:
        while j < events.shape[0] and events[j] != r:
            j += 1
        if j == events.shape[0]:
            raise ValueError(f"filter {filter_name!r} released an event that is not in its input (or out of order): {r}")
        mask[j] = True
        j += 1
    return mask


def edge_frames_of(method: str, events: np.ndarray, sensor_size, times_us, params=None) -> np.ndarray:
    """bool (n_times, H, W) maps of a registered edge detector at ``times_us`` (any order).

    Uses the entry's one-shot ``frames`` metadata when it has one (the
    accumulation baselines), else streams the events through the detector and
    asks ``image_at`` at each instant.
    """
    sensor_size = check_sensor_size(sensor_size)
    entry = METHODS.get(method, kind="edges")
    kw = method_params(method, params)
    events = check_events(events, sensor_size)
    times = np.asarray(times_us, dtype=np.int64)
    if "frames" in entry.metadata:  # one-shot frames take non-decreasing instants: sort, then put back
        order = np.argsort(times, kind="stable")
        out = np.zeros((times.size, sensor_size.height, sensor_size.width), dtype=bool)
        out[order] = np.asarray(entry.metadata["frames"](events, sensor_size, times[order], **kw)) > 0
        return out
    det = entry.factory(sensor_size, **kw)
    out = np.zeros((times.size, sensor_size.height, sensor_size.width), dtype=bool)
    order = np.argsort(times, kind="stable")
    ends = np.searchsorted(events["t"], times[order], side="right")
    start = 0
    for i, end in zip(order, ends):
        if end > start:
            with validated(events, sensor_size):  # slices of checked events: the detector's check is O(1)
                det.process(events[start:end])
            start = end
        img = np.asarray(det.image_at(int(times[i])))
        if img.shape != sensor_size.shape:
            raise ValueError(f"method {method!r}: image_at returned shape {img.shape}, expected {sensor_size.shape}")
        out[i] = img.astype(bool)
    return out


def _default_filter(method: str, use_buffer, filter_name):
    """The filter to run before ``method`` (None: none), from ``use_buffer`` / ``filter_name``."""
    entry = METHODS.get(method, kind="estimator")
    if use_buffer is not None and not isinstance(use_buffer, (bool, np.bool_)):
        raise TypeError(f"use_buffer must be a bool or None, got {use_buffer!r}")
    default = entry.metadata.get("filter")
    if use_buffer is None:
        return filter_name if filter_name is not None else default
    return (filter_name or default or "buffer") if use_buffer else None


def _check_estimate(name: str, out, n: int) -> np.ndarray:
    if not isinstance(out, np.ndarray) or out.dtype != LIFETIME_DTYPE or out.shape != (n,):
        got = f"{type(out).__name__} {getattr(out, 'dtype', '')} shape {getattr(out, 'shape', '?')}"
        raise TypeError(f"method {name!r}: process() must return {n} rows of LIFETIME_DTYPE, got {got}")
    return out


def _with_tiles(name: str, params, n_tiles: int):
    """``params`` with ``n_tiles`` added for a method that runs in strips (others run serially, same result)."""
    if n_tiles == 1 or "n_tiles" not in METHODS.get(name).metadata.get("extra_params", ()):
        return params
    return {**method_params(name, params), "n_tiles": n_tiles}


def detect(events: np.ndarray, sensor_size, method: str = "intra", *, buffer_params=None, params=None,
           use_buffer: bool | None = None, filter: str | None = None, n_tiles: int = 1) -> DetectionResult:
    """Run a noise filter and a lifetime estimator on a whole event array.

    Parameters
    ----------
    events : numpy.ndarray
        Time-sorted events of dtype :data:`evedge.events.EVENT_DTYPE`.
    sensor_size : SensorSize or (width, height)
    method : str
        A registered estimator (``"intra"``: the paper's intra-pixel-area
        RANSAC; ``"mueggler"``: Mueggler et al. 2015) or ``package.module:factory``.
    buffer_params : BufferParams or mapping, optional
        Parameters of the filter.
    params : dataclass or mapping, optional
        Parameters of the estimator (``IntraParams``, ``MuegglerParams``, ...).
    use_buffer : bool, optional
        Run the filter; default: the method's registered default (``intra``:
        the event buffer, as the paper; ``mueggler``: none, as its original).
    filter : str, optional
        A registered noise filter (default ``"buffer"``).
    n_tiles : int
        Row strips run in parallel by the estimator when it can (``intra``;
        :mod:`evedge.detector._tiles`); default 1. Any value gives the same
        bytes. With more than one, the event buffer runs its two one-shot
        passes at once on two threads (:func:`~evedge.detector.buffer.filter_events`).

    Returns
    -------
    DetectionResult
        Filtered events never reach the estimator (they do not update its state).

    Examples
    --------
    >>> import numpy as np
    >>> from evedge.events import make_events
    >>> ev = make_events(np.arange(8) % 4, np.zeros(8), np.arange(8) * 100, np.ones(8, bool))
    >>> res = detect(ev, (4, 2))
    >>> res.lifetimes.shape, res.kept.dtype
    ((8,), dtype('bool'))
    """
    sensor_size = check_sensor_size(sensor_size)
    n_tiles = check_n_tiles(n_tiles, sensor_size.height)
    flt = _default_filter(method, use_buffer, filter)
    estimator = make_method(method, sensor_size, _with_tiles(method, params, n_tiles), kind="estimator")
    if (flt and type(estimator) is IntraPixelLifetime and isinstance(events, np.ndarray)
            and events.dtype == EVENT_DTYPE and events.ndim == 1
            and METHODS.get(flt, kind="filter").metadata.get("keep_mask") is _buffer_keep_mask):
        # the built-in buffer and estimator on records: the buffer's first pass checks range and order on its
        # way (check_events' error on a bad event), so no separate O(n) check of the same records; its passes
        # at once on two threads with n_tiles > 1 (same bytes)
        kept = _buffer_keep_mask(events, sensor_size, n_tiles=n_tiles, **method_params(flt, buffer_params))
        return DetectionResult(_intra_on_kept(estimator, events, kept, n_tiles), kept)
    events = check_events(events, sensor_size)  # the one O(n) check: the stages' own checks are O(1)
    with validated(events, sensor_size):
        # the event buffer: its one-shot passes, at once on two threads with n_tiles > 1 (its strips' gathering
        # and bookkeeping cost more than the passes, benchmarks/bench_buffer.py); same bytes either way
        kept = (keep_mask(flt, events, sensor_size, buffer_params, n_tiles=n_tiles) if flt
                else np.ones(events.shape[0], bool))
        if flt and type(estimator) is IntraPixelLifetime:
            return DetectionResult(_intra_on_kept(estimator, events, kept, n_tiles), kept)
        # compress, not events[kept]: the same rows, ~4x faster on the packed event records
        sub = events.compress(kept) if flt else events
        with validated(sub, sensor_size):  # a subset, in order, of checked events
            est = _check_estimate(method, estimator.process(sub), sub.shape[0])
    return DetectionResult(_expand(est, kept) if flt else est.copy(), kept)


def _intra_on_kept(estimator: IntraPixelLifetime, events: np.ndarray, kept: np.ndarray, n_tiles: int) -> np.ndarray:
    """The built-in estimator on the kept events' columns, its columns scattered back into records aligned with
    ``events`` in one pass each (no record copy, column unpacking, packing or field scatters); with
    ``n_tiles > 1`` over chunks of events in parallel (the same arrays)."""
    out = np.empty(events.shape[0], dtype=LIFETIME_DTYPE)
    off = _kept_offsets(kept) if n_tiles > 1 else None
    # the columns are scratch lent by the workspace (kept mapped between calls: on a 1280 x 720 input a fresh
    # (4, m) array from numba's allocator cost ~11,000 page faults per call, :mod:`._workspace`)
    with WORKSPACE.scope() as take:
        cols = take.empty((4, np.count_nonzero(kept) if off is None else off[-1]), np.int64)
        if off is None:
            _kept_columns_into(events, kept, cols)
        else:
            _kept_columns_par_into(events, kept, off, cols)
        if not cols.shape[1]:  # (the estimator's _estimate takes a non-empty chunk)
            _expand_lifetimes(kept, *(np.empty(0),) * 3, np.empty(0, bool), out)
        elif off is None:
            _expand_lifetimes(kept, *estimator._estimate(*cols), out)
        else:
            _expand_lifetimes_par(kept, *estimator._estimate(*cols), out, off)
    return out


def _expand(est: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """Lifetimes aligned with all events: ``est`` at the kept ones, no estimate (NaN, False) elsewhere.

    Field by field through plain columns: a scatter of the packed records
    (``out[kept] = est``) costs about twice as much.
    """
    out = np.empty(kept.shape[0], dtype=LIFETIME_DTYPE)
    for name in LIFETIME_DTYPE.names:
        col = np.zeros(kept.shape[0], bool) if name == "valid" else np.full(kept.shape[0], np.nan)
        col[kept] = est[name]
        out[name] = col
    return out


class Detector:
    """Streaming detector: noise filter -> lifetime estimator -> edge image.

    Parameters
    ----------
    sensor_size : SensorSize or (width, height)
    buffer_params : BufferParams or mapping, optional
        Parameters of the filter.
    params : dataclass or mapping, optional
        Parameters of the estimator.
    use_buffer : bool, optional
        Run the filter (default: the method's registered default).
    clear_behind, invalid, display
        Passed to :class:`~evedge.detector.edges.EdgeImage` (``display`` names a policy).
    method : str
        Any registered estimator (default ``"intra"``) or ``package.module:factory``.
    filter : str, optional
        Any registered noise filter (default ``"buffer"``).
    n_tiles : int
        Row strips of the estimator run in parallel (numba threads), for a method
        registered with them (the built-in one; others run serially): the same
        bytes for any value. The strips keep their state between chunks (only
        their halo rows are refreshed per chunk), so a chunk costs no copy of the
        sensor's state.

    Notes
    -----
    :meth:`process` returns the events released by the filter (the buffer:
    at most ``tau_min_us`` late) with their lifetimes; :meth:`image_at` answers
    for any ``T`` not before the newest released event. All outputs
    concatenated equal :func:`detect` on the whole stream, restricted to the
    kept events.

    With the built-in buffer and estimator (the default) a chunk costs one pass
    that checks it while copying it into the buffer's slots, the buffer's rules,
    one pass that releases the decided events with their int64 columns, and the
    estimator and the edge image on those columns (no check, column copy or
    record unpacking between the stages), then one pass that packs the
    lifetimes; ``until_us`` releases once, at that time. Any other filter or
    estimator goes through their ``process``, checked. The bytes are the same
    (``tests/detector/test_pipeline.py`` compares each call's output with the
    stage-by-stage path's for several chunkings). Per-chunk fixed cost
    (``benchmarks/bench_streaming.py --base 2a1c4b7``, one-event chunks) 46-47 -> 13-14 us;
    at 2 M events/s the estimator's own ``process`` on the same chunks is then 87-88 % of the
    streamed CPU (the bench's docstring gives the figures).
    """

    def __init__(self, sensor_size, buffer_params=None, params=None, use_buffer: bool | None = None,
                 clear_behind: bool = False, invalid: str = "ignore", *, method: str = "intra",
                 filter: str | None = None, display: str | None = None, n_tiles: int = 1) -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        n_tiles = check_n_tiles(n_tiles, self.sensor_size.height)
        self.method = method
        self.filter_name = _default_filter(method, use_buffer, filter)
        self.use_buffer = self.filter_name is not None
        self.buffer = make_method(self.filter_name, self.sensor_size, buffer_params, kind="filter") \
            if self.filter_name else None
        # the built-in buffer releases, in order, events it took as checked chunks: no check of its output
        self._own_buffer = type(self.buffer) is EventBuffer
        self.estimator = make_method(method, self.sensor_size, _with_tiles(method, params, n_tiles), kind="estimator")
        self.edges = EdgeImage(self.sensor_size, clear_behind=clear_behind, invalid=invalid, display=display)
        # the built-in buffer and estimator: the released events' plain columns go from stage to stage
        # (no check, column copy or record packing between them; the same bytes)
        self._columns = self._own_buffer and type(self.estimator) is IntraPixelLifetime

    def reset(self) -> None:
        """Forget the stream."""
        if self.buffer is not None:
            self.buffer.reset()
        self.estimator.reset()
        self.edges.reset()

    def _run(self, released: np.ndarray, checked: bool = False):
        if not checked:  # the filter's output, checked once for the estimator and the edge image
            released = check_events(released, self.sensor_size, name=f"events released by filter {self.filter_name!r}")
        if released.shape[0] == 0:  # nothing to estimate or display: no stage call (each costs ~20-40 us)
            return released, empty_lifetimes(0)
        with validated(released, self.sensor_size):
            lifetimes = _check_estimate(self.method, self.estimator.process(released), released.shape[0])
            self.edges.process(released, lifetimes)
        return released, lifetimes

    def process(self, events: np.ndarray, until_us: int | None = None):
        """Feed a time-sorted chunk; return ``(released_events, lifetimes)``.

        ``until_us``: no event before it will come (as :meth:`advance_to`, e.g. the
        chunk's end on a driver's clock): the filter then also releases what it
        has decided by that time, and all released events go through the
        estimator and the edge image in one call each (``process(c)`` then
        ``advance_to(t)`` gives the same events and lifetimes, in two calls each).
        """
        if self._columns:
            if not (type(events) is np.ndarray and events.ndim == 1 and events.dtype == EVENT_DTYPE):
                events = check_events(events, self.sensor_size, name="chunk")  # converted (then checked again)
            taken = self.buffer._take(events, until_us)  # checks the chunk in the pass that copies it
            if taken is None:
                self._raise_check(events, until_us)
            return self._run_columns(*taken)
        events = check_events(events, self.sensor_size, name="chunk")
        if self.buffer is None:
            return self._run(events, checked=True)
        with validated(events, self.sensor_size):
            released = self.buffer.process(events)
        if until_us is not None and hasattr(self.buffer, "advance_to"):
            more = self.buffer.advance_to(until_us)
            if more.shape[0]:
                released = np.concatenate([released, more]) if released.shape[0] else more
        return self._run(released, self._own_buffer)

    def _raise_check(self, events, until_us) -> None:
        """The full checks of :meth:`process` (in its order) of a chunk that failed the one-pass check: they raise."""
        events = check_events(events, self.sensor_size, name="chunk")
        check_not_before(events, self.buffer._last_time)
        if until_us is not None:
            self.buffer._check_until(until_us, int(events["t"][-1]) if events.shape[0] else self.buffer._last_time)
        raise AssertionError("the one-pass chunk check refused a chunk the full checks accept")  # pragma: no cover

    def _run_columns(self, released: np.ndarray, cols):
        """:meth:`_run` of the built-in stages on the released events and their columns (``EventBuffer._take``)."""
        n = released.shape[0]
        if n == 0:
            return released, empty_lifetimes(0)
        lt, vx, vy, valid = self.estimator._estimate(*cols)
        self.edges._apply(*cols, lt, vx, vy, valid)
        out = np.empty(n, dtype=LIFETIME_DTYPE)
        _pack_lifetimes(lt, vx, vy, valid, out)
        return released, out

    def advance_to(self, t_us: int):
        """No event before ``t_us`` will come: release what the filter has decided; ``(events, lifetimes)``."""
        if self._columns:
            taken = self.buffer._take(None, t_us)
            if taken is None:
                self.buffer._check_until(t_us, self.buffer._last_time)
                raise AssertionError("the buffer refused an instant its check accepts")  # pragma: no cover
            return self._run_columns(*taken)
        if self.buffer is None or not hasattr(self.buffer, "advance_to"):
            return self._run(np.empty(0, dtype=EVENT_DTYPE))
        return self._run(self.buffer.advance_to(t_us), self._own_buffer)

    def flush(self):
        """End of stream: release what the filter still holds; ``(events, lifetimes)``."""
        if self.buffer is None:
            return self._run(np.empty(0, dtype=EVENT_DTYPE))
        if self._columns:
            return self._run_columns(*self.buffer._release(self.buffer.n_pending, True))
        return self._run(self.buffer.flush(), self._own_buffer)

    def image_at(self, t_us) -> np.ndarray:
        """Edge map at ``t_us`` (see :meth:`EdgeImage.image_at`)."""
        return self.edges.image_at(t_us)
