"""Frame metrics: CDM of a detection's edge frames against the exact edges and against Canny.

A detection frame is graded at its own time ``T`` when the dataset has an
exact edge map (and a grey frame, for Canny) at exactly ``T``; other frames
are counted (``frames_without_reference``) and left out.
"""

from __future__ import annotations

import numpy as np

from . import METRICS, GradeInput


def _at(stack, times: np.ndarray):
    """Index into ``stack`` of each time (-1 where the stack has no image at that exact time)."""
    if stack is None or len(stack) == 0:
        return np.full(times.size, -1)
    pos = np.searchsorted(stack.t_us, times)
    pos_c = np.minimum(pos, len(stack) - 1)
    return np.where(stack.t_us[pos_c] == times, pos_c, -1)


def cdm_frames(inp: GradeInput) -> list[dict]:
    """Median CDM per section (and per frame) against ``exact`` and each Canny setting.

    Rows: ``median_cdm`` per section, ``cdm`` per frame (section ``frame_<i>``),
    ``n_frames`` per section and ``frames_without_reference``.
    """
    from ..canny import CANNY_SETTINGS, canny_edges
    from ..cdm import cdm

    if inp.edge_images is None or inp.edge_t_us is None or len(inp.edge_t_us) == 0:
        return []
    times = np.asarray(inp.edge_t_us, dtype=np.int64)
    images = np.asarray(inp.edge_images, dtype=bool)
    settings = CANNY_SETTINGS[: inp.options.get("canny_settings", 1)]
    refs = {}
    i_exact = _at(inp.exact_edges, times)
    if (i_exact >= 0).any():
        refs["exact"] = (i_exact, lambda i: np.asarray(inp.exact_edges.images[i], bool))
    i_grey = _at(inp.frames, times)
    if (i_grey >= 0).any():
        for s in settings:
            refs[f"canny_{s.name}"] = (i_grey, lambda i, s=s: canny_edges(inp.frames.images[i], s))
    rows = []
    graded = np.zeros(times.size, bool)
    for ref, (idx, make) in refs.items():
        values = np.full(times.size, np.nan)
        for k in np.flatnonzero(idx >= 0):
            values[k] = cdm(images[k], make(int(idx[k])))
            rows.append({"reference": ref, "section": f"frame_{k}", "metric": "cdm", "value": float(values[k])})
        graded |= idx >= 0
        for name, (a, b) in inp.sections.items():
            sel = (times >= a) & (times < b) & np.isfinite(values)
            rows.append({"reference": ref, "section": name, "metric": "median_cdm",
                         "value": float(np.median(values[sel])) if sel.any() else np.nan})
            rows.append({"reference": ref, "section": name, "metric": "n_frames", "value": float(sel.sum())})
    rows.append({"reference": "", "section": "all", "metric": "frames_without_reference",
                 "value": float((~graded).sum())})
    return rows


METRICS.register("cdm", cdm_frames, kind="frames", display_name="CDM vs exact edges and Canny")
