"""The protocols a method follows, one per kind, and the registry of methods.

Every method is registered once in :data:`METHODS` under one name; the CLI's
choices, the bench, the results, the figures' colours and labels and the
verdicts read it. A registered *factory* is called as
``factory(sensor_size, **params)`` and returns an object that follows the
protocol of its kind:

``"estimator"`` (:class:`LifetimeEstimator`)
    Streaming ``process(events) -> lifetimes`` and ``reset()``; ``lifetimes``
    is one :data:`~evedge.detector.result.LIFETIME_DTYPE` row per event of the
    chunk (lifetime in µs, normal flow in px/s, ``valid``), and feeding any
    chunking gives the one-shot bytes. Edge images come from the lifetimes
    through :class:`~evedge.detector.edges.EdgeImage` under a display policy
    (:data:`~evedge.detector.edges.DISPLAYS`): the policy is a parameter of
    the edge image, never part of a method's name.
``"filter"`` (:class:`NoiseFilter`)
    Streaming ``process(events) -> released`` (the kept events, in time order,
    possibly later than they arrived), ``flush() -> released`` at the end of
    the stream and ``reset()``. The one-shot keep mask is
    :func:`evedge.detector.pipeline.keep_mask`.
``"edges"`` (:class:`EdgeDetector`)
    Streaming ``process(events)``, ``image_at(t_us) -> bool (H, W)`` for any
    ``t_us`` not before the newest event, ``reset()``.

Entry metadata the pipeline reads: ``params`` (the frozen parameter dataclass,
used to validate, coerce and echo ``--param key=value``) and, for estimators,
``filter`` (the filter run before it by default, or None).

Third parties register through the entry-point group ``evedge.methods`` or
are named as ``package.module:factory``; a factory (usually a class) says its
kind with a ``kind`` attribute and may carry ``display_name`` and ``colour``.

Examples
--------
>>> from evedge.detector.protocols import METHODS
>>> METHODS.get("intra").display_name
'proposed (intra-pixel-area)'
>>> METHODS.names(kind="filter")
('buffer',)
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from evedge.registry import Registry

__all__ = ["EdgeDetector", "KINDS", "LifetimeEstimator", "METHODS", "NoiseFilter"]

#: The kinds of method, each with its protocol below.
KINDS = ("estimator", "filter", "edges")

#: The one registry of methods (built-ins register themselves in their modules).
METHODS = Registry("method", kinds=KINDS, entry_point_group="evedge.methods",
                   builtins=("evedge.detector.intra", "evedge.detector.mueggler", "evedge.detector.accumulate",
                             "evedge.detector.buffer"))


@runtime_checkable
class LifetimeEstimator(Protocol):
    """Per-event lifetime and normal flow, streaming (kind ``"estimator"``)."""

    def process(self, events: np.ndarray) -> np.ndarray:
        """LIFETIME_DTYPE rows, one per event of the time-sorted chunk."""

    def reset(self) -> None:
        """Forget the stream."""


@runtime_checkable
class NoiseFilter(Protocol):
    """Keeps or drops each event, streaming (kind ``"filter"``)."""

    def process(self, events: np.ndarray) -> np.ndarray:
        """The kept events decided so far, in time order."""

    def flush(self) -> np.ndarray:
        """End of stream: the kept events still held."""

    def reset(self) -> None:
        """Forget the stream."""


@runtime_checkable
class EdgeDetector(Protocol):
    """An edge image at any instant, streaming (kind ``"edges"``)."""

    def process(self, events: np.ndarray) -> None:
        """Take a time-sorted chunk."""

    def image_at(self, t_us: int) -> np.ndarray:
        """bool (H, W) edge map at ``t_us``."""

    def reset(self) -> None:
        """Forget the stream."""
