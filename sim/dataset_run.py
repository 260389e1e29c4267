"""Generate a dataset on Dask: resumable, verified, one file per sequence, a manifest and a card.

Output folder::

    DIR/dataset.json             the spec (as parsed) and layouts: a rerun must match it
    DIR/manifest.jsonl           one JSON row per sequence, sorted by index (written by the client)
    DIR/README.md                the dataset card: spec, versions, counts, totals
    DIR/sequences/seq_00000.h5   evedge HDF5: events, truth, frames, edge maps, metadata
    DIR/dsec/seq_00000/events/left/events.h5   with layout "dsec" (DSEC's folder shape)

Each task simulates one sequence and writes its files to temporary names,
then renames them; the client rewrites the manifest atomically as rows come
in (at most once a second, and at the end). A rerun verifies every ``ok`` row
(files present, sha256 equal) and redoes only the missing, corrupt, failed or
never finished sequences; as sequence ``i`` depends only on ``(spec, i)``, the
result is the same dataset, byte for byte. A layout added on a rerun is
written from the verified evedge file, without simulating again.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import platform
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

from evedge.io._atomic import atomic_path

from .dataset import PARAMETERS, DatasetError, DatasetSpec, sequence_scene
from .scene import SceneError

MANIFEST = "manifest.jsonl"
LAYOUTS = ("evedge", "dsec")
#: Manifest fields that depend on the run (which worker, how long), not on the spec.
RUN_FIELDS = ("wall_s", "cpu_s", "worker")


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def sequence_files(spec: DatasetSpec, index: int, layouts) -> dict[str, str]:
    """Layout -> path (relative to the dataset folder) of sequence ``index``'s files."""
    name = spec.sequence_name(index)
    paths = {"evedge": f"sequences/{name}.h5", "dsec": f"dsec/{name}/events/left/events.h5"}
    return {k: paths[k] for k in layouts}


@dataclass(frozen=True)
class SequenceTask:
    """What a worker needs to make one sequence (picklable)."""

    spec: DatasetSpec
    index: int
    out_dir: str
    layouts: tuple[str, ...]
    #: A verified manifest row whose evedge file holds the sequence: only the missing layouts are
    #: written, from that file's events, instead of simulating again.
    base_row: dict | None = None


def _export(task: SequenceTask, t0: float, c0: float) -> dict:
    """Write the layouts missing from ``task.base_row`` from its verified evedge file."""
    from evedge.io import read_hdf5
    from evedge.io.dsec import write_dsec_events

    out, row = Path(task.out_dir), dict(task.base_row)
    wanted = sequence_files(task.spec, task.index, task.layouts)
    source = sequence_files(task.spec, task.index, ("evedge",))["evedge"]
    files = {rel: d for rel, d in row["files"].items() if rel in wanted.values()}
    rec = None
    for layout, rel in wanted.items():
        if rel in files:
            continue
        rec = rec or read_hdf5(out / source)
        path = out / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        write_dsec_events(path, rec.events)
        files[rel] = sha256_file(path)
    row.update(files=files, bytes=sum((out / rel).stat().st_size for rel in files),
               wall_s=round(time.perf_counter() - t0, 3), cpu_s=round(time.process_time() - c0, 3),
               worker=f"{platform.node()}:{os.getpid()}")
    return row


def generate_sequence(task: SequenceTask) -> dict:
    """Simulate and write one sequence (or only its missing layouts); its manifest row.

    An invalid scene or parameters (a ``ValueError``, e.g. a light intensity
    above 1) or a ``MemoryError`` give a row with ``status = "failed"`` and
    the message: retrying would fail the same way. Anything else raises, so
    Dask retries the task.
    """
    from evedge.io import write_recording
    from evedge.io.dsec import write_dsec_events

    from .simulate import simulate

    t0, c0 = time.perf_counter(), time.process_time()
    if task.base_row is not None:
        return _export(task, t0, c0)
    spec, out = task.spec, Path(task.out_dir)
    seq = spec.sequence(task.index)
    row = {"index": seq.index, "name": seq.name, "seed": seq.seed, "status": "ok", "error": None,
           "n_events": None, "n_signal": None, "n_noise": None, "duration_s": None, "files": {},
           "bytes": 0, "params": seq.params}
    try:
        scene = sequence_scene(spec, seq)
        rec = simulate(scene, progress=False)
    except (SceneError, ValueError, MemoryError) as err:
        row.update(status="failed", error=f"{type(err).__name__}: {err}")
    else:
        md = dict(rec.metadata)
        md["dataset"] = {"name": spec.name, "index": seq.index, "spec_seed": spec.seed, "params": seq.params}
        rec = replace(rec, metadata=md)
        row.update(n_events=int(rec.events.shape[0]), n_signal=md["n_signal"], n_noise=md["n_noise"],
                   duration_s=md["duration_s"])
        for layout, rel in sequence_files(spec, seq.index, task.layouts).items():
            path = out / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            if layout == "evedge":
                write_recording(path, rec)
            else:
                write_dsec_events(path, rec.events)
            row["files"][rel] = sha256_file(path)
            row["bytes"] += path.stat().st_size
    row.update(wall_s=round(time.perf_counter() - t0, 3), cpu_s=round(time.process_time() - c0, 3),
               worker=f"{platform.node()}:{os.getpid()}")
    return row


def _canonical(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"))


def read_manifest(out_dir: Path) -> dict[int, dict]:
    """Rows of ``out_dir/manifest.jsonl`` by index (unreadable lines are dropped: redone)."""
    rows = {}
    try:
        text = (out_dir / MANIFEST).read_text(encoding="utf-8")
    except FileNotFoundError:
        return rows
    except (OSError, UnicodeDecodeError):
        return rows
    for line in text.splitlines():
        try:
            row = json.loads(line)
            rows[int(row["index"])] = row
        except (ValueError, KeyError, TypeError):
            continue
    return rows


def write_manifest(out_dir: Path, rows: dict[int, dict]) -> None:
    text = "".join(_canonical(rows[i]) + "\n" for i in sorted(rows))
    with atomic_path(out_dir / MANIFEST) as tmp:
        tmp.write_text(text, encoding="utf-8")


def _verified(out_dir: Path, row: dict) -> dict[str, str]:
    """The files of an ``ok`` row that exist and match their sha256 (path -> sha256)."""
    if row.get("status") != "ok" or not isinstance(row.get("files"), dict):
        return {}
    good = {}
    for rel, digest in row["files"].items():
        try:
            if sha256_file(out_dir / rel) == digest:
                good[rel] = digest
        except OSError:
            pass
    return good


def _check_folder(spec: DatasetSpec, out_dir: Path, layouts: tuple[str, ...]) -> None:
    """Record the spec in ``dataset.json``, or check that the folder holds this spec's dataset."""
    record = {"spec": spec.raw, "name": spec.name, "layouts": list(layouts)}
    path = out_dir / "dataset.json"
    if path.exists():
        try:
            old = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as err:
            raise DatasetError(f"{path}: unreadable ({err}); remove it or choose another output folder") from None
        if _canonical(old.get("spec")) != _canonical(spec.raw):
            raise DatasetError(f"{out_dir} holds a dataset made from another spec (see {path}); "
                               f"choose another output folder")
        if old.get("layouts") == list(layouts):
            return
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n", encoding="utf-8")


@dataclass(frozen=True)
class DatasetRun:
    """What a run did: the manifest rows (by index), how many were made, skipped, failed."""

    out_dir: Path
    rows: dict
    made: int
    skipped: int
    failed: int


def _refuse_links(out_dir: Path) -> None:
    """A symbolic link anywhere in the dataset folder would make the run write or delete outside it."""
    for root, dirs, files in os.walk(out_dir):  # links to folders are listed, never entered
        for name in dirs + files:
            if os.path.islink(os.path.join(root, name)):
                raise DatasetError(f"{os.path.join(root, name)} is a symbolic link: {out_dir} is not written into "
                                   "(a dataset folder holds only its own files)")


def generate_dataset(spec: DatasetSpec, out_dir, *, layouts=("evedge",), workers: int | None = None,
                     scheduler: str | None = None, client=None, retries: int = 2, progress: bool = True,
                     task_fn=generate_sequence) -> DatasetRun:
    """Make (or complete) the dataset of ``spec`` in ``out_dir`` on Dask.

    Parameters
    ----------
    spec : DatasetSpec
        From :func:`evedge.sim.dataset.load_dataset`.
    out_dir : path-like
        Created if missing (its parent must exist).
    layouts : sequence of str
        ``"evedge"`` (HDF5 with truth, frames and edge maps) and/or ``"dsec"``.
    workers, scheduler, client
        Where to run (see :func:`evedge.parallel.dask_client`): a new
        ``LocalCluster`` of ``workers`` processes (default: the cores), an
        existing scheduler's address, or an open client.
    retries : int
        Extra attempts of a sequence whose task raised.
    progress : bool
        A bar over sequences.
    task_fn : callable
        The per-sequence task (tests inject faults with it).

    Returns
    -------
    DatasetRun

    Raises
    ------
    DatasetError
        ``out_dir`` holds another spec's dataset, or a layout is unknown.
    evedge.parallel.ClusterError
        The scheduler cannot be reached.

    Examples
    --------
    >>> from evedge.sim.dataset import load_dataset
    >>> run = generate_dataset(load_dataset("scenes/datasets/small.toml"), "out/small")  # doctest: +SKIP
    >>> run.failed                                                                      # doctest: +SKIP
    0
    """
    from tqdm import tqdm

    from evedge.parallel import dask_client, run_tasks

    layouts = tuple(dict.fromkeys(layouts))
    bad = [k for k in layouts if k not in LAYOUTS]
    if bad or not layouts:
        raise DatasetError(f"layouts must be a non-empty subset of {list(LAYOUTS)}, got {list(layouts)}")
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise DatasetError(f"{out_dir} is an existing file; the dataset is a folder")
    if not out_dir.parent.is_dir():
        raise DatasetError(f"folder {out_dir.parent} of {out_dir} does not exist")
    out_dir.mkdir(exist_ok=True)
    # one run per folder: a second one would rewrite the same files and manifest
    lock = open(out_dir / ".lock", "w")
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.close()
        raise DatasetError(f"{out_dir} is being written by another run (its .lock is held)") from None
    try:
        _refuse_links(out_dir)
        _check_folder(spec, out_dir, layouts)
        # temporary files (".<name>.XXXX.tmp", evedge.io._atomic) left by a run killed mid-write;
        # the lock says no other run is writing here
        for stale in out_dir.glob("**/.*.tmp"):
            if stale.is_file():
                stale.unlink(missing_ok=True)
        rows = {}
        old = read_manifest(out_dir)
        todo, bases = [], {}
        # hashing every kept file is long work on a big dataset: a bar when there is a manifest to check
        for i in tqdm(range(spec.count), desc=f"verify {spec.name}", unit="seq", file=sys.stderr,
                      disable=not (progress and old), leave=False):
            expected = set(sequence_files(spec, i, layouts).values())
            source = sequence_files(spec, i, ("evedge",))["evedge"]
            row = old.get(i)
            good = _verified(out_dir, row) if row is not None else {}
            if expected <= set(good):  # every file this run wants is there and intact
                files = {rel: good[rel] for rel in sorted(expected)}
                rows[i] = dict(row, files=files, bytes=sum((out_dir / rel).stat().st_size for rel in files))
                continue
            if source in good:  # the simulation is intact: write only the missing layouts from it
                bases[i] = dict(row, files=good)
            todo.append(i)
        skipped = len(rows)
        write_manifest(out_dir, rows)
        made = failed = 0
        if todo:
            tasks = [SequenceTask(spec, i, str(out_dir.resolve()), layouts, bases.get(i)) for i in todo]
            with dask_client(workers, scheduler, client=client) as c:
                last = time.monotonic()
                for k, row, err in run_tasks(c, task_fn, tasks, retries=retries, progress=progress,
                                             desc=f"dataset {spec.name}", unit="seq"):
                    i = todo[k]
                    if err is not None:
                        seq = spec.sequence(i)
                        row = {"index": i, "name": seq.name, "seed": seq.seed, "status": "failed",
                               "error": f"{type(err).__name__}: {err}", "n_events": None, "n_signal": None,
                               "n_noise": None, "duration_s": None, "files": {}, "bytes": 0, "params": seq.params}
                    rows[i] = row
                    made += row["status"] == "ok"
                    if time.monotonic() - last > 1.0:
                        write_manifest(out_dir, rows)
                        last = time.monotonic()
        write_manifest(out_dir, rows)
        failed = sum(r["status"] != "ok" for r in rows.values())
        write_card(spec, out_dir, rows, layouts)
        return DatasetRun(out_dir, rows, made, skipped, failed)
    finally:
        lock.close()


def _versions() -> dict[str, str]:
    import dask
    import distributed
    import h5py
    import numba
    import numpy as np

    from evedge import __version__

    return {"evedge": __version__, "python": platform.python_version(), "numpy": np.__version__,
            "numba": numba.__version__, "h5py": h5py.__version__, "dask": dask.__version__,
            "distributed": distributed.__version__}


def _fmt(v) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def write_card(spec: DatasetSpec, out_dir: Path, rows: dict, layouts) -> Path:
    """Write the dataset card ``out_dir/README.md`` (spec, versions, counts, totals, parameters)."""
    ok = [r for r in rows.values() if r["status"] == "ok"]
    failed = sorted((r for r in rows.values() if r["status"] != "ok"), key=lambda r: r["index"])
    lines = [f"# Dataset `{spec.name}`", ""]
    if spec.description:
        lines += [spec.description, ""]
    lines += [
        f"Made by `evedge dataset` from the spec below (seed {spec.seed}); sequence *i* depends only on "
        f"(spec, *i*), so the same spec remakes the same bytes. Schema: `sim/DATASETS.md` in evedge.", "",
        "## Counts and totals", "",
        "| | |", "|---|---|",
        f"| sequences in spec | {spec.count} |",
        f"| ok | {len(ok)} |",
        f"| failed | {len(failed)} |",
        f"| not made yet | {spec.count - len(rows)} |",
        f"| events | {sum(r['n_events'] for r in ok)} ({sum(r['n_signal'] for r in ok)} signal, "
        f"{sum(r['n_noise'] for r in ok)} noise) |",
        f"| simulated time | {sum(r['duration_s'] for r in ok):.6g} s |",
        f"| bytes on disk | {sum(r['bytes'] for r in ok)} |",
        f"| layouts | {', '.join(layouts)} |", "",
        "## Parameters", "",
        "| parameter | spec | drawn |", "|---|---|---|",
    ]
    for name, p in PARAMETERS.items():
        # .get: a row kept from a run of an older evedge may lack a newer parameter
        vals = [r["params"].get(name) for r in rows.values() if r["params"].get(name) is not None]
        flat = [x for v in vals for x in (v if isinstance(v, list) else [v])]
        nums = [x for x in flat if isinstance(x, (int, float))]
        if nums:
            drawn = _fmt(nums[0]) if min(nums) == max(nums) else f"{_fmt(min(nums))} to {_fmt(max(nums))}"
        else:
            drawn = ", ".join(sorted(set(map(str, flat)))) or "(not used by these sequences' families)"
        lines.append(f"| `{name}` | {spec.parameters[name].describe()} | {drawn} |")
    lines += ["", "## Files", "",
              "- `manifest.jsonl`: one JSON row per sequence (index, name, seed, status, error, n_events, "
              "duration_s, files with their sha256, bytes, params; wall_s, cpu_s, worker of the run)",
              "- `sequences/seq_*.h5`: evedge HDF5 (`evedge.io.read_hdf5`): events, truth, frames, edge maps"
              if "evedge" in layouts else "",
              "- `dsec/seq_*/events/left/events.h5`: DSEC layout (`events/{x,y,t,p}`, `ms_to_idx`, `t_offset`)"
              if "dsec" in layouts else "", ""]
    if failed:
        lines += ["## Failed sequences", ""] + [f"- {r['name']}: {r['error']}" for r in failed] + [""]
    lines += ["## Versions", ""] + [f"- {k} {v}" for k, v in _versions().items()] + [""]
    if spec.text:
        lines += ["## Spec", "", f"`{spec.source}`:", "", "```toml", spec.text.rstrip("\n"), "```", ""]
    else:
        lines += ["## Spec", "", "```json", json.dumps(spec.raw, indent=1, sort_keys=True), "```", ""]
    path = out_dir / "README.md"
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(x for x in lines if x is not None) + "\n", encoding="utf-8")
    return path
