"""Results as one long (tidy) table: one row per number.

Columns :data:`COLUMNS`: ``experiment``, ``dataset``, ``reference`` (the truth
a number is measured against: ``exact``, ``canny_matlab_0.3``, ``truth``,
``noise_labels``, or ``""``), ``method`` (a registry name: ``intra``,
``mueggler``, ``time``, ``count`` or a plug-in's; in the lifetime experiment also ``truth``, the
simulator's lifetimes, and ``regions``, how its speed regions were found), ``variant`` (the compared
configuration's result key, e.g. ``acc_1ms``, or the method itself),
``display`` (the display policy, ``""`` when it does not apply), ``section``
(``slow``, ``fast``, ``all``, a frame index, ...), ``metric`` and ``value``
(float; NaN when undefined).

Saved as CSV (for people and spreadsheets) and as a columnar HDF5 file (one
dataset per column, for tools; h5py is already a dependency, so no columnar
library such as pyarrow is added for this).

Examples
--------
>>> t = ResultsTable()
>>> t.add(experiment="grade", dataset="d", method="intra", metric="median_rel_error", value=0.02)
>>> t.query(metric="median_rel_error")[0]["value"]
0.02
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from ._files import write_text_atomic

__all__ = ["COLUMNS", "ResultsTable", "read_results"]

COLUMNS = ("experiment", "dataset", "reference", "method", "variant", "display", "section", "metric", "value")
_TEXT = COLUMNS[:-1]


def _row(fields: Mapping) -> dict:
    unknown = sorted(set(fields) - set(COLUMNS))
    if unknown:
        raise ValueError(f"results row: unknown column(s) {unknown}; columns are {COLUMNS}")
    for need in ("experiment", "method", "metric"):
        if not fields.get(need):
            raise ValueError(f"results row: column {need!r} is required, got {fields.get(need)!r}")
    row = {c: "" if fields.get(c) is None else str(fields.get(c, "")) for c in _TEXT}
    if not row["variant"]:
        row["variant"] = row["method"]
    value = fields.get("value")
    try:
        row["value"] = float("nan") if value is None else float(value)
    except (TypeError, ValueError):
        raise ValueError(f"results row {row['metric']!r}: value must be a number, got {value!r}") from None
    return row


class ResultsTable:
    """An append-only long table of results (see the module notes for the columns)."""

    def __init__(self, rows: Iterable[Mapping] = ()) -> None:
        self.rows: list[dict] = []
        self.extend(rows)

    def add(self, **fields) -> None:
        """Append one row (``value`` a number; text columns default to ``""``)."""
        self.rows.append(_row(fields))

    def extend(self, rows: Iterable[Mapping], **common) -> None:
        """Append rows, each completed by ``common`` (a row's own fields win)."""
        for r in rows:
            self.rows.append(_row({**common, **r}))

    def __len__(self) -> int:
        return len(self.rows)

    def __iter__(self):
        return iter(self.rows)

    def query(self, **where) -> list[dict]:
        """Rows whose columns equal ``where`` (a value may be a tuple of accepted values)."""
        def ok(r):
            return all(r[k] in v if isinstance(v, tuple) else r[k] == v for k, v in where.items())
        bad = sorted(set(where) - set(COLUMNS))
        if bad:
            raise ValueError(f"query: unknown column(s) {bad}")
        return [r for r in self.rows if ok(r)]

    def value(self, **where) -> float:
        """The one value matching ``where``; NaN when none; ``ValueError`` when several."""
        hits = self.query(**where)
        if len(hits) > 1:
            raise ValueError(f"value: {len(hits)} rows match {where}")
        return hits[0]["value"] if hits else math.nan

    def unique(self, column: str, **where) -> list[str]:
        """Distinct values of ``column`` among the rows matching ``where``, in first-seen order."""
        return list(dict.fromkeys(r[column] for r in self.query(**where)))

    # -- files -------------------------------------------------------------------------------
    def to_csv_text(self) -> str:
        """CSV with a header row; values with ``repr`` precision (a round trip gives the same floats)."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(COLUMNS)
        for r in self.rows:
            w.writerow([r[c] for c in _TEXT] + [repr(r["value"])])
        return buf.getvalue()

    def save(self, stem: str | os.PathLike) -> tuple[Path, Path]:
        """Write ``STEM.csv`` and ``STEM.h5`` (columnar), each through a temporary file; their paths."""
        import h5py

        from evedge.io._atomic import write_hdf5_atomic

        stem = Path(stem)
        csv_path = write_text_atomic(stem.with_suffix(".csv"), self.to_csv_text())

        def fill(f):
            f.attrs["format"] = "evedge-results"
            f.attrs["format_version"] = np.int64(1)
            g = f.create_group("results", track_order=True)
            text = h5py.string_dtype("utf-8")
            for c in _TEXT:
                g.create_dataset(c, data=np.array([r[c] for r in self.rows], dtype=object), dtype=text,
                                 track_times=False)
            g.create_dataset("value", data=np.array([r["value"] for r in self.rows], dtype=np.float64),
                             track_times=False)

        # built in memory, then written with plain writes: HDF5 can crash the process on a full disk
        return csv_path, write_hdf5_atomic(stem.with_suffix(".h5"), fill)


def read_results(path: str | os.PathLike) -> ResultsTable:
    """Read a table saved by :meth:`ResultsTable.save` (the ``.csv`` or the ``.h5``).

    Raises
    ------
    ValueError
        Naming the file and the missing column or bad value.
    """
    path = Path(path)
    if path.suffix == ".h5":
        import h5py

        with h5py.File(path, "r") as f:
            if f.attrs.get("format") != "evedge-results":
                raise ValueError(f"{path}: not an evedge results file")
            g = f["results"]
            missing = [c for c in COLUMNS if c not in g]
            if missing:
                raise ValueError(f"{path}: results lack column(s) {missing}")
            cols = {c: [v.decode() if isinstance(v, bytes) else str(v) for v in g[c][()]] for c in _TEXT}
            values = g["value"][()]
        return ResultsTable({**{c: cols[c][i] for c in _TEXT}, "value": float(values[i])} for i in range(len(values)))
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        if tuple(reader.fieldnames or ()) != COLUMNS:
            raise ValueError(f"{path}: header {reader.fieldnames} is not {list(COLUMNS)}")
        table = ResultsTable()
        for line, r in enumerate(reader, start=2):
            try:
                table.add(**r)
            except ValueError as err:
                raise ValueError(f"{path}: line {line}: {err}") from None
        return table


# -- the paper experiments' numbers as rows ------------------------------------------------------
def _method_columns(key: str) -> dict:
    """method (registry name), variant (result key) and display of a compared method's result key."""
    from .methods import COMPARED

    c = COMPARED.get(key)
    if c is None:
        return {"method": key, "variant": key, "display": ""}
    return {"method": c.method, "variant": key, "display": c.display or ""}


def _number(v):
    if isinstance(v, bool):
        return float(v)
    if isinstance(v, (int, float, np.integer, np.floating)):
        return float(v)
    if v is None:
        return math.nan
    return None


def cdm_rows(experiment: str, dataset: str, cdm: Mapping) -> list[dict]:
    """``cdm[truth][result key][section] = summary`` -> rows ``cdm_<stat>`` (median, q1, q3, mean, n)."""
    rows = []
    for ref, per in cdm.items():
        for key, sections in per.items():
            for section, summary in sections.items():
                for stat, v in summary.items():
                    rows.append({"experiment": experiment, "dataset": dataset, "reference": ref,
                                 **_method_columns(key), "section": section, "metric": f"cdm_{stat}",
                                 "value": _number(v)})
    return rows


def real_rows(recording: str, per_method: Mapping) -> list[dict]:
    """``real[recording][result key] = {cdm_per_frame: {ref: [...]}, median: {ref: v}}`` -> rows."""
    rows = []
    for key, r in per_method.items():
        for ref, values in (r.get("cdm_per_frame") or {}).items():
            for i, v in enumerate(values):
                rows.append({"dataset": recording, "reference": ref, **_method_columns(key), "section": f"frame_{i}",
                             "metric": "cdm", "value": _number(v)})
        for ref, v in (r.get("median") or {}).items():
            rows.append({"dataset": recording, "reference": ref, **_method_columns(key), "section": "all",
                         "metric": "cdm_median", "value": _number(v)})
    return rows


#: Fields of a histogram peak (``exp_lifetime``'s ``peaks`` / ``shoulder_peaks``) -> metric suffix.
_PEAK_FIELDS = {"mode": "mode_us", "median": "median_us", "mad": "mad_us", "mad_log10": "mad_log10",
                "fwhm_log10": "fwhm_log10", "fraction": "fraction"}
#: A shoulder-aware component's ``kind`` as a number (metric ``shoulder_<k>_is_shoulder``).
_PEAK_KINDS = ("peak", "shoulder")


def _scalar_rows(base: dict, res: Mapping, section: str) -> list[dict]:
    return [{**base, "section": section, "metric": metric, "value": num}
            for metric, v in res.items() if (num := _number(v)) is not None]


def _peak_rows(base: dict, prefix: str, peaks) -> list[dict]:
    """One row per field of each peak: ``<prefix>_<k>_<field>`` (k from 0), and ``n_<prefix>s``."""
    rows = [{**base, "section": "all", "metric": f"n_{prefix}s", "value": float(len(peaks))}]
    for k, p in enumerate(peaks):
        for name, suffix in _PEAK_FIELDS.items():
            if name in p:
                rows.append({**base, "section": "all", "metric": f"{prefix}_{k}_{suffix}", "value": _number(p[name])})
        if "kind" in p:
            rows.append({**base, "section": "all", "metric": f"{prefix}_{k}_is_shoulder",
                         "value": float(_PEAK_KINDS.index(p["kind"]))})
    return rows


def lifetime_rows(lifetime: Mapping, datasets: Mapping | None = None) -> list[dict]:
    """The lifetime experiment as rows: everything its verdict reads (:func:`lifetime_view` reads them back).

    ``lifetime[dataset][key]`` (key ``proposed``, ``mueggler``, ``truth``) holds scalars (section
    ``all``), histogram peaks (``peak_<k>_mode_us``, ``peak_<k>_fwhm_log10``, ...; shoulder-aware
    components ``shoulder_<k>_...``; counts ``n_peaks``, ``n_shoulders``), per speed region spreads
    (section = region: ``mad_log10``, ``iqr_over_median``, ``frac_within``, ``median_rel_error``, ...;
    ``<region>_core`` without the band ends) and Mueggler on the event buffer's output (variant
    ``mueggler_on_buffer``). ``datasets[dataset]["regions"]`` gives how the regions were found
    (variant ``regions``: ``regions_from_truth``, ``regions_min_row_share``). The reference is
    ``truth`` on a dataset with true lifetimes, else ``""``.
    """
    rows = []
    for ds, per in lifetime.items():
        has_truth = any(isinstance(r, Mapping) and "median_rel_error" in r for k, r in per.items() if k != "truth")
        ref = "truth" if has_truth else ""
        for key, res in per.items():
            if not isinstance(res, Mapping):
                continue
            method = {"proposed": "intra"}.get(key, key)
            base = {"dataset": ds, "reference": ref, "method": method, "variant": key}
            rows += _scalar_rows(base, res, "all")
            rows += _peak_rows(base, "peak", res.get("peaks") or [])
            if "shoulder_peaks" in res:
                rows += _peak_rows(base, "shoulder", res["shoulder_peaks"])
            for group in ("regions", "regions_core"):
                for region, q in (res.get(group) or {}).items():
                    rows += _scalar_rows(base, q or {}, region if group == "regions" else f"{region}_core")
            buffered = res.get("on_buffered_events")
            if isinstance(buffered, Mapping):
                bbase = dict(base, variant=f"{key}_on_buffer")
                rows += _scalar_rows(bbase, buffered, "all")
                for region, q in (buffered.get("regions") or {}).items():
                    rows += _scalar_rows(bbase, q or {}, region)
        reg = ((datasets or {}).get(ds) or {}).get("regions") or {}
        if "from_truth" in reg:
            base = {"dataset": ds, "reference": ref, "method": "regions", "variant": "regions", "section": "all"}
            rows.append({**base, "metric": "regions_from_truth", "value": float(reg["from_truth"])})
            if "min_row_share" in reg:
                rows.append({**base, "metric": "regions_min_row_share", "value": reg["min_row_share"]})
    return rows


def _peaks_of(values: Mapping, prefix: str) -> list[dict]:
    n = values.get(f"n_{prefix}s")
    if n is None:
        return []
    out = []
    for k in range(int(n)):
        p = {name: values[f"{prefix}_{k}_{suffix}"] for name, suffix in _PEAK_FIELDS.items()
             if f"{prefix}_{k}_{suffix}" in values}
        if f"{prefix}_{k}_is_shoulder" in values:
            p["kind"] = _PEAK_KINDS[int(values[f"{prefix}_{k}_is_shoulder"])]
        out.append(p)
    return out


def lifetime_view(table: ResultsTable, experiment: str = "lifetime") -> tuple[dict, dict]:
    """``(lifetime, datasets)`` in the shapes :func:`evedge.bench.verdicts.lifetime_verdicts` reads, from the rows
    of :func:`lifetime_rows` (NaN where the experiment had None)."""
    from .regions import TRUTH_METHOD, delays_method

    flat: dict = {}
    for r in table.query(experiment=experiment):
        (flat.setdefault(r["dataset"], {}).setdefault(r["variant"], {}).setdefault(r["section"], {}))[r["metric"]] = \
            r["value"]
    lifetime, datasets = {}, {}
    for ds, per in flat.items():
        out = lifetime[ds] = {}
        for key, sections in per.items():
            if key == "regions" or key.endswith("_on_buffer"):
                continue
            top = sections.get("all", {})
            res = {m: v for m, v in top.items()
                   if not (m.startswith(("peak_", "shoulder_")) or m in ("n_peaks", "n_shoulders"))}
            res["peaks"] = _peaks_of(top, "peak")
            if "n_shoulders" in top:
                res["shoulder_peaks"] = _peaks_of(top, "shoulder")
            regions = {s: q for s, q in sections.items() if s != "all" and not s.endswith("_core")}
            core = {s[: -len("_core")]: q for s, q in sections.items() if s.endswith("_core")}
            if regions:
                res["regions"] = regions
            if core:
                res["regions_core"] = core
            buffered = per.get(f"{key}_on_buffer")
            if buffered:
                res["on_buffered_events"] = dict(buffered.get("all", {}),
                                                 regions={s: q for s, q in buffered.items() if s != "all"})
            out[key] = res
        how = (per.get("regions") or {}).get("all", {})
        if "regions_from_truth" in how:
            datasets[ds] = {"regions": {"method": TRUTH_METHOD if how["regions_from_truth"]
                                        else delays_method(how.get("regions_min_row_share", 0.25))}}
    return lifetime, datasets


def diagnostic_rows(dataset: str, diagnostics: Mapping) -> list[dict]:
    """The similarity experiment's diagnostics (they explain a lost CDM comparison) as rows.

    ``pixel_ratio[reference][key][section]`` -> metric ``edge_pixel_ratio``;
    ``lifetime[key][section] = {n_signal, coverage, median_rel_error, over_2x, under_2x}`` ->
    metrics ``signal_<stat>`` (reference ``truth``).
    """
    rows = []
    for ref, per in (diagnostics.get("pixel_ratio") or {}).items():
        for key, sections in per.items():
            for section, v in sections.items():
                rows.append({"dataset": dataset, "reference": ref, **_method_columns(key), "section": section,
                             "metric": "edge_pixel_ratio", "value": _number(v)})
    for key, sections in (diagnostics.get("lifetime") or {}).items():
        for section, stats in sections.items():
            for stat, v in stats.items():
                rows.append({"dataset": dataset, "reference": "truth", **_method_columns(key), "section": section,
                             "metric": f"signal_{stat}", "value": _number(v)})
    return rows


def diagnostics_view(table: ResultsTable, experiment: str = "similarity") -> dict:
    """``{dataset: {"pixel_ratio": {ref: {key: {section: v}}}, "lifetime": {key: {section: {stat: v}}}}}``
    (what :func:`evedge.bench.verdicts.cdm_verdicts` reads), from the rows of :func:`diagnostic_rows`."""
    out: dict = {}
    for r in table.query(experiment=experiment):
        if r["metric"] == "edge_pixel_ratio":
            (out.setdefault(r["dataset"], {}).setdefault("pixel_ratio", {}).setdefault(r["reference"], {})
             .setdefault(r["variant"], {}))[r["section"]] = r["value"]
        elif r["metric"].startswith("signal_"):
            stat = r["metric"][len("signal_"):]
            (out.setdefault(r["dataset"], {}).setdefault("lifetime", {}).setdefault(r["variant"], {})
             .setdefault(r["section"], {}))[stat] = int(r["value"]) if stat == "n_signal" else r["value"]
    return out


def ransac_rows(fmeasure: Mapping, sensitivity: Mapping | None = None) -> list[dict]:
    """``fmeasure[noise kind][variant] = {noise_px: [...], <metric>: [...]}`` -> one row per noise level.

    Sections ``noise_<level>`` (the timestamp noise std in units of the lifetime); the variant's
    ``use_intra`` and ``delta_px`` as rows of section ``all``; ``sensitivity[tolerance][kind][variant]``
    (F-measure under other definitions of a true inlier) as metric ``f_measure@<tolerance>``.
    """
    rows = []
    for kind, per in fmeasure.items():
        for variant, r in per.items():
            levels = list(r.get("noise_px", []))
            common = {"dataset": f"ransac_{kind}", "reference": "true inliers", "method": "intra", "variant": variant}
            for metric in ("use_intra", "delta_px"):
                if metric in r:
                    rows.append({**common, "section": "all", "metric": metric, "value": _number(r[metric])})
            series = [(m, v) for m, v in r.items() if m != "noise_px"]
            series += [(f"f_measure@{tol}", (per_kind.get(kind) or {}).get(variant))
                       for tol, per_kind in (sensitivity or {}).items()]
            for metric, values in series:
                if not isinstance(values, (list, tuple, np.ndarray)) or len(values) != len(levels):
                    continue
                for level, v in zip(levels, values):
                    num = _number(v)
                    if num is not None:
                        rows.append({**common, "section": f"noise_{float(level)!r}", "metric": metric, "value": num})
    return rows


def ransac_view(table: ResultsTable, experiment: str = "ransac") -> tuple[dict, dict]:
    """``(fmeasure, sensitivity)`` in the shapes :func:`evedge.bench.verdicts.intra_verdicts` reads, from the table."""
    fmeasure: dict = {}
    sensitivity: dict = {}
    for r in table.query(experiment=experiment):
        if not r["dataset"].startswith("ransac_"):
            continue
        kind = r["dataset"][len("ransac_"):]
        res = fmeasure.setdefault(kind, {}).setdefault(r["variant"], {})
        if r["section"] == "all":
            res[r["metric"]] = bool(r["value"]) if r["metric"] == "use_intra" else r["value"]
            continue
        level = float(r["section"][len("noise_"):])
        if r["metric"].startswith("f_measure@"):
            tol = r["metric"].split("@", 1)[1]
            target = sensitivity.setdefault(tol, {}).setdefault(kind, {}).setdefault(r["variant"], {})
        else:
            target = res.setdefault(r["metric"], {})
        target[level] = None if math.isnan(r["value"]) else r["value"]
    for kind, per in fmeasure.items():  # level -> value maps to the study's lists
        for res in per.values():
            levels = sorted({lv for v in res.values() if isinstance(v, dict) for lv in v})
            for metric in [m for m, v in res.items() if isinstance(v, dict)]:
                res[metric] = [res[metric].get(lv) for lv in levels]
            res["noise_px"] = levels
    for per_kind in sensitivity.values():
        for per in per_kind.values():
            for variant, by_level in per.items():
                per[variant] = [by_level[lv] for lv in sorted(by_level)]
    return fmeasure, sensitivity


def leaderboard(table: ResultsTable, *, metric: str = "cdm_median", experiments=("similarity", "real"),
                display: str | None = None) -> dict:
    """Median CDM per method (rows) x (dataset, section, truth) (columns), and the winner of each column.

    Only the primary display's rows of lifetime methods (or ``display``) and
    non-diagnostic methods enter; a winner is the highest value of its column.

    Returns
    -------
    dict
        ``{"columns": [(dataset, section, reference)], "rows": [(variant, [values])],
        "winners": {column: variant}}``.
    """
    from .methods import COMPARED, PRIMARY_DISPLAY

    display = display or PRIMARY_DISPLAY
    picked = [r for r in table.rows if r["experiment"] in experiments and r["metric"] == metric
              and r["display"] in ("", display) and not (r["variant"] in COMPARED and COMPARED[r["variant"]].diagnostic)
              and r["section"] in ("slow", "fast", "all")]
    cols = list(dict.fromkeys((r["dataset"], r["section"], r["reference"]) for r in picked
                              if not (r["experiment"] == "similarity" and r["section"] == "all")))
    variants = list(dict.fromkeys(r["variant"] for r in picked))
    cell = {(r["variant"], (r["dataset"], r["section"], r["reference"])): r["value"] for r in picked}
    rows = [(v, [cell.get((v, c), math.nan) for c in cols]) for v in variants]
    winners = {}
    for j, c in enumerate(cols):
        vals = [(row[1][j], row[0]) for row in rows if math.isfinite(row[1][j])]
        if vals:
            winners[c] = max(vals)[1]
    return {"columns": cols, "rows": rows, "winners": winners}


def cdm_view(table: ResultsTable, experiment: str = "similarity") -> dict:
    """``{dataset: {reference: {variant: {section: {stat: value}}}}}`` of the CDM summary rows (``cdm_<stat>``).

    The shape :func:`evedge.bench.verdicts.cdm_verdicts` reads, rebuilt from the table.
    """
    out: dict = {}
    for r in table.query(experiment=experiment):
        if not r["metric"].startswith("cdm_") or r["section"].startswith("frame_"):
            continue
        stat = r["metric"][4:]
        value = int(r["value"]) if stat == "n" else r["value"]
        (out.setdefault(r["dataset"], {}).setdefault(r["reference"], {}).setdefault(r["variant"], {})
         .setdefault(r["section"], {}))[stat] = value
    return out


def real_view(table: ResultsTable, experiment: str = "real") -> dict:
    """``{recording: {variant: {"median": {reference: value}}}}`` (what ``real_verdicts`` reads), from the table."""
    out: dict = {}
    for r in table.query(experiment=experiment, metric="cdm_median", section="all"):
        (out.setdefault(r["dataset"], {}).setdefault(r["variant"], {}).setdefault("median", {}))[r["reference"]] = \
            r["value"]
    return out
