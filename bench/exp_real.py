"""Experiment 5: CDM against Canny on real APS frames (Event Camera Dataset ``slider_depth``).

The events of ``slider_depth`` at hand span 0.0038-0.1742 s; the frames inside
that span (4 of them, at 38.8, 77.5, 116.3 and 155.1 ms) are the references.
At each such frame time every method's edge map is compared by CDM with the
Canny map of the frame, for every Canny setting.

Both lifetime methods run under each display policy (see
:mod:`evedge.bench.methods`); the figure shows the primary policy (predecessor
display) and the accumulation baselines, the tables and ``results.json`` every
policy.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._files import relative_figures, save_figure, write_csv_atomic, write_json_atomic
from ._plot import pyplot
from .canny import CANNY_SETTINGS
from .frame_eval import canny_references, cdm_table, summarise
from .methods import (ACCUMULATION_METHODS, DISPLAY_LABELS, DISPLAYS, PRIMARY_DISPLAY, add_method, check_displays,
                      colour, compared, display_record, edge_maps, label, methods_for)

#: Where the shared real recordings live, relative to the repository (``../shared/realdata``).
def default_realdata_dir(data_dir=None) -> Path:
    """Folder of the real recordings: ``data_dir``, else ``$EVEDGE_DATA``, else ``<repo>/../shared/realdata``.

    The last is where a repository checkout finds them (it sits beside ``shared/``).
    """
    import os

    if data_dir is not None:
        return Path(data_dir)
    if os.environ.get("EVEDGE_DATA"):
        return Path(os.environ["EVEDGE_DATA"])
    return Path(__file__).resolve().parents[1] / ".." / "shared" / "realdata"


class NoFramesError(ValueError):
    """The recording has no frame within its events' time span (nothing to compare with Canny)."""


def frames_inside_events(recording) -> np.ndarray:
    """Indices of the frames whose time lies within the span of the events."""
    if recording.frames is None or recording.events.size == 0:
        return np.zeros(0, dtype=np.int64)
    t0, t1 = recording.events["t"][0], recording.events["t"][-1]
    ft = recording.frames.t_us
    return np.flatnonzero((ft >= t0) & (ft <= t1))


def count_for(references: dict[str, np.ndarray]) -> int:
    """Event count of the fixed-count baseline: mean edge pixels of the first reference (>= 1)."""
    first = next(iter(references.values()))
    if first.shape[0] == 0:
        return 1000
    return max(1, int(round(first.reshape(first.shape[0], -1).sum(axis=1).mean())))


def run_real(out_dir, *, path=None, quick: bool = False, progress: bool = True, name: str = "slider_depth",
             keep_maps: bool = False, displays=DISPLAYS, methods_extra=(), data_dir=None) -> dict:
    """CDM against Canny at the real frames inside the events.

    Parameters
    ----------
    out_dir : path
        Output directory (``real_<name>.csv``, ``real_<name>.json``, PNG).
    path : path, optional
        Recording with frames (default ``../shared/realdata/slider_depth``).
    quick : bool
        Only the first Canny setting.
    progress : bool
    name : str
        Label of the recording in the results.
    keep_maps : bool
        Also return the grey frames, Canny and method maps (for the qualitative panel).
    displays : sequence of str
        Display policies of the lifetime methods (default both); recorded in the result.
    methods_extra : sequence of str
        Other registered methods (or ``package.module:factory``) compared beside
        the paper's (see :func:`evedge.bench.methods.add_method`).
    data_dir : path, optional
        Folder of the real recordings (see :func:`default_realdata_dir`).

    Returns
    -------
    dict
        ``{"recordings": {name: {"frame_t_us": [...], "canny_settings": [...],
        "cdm": {reference: {method: [per frame]}}, "summary": {reference: {method: {...}}},
        "count_n": int, "displays": {...}}}, "figures": [...]}``
    """
    from evedge.io import read_events

    displays = check_displays(displays, "run_real")
    out_dir = Path(out_dir)
    path = Path(path) if path is not None else default_realdata_dir(data_dir) / "slider_depth"
    if not path.exists():
        raise FileNotFoundError(f"run_real: recording not found: {path}")
    rec = read_events(path)
    idx = frames_inside_events(rec)
    if idx.size == 0:
        raise NoFramesError(f"run_real: no frame of {path} lies within its events' time span")
    times = rec.frames.t_us[idx]
    grey = rec.frames.images[idx]
    settings = CANNY_SETTINGS[:1] if quick else CANNY_SETTINGS
    refs = canny_references(grey, settings)
    count_n = count_for(refs)
    methods = methods_for(displays) + ACCUMULATION_METHODS + methods_for(displays, bases=("mueggler_t0",))
    for extra in methods_extra:
        methods += tuple(k for k in add_method(extra) if compared(k).display in (None, *displays))
    maps, _ = edge_maps(rec.events, rec.sensor_size, times, methods=methods, count_n=count_n)
    table = cdm_table(maps, refs, progress=progress, desc=f"CDM {name}")
    summary = {ref: {m: summarise(v) for m, v in per.items()} for ref, per in table.items()}
    rows = [[name, ref, m, i, int(times[i]), float(v[i])] for ref, per in table.items()
            for m, v in per.items() for i in range(len(times))]
    write_csv_atomic(out_dir / f"real_{name}.csv", ["recording", "reference", "method", "frame", "t_us", "cdm"], rows)
    fig_path = _plot(out_dir, name, times, table)
    res = {"frame_t_us": times, "frame_index": idx, "canny_settings": [s.as_dict() for s in settings],
           "cdm": table, "summary": summary, "count_n": count_n, "source": str(path),
           "displays": display_record(displays)}
    out = {"recordings": {name: res}, "figures": relative_figures(out_dir, [fig_path])}
    write_json_atomic(out_dir / f"real_{name}.json", out)
    if keep_maps:
        out["_maps"] = {"grey": grey, "times": times, "canny": refs[next(iter(refs))], "maps": maps}
    return out


def _plot(out_dir: Path, name: str, times, table) -> Path:
    plt = pyplot()
    refs = list(table)
    fig, axes = plt.subplots(1, len(refs), figsize=(4.2 * len(refs), 3.6), squeeze=False)
    for ax, ref in zip(axes[0], refs):
        for m, v in table[ref].items():
            if compared(m).display not in (None, PRIMARY_DISPLAY):
                continue  # the figure shows the primary display; the tables have both
            ax.plot(np.asarray(times) / 1e3, v, marker="o", color=colour(m), label=label(m))
        ax.set_title(f"{name}: CDM vs {ref}", fontsize=9)
        ax.set_xlabel("frame time (ms)")
        ax.set_ylabel("CDM")
        ax.set_ylim(0, 100)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(f"lifetime methods shown with the {DISPLAY_LABELS[PRIMARY_DISPLAY]} (primary policy)",
                 fontsize=9, y=1.03)
    return save_figure(fig, out_dir / f"real_{name}.png")
