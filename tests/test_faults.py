"""Faults: ``kill -9`` at random points and a full disk never leave an output a reader takes as complete.

Each command runs as a child process (``python -m evedge.cli ...``) and is
killed with SIGKILL after a seeded random delay inside its measured run time.
Afterwards the output must be the earlier good one or the new complete one,
never a mix, and a rerun must succeed. A full disk is a small tmpfs when this
machine lets the test mount one (root), else a file-size limit (``EFBIG``, the
same write failure for the code).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "stripes.toml"


def _cli(*args, preexec_fn=None):
    return subprocess.Popen([sys.executable, "-m", "evedge.cli", *map(str, args)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=preexec_fn, cwd=ROOT)


def _run(*args, preexec_fn=None) -> tuple[int, str, float]:
    start = time.monotonic()
    proc = _cli(*args, preexec_fn=preexec_fn)
    out, err = proc.communicate(timeout=120)
    return proc.returncode, out + err, time.monotonic() - start


def _kill_at(delay_s: float, *args) -> None:
    proc = _cli(*args)
    try:
        proc.wait(timeout=delay_s)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGKILL)
        proc.wait()


def _h5_digest(path: Path) -> str:
    from evedge._fuzz.targets import recording_digest
    from evedge.io import read_hdf5

    return recording_digest(read_hdf5(path))


def _detection_digest(out: Path) -> str:
    """What a reader of a detect output sees, after checking it is complete and consistent."""
    import h5py
    from PIL import Image

    with h5py.File(out / "detection.h5", "r") as f:
        times, frames = f["edges/t_us"][()], f["edges/images"][()]
    pngs = sorted((out / "edges").iterdir())
    assert [p.name for p in pngs] == [f"edges_{i:06d}_{int(t)}us.png" for i, t in enumerate(times)]
    from evedge.video import edge_png

    for png, frame in zip(pngs, frames):
        assert np.array_equal(np.asarray(Image.open(png)), edge_png(frame.astype(bool)))
    return hashlib.sha256(times.tobytes() + frames.tobytes()).hexdigest()


def _events_file(path: Path, n: int = 40_000) -> Path:
    from evedge._fuzz.corpus import small_recording
    from evedge.io import write_recording

    return write_recording(path, small_recording(n, 14, frames=False, truth=False))


@pytest.mark.parametrize("command", ["simulate", "detect"])
def test_kill_9_leaves_the_old_or_the_new_output_and_a_rerun_succeeds(tmp_path, command):
    rng = np.random.default_rng(14)
    if command == "simulate":
        out = tmp_path / "s.h5"
        args = lambda d: ("simulate", SCENE, "-o", out, "--duration", d, "--quiet", "--overwrite")  # noqa: E731
        digest, first, second = _h5_digest, "0.02", "0.1"
    else:
        src = _events_file(tmp_path / "src.h5")
        out = tmp_path / "det"
        args = lambda d: ("detect", src, "-o", out, "--fps", d, "--quiet", "--overwrite",  # noqa: E731
                          "--method", "count")
        digest, first, second = _detection_digest, "10", "1000"
    code, text, full_s = _run(*args(first))
    assert code == 0, text
    old = digest(out)
    for delay in rng.uniform(0.4, 1.2, 2) * full_s:  # inside the longer run: reading, computing, writing
        _kill_at(delay, *args(second))
        seen = digest(out)  # raises if the output is incomplete or inconsistent
        assert seen == old or _run(*args(first))[0] == 0 and digest(out) == old, \
            f"killed after {delay:.2f} s: neither the earlier output nor a complete new one"
    code, text, _ = _run(*args(second))
    assert code == 0 and digest(out) != old, text
    assert not [p.name for p in out.parent.iterdir() if p.name.endswith(".tmp")]  # killed runs' leftovers removed


def _folder_digest(out: Path) -> dict[str, str]:
    """Every file under ``out`` (relative path) and its sha256: a bench output as a reader sees it."""
    return {p.relative_to(out).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(out.rglob("*")) if p.is_file()}


def test_kill_9_during_bench_leaves_the_old_or_the_new_run_and_a_rerun_succeeds(tmp_path):
    out = tmp_path / "b"
    args = lambda o, seed: ("bench", "ransac", "-o", o, "--quick", "--repetitions", "2", "--seed", seed,  # noqa: E731
                            "--no-progress", "--overwrite")
    runs = {}
    # the two complete runs, each built from scratch (same seed = same bytes), side by side
    procs = {seed: _cli(*args(tmp_path / f"ref{seed}", seed)) for seed in (0, 1)}
    for seed, proc in procs.items():
        out_text, err_text = proc.communicate(timeout=120)
        assert proc.returncode == 0, out_text + err_text
        runs[seed] = _folder_digest(tmp_path / f"ref{seed}")
    # every file but the constant bench marker differs between the seeds, so a mix would show
    assert runs[0].keys() == runs[1].keys() and all(runs[0][k] != runs[1][k] for k in runs[0] if k != ".evedge-bench")
    code, text, full_s = _run(*args(out, 0))  # alone: the run time the kill delays are drawn within
    assert code == 0 and _folder_digest(out) == runs[0], text
    current = 0
    for delay in np.random.default_rng(14).uniform(0.3, 1.1, 3) * full_s:  # start-up, computing, writing, swap
        target = 1 - current
        _kill_at(delay, *args(out, target))
        seen = _folder_digest(out)
        assert seen in (runs[current], runs[target]), \
            f"killed after {delay:.2f} s: {out} is neither the earlier run nor a complete new one"
        current = current if seen == runs[current] else target
    code, text, _ = _run(*args(out, 1 - current))
    assert code == 0 and _folder_digest(out) == runs[1 - current], text
    figures = json.loads((out / "ransac_study.json").read_text())["figures"]
    assert figures and all(not Path(f).is_absolute() and (out / f).is_file() for f in figures)  # nothing points away
    assert not [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")]  # killed runs' leftovers removed


@pytest.fixture
def full_disk(tmp_path):
    """A folder on a 256 KiB tmpfs, or None and a file-size limit when mounting is not allowed."""
    mount = tmp_path / "small"
    mount.mkdir()
    ok = os.geteuid() == 0 and subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mount)],
                                              capture_output=True).returncode == 0
    yield (mount, None) if ok else (mount, 256 * 1024)
    if ok:
        subprocess.run(["umount", str(mount)], check=True)


def test_a_full_disk_is_an_error_line_and_keeps_the_earlier_output(tmp_path, full_disk):
    folder, fsize = full_disk

    def limit():
        if fsize:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # write() fails with EFBIG instead
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    src = _events_file(tmp_path / "src.h5")
    # a small earlier output fits; the big new one does not
    small = ("detect", src, "-o", folder / "det", "--times", "100000", "--quiet", "--method", "count",
             "--no-embed-events")
    code, text, _ = _run(*small, preexec_fn=limit)
    assert code == 0, text
    old = _detection_digest(folder / "det")
    code, text, _ = _run("detect", src, "-o", folder / "det", "--fps", "400", "--quiet", "--overwrite",
                         "--method", "count", "--no-embed-events", preexec_fn=limit)
    assert code == 1 and "Traceback" not in text and "cannot write the output" in text, text
    assert _detection_digest(folder / "det") == old
    assert sorted(p.name for p in folder.iterdir()) == ["det"]  # no temp folder left
    code, text, _ = _run("simulate", SCENE, "-o", folder / "s.h5", "--duration", "0.2", "--quiet", preexec_fn=limit)
    assert code == 1 and "Traceback" not in text and "Error:" in text, text
    assert sorted(p.name for p in folder.iterdir()) == ["det"]
    code, text, _ = _run("bench", "ransac", "-o", folder / "b", "--quick", "--repetitions", "2", "--no-progress",
                         preexec_fn=limit)
    assert code == 1 and "Traceback" not in text and "cannot write the output" in text, text


def test_kill_9_during_dataset_keeps_only_whole_sequences_and_a_rerun_completes(tmp_path):
    from evedge.io import read_hdf5

    out = tmp_path / "ds"
    args = ("dataset", "small", "-o", out, "--workers", "1", "--quiet")
    _kill_at(float(np.random.default_rng(14).uniform(3.0, 6.0)), *args)
    rows = [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()] \
        if (out / "manifest.jsonl").exists() else []
    for row in rows:
        if row["status"] == "ok":
            for rel, digest in row["files"].items():
                assert hashlib.sha256((out / rel).read_bytes()).hexdigest() == digest
    for h5 in out.rglob("*.h5") if out.exists() else ():
        read_hdf5(h5)  # every sequence file present is whole (checksums verified)
    code, text, _ = _run(*args)
    assert code == 0 and "6/6 sequences ok" in text, text
    assert not list(out.rglob("*.tmp"))


@pytest.fixture(scope="module")
def grade_inputs(tmp_path_factory):
    """A simulated dataset and its detection file (made once by the CLI)."""
    tmp = tmp_path_factory.mktemp("grade_inputs")
    code, text, _ = _run("simulate", SCENE, "-o", tmp / "s.h5", "--duration", "0.1", "--quiet")
    assert code == 0, text
    code, text, _ = _run("detect", tmp / "s.h5", "-o", tmp / "det", "--fps", "100", "--quiet")
    assert code == 0, text
    return tmp / "s.h5", tmp / "det" / "detection.h5"


def _grade_digest(out: Path) -> dict[str, str]:
    """Every file of a grade output and its sha256, its date of writing left out (the rest is reproducible)."""
    files = {}
    for p in sorted(out.rglob("*")):
        if p.is_file():
            data = re.sub(rb"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d UTC", b"DATE", p.read_bytes())
            files[p.relative_to(out).as_posix()] = hashlib.sha256(data).hexdigest()
    return files


def test_kill_9_during_grade_leaves_the_old_or_the_new_grade_and_a_rerun_succeeds(tmp_path, grade_inputs):
    data, det = grade_inputs
    out = tmp_path / "g"
    args = lambda method: ("grade", data, "-d", det, "-o", out, "--method", method, "--overwrite")  # noqa: E731
    runs = {}
    for method in ("a", "b"):  # two complete grades in OUT itself (the command line is in the report)
        code, text, full_s = _run(*args(method))
        assert code == 0, text
        runs[method] = _grade_digest(out)
    assert set(runs["a"]) == {".evedge-bench", "grade.csv", "grade.h5", "grade.json", "grade.png", "report.html"}
    assert all(runs["a"][k] != runs["b"][k] for k in runs["a"] if k != ".evedge-bench")  # a mix would show
    current = "b"
    for delay in np.random.default_rng(14).uniform(0.3, 1.1, 2) * full_s:
        target = "a" if current == "b" else "b"
        _kill_at(delay, *args(target))
        seen = _grade_digest(out)
        assert seen in (runs[current], runs[target]), \
            f"killed after {delay:.2f} s: {out} is neither the earlier grade nor a complete new one"
        current = current if seen == runs[current] else target
    target = "a" if current == "b" else "b"
    code, text, _ = _run(*args(target))
    assert code == 0 and "replacing the earlier output" in text and _grade_digest(out) == runs[target], text
    assert not [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")]  # killed runs' leftovers removed


def test_grade_replaces_only_with_overwrite_and_never_through_links(tmp_path, grade_inputs):
    from click.testing import CliRunner

    from evedge.bench.cli import grade

    data, det = grade_inputs

    def run(*args):
        res = CliRunner().invoke(grade, [str(data), "-d", str(det), *map(str, args)])
        assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
        return res.exit_code, res.output

    out = tmp_path / "g"
    code, text = run("-o", out)
    assert code == 0, text
    before = _grade_digest(out)
    code, text = run("-o", out, "--method", "x")
    assert code == 2 and "already exists; pass --overwrite to replace it" in text and _grade_digest(out) == before
    # a folder of other files is not a grade output: refused even with --overwrite
    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep me")
    code, text = run("-o", other, "--overwrite")
    assert code == 2 and "is not an earlier evedge bench output" in text
    assert [p.name for p in other.iterdir()] == ["notes.txt"]
    # links: an OUT that is a link, or a link inside OUT, is refused; nothing behind them is touched
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "grade.csv").write_text("not yours")
    (tmp_path / "link").symlink_to(victim, target_is_directory=True)
    code, text = run("-o", tmp_path / "link", "--overwrite")
    assert code != 0 and "symbolic link" in text, text
    (out / "report.html").unlink()
    (out / "report.html").symlink_to(victim / "grade.csv")
    code, text = run("-o", out, "--overwrite")
    assert code != 0 and "symbolic link" in text, text
    assert (victim / "grade.csv").read_text() == "not yours" and sorted(os.listdir(victim)) == ["grade.csv"]


def test_a_full_disk_during_grade_is_an_error_line_and_keeps_the_earlier_grade(tmp_path, full_disk, grade_inputs):
    data, det = grade_inputs
    folder, fsize = full_disk
    out = folder / "g"
    code, text, _ = _run("grade", data, "-d", det, "-o", out)
    assert code == 0, text
    before = _grade_digest(out)
    if fsize:  # a file-size limit below the report's size
        def limit():
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (16 * 1024, 16 * 1024))
    else:  # the tmpfs filled up to 16 KiB
        limit = None
        st = os.statvfs(folder)
        (folder / "filler").write_bytes(bytes(max(0, st.f_bavail * st.f_frsize - 16 * 1024)))
    code, text, _ = _run("grade", data, "-d", det, "-o", out, "--method", "x", "--overwrite", preexec_fn=limit)
    assert code == 1 and "Traceback" not in text and "cannot write the output" in text, text
    assert _grade_digest(out) == before
    assert not [p.name for p in folder.iterdir() if p.name.endswith(".tmp")]  # no temp folder left
