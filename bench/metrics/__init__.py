"""Metrics: registered functions from a detection and its dataset's truth to result rows.

Every metric is registered once in :data:`METRICS` (kind ``"per_event"`` or
``"frames"``) as ``metric(inp: GradeInput) -> list[dict]``; each dict holds
``reference``, ``section``, ``metric`` and ``value`` (the columns of
:mod:`evedge.bench.results` that the metric knows; the grader adds the rest).
A metric returns no rows when its inputs are absent (a detection without
lifetimes has no lifetime error). Add one with
``METRICS.register(name, function, kind=..., display_name=...)`` in a module
of this package (or any module, through the entry-point group
``evedge.metrics``).

Built-ins: ``lifetime_error`` (median relative error, p90, share estimated),
``normal_flow_error`` (angle and relative magnitude error of the normal
flow), ``noise_filter`` (precision and recall of the removed events against
the noise labels, share of signal kept), ``cdm`` (CDM of the edge frames
against the exact edges and against Canny of the grey frames).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from evedge.registry import Registry

__all__ = ["GradeInput", "METRICS", "section_masks"]

METRICS = Registry("metric", kinds=("per_event", "frames"), entry_point_group="evedge.metrics",
                   builtins=("evedge.bench.metrics.per_event", "evedge.bench.metrics.frames"))


@dataclass
class GradeInput:
    """What a metric sees.

    Attributes
    ----------
    events : numpy.ndarray
        The dataset's events (EVENT_DTYPE).
    sensor_size : SensorSize
    sections : dict
        name -> (start_us, end_us), ``all`` included.
    truth : numpy.ndarray or None
        Per-event truth (``TRUTH_DTYPE`` of the simulator), aligned with ``events``.
    lifetime_us, vx_px_s, vy_px_s : numpy.ndarray or None
        The detection's per-event estimates (NaN: no estimate), aligned with ``events``.
    kept : numpy.ndarray or None
        The detection's noise-filter decision per event.
    edge_t_us : numpy.ndarray or None
        Times of the detection's edge frames.
    edge_images : numpy.ndarray or None
        bool (n, H, W) edge frames.
    frames, exact_edges : Frames or None
        The dataset's grey frames and exact edge maps.
    """

    events: np.ndarray
    sensor_size: object
    sections: dict
    truth: np.ndarray | None = None
    lifetime_us: np.ndarray | None = None
    vx_px_s: np.ndarray | None = None
    vy_px_s: np.ndarray | None = None
    kept: np.ndarray | None = None
    edge_t_us: np.ndarray | None = None
    edge_images: np.ndarray | None = None
    frames: object = None
    exact_edges: object = None
    options: dict = field(default_factory=dict)


def section_masks(t_us: np.ndarray, sections: dict) -> dict[str, np.ndarray]:
    """name -> bool mask of ``start <= t < end`` per section."""
    t = np.asarray(t_us)
    return {name: (t >= a) & (t < b) for name, (a, b) in sections.items()}
