"""The whole detector: event buffer, then a lifetime estimator (paper sections 2.2-2.4).

:func:`detect` is the one-shot form; :class:`Detector` the streaming one
(buffer -> estimator -> edge image, with ``image_at(T)`` at any instant).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

import numpy as np

from evedge.events import EVENT_DTYPE

from ._checks import check_events, check_sensor_size
from ._tiles import check_n_tiles
from .buffer import BufferParams, EventBuffer, _filter
from .buffer import _check_params as _buffer_params
from .edges import EdgeImage
from .intra import IntraParams, IntraPixelLifetime
from .result import empty_lifetimes

__all__ = ["DetectionResult", "Detector", "detect", "METHODS"]

#: Lifetime methods and whether the event buffer runs before them by default.
METHODS = {"intra": True, "mueggler": False}


@dataclass
class DetectionResult:
    """Per-event output of :func:`detect`.

    Attributes
    ----------
    lifetimes : numpy.ndarray
        :data:`~evedge.detector.result.LIFETIME_DTYPE`, aligned with the input
        events; filtered events are invalid (NaN).
    kept : numpy.ndarray
        bool, True for events that passed the buffer (all True without buffer).
    """

    lifetimes: np.ndarray
    kept: np.ndarray


def _mueggler():
    try:
        return importlib.import_module("evedge.detector.mueggler")
    except ImportError as exc:  # the baseline lives in its own module, written separately
        raise RuntimeError(f"method 'mueggler' needs evedge.detector.mueggler: {exc}") from exc


def _check_method(method: str, use_buffer) -> bool:
    if method not in METHODS:
        raise ValueError(f"method must be one of {sorted(METHODS)}, got {method!r}")
    if use_buffer is None:
        return METHODS[method]
    if not isinstance(use_buffer, (bool, np.bool_)):
        raise TypeError(f"use_buffer must be a bool or None, got {use_buffer!r}")
    return bool(use_buffer)


def detect(events: np.ndarray, sensor_size, method: str = "intra", *, buffer_params: BufferParams | None = None,
           params=None, use_buffer: bool | None = None, n_tiles: int = 1) -> DetectionResult:
    """Run the event buffer and a lifetime estimator on a whole event array.

    Parameters
    ----------
    events : numpy.ndarray
        Time-sorted events of dtype :data:`evedge.events.EVENT_DTYPE`.
    sensor_size : SensorSize or (width, height)
    method : {"intra", "mueggler"}
        The paper's intra-pixel-area RANSAC, or Mueggler et al. 2015.
    buffer_params : BufferParams, optional
    params : IntraParams or MuegglerParams, optional
        Parameters of the estimator.
    use_buffer : bool, optional
        Default: True for ``intra`` (the paper's pipeline), False for
        ``mueggler`` (its original has no such filter).
    n_tiles : int
        Row strips the buffer and the ``intra`` estimator run on in parallel
        (default 1); any value gives the same bytes.

    Returns
    -------
    DetectionResult
        Filtered events never reach the estimator (they do not update its SAE).
    """
    sensor_size = check_sensor_size(sensor_size)
    buffered = _check_method(method, use_buffer)
    check_events(events, sensor_size)
    n_tiles = check_n_tiles(n_tiles, sensor_size.height)
    # validated once here; the stages below take the checked events as they are
    kept = (_filter(events, sensor_size, _buffer_params(buffer_params), n_tiles) if buffered
            else np.ones(events.shape[0], bool))
    sub = events[kept] if buffered else events
    if method == "intra":
        if params is not None and not isinstance(params, IntraParams):
            raise TypeError(f"params: method 'intra' takes IntraParams, got {type(params).__name__}")
        est = IntraPixelLifetime(sensor_size, params, n_tiles=n_tiles)._estimate(sub)
    else:
        est = _mueggler().estimate_lifetimes_mueggler(sub, sensor_size, params)
    lifetimes = empty_lifetimes(events.shape[0])
    lifetimes[kept] = est
    return DetectionResult(lifetimes, kept)


class Detector:
    """Streaming intra-pixel-area detector: buffer -> lifetimes -> edge image.

    Parameters
    ----------
    sensor_size : SensorSize or (width, height)
    buffer_params : BufferParams, optional
    params : IntraParams, optional
    use_buffer : bool
    clear_behind, invalid
        Passed to :class:`~evedge.detector.edges.EdgeImage`.

    Notes
    -----
    :meth:`process` returns the events released by the buffer (at most
    ``tau_min_us`` late) with their lifetimes; :meth:`image_at` answers for any
    ``T`` not before the newest released event. All outputs concatenated equal
    :func:`detect` on the whole stream, restricted to the kept events.
    """

    def __init__(self, sensor_size, buffer_params: BufferParams | None = None, params: IntraParams | None = None,
                 use_buffer: bool = True, clear_behind: bool = False, invalid: str = "ignore") -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        self.use_buffer = _check_method("intra", use_buffer)
        self.buffer = EventBuffer(self.sensor_size, buffer_params)
        self.estimator = IntraPixelLifetime(self.sensor_size, params)
        self.edges = EdgeImage(self.sensor_size, clear_behind=clear_behind, invalid=invalid)

    def reset(self) -> None:
        """Forget the stream."""
        self.buffer.reset()
        self.estimator.reset()
        self.edges.reset()

    def _run(self, released: np.ndarray):
        # the buffer validated these events: the later stages do not check them again
        lifetimes = self.estimator._estimate(released)
        self.edges._apply(released, lifetimes)
        return released, lifetimes

    def _run_unbuffered(self, events: np.ndarray):
        check_events(events, self.sensor_size)
        return self._run(events)

    def process(self, events: np.ndarray):
        """Feed a time-sorted chunk; return ``(released_events, lifetimes)``."""
        if not self.use_buffer:
            return self._run_unbuffered(events)
        return self._run(self.buffer.process(events))

    def advance_to(self, t_us: int):
        """No event before ``t_us`` will come: release what the buffer has decided; ``(events, lifetimes)``."""
        if not self.use_buffer:
            return self._run(np.empty(0, dtype=EVENT_DTYPE))
        return self._run(self.buffer.advance_to(t_us))

    def flush(self):
        """End of stream: release what the buffer still holds; ``(events, lifetimes)``."""
        if not self.use_buffer:
            return self._run(np.empty(0, dtype=EVENT_DTYPE))
        return self._run(self.buffer.flush())

    def image_at(self, t_us) -> np.ndarray:
        """Edge map at ``t_us`` (see :meth:`EdgeImage.image_at`)."""
        return self.edges.image_at(t_us)
