"""Grade any method's output against a dataset's exact truth: ``evedge grade DATASET -d DETECTIONS -o OUT``.

DATASET is a recording with truth (``evedge simulate`` output, or any file
:func:`evedge.io.read_events` reads; metrics whose truth is absent give no
rows). DETECTIONS is either

* an ``evedge detect`` output (``detection.h5``, format ``evedge-detection``:
  its events, or its source's sha256, must match the dataset), or
* a plain layout, one value per dataset event *in the dataset's event order*
  (NaN: no estimate), any subset of the columns

  ``lifetime_us`` (µs), ``vx_px_s``, ``vy_px_s`` (normal flow, px/s),
  ``kept`` (bool/0-1: the noise filter's decision),

  plus, in HDF5 and NPZ, edge frames ``edge_t_us`` (int64 µs, shape (n,)) and
  ``edge_images`` (bool, (n, height, width)); in HDF5 also as ``edges/t_us``
  and ``edges/images``. As ``.h5``/``.hdf5`` (datasets at the root),
  ``.npz`` (arrays of those names) or ``.csv`` (a header row naming the
  columns, one row per event; no frames).

A detection that does not fit the dataset (event count, order, sensor, frame
size) is refused with a message naming the first mismatch. The grade is a
long results table (:mod:`evedge.bench.results`) written as ``OUT/grade.csv``
and ``OUT/grade.h5``, a figure and ``OUT/report.html``.
"""

from __future__ import annotations

import csv
import datetime as _dt
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._files import save_figure, write_json_atomic, write_text_atomic
from .metrics import METRICS, GradeInput
from .results import ResultsTable

__all__ = ["DetectionInput", "GradeError", "grade", "load_detections"]

PLAIN_COLUMNS = ("lifetime_us", "vx_px_s", "vy_px_s", "kept")


class GradeError(ValueError):
    """A detection file that cannot be graded against the dataset (the message names the mismatch)."""


@dataclass
class DetectionInput:
    """A detection, whatever file it came from."""

    path: Path
    method: str
    display: str = ""
    columns: dict = field(default_factory=dict)   # name -> per-event array
    edge_t_us: np.ndarray | None = None
    edge_images: np.ndarray | None = None
    events: np.ndarray | None = None              # the events the method saw, when the file has them
    sensor_size: object = None
    source: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)


def _plain_h5(path: Path) -> dict:
    import h5py

    out = {}
    with h5py.File(path, "r") as f:
        fmt = f.attrs.get("format")
        if (fmt.decode() if isinstance(fmt, bytes) else fmt) == "evedge":
            raise GradeError(f"{path}: is an evedge recording (events, truth), not a detection file; run "
                             f"'evedge detect {path} -o OUT --at-frames' and grade OUT/detection.h5")
        for name in PLAIN_COLUMNS + ("edge_t_us", "edge_images"):
            if name in f:
                out[name] = np.asarray(f[name][()])
        for a, b in (("edges/t_us", "edge_t_us"), ("edges/images", "edge_images")):
            if a in f and b not in out:
                out[b] = np.asarray(f[a][()])
        out["_method"] = f.attrs.get("method")
    return out


def _plain_npz(path: Path) -> dict:
    with np.load(path, allow_pickle=False) as z:
        return {k: np.asarray(z[k]) for k in z.files if k in PLAIN_COLUMNS + ("edge_t_us", "edge_images")}


def _plain_csv(path: Path) -> dict:
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        header = [h.strip() for h in next(reader, [])]
        unknown = [h for h in header if h not in PLAIN_COLUMNS]
        if not header or unknown:
            raise GradeError(f"{path}: the header must name columns among {PLAIN_COLUMNS}, got {header}")
        rows = list(reader)
    out = {}
    for j, name in enumerate(header):
        values = []
        for line, r in enumerate(rows, start=2):
            if len(r) != len(header):
                raise GradeError(f"{path}: line {line} has {len(r)} fields, the header {len(header)}")
            text = r[j].strip()
            try:
                values.append(float(text) if text not in ("", "nan", "NaN") else np.nan)
            except ValueError:
                raise GradeError(f"{path}: line {line}, column {name!r}: not a number: {text!r}") from None
        out[name] = np.asarray(values)
    return out


def load_detections(path, *, method: str | None = None) -> DetectionInput:
    """Read an ``evedge detect`` file or a plain layout (see the module notes).

    Raises
    ------
    GradeError
        Unreadable or malformed file, naming it and the column.
    """
    from evedge.io.detection import is_detection_file, read_detection

    path = Path(path)
    if not path.is_file():
        raise GradeError(f"{path}: no such file")
    if is_detection_file(path):
        d = read_detection(path)
        cols = {}
        if d.lifetimes is not None:
            cols = {n: d.lifetimes[n] for n in ("lifetime_us", "vx_px_s", "vy_px_s")}
            cols["lifetime_us"] = np.where(d.lifetimes["valid"], d.lifetimes["lifetime_us"], np.nan)
            if d.metadata.get("filter"):
                cols["kept"] = d.lifetimes["kept"]
        return DetectionInput(path, method or d.metadata.get("method") or path.stem, d.metadata.get("display") or "",
                              cols, d.edges.t_us if d.edges is not None else None,
                              d.edges.images if d.edges is not None else None, d.events, d.sensor_size,
                              d.metadata.get("source") or {}, d.metadata)
    suffix = path.suffix.lower()
    try:
        if suffix in (".h5", ".hdf5"):
            raw = _plain_h5(path)
        elif suffix == ".npz":
            raw = _plain_npz(path)
        elif suffix == ".csv":
            raw = _plain_csv(path)
        else:
            raise GradeError(f"{path}: unknown detection layout {suffix!r}; expected an evedge detection file, "
                             f".h5/.hdf5, .npz or .csv (see evedge grade --help)")
    except OSError as err:
        raise GradeError(f"{path}: cannot read: {err}") from None
    file_method = raw.pop("_method", None)
    if isinstance(file_method, bytes):
        file_method = file_method.decode()
    cols = {}
    for name in PLAIN_COLUMNS:
        if name in raw:
            col = np.asarray(raw[name])
            if col.ndim != 1:
                raise GradeError(f"{path}: column {name!r} must be 1-D (one value per event), got shape {col.shape}")
            if name == "kept":
                if not np.all(np.isin(col, (0, 1))):
                    raise GradeError(f"{path}: column 'kept' must hold 0/1 or booleans")
                col = col.astype(bool)
            else:
                col = col.astype(np.float64)
            cols[name] = col
    t, images = raw.get("edge_t_us"), raw.get("edge_images")
    if (t is None) != (images is None):
        raise GradeError(f"{path}: edge frames need both edge_t_us and edge_images")
    if t is not None:
        t = np.asarray(t)
        if t.ndim != 1 or t.dtype.kind not in "iu" or images.ndim != 3 or images.shape[0] != t.shape[0]:
            raise GradeError(f"{path}: edge_t_us must be integer (n,) and edge_images (n, height, width); got "
                             f"{t.dtype} {t.shape} and {images.shape}")
        t = t.astype(np.int64)
        images = images.astype(bool)
    if not cols and t is None:
        raise GradeError(f"{path}: nothing to grade: no column among {PLAIN_COLUMNS} and no edge frames")
    return DetectionInput(path, method or file_method or path.stem, "", cols, t, images)


def _check_match(det: DetectionInput, rec, dataset_path: Path) -> None:
    """Refuse a detection that was not made from the dataset's events, naming the first mismatch."""
    from evedge.io.detection import file_sha256

    ev, size = rec.events, rec.sensor_size
    where = f"{det.path} does not match the dataset {dataset_path}"
    if det.sensor_size is not None and det.sensor_size != size:
        raise GradeError(f"{where}: sensor {det.sensor_size.width}x{det.sensor_size.height} vs "
                         f"{size.width}x{size.height}")
    if det.events is not None:
        if det.events.size != ev.size:
            raise GradeError(f"{where}: {det.events.size} events vs {ev.size}")
        for name in ("t", "x", "y", "p"):
            diff = np.flatnonzero(det.events[name] != ev[name])
            if diff.size:
                i = int(diff[0])
                a, b = det.events[i], ev[i]
                raise GradeError(f"{where}: event {i} differs (field {name!r}): detection (x={a['x']}, y={a['y']}, "
                                 f"t={a['t']}, p={a['p']}), dataset (x={b['x']}, y={b['y']}, t={b['t']}, p={b['p']})")
    elif det.source:
        n = det.source.get("n_events")
        if n is not None and int(n) != ev.size:
            raise GradeError(f"{where}: the detection was made from {n} events, the dataset has {ev.size}")
        sha = det.source.get("sha256")
        if sha and sha != file_sha256(dataset_path):
            raise GradeError(f"{where}: it was made from {det.source.get('path')} (sha256 {sha[:16]}...), "
                             f"the dataset's sha256 is {file_sha256(dataset_path)[:16]}...")
    for name, col in det.columns.items():
        if col.shape[0] != ev.size:
            raise GradeError(f"{where}: column {name!r} has {col.shape[0]} rows, the dataset {ev.size} events "
                             f"(one value per event, in the dataset's order)")
    if det.edge_images is not None and det.edge_images.shape[1:] != size.shape:
        raise GradeError(f"{where}: edge frames are {det.edge_images.shape[2]}x{det.edge_images.shape[1]}, "
                         f"the sensor {size.width}x{size.height}")


def grade_recording(rec, det: DetectionInput, *, dataset: str, experiment: str = "grade",
                    metrics=None, canny_settings: int = 1) -> ResultsTable:
    """Rows of every registered metric (or of ``metrics``) for one detection of one recording."""
    from .exp_similarity import sections_us

    t_end = int(rec.events["t"][-1]) if rec.events.size else 0
    sections = sections_us(rec.metadata, t_end)
    sections.setdefault("all", (int(rec.events["t"][0]) if rec.events.size else 0, t_end + 1))
    inp = GradeInput(rec.events, rec.sensor_size, sections, rec.truth, det.columns.get("lifetime_us"),
                     det.columns.get("vx_px_s"), det.columns.get("vy_px_s"), det.columns.get("kept"),
                     det.edge_t_us, det.edge_images, rec.frames, rec.edges, {"canny_settings": canny_settings})
    table = ResultsTable()
    for name in metrics or METRICS.names():
        entry = METRICS.get(name)
        table.extend(entry.factory(inp), experiment=experiment, dataset=dataset, method=det.method,
                     display=det.display)
    return table


def grade(dataset_path, detections_path, out_dir, *, method: str | None = None, canny_settings: int = 1,
          command: str = "evedge grade") -> dict:
    """Grade a detection file against a dataset; write the table, a figure and ``report.html``.

    Returns
    -------
    dict
        ``{"table": ResultsTable, "files": [...], "report": path}``.

    Raises
    ------
    GradeError
        For a dataset without events or a detection that does not match it.
    """
    from evedge.io import read_events

    dataset_path = Path(dataset_path)
    out_dir = Path(out_dir)
    try:
        rec = read_events(dataset_path)
    except (ValueError, OSError) as err:
        raise GradeError(str(err)) from None
    det = load_detections(detections_path, method=method)
    _check_match(det, rec, dataset_path)
    name = rec.metadata.get("scene_name") or dataset_path.stem
    table = grade_recording(rec, det, dataset=name, canny_settings=canny_settings)
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path, h5_path = table.save(out_dir / "grade")
    figure = _plot(out_dir, table, det.method)
    info = {"dataset": str(dataset_path.resolve()), "detections": str(Path(detections_path).resolve()),
            "method": det.method, "display": det.display, "n_events": int(rec.events.size),
            "date_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC"), "command": command,
            "detection_metadata": det.metadata}
    write_json_atomic(out_dir / "grade.json", {"info": info, "rows": table.rows})
    from .report_render import render_grade

    report = write_text_atomic(out_dir / "report.html", render_grade(table, info, [figure] if figure else []))
    return {"table": table, "files": [str(csv_path), str(h5_path), str(out_dir / "grade.json")],
            "figure": str(figure) if figure else None, "report": str(report)}


def _plot(out_dir: Path, table: ResultsTable, method: str):
    """Bars per section: lifetime error (median, p90), and median CDM per reference."""
    from ._plot import pyplot
    from .methods import colour, label

    life = table.query(metric=("median_rel_error", "p90_rel_error"))
    cdm_rows = table.query(metric="median_cdm")
    if not life and not cdm_rows:
        return None
    plt = pyplot()
    panels = [p for p in (life, cdm_rows) if p]
    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 3.4), squeeze=False)
    for ax, rows in zip(axes[0], panels):
        keys = list(dict.fromkeys((r["metric"], r["reference"]) for r in rows))
        sections = list(dict.fromkeys(r["section"] for r in rows))
        width = 0.8 / len(keys)
        for k, (metric, ref) in enumerate(keys):
            vals = [next((r["value"] for r in rows if r["section"] == s and r["metric"] == metric
                          and r["reference"] == ref), np.nan) for s in sections]
            ax.bar(np.arange(len(sections)) + k * width, vals, width, color=colour(method, "C0"),
                   alpha=1.0 - 0.35 * k, edgecolor="k", label=f"{metric.replace('_', ' ')} vs {ref}")
        ax.set_xticks(np.arange(len(sections)) + width * (len(keys) - 1) / 2, sections)
        ax.set_xlabel("section")
        ax.set_ylabel("relative lifetime error" if rows is life else "median CDM (higher: closer)")
        ax.legend(fontsize=7)
    fig.suptitle(f"{label(method)}: graded against the dataset's truth", fontsize=9)
    return save_figure(fig, out_dir / "grade.png")
