"""Experiment 3: similarity over time on a slow-then-fast sequence (paper fig. 9).

The simulated ``shapes_translation`` scene moves slowly, then fast. At every
frame time (from 30 ms after the first event on, so that no method is judged
before its window could fill) each method's edge map is compared by CDM with

* Canny on the clean grey frame, for each Canny setting (``canny_<name>``), and
* the simulator's exact edge map at that time (``exact``: every pixel whose
  open square a boundary crosses) and its thin exact edge map (``exact_thin``:
  one pixel per boundary crossing of each row and column, as thin as Canny's;
  :mod:`evedge.sim.thin_edges`).

Both lifetime methods run under each display policy of
:mod:`evedge.bench.methods` (``proposed``/``mueggler``: predecessor display,
the primary one; ``proposed_noclear``/``mueggler_noclear``: lifetime only).

Box plots per section (slow, fast) as in the paper; medians per section,
truth and method go to ``results.json`` under ``cdm``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._files import relative_figures, save_figure, write_csv_atomic, write_json_atomic
from ._plot import pyplot
from .canny import CANNY_SETTINGS
from .exp_real import count_for
from .frame_eval import canny_references, cdm_table, summarise
from .methods import (ACCUMULATION_METHODS, COMPARED, DISPLAY_LABELS, DISPLAYS, PRIMARY_DISPLAY, add_method,
                      check_displays, colour, compared, display_record, edge_maps, label, methods_for)

#: Frames earlier than this after the first event are skipped (the longest window, 30 ms).
WARMUP_US = 30_000


def scenes_dir() -> Path:
    """The shipped scenes: the package data ``evedge.scenes`` (the repository's ``scenes/``)."""
    from importlib.resources import files

    try:
        return Path(str(files("evedge.scenes")))
    except ModuleNotFoundError:  # an old editable install that predates the package data
        return Path(__file__).resolve().parents[1] / "scenes"


def shipped_scenes() -> tuple[str, ...]:
    """Names of the shipped scenes (``shapes_translation``, ``stripes``, ...)."""
    return tuple(sorted(p.stem for p in scenes_dir().glob("*.toml")))


def scene_path(scene) -> Path:
    """The TOML file of a scene given by shipped name (``stripes``) or by path (``my/scene.toml``).

    Raises
    ------
    FileNotFoundError
        Naming the scene and the shipped ones.
    """
    text = str(scene)
    if text.endswith(".toml") or "/" in text or isinstance(scene, Path):
        path = Path(scene)
        if not path.is_file():
            raise FileNotFoundError(f"scene file not found: {path}")
        return path
    path = scenes_dir() / f"{text}.toml"
    if not path.is_file():
        raise FileNotFoundError(f"no shipped scene {text!r} (in {scenes_dir()}); shipped: "
                                f"{', '.join(shipped_scenes()) or 'none'}; or give a path to a .toml file")
    return path


def scene_label(scene) -> str:
    """The name a scene goes by in results: its shipped name or its file's stem."""
    return Path(str(scene)).stem if str(scene).endswith(".toml") else str(scene)


def simulate_scene(name, *, seed: int = 0, duration_s: float | None = None,
                   frame_rate_hz: float | None = None, progress: bool = True):
    """Load a scene (shipped name or TOML path, see :func:`scene_path`) and simulate it (events, truth,
    frames, exact edges)."""
    from evedge.sim import load_scene, simulate

    try:
        path = scene_path(name)
    except FileNotFoundError as err:
        raise FileNotFoundError(f"simulate_scene: {err}") from None
    kwargs = {"seed": seed, "duration_s": duration_s, "progress": progress}
    if frame_rate_hz is not None:
        kwargs["frame_rate_hz"] = frame_rate_hz
    return simulate(load_scene(path), **kwargs)


def _thin_exact(rec, times_us):
    """The simulator's thin exact edge maps (:func:`evedge.sim.thin_edge_map`) at ``times_us``, or None.

    Rebuilt from the scene stored in the recording's metadata; None when it has
    none or its renderer has no analytic geometry (mesh scenes).
    """
    from evedge.sim import parse_scene, thin_edge_map

    raw = rec.metadata.get("scene") if isinstance(rec.metadata, dict) else None
    if not isinstance(raw, dict):
        return None
    scene = parse_scene(raw, str(rec.metadata.get("scene_file", "<recording>")))
    try:
        return np.stack([thin_edge_map(scene, float(t) / 1e6) for t in times_us]) if len(times_us) else None
    except NotImplementedError:
        return None


def sections_us(metadata: dict, t_end_us: int) -> dict[str, tuple[int, int]]:
    """The named time sections (e.g. slow, fast) of a simulated recording, in microseconds.

    Accepts ``metadata["sections"]`` as a mapping name -> (start, end) or a list of
    mappings with ``name`` and ``start``/``end`` (keys ending in ``_s`` are seconds,
    ``_us`` microseconds; bare ``start``/``end`` are taken as seconds). Without
    sections the whole recording is one section ``all``.
    """
    sec = metadata.get("sections") if isinstance(metadata, dict) else None
    out: dict[str, tuple[int, int]] = {}

    def _time(d: dict, key: str):
        for suffix, scale in (("_us", 1.0), ("_s", 1e6), ("", 1e6)):
            if key + suffix in d:
                return int(round(float(d[key + suffix]) * scale))
        raise ValueError(f"sections: entry {d} lacks {key}")

    if isinstance(sec, dict):
        for name, val in sec.items():
            if isinstance(val, dict):
                out[name] = (_time(val, "start"), _time(val, "end"))
            else:
                a, b = val
                out[name] = (int(round(float(a) * 1e6)), int(round(float(b) * 1e6)))
    elif isinstance(sec, (list, tuple)):
        for val in sec:
            out[str(val["name"])] = (_time(val, "start"), _time(val, "end"))
    if not out:
        out["all"] = (0, int(t_end_us) + 1)
    return out


def run_similarity(out_dir, *, recording=None, scene: str = "shapes_translation", quick: bool = False,
                   progress: bool = True, seed: int = 0, duration_s: float | None = None,
                   frame_rate_hz: float | None = None, max_frames: int | None = None,
                   keep_maps: bool = False, diagnostics: bool = True, displays=DISPLAYS, methods_extra=()) -> dict:
    """CDM over time against Canny and exact edges, per method; box plots per section.

    Parameters
    ----------
    out_dir : path
    recording : Recording, optional
        A simulated recording with ``frames`` and ``edges``; simulated from
        ``scene`` when not given.
    scene : str
        A shipped scene's name (default ``shapes_translation``) or a scene TOML file.
    quick : bool
        Only the first Canny setting and at most 24 frames (evenly spread).
    progress : bool
    seed, duration_s, frame_rate_hz
        Passed to the simulator.
    max_frames : int, optional
        Evaluate at most this many frames, evenly spread over the sequence.
    keep_maps : bool
        Also return grey frames and maps (for the qualitative panel).
    diagnostics : bool
        Also run :data:`~evedge.bench.methods.DIAGNOSTIC_METHODS` and compute
        the explanatory numbers (edge pixels per reference pixel, lifetime
        errors against the simulator's truth, per section).
    displays : sequence of str
        Display policies of the lifetime methods (default both, see
        :data:`evedge.bench.methods.DISPLAYS`); recorded in the result.
    methods_extra : sequence of str
        Other registered methods (or ``package.module:factory``) compared beside
        the paper's (see :func:`evedge.bench.methods.add_method`).

    Returns
    -------
    dict
        ``{"scenes": {scene: {"sections_us": {...}, "frame_t_us": [...],
        "frame_section": [...], "cdm_per_frame": {truth: {method: [...]}},
        "cdm": {truth: {method: {section: summary}}}, "count_n": int, "displays": {...}}},
        "figures": [...]}``; ``method`` is a result key (see :func:`evedge.bench.methods.method_key`).
    """
    displays = check_displays(displays, "run_similarity")
    out_dir = Path(out_dir)
    rec = recording if recording is not None else simulate_scene(
        scene, seed=seed, duration_s=duration_s, frame_rate_hz=frame_rate_hz, progress=progress)
    scene = scene_label(scene)
    if rec.frames is None:
        raise ValueError("run_similarity: the recording has no grey frames")
    t_first = int(rec.events["t"][0]) if rec.events.size else 0
    t_last = int(rec.events["t"][-1]) if rec.events.size else 0
    ft = rec.frames.t_us
    idx = np.flatnonzero((ft >= t_first + WARMUP_US) & (ft <= t_last))
    if max_frames is None and quick:
        max_frames = 24
    if max_frames is not None and idx.size > max_frames:
        idx = idx[np.unique(np.linspace(0, idx.size - 1, max_frames).round().astype(int))]
    if idx.size == 0:
        raise ValueError("run_similarity: no frame lies within the events (after the 30 ms warm-up)")
    times = ft[idx]
    grey = rec.frames.images[idx]
    settings = CANNY_SETTINGS[:1] if quick else CANNY_SETTINGS
    refs = canny_references(grey, settings)
    if rec.edges is not None:
        et = rec.edges.t_us
        pos = np.searchsorted(et, times)
        if np.all(pos < et.size) and np.array_equal(et[np.minimum(pos, et.size - 1)], times):
            refs["exact"] = rec.edges.images[pos].astype(bool)
    thin = _thin_exact(rec, times)
    if thin is not None:
        refs["exact_thin"] = thin
    count_n = count_for(refs)
    methods = methods_for(displays) + ACCUMULATION_METHODS
    if diagnostics:
        methods += methods_for(displays, bases=("mueggler_t0",))
    for extra in methods_extra:
        methods += tuple(k for k in add_method(extra) if compared(k).display in (None, *displays))
    maps, runs = edge_maps(rec.events, rec.sensor_size, times, methods=methods, count_n=count_n)
    table = cdm_table(maps, refs, progress=progress, desc=f"CDM {scene}")
    sections = sections_us(rec.metadata, t_last)
    frame_section = np.array([_section_of(sections, t) for t in times], dtype=object)
    summary = {}
    for ref, per in table.items():
        summary[ref] = {}
        for m, v in per.items():
            summary[ref][m] = {name: summarise(v[frame_section == name]) for name in sections}
            summary[ref][m]["all"] = summarise(v)
    rows = [[scene, ref, m, i, int(times[i]), frame_section[i], float(v[i])]
            for ref, per in table.items() for m, v in per.items() for i in range(len(times))]
    write_csv_atomic(out_dir / f"similarity_{scene}.csv",
                     ["scene", "reference", "method", "frame", "t_us", "section", "cdm"], rows)
    figures = _plot(out_dir, scene, times, frame_section, sections, table)
    res = {"sections_us": sections, "frame_t_us": times, "frame_section": list(frame_section),
           "canny_settings": [s.as_dict() for s in settings], "cdm_per_frame": table, "cdm": summary,
           "count_n": count_n, "n_events": int(rec.events.size), "displays": display_record(displays),
           "diagnostics": _diagnostics(rec, maps, refs, runs, sections, frame_section) if diagnostics else {},
           "metadata": {k: v for k, v in rec.metadata.items() if isinstance(v, (str, int, float, bool))}}
    out = {"scenes": {scene: res}, "figures": relative_figures(out_dir, figures)}
    write_json_atomic(out_dir / f"similarity_{scene}.json", out)
    if keep_maps:
        out["_maps"] = {"grey": grey, "times": times, "canny": refs[next(iter(refs))], "maps": maps,
                        "frame_section": frame_section, "exact": refs.get("exact")}
    return out


def _section_of(sections: dict, t: int):
    hit = [name for name, (a, b) in sections.items() if a <= t < b]
    return hit[0] if hit else None


def _diagnostics(rec, maps, refs, runs, sections, frame_section) -> dict:
    """Numbers that explain the CDM: map sizes and lifetime errors per section.

    ``pixel_ratio[ref][method][section]``: mean edge pixels of the method's maps
    over mean edge pixels of the reference (> 1: thick or trailing edges,
    < 1: sparse edges). ``lifetime[method][section]``: over the signal events
    of the section with a true lifetime, the share with an estimate
    (``coverage``), the median relative error, and the shares estimated more
    than twice too long (``over_2x``, trails) or too short (``under_2x``).
    """
    out: dict = {"pixel_ratio": {}, "lifetime": {}}
    for ref, rstack in refs.items():
        out["pixel_ratio"][ref] = {}
        for m, stack in maps.items():
            out["pixel_ratio"][ref][m] = {}
            for name in sections:
                sel = frame_section == name
                denom = rstack[sel].sum(axis=(1, 2)).mean() if sel.any() else np.nan
                num = stack[sel].sum(axis=(1, 2)).mean() if sel.any() else np.nan
                out["pixel_ratio"][ref][m][name] = float(num / denom) if denom and np.isfinite(denom) else np.nan
    truth = rec.truth
    if truth is None or "lifetime_us" not in (truth.dtype.names or ()):
        return out
    true_lt = np.asarray(truth["lifetime_us"], dtype=np.float64)
    if "is_signal" in truth.dtype.names:
        true_lt = np.where(truth["is_signal"], true_lt, np.nan)
    sec_of_event = np.full(rec.events.size, None, dtype=object)
    for name, (a, b) in sections.items():
        sec_of_event[(rec.events["t"] >= a) & (rec.events["t"] < b)] = name
    for m, run in runs.items():
        tr = true_lt if run.kept is None else true_lt[run.kept]
        sec = sec_of_event if run.kept is None else sec_of_event[run.kept]
        est = np.where(run.lifetimes["valid"], run.lifetimes["lifetime_us"], np.nan)
        out["lifetime"][m] = {}
        for name in sections:
            sel = (sec == name) & np.isfinite(tr) & (tr > 0)
            n = int(sel.sum())
            ok = sel & np.isfinite(est)
            ratio = est[ok] / tr[ok]
            out["lifetime"][m][name] = {
                "n_signal": n,
                "coverage": float(ok.sum() / n) if n else np.nan,
                "median_rel_error": float(np.median(np.abs(ratio - 1))) if ratio.size else np.nan,
                "over_2x": float(np.mean(ratio > 2)) if ratio.size else np.nan,
                "under_2x": float(np.mean(ratio < 0.5)) if ratio.size else np.nan,
            }
    return out


def _plot(out_dir: Path, scene: str, times, frame_section, sections, table) -> list[Path]:
    plt = pyplot()
    paths = []
    refs = list(table)
    fig, axes = plt.subplots(len(refs), 1, figsize=(9, 2.6 * len(refs)), squeeze=False, sharex=True)
    for ax, ref in zip(axes[:, 0], refs):
        for m, v in table[ref].items():
            ax.plot(np.asarray(times) / 1e6, v, marker=".", ms=3, lw=1, color=colour(m),
                    ls=_line_style(m), label=label(m))
        for k, (name, (a, b)) in enumerate(sections.items()):
            if name != "all":
                ax.axvspan(a / 1e6, b / 1e6, color=("0.85", "0.7")[k % 2], alpha=0.35, lw=0)
                if ax is axes[0, 0]:
                    ax.text((a + b) / 2e6, 2, f"{name} section", ha="center", va="bottom", fontsize=8)
        ax.set_ylabel(f"CDM vs {ref}", fontsize=8)
        ax.set_ylim(0, 100)
    axes[-1, 0].set_xlabel("time (s)")
    # below the plots: with both display policies there are too many lines for a legend inside
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=3, fontsize=7, frameon=False)
    fig.suptitle(f"{scene}: similarity over time (shaded: {', '.join(sections)} sections; solid: "
                 f"{DISPLAY_LABELS[PRIMARY_DISPLAY]}, primary; dashed: other display)", fontsize=9)
    paths.append(save_figure(fig, out_dir / f"similarity_{scene}_over_time.png"))

    names = [n for n in sections]
    fig, axes = plt.subplots(len(refs), len(names), figsize=(5.2 * len(names), 3.2 * len(refs)), squeeze=False)
    for r, ref in enumerate(refs):
        methods = _box_order(table[ref])
        for c, name in enumerate(names):
            ax = axes[r, c]
            data = [np.asarray(table[ref][m])[frame_section == name] for m in methods]
            bp = ax.boxplot(data, patch_artist=True, widths=0.6, medianprops={"color": "k"})
            for patch, m in zip(bp["boxes"], methods):
                display = compared(m).display
                patch.set_facecolor(colour(m, "w"))
                if display is not None and display != PRIMARY_DISPLAY:
                    patch.set_alpha(0.45)
                    patch.set_hatch("///")
            ax.set_xticks(range(1, len(methods) + 1), [_short(m) for m in methods], fontsize=7)
            ax.set_title(f"{name} section, vs {ref}", fontsize=9)
            ax.set_ylabel(f"CDM vs {ref} (higher: closer)", fontsize=8)
            ax.set_xlabel("method", fontsize=8)
            ax.set_ylim(0, 100)
    from matplotlib.patches import Patch

    shown = dict.fromkeys(compared(m).base for m in _box_order(table[refs[0]]))
    fig.legend([Patch(facecolor=colour(b, "w"), edgecolor="k") for b in shown], [label(b) for b in shown],
               loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=3, fontsize=7, frameon=False)
    fig.suptitle(f"{scene}: CDM per section\nplain boxes: {DISPLAY_LABELS[PRIMARY_DISPLAY]} (primary); "
                 f"hatched ('no clear'): {', '.join(DISPLAY_LABELS[d] for d in DISPLAYS if d != PRIMARY_DISPLAY)}",
                 fontsize=9)
    fig.subplots_adjust(hspace=0.45)
    paths.append(save_figure(fig, out_dir / f"similarity_{scene}_boxplots.png"))
    return paths


def _line_style(key: str) -> str:
    display = compared(key).display
    return "-" if display in (None, PRIMARY_DISPLAY) else "--"


def _box_order(per_method: dict) -> list[str]:
    """Box plot order: each lifetime method's policies side by side, then the accumulation
    baselines; diagnostic variants are left out (they are in the tables)."""
    keys = [m for m in per_method if not compared(m).diagnostic]
    rank = {b: i for i, b in enumerate(dict.fromkeys(c.base for c in COMPARED.values()))}
    pol = {d: i for i, d in enumerate(DISPLAYS)}
    return sorted(keys, key=lambda m: (rank.get(compared(m).base, 99), pol.get(compared(m).display, -1)))


def _short(key: str) -> str:
    c = compared(key)
    base, display = c.base, c.display
    text = base.replace("acc_", "")
    return text + ("\nno clear" if display is not None and display != PRIMARY_DISPLAY else "")
