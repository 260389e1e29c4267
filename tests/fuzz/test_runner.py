"""The harness classifies every way a reader can fail, in limited child processes."""

from __future__ import annotations

from pathlib import Path

import pytest

from evedge._fuzz import Limits
from evedge._fuzz.corpus import Case
from evedge._fuzz.runner import run_cases


def _case(tmp_path: Path, i: int, word: str) -> Case:
    def build(d: Path) -> Path:
        (d / "in.txt").write_text(word)
        return d / "in.txt"

    return Case(f"selftest/{i}", "selftest", word, build, tmp_path)


def test_each_outcome_is_recognised_and_a_dead_worker_is_replaced(tmp_path):
    words = ["ok", "error", "unnamed", "keyerror", "panic", "alloc", "abort", "ok", "hang", "ok"]
    tally = run_cases([_case(tmp_path, i, w) for i, w in enumerate(words)], Limits(2**30, 2.0))
    got = {r.mutation: r.outcome for r in [*tally.failures]}
    counts = tally.counts["selftest"]
    assert counts["ok"] == 3 and counts["error"] == 1  # the workers after the abort and the hang still answer
    assert got == {"unnamed": "unnamed", "keyerror": "traceback", "panic": "traceback", "alloc": "memory",
                   "abort": "crash", "hang": "timeout"}
    crash = next(r for r in tally.failures if r.outcome == "crash")
    assert "SIGABRT" in crash.detail
    assert not any(tmp_path.iterdir())  # every input removed after its case


def test_limits_are_checked():
    with pytest.raises(ValueError, match="memory_bytes"):
        Limits(1000, 1.0)
    with pytest.raises(ValueError, match="time_s"):
        Limits(2**30, 0)


def test_the_frames_check_sees_a_different_frame_and_truth_out_of_domain(tmp_path):
    """The frames/video targets' check can fail: a damaged PNG decoded to other pixels, flow that is not NaN."""
    import dataclasses

    from evedge._fuzz.corpus import Seeds
    from evedge._fuzz.targets import check_frames_run, frames_folder

    seeds = Seeds(tmp_path / "seeds", realdata=None)
    files = seeds.frames_folders()[0]
    for rel, content in files.items():
        (tmp_path / "f" / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / "f" / rel).write_bytes(content)
    run = frames_folder(str(tmp_path / "f" / "images"))
    assert run.frames_digest == seeds.frames_digest(0)
    assert check_frames_run(run, {"expect_digest": seeds.frames_digest(0)}) is None
    assert check_frames_run(run, {"expect_digest": seeds.frames_digest(3)}) == \
        "a damaged image was read as a different frame"
    truth = run.recording.truth.copy()
    truth["vx_px_s"][0] = 1.0
    bad = dataclasses.replace(run, recording=dataclasses.replace(run.recording, truth=truth))
    assert check_frames_run(bad, {}) == "truth vx_px_s not NaN"
