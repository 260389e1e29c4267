"""The renderer protocol: what the event converter needs from a scene.

A renderer answers, for any time ``t_s`` (seconds), the linear intensity image,
the motion field and the exact edge map, and bounds the image speed over a time
interval (used to bound the sampling step). Planar analytic renderers
(:mod:`evedge.sim.planar`) and the 3-D mesh renderer
(:class:`evedge.sim.render3d.MeshRenderer`) implement it.

A renderer whose intensity is not a continuous function of time (e.g.
supersampled: it jumps as sub-samples flip) should set an attribute
``continuous_in_time = False``; the converter then samples by ESIM's predicted
rule instead of verifying each step (see :mod:`evedge.sim.converter`).

A renderer may also offer ``intensity_into(t_s, out, dirty) -> boxes`` (the
planar ones do, see :meth:`evedge.sim.planar._CoverageRenderer.intensity_into`):
it redraws into a reused flat buffer and returns boxes outside which the image
is its constant background; the converter then reuses two buffers and scans
only those boxes (same events, fewer memory passes).

A renderer may also offer ``pixel_intensity(pix, t_s) -> I``: the exact
intensity of flat pixels ``pix`` at times ``t_s`` (one per pixel; the planar
ones do). With geometric truth it lets the converter solve every crossing
for its exact instant instead of interpolating between samples.

A renderer with fixed sample times (frames input) offers
``next_sample_s(t_s)``; the converter then samples exactly those times. It may
also offer ``samples(t_s, until_s, max_n) -> (times_s, images)``: the next
samples after ``t_s`` (up to ``max_n``, the last one the first at or after
``until_s``) as one ``(n, H, W)`` array, which the converter turns into
events in one kernel call per batch (same events as sample by sample).

Renderers that know their geometry may also implement :class:`GeometricTruth`;
the simulator then takes each event's flow and brightness-gradient direction
from the geometry at the event's exact time instead of from the sampled frames.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Renderer(Protocol):
    """A scene seen by the sensor, queried at any time.

    Attributes
    ----------
    width, height : int
        Image size in pixels; images are indexed ``[y, x]``.
    """

    width: int
    height: int

    def intensity(self, t_s: float) -> np.ndarray:
        """(H, W) float64 linear intensity in [0, 1] at time ``t_s``."""
        ...

    def flow(self, t_s: float) -> np.ndarray:
        """(2, H, W) float64 motion field ``vx, vy`` in px/s at time ``t_s``."""
        ...

    def edges(self, t_s: float) -> np.ndarray:
        """(H, W) bool exact edge map at time ``t_s``."""
        ...

    def max_speed_px_s(self, t0_s: float, t1_s: float) -> float:
        """Upper bound of the image speed (px/s) over ``[t0_s, t1_s]``."""
        ...

    def close(self) -> None:
        """Release resources (GL contexts); idempotent."""
        ...


@runtime_checkable
class GeometricTruth(Protocol):
    """Optional: exact per-point ground truth from the scene geometry."""

    def point_truth(self, x: np.ndarray, y: np.ndarray, t_s: np.ndarray) -> tuple[np.ndarray, ...]:
        """Flow and brightness-gradient direction at pixel centres ``(x, y)`` and times ``t_s``.

        Returns
        -------
        vx, vy, nx, ny : numpy.ndarray
            Flow in px/s and the unit normal of the nearest shape boundary,
            pointing towards the brighter side (the direction of the
            brightness gradient).
        """
        ...
