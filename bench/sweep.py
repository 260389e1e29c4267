"""Sweeps: grade the compared methods over every sequence of a dataset, on Dask.

A sweep spec is a dataset spec (``sim/DATASETS.md``) with an optional
``[sweep]`` table:

``methods`` (default: :data:`evedge.bench.methods.METHODS`)
    Result keys of the compared methods.
``warmup_s`` (default 0.02)
    Frames before this time are not graded (no method has seen enough
    events yet; the 30 ms accumulation not even one window).

``evedge bench sweep SPEC.toml -o DIR`` makes (or completes, verifying it)
the dataset in ``DIR/dataset``, grades each sequence in one task (every
method on the same events; lifetimes computed once per lifetime method and
shared by both display policies), stores each sequence's grades in
``DIR/grades/<seq>.json`` (with the sha256 of the graded file, so a rerun
grades only new or changed sequences) and assembles:

``DIR/results.csv``
    One long table, one row per (sequence, method, metric): ``experiment,
    dataset, reference, method, display, section, metric, value`` (``section``
    is the sequence) followed by the sequence's drawn parameters
    (``param_<name>``).
``DIR/report.md`` and ``DIR/sweep_<metric>_<parameter>.png``
    Per swept parameter, per metric, per method: every sequence's value and
    the median with its interquartile range in quantile bins of the parameter.

Metrics (per sequence and method):

``cdm``
    Mean over the graded frames of ``CDM_3(method map, exact edge map)``
    (:func:`evedge.bench.cdm.cdm`, 100 = identical).
``lifetime_rel_error`` (lifetime methods; method = its base key)
    Median over signal events with an estimate of ``|tau - tau_true| / tau_true``.
``lifetime_estimated``
    Share of the signal events (of those the method kept) with an estimate.

The grading here uses today's :func:`evedge.bench.methods.edge_maps` and
:mod:`evedge.bench.cdm`; a shared grading API and results table
(``bench/grade.py``, ``bench/results.py``) can replace :func:`grade_sequence`
and :func:`write_results` without changing the task layout.
"""

from __future__ import annotations

import csv
import io
import json
import math
import time
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from evedge.sim.dataset import PARAMETERS, DatasetError, DatasetSpec, parse_dataset
from evedge.sim.scene import _Table

#: Columns of the long results table before the parameter columns (tidy, as the bench's tables).
COLUMNS = ("experiment", "dataset", "reference", "method", "display", "section", "metric", "value")
METRICS = {"cdm": "CDM to the exact edge maps (100 = identical)",
           "lifetime_rel_error": "median relative lifetime error |tau - tau_true| / tau_true",
           "lifetime_estimated": "share of signal events with a lifetime estimate"}


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep: the dataset to grade on and how to grade."""

    dataset: DatasetSpec
    methods: tuple[str, ...]
    warmup_s: float
    source: str


def _known_methods() -> tuple[str, ...]:
    from .methods import DIAGNOSTIC_METHODS, METHODS

    return tuple(METHODS) + tuple(DIAGNOSTIC_METHODS)


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
        known = _known_methods()
        for j, m in enumerate(methods):
            if m not in known:
                t.fail(f"methods[{j}]", f"unknown method {m!r}; known: {list(known)}")
        warmup = t.number("warmup_s", 0.02, lo=0)
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
    return SweepSpec(spec, tuple(dict.fromkeys(methods)), warmup, source)


def load_sweep(path) -> SweepSpec:
    """Read and validate a sweep spec file (TOML); errors as :func:`parse_sweep`."""
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
        data = tomllib.loads(text)
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read sweep spec: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{path}: not valid TOML: {exc}") from None
    sweep = parse_sweep(data, str(path))
    return replace(sweep, dataset=replace(sweep.dataset, text=text))


@dataclass(frozen=True)
class GradeTask:
    """One sequence to grade (picklable)."""

    path: str
    sha256: str
    methods: tuple[str, ...]
    warmup_s: float
    out: str


def grade_sequence(task: GradeTask) -> dict:
    """Grade every method on one sequence; ``{"sha256", "methods", "metrics": [{method, display, metric, value}]}``.

    Written to ``task.out`` atomically, so a rerun can reuse it.
    """
    from evedge.io import read_hdf5

    from ._files import write_json_atomic
    from .cdm import cdm
    from .methods import edge_maps
    from .stats import relative_errors

    t0 = time.perf_counter()
    rec = read_hdf5(task.path)
    if rec.edges is None:
        raise ValueError(f"{task.path}: no exact edge maps to grade against (frame_rate_hz = 0)")
    t_us = rec.edges.t_us
    sel = t_us >= int(round(task.warmup_s * 1e6))
    times, truth_maps = t_us[sel], rec.edges.images[sel]
    metrics = []
    if times.size:
        # acc_count: as many events as the truth has edge pixels on average (as the experiments do)
        count_n = max(1, int(round(truth_maps.reshape(truth_maps.shape[0], -1).sum(axis=1).mean())))
        maps, runs = edge_maps(rec.events, rec.sensor_size, times, methods=task.methods, count_n=count_n)
        for m in task.methods:
            scores = [cdm(maps[m][k], truth_maps[k]) for k in range(times.size)]
            metrics.append({"method": m, "display": _display_of(m), "reference": "truth_edges", "metric": "cdm",
                            "value": float(np.mean(scores))})
        truth = np.asarray(rec.truth["lifetime_us"], dtype=np.float64).copy()
        truth[~np.asarray(rec.truth["is_signal"], bool)] = np.nan
        for base, run in runs.items():
            tr = truth if run.kept is None else truth[run.kept]
            lt = run.lifetimes
            valid = np.asarray(lt["valid"], bool) & np.isfinite(lt["lifetime_us"])
            err = relative_errors(np.where(valid, lt["lifetime_us"], np.nan), tr)
            signal = np.isfinite(tr) & (tr > 0)
            # lifetimes do not depend on the display policy: one row per lifetime method, no display
            metrics.append({"method": base, "display": "", "reference": "truth_lifetime",
                            "metric": "lifetime_rel_error",
                            "value": float(np.median(err)) if err.size else float("nan")})
            metrics.append({"method": base, "display": "", "reference": "truth_lifetime",
                            "metric": "lifetime_estimated",
                            "value": float((valid & signal).sum() / signal.sum()) if signal.any() else float("nan")})
    out = {"sha256": task.sha256, "methods": list(task.methods), "warmup_s": task.warmup_s,
           "n_frames": int(times.size), "metrics": metrics, "wall_s": round(time.perf_counter() - t0, 3)}
    write_json_atomic(task.out, out)
    return out


def _display_of(method: str) -> str:
    """Display policy of a compared method's edge maps ('' for an accumulation baseline)."""
    from .methods import split_key

    return split_key(method)[1] or ""


def _scalar_params(spec: DatasetSpec) -> list[str]:
    return [k for k, p in PARAMETERS.items() if not p.per_shape]


def results_rows(spec: DatasetSpec, manifest: dict, grades: dict) -> list[list]:
    """The long results table's rows (see the module docstring), sorted by sequence then method."""
    names = _scalar_params(spec)
    rows = []
    for i in sorted(grades):
        seq = manifest[i]
        params = [seq["params"].get(k) for k in names]
        for g in grades[i]["metrics"]:
            rows.append(["sweep", spec.name, g["reference"], g["method"], g["display"], seq["name"],
                         g["metric"], g["value"], *params])
    return rows


def write_results(path: Path, spec: DatasetSpec, rows: list[list]) -> Path:
    from ._files import write_text_atomic

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(COLUMNS) + [f"param_{k}" for k in _scalar_params(spec)])
    w.writerows(rows)
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
    """One swept parameter: every sequence's value, and per method the binned median with its IQR."""
    from ._plot import METHOD_COLOURS

    values = [r[f"param_{param}"] for r in rows]
    numeric = all(isinstance(v, (int, float)) for v in values)
    cats = None if numeric else sorted(set(map(str, values)))
    log = spec.parameters[param].kind == "log_uniform"
    for j, m in enumerate(methods):
        mr = [r for r in rows if r["method"] == m]
        y = np.array([r["value"] for r in mr], dtype=np.float64)
        colour = METHOD_COLOURS.get(m.removesuffix("_noclear"), f"C{j}")
        style = "--" if m.endswith("_noclear") else "-"
        if numeric:
            x = np.array([r[f"param_{param}"] for r in mr], dtype=np.float64)
            ax.scatter(x, y, s=9, alpha=0.35, color=colour, linewidths=0)
            cx, q1, med, q3 = _binned(x, y, max(2, min(6, len(x) // 6)), log)
            ax.plot(cx, med, style, color=colour, label=m, marker="o", ms=3)
            ax.fill_between(cx, q1, q3, color=colour, alpha=0.15, linewidth=0)
        else:
            pos = np.arange(len(cats)) + (j - (len(methods) - 1) / 2) * 0.8 / max(1, len(methods))
            groups = [y[np.array([str(r[f"param_{param}"]) == c for r in mr])] for c in cats]
            groups = [g[np.isfinite(g)] for g in groups]
            meds = np.array([np.median(g) if g.size else np.nan for g in groups])
            lo = np.array([np.percentile(g, 25) if g.size else np.nan for g in groups])
            hi = np.array([np.percentile(g, 75) if g.size else np.nan for g in groups])
            ax.errorbar(pos, meds, yerr=[meds - lo, hi - meds], fmt="o", color=colour, label=m, capsize=3)
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
    for metric, text in METRICS.items():
        rows = [r for r in table if r["metric"] == metric]
        methods = list(dict.fromkeys(r["method"] for r in rows))
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
            ax.set_ylabel(metric)
        handles, labels = axes.flat[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="upper center", ncol=min(7, len(labels)), fontsize=8,
                   bbox_to_anchor=(0.5, 1.0))
        fig.suptitle(f"{text}: each dot a sequence; line and band: median and interquartile range in "
                     f"quantile bins of the parameter", fontsize=9, y=1.04)
        fig.tight_layout()
        figures.append((metric, save_figure(fig, out_dir / f"sweep_{metric}.png")))
    return figures


def _table_dicts(spec: DatasetSpec, rows: list[list]) -> list[dict]:
    keys = list(COLUMNS) + [f"param_{k}" for k in _scalar_params(spec)]
    return [dict(zip(keys, r)) for r in rows]


def write_report(out_dir: Path, sweep: SweepSpec, table: list[dict], figures, dataset_run, graded: int) -> Path:
    from ._files import write_text_atomic

    spec = sweep.dataset
    lines = [f"# Sweep over dataset `{spec.name}`", "",
             f"{len(dataset_run.rows)} sequences ({dataset_run.failed} failed to simulate), {graded} graded; "
             f"frames from {sweep.warmup_s} s on. Results: `results.csv` (one row per sequence, method and "
             f"metric). Swept: {', '.join(f'`{k}`' for k in spec.swept) or 'nothing'}.", "",
             "## Per method (median [interquartile range] over sequences)", "",
             "| method | " + " | ".join(METRICS) + " | sequences |", "|---|" + "---|" * (len(METRICS) + 1)]
    methods = list(dict.fromkeys(r["method"] for r in table))
    for m in methods:
        cells, n = [], 0
        for metric in METRICS:
            v = np.array([r["value"] for r in table if r["method"] == m and r["metric"] == metric], dtype=float)
            v = v[np.isfinite(v)]
            n = max(n, v.size)
            cells.append(f"{np.median(v):.3g} [{np.percentile(v, 25):.3g}, {np.percentile(v, 75):.3g}]"
                         if v.size else "")
        lines.append(f"| `{m}` | " + " | ".join(cells) + f" | {n} |")
    lines += ["", "Metrics: " + "; ".join(f"`{k}`: {v}" for k, v in METRICS.items()) + ".", ""]
    for metric, path in figures:
        lines += [f"### `{metric}` against each swept parameter", "", f"![{metric}]({path.name})", ""]
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
                        old["warmup_s"] == sweep.warmup_s:
                    grades[i] = old
                    continue
            except (OSError, ValueError, KeyError, TypeError):
                pass
            tasks.append((i, GradeTask(str((out_dir / "dataset" / rel).resolve()), digest, sweep.methods,
                                       sweep.warmup_s, str(gpath.resolve()))))
        reused = len(grades)
        for k, res, err in run_tasks(c, grade_sequence, [t for _, t in tasks], retries=retries, progress=progress,
                                     desc=f"grade {spec.name}", unit="seq"):
            i = tasks[k][0]
            if err is not None:
                failed[i] = f"{type(err).__name__}: {err}"
            else:
                grades[i] = res
    rows = results_rows(spec, ds.rows, grades)
    results = write_results(out_dir / "results.csv", spec, rows)
    table = _table_dicts(spec, rows)
    figures = plot_sweeps(out_dir, spec, table)
    report = write_report(out_dir, sweep, table, figures, ds, len(grades))
    return {"results": results, "report": report, "figures": [p for _, p in figures], "graded": len(grades),
            "reused": reused, "failed": failed, "rows": len(rows)}


def read_results(path) -> list[dict]:
    """The long table back, values as floats (NaN for an empty cell)."""
    with open(path, newline="") as f:
        out = []
        for r in csv.DictReader(f):
            r["value"] = float(r["value"]) if r["value"] not in ("", "nan") else math.nan
            out.append(r)
        return out
