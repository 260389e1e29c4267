"""Experiment 4: qualitative panel (paper figs. 1 and 8).

Side by side for one frame: the grey frame, its Canny edges (the paper's
MATLAB ``edge(I, 'Canny', 0.3)`` equivalent), the proposed method, Mueggler et
al. (both with the primary display policy, the predecessor's display that
clears the pixel behind each event), 1 ms and 30 ms accumulation. One row per chosen frame; rows come from the
other experiments' maps (simulated slow and fast frames, a real frame) or, when
run alone, from the real ``slider_depth`` frames.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._files import relative_figures, save_figure, write_json_atomic
from ._plot import pyplot
from .canny import CANNY_SETTINGS, canny_edges
from .methods import DISPLAY_LABELS, PRIMARY_DISPLAY, edge_maps, method_key
from .methods import label as method_label

#: Result keys of the panel's columns: the lifetime methods under the primary display policy.
PANEL_METHODS = (method_key("proposed", PRIMARY_DISPLAY), method_key("mueggler", PRIMARY_DISPLAY),
                 "acc_1ms", "acc_30ms")


def panel_row(title: str, grey: np.ndarray, canny: np.ndarray, maps: dict[str, np.ndarray]) -> dict:
    """One row of the panel: a frame, its Canny map and one map per method in :data:`PANEL_METHODS`."""
    missing = [m for m in PANEL_METHODS if m not in maps]
    if missing:
        raise ValueError(f"panel_row: maps lack {missing}")
    return {"title": title, "grey": np.asarray(grey), "canny": np.asarray(canny, bool),
            "maps": {m: np.asarray(maps[m], bool) for m in PANEL_METHODS}}


def rows_from_maps(label: str, kept: dict, picks) -> list[dict]:
    """Panel rows for frame indices ``picks`` of an experiment's kept maps (``_maps``)."""
    rows = []
    for i in picks:
        t_ms = float(kept["times"][i]) / 1e3
        rows.append(panel_row(f"{label} t={t_ms:.0f} ms", kept["grey"][i], kept["canny"][i],
                              {m: kept["maps"][m][i] for m in PANEL_METHODS}))
    return rows


def run_qualitative(out_dir, *, rows: list[dict] | None = None, quick: bool = False, progress: bool = True,
                    data_dir=None) -> dict:
    """Draw the panel.

    Parameters
    ----------
    out_dir : path
    rows : list of dict, optional
        From :func:`panel_row`; default: two frames of the real ``slider_depth``.
    quick, progress : bool
        Unused beyond the default rows (kept for a uniform experiment signature).
    data_dir : path, optional
        Folder of the real recordings, for the default rows (see :func:`~evedge.bench.exp_real.default_realdata_dir`).

    Returns
    -------
    dict
        ``{"rows": [titles], "edge_pixels": {title: {method: count}}, "figures": [path]}``
    """
    out_dir = Path(out_dir)
    if rows is None:
        rows = _default_rows(data_dir)
    if not rows:
        raise ValueError("run_qualitative: no rows to draw")
    plt = pyplot()
    cols = ["grey", "canny"] + list(PANEL_METHODS)
    fig, axes = plt.subplots(len(rows), len(cols), figsize=(3.0 * len(cols), 2.5 * len(rows)), squeeze=False)
    counts = {}
    for r, row in enumerate(rows):
        counts[row["title"]] = {"canny": int(row["canny"].sum())}
        for c, col in enumerate(cols):
            ax = axes[r, c]
            if col == "grey":
                ax.imshow(row["grey"], cmap="gray")
            elif col == "canny":
                ax.imshow(~row["canny"], cmap="gray", vmin=0, vmax=1)
            else:
                ax.imshow(~row["maps"][col], cmap="gray", vmin=0, vmax=1)
                counts[row["title"]][col] = int(row["maps"][col].sum())
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                label = {"grey": "grey frame", "canny": "Canny (MATLAB 0.3)"}.get(col) or method_label(col)
                ax.set_title(label, fontsize=8)
            if c == 0:
                ax.set_ylabel(row["title"], fontsize=7)
    fig.suptitle(f"Lifetime methods shown with the {DISPLAY_LABELS[PRIMARY_DISPLAY]} (the primary display "
                 "policy, as in the authors' code); black: edge", fontsize=9)
    path = save_figure(fig, out_dir / "qualitative.png", dpi=130)
    out = {"rows": [row["title"] for row in rows], "edge_pixels": counts, "figures": relative_figures(out_dir, [path]),
           "display": PRIMARY_DISPLAY}
    write_json_atomic(out_dir / "qualitative.json", out)
    return out


def _default_rows(data_dir=None) -> list[dict]:
    from evedge.io import read_events

    from .exp_real import default_realdata_dir, frames_inside_events

    path = default_realdata_dir(data_dir) / "slider_depth"
    rec = read_events(path)
    idx = frames_inside_events(rec)[1:3]
    times = rec.frames.t_us[idx]
    maps, _ = edge_maps(rec.events, rec.sensor_size, times, methods=PANEL_METHODS)
    return [panel_row(f"slider_depth t={times[k] / 1e3:.0f} ms", rec.frames.images[i],
                      canny_edges(rec.frames.images[i], CANNY_SETTINGS[0]),
                      {m: maps[m][k] for m in PANEL_METHODS}) for k, i in enumerate(idx)]
