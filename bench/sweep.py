"""Sweeps: grade the compared methods over every sequence of a dataset, on Dask.

A sweep spec is a dataset spec (``sim/DATASETS.md``) with an optional
``[sweep]`` table:

``methods`` (default: :data:`evedge.bench.methods.METHODS`)
    Keys of compared methods, or registered method names (see below).
``warmup_s`` (default 0.02)
    Frames before this time are not graded (no method has seen enough
    events yet; the 30 ms accumulation not even one window).
``canny_settings`` (default 0)
    Also grade the edge maps against Canny of the clean frames with the
    first N of :data:`evedge.bench.canny.CANNY_SETTINGS` (0: exact edges only).

``evedge bench sweep SPEC.toml -o DIR`` makes (or completes, verifying it)
the dataset in ``DIR/dataset``, grades each sequence in one task (every
method on the same events; lifetimes computed once per lifetime method and
shared by both display policies), stores each sequence's grades in
``DIR/grades/<seq>.json`` (with the sha256 of the graded file, so a rerun
grades only new or changed sequences) and assembles:

``DIR/results.csv`` and ``DIR/results.h5``
    One long table (:class:`evedge.bench.results.ResultsTable`, the columns
    every bench table has): ``experiment = "sweep"``, ``dataset`` = the
    sequence (``seq_00042``), ``method`` = registry name, ``variant`` = the
    compared method's key (``acc_1ms``), ``display``, ``reference``,
    ``section``, ``metric``, ``value``; the rows are those of every
    registered metric (:data:`evedge.bench.metrics.METRICS`) through
    :func:`evedge.bench.grade.grade_recording`, as ``evedge grade`` gives.
``DIR/sequences.csv``
    One row per sequence: ``dataset`` (the sequence, the key to join on),
    ``index``, ``seed``, ``status``, ``n_events`` and every drawn parameter.
``DIR/report.md`` and ``DIR/sweep_<metric>.png``
    Per metric, one panel per swept parameter: every sequence's value and,
    per method, the median with its interquartile range in bins of the
    parameter.

Plotted (section ``all``): ``median_cdm`` against the exact edge maps (over
the frames from ``warmup_s`` on), and for lifetime methods
``median_rel_error`` and ``share_estimated`` against the truth lifetimes.
A lifetime method's per-event metrics do not depend on the display policy;
they are computed once, for the first of its keys (with the default methods,
the primary policy's).

Methods: the keys of :data:`evedge.bench.methods.COMPARED`, or any
registered estimator / edge detector name (or ``package.module:factory``),
which joins through :func:`evedge.bench.methods.add_method` (on each worker
too).
"""

from __future__ import annotations

import csv
import io
import json
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from evedge.sim.dataset import PARAMETERS, DatasetError, DatasetSpec, parse_dataset
from evedge.sim.scene import _read_toml, _Table

from .results import ResultsTable

#: (metric, reference) of the results table plotted against the swept parameters, section "all".
PLOTTED = {("median_cdm", "exact"): "median CDM to the exact edge maps (100 = identical)",
           ("median_rel_error", "truth"): "median relative lifetime error |tau / tau_true - 1|",
           ("share_estimated", "truth"): "share of signal events with a lifetime estimate"}


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep: the dataset to grade on and how to grade."""

    dataset: DatasetSpec
    methods: tuple[str, ...]
    warmup_s: float
    source: str
    canny_settings: int = 0


def _check_method(name: str) -> str | None:
    """None when ``name`` is a compared key or a registered estimator / edge detector; else the problem."""
    from .methods import COMPARED, REGISTRY

    if not isinstance(name, str):
        return f"expected a method name, got {name!r}"
    if name in COMPARED:
        return None
    builtin = [k for k, c in COMPARED.items() if c.method == name and c.builtin]
    if builtin:
        return f"{name!r} is compared as {builtin}; name those keys"
    try:
        REGISTRY.get(name, kind=("estimator", "edges"))
    except (ValueError, KeyError, ImportError, AttributeError) as err:
        return f"unknown method {name!r} ({err}); compared: {list(COMPARED)}"
    return None


def parse_sweep(data: dict, source: str = "<sweep>") -> SweepSpec:
    """Validate a sweep spec dict: a dataset spec plus an optional ``[sweep]`` table.

    Parameters
    ----------
    data : dict
        The parsed TOML.
    source : str
        File name quoted in messages.

    Returns
    -------
    SweepSpec

    Raises
    ------
    DatasetError
        Naming the key, as dataset and scene specs do (e.g. ``sweep.methods[1]``).

    Examples
    --------
    >>> s = parse_sweep({"dataset": {"count": 2}, "sweep": {"methods": ["acc_1ms"]}}, "s.toml")
    >>> s.methods, s.dataset.count
    (('acc_1ms',), 2)
    """
    from .methods import METHODS

    if not isinstance(data, dict):
        raise DatasetError(f"{source}: expected a table at the top level")
    data = dict(data)
    raw = data.pop("sweep", {})
    try:
        t = _Table(source, "sweep", raw)
        methods = t.raw("methods", list(METHODS))
        if not isinstance(methods, list) or not methods:
            t.fail("methods", f"expected a non-empty array of method keys, got {methods!r}")
        for j, m in enumerate(methods):
            problem = _check_method(m)
            if problem:
                t.fail(f"methods[{j}]", problem)
        warmup = t.number("warmup_s", 0.02, lo=0)
        canny = t.number("canny_settings", 0, lo=0, hi=3, integer=True)
        t.finish()
    except DatasetError:
        raise
    except ValueError as err:  # SceneError from the shared reader
        raise DatasetError(str(err)) from None
    spec = parse_dataset(data, source)
    fr = spec.parameters["frame_rate_hz"]
    if (fr.kind == "fixed" and fr.args[0] <= 0) or (fr.kind == "choice" and min(fr.args) <= 0) or \
            (fr.kind in ("uniform", "log_uniform") and fr.args[0] <= 0):
        raise DatasetError(f"{source}: key 'parameters.frame_rate_hz': a sweep grades edge maps at the frame "
                           f"times, so it must be > 0, got {fr.describe()}")
    return SweepSpec(spec, tuple(dict.fromkeys(methods)), warmup, source, canny)


def load_sweep(path) -> SweepSpec:
    """Read and validate a sweep spec file (TOML); errors as :func:`parse_sweep`."""
    path = Path(path)
    text, data = _read_toml(path, "sweep spec", DatasetError)
    sweep = parse_sweep(data, str(path))
    return replace(sweep, dataset=replace(sweep.dataset, text=text))


@dataclass(frozen=True)
class GradeTask:
    """One sequence to grade (picklable)."""

    path: str
    name: str
    sha256: str
    methods: tuple[str, ...]
    warmup_s: float
    canny_settings: int
    out: str


def _keys(methods) -> list[str]:
    """Compared keys of ``methods`` (a registered method joins through ``add_method``: one key per policy)."""
    from .methods import COMPARED, add_method

    keys = []
    for m in methods:
        keys.extend([m] if m in COMPARED else add_method(m))
    return list(dict.fromkeys(keys))


def _detection(rec, key: str, maps: dict, runs: dict, times: np.ndarray, path: str):
    """What ``key`` detected on ``rec``, as :func:`evedge.bench.grade.grade_recording` takes it."""
    from .grade import DetectionInput
    from .methods import COMPARED

    c = COMPARED[key]
    cols = {}
    if c.display is not None:
        run = runs[c.base]
        n = rec.events.shape[0]
        idx = np.arange(n) if run.kept is None else np.flatnonzero(run.kept)
        valid = np.asarray(run.lifetimes["valid"], bool)
        for name in ("lifetime_us", "vx_px_s", "vy_px_s"):
            col = np.full(n, np.nan)
            col[idx] = np.where(valid, run.lifetimes[name], np.nan)
            cols[name] = col
        if run.kept is not None:
            cols["kept"] = np.asarray(run.kept, bool)
    return DetectionInput(Path(path), c.method, c.display or "", cols, times, np.asarray(maps[key], bool))


def grade_sequence(task: GradeTask) -> dict:
    """Grade every method on one sequence: ``{"sha256", "methods", ..., "rows": [results rows]}``.

    Every registered metric runs once per compared key, except that the
    per-event metrics of a lifetime method run only for its first key (they
    do not depend on the display policy). Written to ``task.out``
    atomically, so a rerun can reuse it.
    """
    from evedge.io import read_hdf5

    from ._files import write_json_atomic
    from .grade import grade_recording
    from .methods import COMPARED, edge_maps
    from .metrics import METRICS

    t0 = time.perf_counter()
    rec = read_hdf5(task.path)
    if rec.edges is None:
        raise ValueError(f"{task.path}: no exact edge maps to grade against (frame_rate_hz = 0)")
    keys = _keys(task.methods)
    sel = rec.edges.t_us >= int(round(task.warmup_s * 1e6))
    times, truth_maps = rec.edges.t_us[sel], rec.edges.images[sel]
    # acc_count: as many events as the truth has edge pixels on average (as the experiments do)
    count_n = max(1, int(round(truth_maps.reshape(truth_maps.shape[0], -1).sum(axis=1).mean()))) \
        if times.size else 1
    maps, runs = edge_maps(rec.events, rec.sensor_size, times, methods=keys, count_n=count_n)
    rows, seen = [], set()
    for key in keys:
        c = COMPARED[key]
        metrics = METRICS.names() if c.base not in seen else METRICS.names(kind="frames")
        seen.add(c.base)
        table = grade_recording(rec, _detection(rec, key, maps, runs, times, task.path), dataset=task.name,
                                experiment="sweep", metrics=metrics, canny_settings=task.canny_settings)
        for r in table.rows:
            r["variant"] = key
        rows.extend(table.rows)
    out = {"sha256": task.sha256, "methods": list(task.methods), "warmup_s": task.warmup_s,
           "canny_settings": task.canny_settings, "n_frames": int(times.size), "rows": rows,
           "wall_s": round(time.perf_counter() - t0, 3)}
    write_json_atomic(task.out, out)
    return out


def _scalar_params() -> list[str]:
    return [k for k, p in PARAMETERS.items() if not p.per_shape]


def write_sequences(path: Path, manifest: dict) -> Path:
    """``sequences.csv``: one row per sequence, its drawn (scalar) parameters; join on ``dataset``."""
    from ._files import write_text_atomic

    names = _scalar_params()
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["dataset", "index", "seed", "status", "n_events"] + names)
    for i in sorted(manifest):
        r = manifest[i]
        w.writerow([r["name"], i, r["seed"], r["status"], r["n_events"]] + [r["params"].get(k) for k in names])
    return write_text_atomic(path, buf.getvalue())


def _binned(x: np.ndarray, y: np.ndarray, n_bins: int, log: bool):
    """Median and quartiles of ``y`` in quantile bins of ``x``: (centre, q1, median, q3) arrays."""
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size == 0:
        return (np.empty(0),) * 4
    distinct = np.unique(x)
    if distinct.size <= n_bins:  # a choice or a few integers: one bin per value
        idx, n = np.searchsorted(distinct, x), distinct.size
    else:
        edges = np.unique(np.quantile(x, np.linspace(0, 1, n_bins + 1)))
        idx, n = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2), edges.size - 1
    out = [[], [], [], []]
    for b in range(n):
        yb = y[idx == b]
        if yb.size == 0:
            continue
        xb = x[idx == b]
        out[0].append(float(np.exp(np.mean(np.log(xb)))) if log and np.all(xb > 0) else float(np.mean(xb)))
        for k, v in enumerate(np.percentile(yb, [25, 50, 75]), start=1):
            out[k].append(float(v))
    return tuple(np.asarray(v) for v in out)


def _panel(ax, spec: DatasetSpec, rows: list[dict], methods: list[str], param: str) -> None:
    """One swept parameter: every sequence's value, and per method (variant) the binned median with its IQR."""
    from .methods import COMPARED, PRIMARY_DISPLAY, colour, label

    rows = [r for r in rows if r[f"param_{param}"] is not None]  # sequences it applies to (their family)
    values = [r[f"param_{param}"] for r in rows]
    numeric = all(isinstance(v, (int, float)) for v in values)
    cats = None if numeric else sorted(set(map(str, values)))
    log = spec.parameters[param].kind == "log_uniform"
    for j, m in enumerate(methods):
        mr = [r for r in rows if r["variant"] == m]
        y = np.array([r["value"] for r in mr], dtype=np.float64)
        c = COMPARED.get(m)
        tint = colour(m, f"C{j}")
        style = "--" if c is not None and c.display not in (None, PRIMARY_DISPLAY) else "-"
        name = label(m)
        if numeric:
            x = np.array([r[f"param_{param}"] for r in mr], dtype=np.float64)
            ax.scatter(x, y, s=9, alpha=0.35, color=tint, linewidths=0)
            cx, q1, med, q3 = _binned(x, y, max(2, min(6, len(x) // 6)), log)
            ax.plot(cx, med, style, color=tint, label=name, marker="o", ms=3)
            ax.fill_between(cx, q1, q3, color=tint, alpha=0.15, linewidth=0)
        else:
            pos = np.arange(len(cats)) + (j - (len(methods) - 1) / 2) * 0.8 / max(1, len(methods))
            groups = [y[np.array([str(r[f"param_{param}"]) == c for r in mr])] for c in cats]
            groups = [g[np.isfinite(g)] for g in groups]
            meds = np.array([np.median(g) if g.size else np.nan for g in groups])
            lo = np.array([np.percentile(g, 25) if g.size else np.nan for g in groups])
            hi = np.array([np.percentile(g, 75) if g.size else np.nan for g in groups])
            ax.errorbar(pos, meds, yerr=[meds - lo, hi - meds], fmt="o", color=tint, label=name, capsize=3,
                        mfc="none" if style == "--" else tint)
    if cats is not None:
        ax.set_xticks(np.arange(len(cats)), cats)
    elif log:
        from matplotlib.ticker import NullFormatter, ScalarFormatter

        ax.set_xscale("log")
        ax.xaxis.set_major_formatter(ScalarFormatter())
        ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel(param)
    ax.grid(alpha=0.3)


def plot_sweeps(out_dir: Path, spec: DatasetSpec, table: list[dict]) -> list[tuple[str, Path]]:
    """One figure per metric, one panel per swept parameter (per-shape parameters aside)."""
    from ._files import save_figure
    from ._plot import pyplot

    plt = pyplot()
    figures = []
    swept = [k for k in spec.swept if not PARAMETERS[k].per_shape]
    if not swept:
        return figures
    for (metric, reference), text in PLOTTED.items():
        rows = [r for r in table if r["metric"] == metric and r["reference"] == reference and r["section"] == "all"]
        methods = list(dict.fromkeys(r["variant"] for r in rows))
        if not methods:
            continue
        ncols = min(3, len(swept))
        nrows = math.ceil(len(swept) / ncols)
        fig, axes = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 3.3 * nrows), squeeze=False, sharey=True)
        for ax, param in zip(axes.flat, swept):
            _panel(ax, spec, rows, methods, param)
        for ax in axes.flat[len(swept):]:
            ax.set_visible(False)
        for ax in axes[:, 0]:
            ax.set_ylabel(f"{metric} ({reference})")
        handles, labels = axes.flat[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="upper center", ncol=min(4, len(labels)), fontsize=8,
                   bbox_to_anchor=(0.5, 1.0))
        fig.suptitle(f"{text}: each dot a sequence; line and band: median and interquartile range in "
                     f"quantile bins of the parameter", fontsize=9, y=1.07)
        fig.tight_layout()
        figures.append(((metric, reference), save_figure(fig, out_dir / f"sweep_{metric}.png")))
    return figures


def joined(table, manifest: dict) -> list[dict]:
    """The results rows, each with its sequence's drawn parameters as ``param_<name>``."""
    by_name = {r["name"]: r for r in manifest.values()}
    names = _scalar_params()
    out = []
    for r in table:
        seq = by_name.get(r["dataset"])
        if seq is not None:
            out.append({**r, **{f"param_{k}": seq["params"].get(k) for k in names}})
    return out


def write_report(out_dir: Path, sweep: SweepSpec, table: list[dict], figures, dataset_run, graded: int) -> Path:
    from ._files import write_text_atomic
    from .methods import label

    spec = sweep.dataset
    lines = [f"# Sweep over dataset `{spec.name}`", "",
             f"{len(dataset_run.rows)} sequences ({dataset_run.failed} failed to simulate), {graded} graded; "
             f"edge maps from {sweep.warmup_s} s on. Results: `results.csv` / `results.h5` (the bench's long "
             f"table, `dataset` = sequence), parameters per sequence: `sequences.csv`. Swept: "
             f"{', '.join(f'`{k}`' for k in spec.swept) or 'nothing'}.", "",
             "## Per method (median [interquartile range] over sequences, section `all`)", "",
             "| method | " + " | ".join(f"{m} ({ref})" for m, ref in PLOTTED) + " | sequences |",
             "|---|" + "---|" * (len(PLOTTED) + 1)]
    variants = list(dict.fromkeys(r["variant"] for r in table))
    for m in variants:
        cells, n = [], 0
        for metric, ref in PLOTTED:
            v = np.array([r["value"] for r in table if r["variant"] == m and r["metric"] == metric
                          and r["reference"] == ref and r["section"] == "all"], dtype=float)
            v = v[np.isfinite(v)]
            n = max(n, v.size)
            cells.append(f"{np.median(v):.3g} [{np.percentile(v, 25):.3g}, {np.percentile(v, 75):.3g}]"
                         if v.size else "")
        lines.append(f"| {label(m)} (`{m}`) | " + " | ".join(cells) + f" | {n} |")
    lines += [""]
    for (metric, ref), path in figures:
        lines += [f"### `{metric}` ({ref}) against each swept parameter", "", f"![{metric}]({path.name})", ""]
    return write_text_atomic(out_dir / "report.md", "\n".join(lines))


def run_sweep(sweep: SweepSpec, out_dir, *, workers: int | None = None, scheduler: str | None = None, client=None,
              retries: int = 2, progress: bool = True) -> dict:
    """Make the dataset if needed, grade every sequence on Dask, write the table, figures and report.

    Parameters
    ----------
    sweep : SweepSpec
        From :func:`load_sweep`.
    out_dir : path-like
        Output folder (created; its parent must exist).
    workers, scheduler, client, retries, progress
        As :func:`evedge.sim.dataset_run.generate_dataset`.

    Returns
    -------
    dict
        ``results`` (path of the CSV), ``report``, ``figures``, ``graded``,
        ``reused`` (grades kept from an earlier run), ``failed`` (index -> error).
    """
    from evedge.parallel import dask_client, run_tasks
    from evedge.sim.dataset_run import generate_dataset

    out_dir = Path(out_dir)
    if not out_dir.parent.is_dir():
        raise DatasetError(f"folder {out_dir.parent} of {out_dir} does not exist")
    out_dir.mkdir(exist_ok=True)
    (out_dir / "grades").mkdir(exist_ok=True)
    spec = sweep.dataset
    with dask_client(workers, scheduler, client=client) as c:
        ds = generate_dataset(spec, out_dir / "dataset", client=c, retries=retries, progress=progress)
        grades, tasks, failed = {}, [], {}
        for i, row in sorted(ds.rows.items()):
            if row["status"] != "ok":
                failed[i] = f"not simulated: {row['error']}"
                continue
            rel, digest = next((k, v) for k, v in row["files"].items() if k.endswith(".h5"))
            gpath = out_dir / "grades" / f"{row['name']}.json"
            try:
                old = json.loads(gpath.read_text())
                if old["sha256"] == digest and old["methods"] == list(sweep.methods) and \
                        old["warmup_s"] == sweep.warmup_s and old["canny_settings"] == sweep.canny_settings:
                    grades[i] = old
                    continue
            except (OSError, ValueError, KeyError, TypeError):
                pass
            tasks.append((i, GradeTask(str((out_dir / "dataset" / rel).resolve()), row["name"], digest,
                                       sweep.methods, sweep.warmup_s, sweep.canny_settings, str(gpath.resolve()))))
        reused = len(grades)
        for k, res, err in run_tasks(c, grade_sequence, [t for _, t in tasks], retries=retries, progress=progress,
                                     desc=f"grade {spec.name}", unit="seq"):
            i = tasks[k][0]
            if err is not None:
                failed[i] = f"{type(err).__name__}: {err}"
            else:
                grades[i] = res
    results = ResultsTable()
    for i in sorted(grades):  # by sequence: the same table whatever order the grades came in
        results.extend(grades[i]["rows"])
    csv_path, h5_path = results.save(out_dir / "results")
    sequences = write_sequences(out_dir / "sequences.csv", ds.rows)
    table = joined(results, ds.rows)
    figures = plot_sweeps(out_dir, spec, table)
    report = write_report(out_dir, sweep, table, figures, ds, len(grades))
    return {"results": csv_path, "results_h5": h5_path, "sequences": sequences, "report": report,
            "figures": [p for _, p in figures], "graded": len(grades), "reused": reused, "failed": failed,
            "rows": len(results)}
