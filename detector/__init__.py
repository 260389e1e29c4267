"""The detector: event buffer, SAE, intra-pixel-area RANSAC lifetimes, edge images.

Implements Lee, Kim & Kim, "Edge Detection for Event Cameras using
Intra-pixel-area Events" (BMVC 2019) and, beside it, its baselines (Mueggler et
al. 2015 lifetimes; accumulation over a time window or an event count). Never
imports :mod:`evedge.sim` or :mod:`evedge.bench`: a real camera has no ground truth.

Public API (loaded on first use, so ``import evedge.detector`` stays cheap):

- :mod:`~evedge.detector.buffer`: ``BufferParams``, ``EventBuffer``, ``filter_events``
- :mod:`~evedge.detector.sae`: ``SurfaceOfActiveEvents``, ``NEVER_US``
- :mod:`~evedge.detector.intra`: ``IntraParams``, ``IntraPixelLifetime``,
  ``estimate_lifetimes``, ``fit_window``, ``fit_windows``, ``WindowFit``
- :mod:`~evedge.detector.edges`: ``EdgeImage``, ``edge_frames``
- :mod:`~evedge.detector.pipeline`: ``detect``, ``Detector``, ``DetectionResult``, ``make_method``,
  ``keep_mask``, ``edge_frames_of``
- :mod:`~evedge.detector.protocols`: ``METHODS`` (the method registry), ``LifetimeEstimator``,
  ``NoiseFilter``, ``EdgeDetector``
- :mod:`~evedge.detector.result`: ``LIFETIME_DTYPE``, ``empty_lifetimes``
- ``free_scratch``: release the scratch memory the parallel strips keep between calls
- baselines: ``MuegglerParams``, ``MuegglerLifetime``, ``estimate_lifetimes_mueggler``
  (:mod:`~evedge.detector.mueggler`); ``accumulate_time``, ``accumulate_count``,
  ``TimeWindowAccumulator``, ``CountWindowAccumulator`` (:mod:`~evedge.detector.accumulate`)
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "BufferParams": "buffer",
    "EventBuffer": "buffer",
    "filter_events": "buffer",
    "SurfaceOfActiveEvents": "sae",
    "NEVER_US": "sae",
    "IntraParams": "intra",
    "IntraPixelLifetime": "intra",
    "estimate_lifetimes": "intra",
    "fit_window": "intra",
    "fit_windows": "intra",
    "WindowFit": "intra",
    "NeighbourFill": "fill",
    "fill_lifetimes": "fill",
    "EdgeImage": "edges",
    "edge_frames": "edges",
    "detect": "pipeline",
    "Detector": "pipeline",
    "DetectionResult": "pipeline",
    "make_method": "pipeline",
    "keep_mask": "pipeline",
    "edge_frames_of": "pipeline",
    "METHODS": "protocols",
    "LifetimeEstimator": "protocols",
    "NoiseFilter": "protocols",
    "EdgeDetector": "protocols",
    "LIFETIME_DTYPE": "result",
    "empty_lifetimes": "result",
    "free_scratch": "_workspace",
    "MuegglerParams": "mueggler",
    "MuegglerLifetime": "mueggler",
    "estimate_lifetimes_mueggler": "mueggler",
    "accumulate_time": "accumulate",
    "accumulate_count": "accumulate",
    "TimeWindowAccumulator": "accumulate",
    "CountWindowAccumulator": "accumulate",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'evedge.detector' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
