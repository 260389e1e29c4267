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
