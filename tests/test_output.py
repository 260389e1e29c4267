"""evedge._output and the temp-file helpers: whole outputs swapped in, links refused, stale temps removed."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from evedge import _output
from evedge._output import OutputExistsError, check_output, staged_folder
from evedge.io._atomic import remove_stale_temps, temp_prefix


def _write(folder, text):
    (folder / "a.txt").write_text(text)


@pytest.mark.parametrize("exchange", [True, False], ids=["renameat2", "two_renames"])
def test_a_folder_is_replaced_as_a_whole(tmp_path, monkeypatch, exchange):
    if not exchange:
        monkeypatch.setattr(_output, "_exchange", lambda a, b: False)
    out = tmp_path / "out"
    with staged_folder(out) as stage:
        _write(stage, "old")
    with staged_folder(out) as stage:
        assert (out / "a.txt").read_text() == "old"  # untouched while the new one is written
        _write(stage, "new")
    assert (out / "a.txt").read_text() == "new"
    with pytest.raises(RuntimeError):
        with staged_folder(out) as stage:
            _write(stage, "broken")
            raise RuntimeError("the run failed")
    assert (out / "a.txt").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no temp folder left


def test_links_and_foreign_content_are_refused(tmp_path):
    target = tmp_path / "elsewhere"
    target.mkdir()
    (tmp_path / "link").symlink_to(target)
    with pytest.raises(OutputExistsError, match="symbolic link"):
        check_output(tmp_path / "link", overwrite=True)
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("x")
    with pytest.raises(OutputExistsError, match="pass --overwrite"):
        check_output(out, overwrite=False)
    assert check_output(out, overwrite=True) is True
    with pytest.raises(OutputExistsError, match="mine.txt is not written by this command"):
        with staged_folder(out, allowed=("detection.h5",)):
            pass
    assert check_output(tmp_path / "new", overwrite=False) is False


def test_only_the_temps_of_dead_writers_are_removed(tmp_path):
    target = tmp_path / "rec.h5"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = tmp_path / f".rec.h5.{int(dead.stdout)}.abc.tmp"
    stale.write_text("half")
    live = tmp_path / f".rec.h5.{os.getppid()}.abc.tmp"  # a process that still runs
    live.write_text("being written")
    mine = tmp_path / f"{temp_prefix(target)}abc.tmp"
    mine.write_text("mine")
    remove_stale_temps(target)
    assert not stale.exists() and live.exists() and mine.exists()


def _bench_ransac(out, *extra):
    return subprocess.run([sys.executable, "-m", "evedge.cli", "bench", "ransac", "--quick", "--repetitions", "2",
                           "--no-progress", "-o", str(out), *extra], capture_output=True, text=True, timeout=300)


def test_bench_overwrite_never_replaces_a_folder_of_other_files(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("months of work")
    proc = _bench_ransac(out, "--overwrite")
    assert proc.returncode == 2, proc.stderr
    assert "is not an earlier evedge bench output" in proc.stderr and "Traceback" not in proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["thesis.tex"]
    assert (out / "thesis.tex").read_text() == "months of work"


def test_bench_overwrite_replaces_its_own_earlier_output(tmp_path):
    legacy = tmp_path / "legacy"  # written before the marker existed: report.html + results.json
    legacy.mkdir()
    (legacy / "report.html").write_text("<html></html>")
    (legacy / "results.json").write_text("{}")
    proc = _bench_ransac(legacy, "--overwrite")
    assert proc.returncode == 0, proc.stderr
    assert (legacy / ".evedge-bench").is_file() and not (legacy / "report.html").exists()
    again = _bench_ransac(legacy, "--overwrite")  # now it carries the marker
    assert again.returncode == 0, again.stderr
