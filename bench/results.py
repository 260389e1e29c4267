"""Results as one long (tidy) table: one row per number.

Columns :data:`COLUMNS`: ``experiment``, ``dataset``, ``reference`` (the truth
a number is measured against: ``exact``, ``canny_matlab_0.3``, ``truth``,
``noise_labels``, or ``""``), ``method`` (a registry name: ``intra``,
``mueggler``, ``time``, ``count`` or a plug-in's), ``variant`` (the compared
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

        from evedge.io._atomic import atomic_path

        stem = Path(stem)
        csv_path = write_text_atomic(stem.with_suffix(".csv"), self.to_csv_text())
        h5_path = stem.with_suffix(".h5")
        with atomic_path(h5_path) as tmp:
            with h5py.File(tmp, "w", track_order=True) as f:
                f.attrs["format"] = "evedge-results"
                f.attrs["format_version"] = np.int64(1)
                g = f.create_group("results", track_order=True)
                text = h5py.string_dtype("utf-8")
                for c in _TEXT:
                    g.create_dataset(c, data=np.array([r[c] for r in self.rows], dtype=object), dtype=text,
                                     track_times=False)
                g.create_dataset("value", data=np.array([r["value"] for r in self.rows], dtype=np.float64),
                                 track_times=False)
        return csv_path, h5_path


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
