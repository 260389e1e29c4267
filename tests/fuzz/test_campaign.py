"""A bounded, seeded fuzz run of every public reader: no traceback, crash, hang or unbounded allocation.

80 malformed inputs per target, every target of ``TARGETS`` (mutations of the
real recordings beside the repository when present and of generated files in
every registered format, crafted HDF5/.mat/AEDAT4/PNG/JPEG/video structures,
mutated scenes, dataset specs, meshes, detection files, frames folders and
videos with their timestamps), each in a worker under a 2 GiB address-space and
a 20 s time limit. Every failure must be the documented error naming the file;
a corrupted evedge HDF5 file must never read as a different recording. The
long campaign is ``benchmarks/fuzz_campaign.py``.
"""

from __future__ import annotations

import pytest

from evedge._fuzz import FAILURES, TARGETS, Limits, run

CASES_PER_TARGET = 80


@pytest.fixture(scope="module")
def tally():
    return run(list(TARGETS), CASES_PER_TARGET, seed=20261201, limits=Limits(2 * 2**30, 20.0))


@pytest.mark.parametrize("target", sorted(TARGETS))
def test_every_malformed_input_is_a_documented_error(tally, target):
    counts = tally.counts[target]
    assert sum(counts.values()) == CASES_PER_TARGET
    failures = [f"{r.outcome} {r.case_id} [{r.mutation}] {r.detail}" for r in tally.failures if r.target == target]
    assert not failures, "\n".join(failures[:20])
    assert not any(counts[o] for o in FAILURES)
    # the inputs are not all trivially rejected: some still read, most are refused (videos have no checksums:
    # FFmpeg decodes many damaged ones, so a third of them)
    assert counts["error"] > CASES_PER_TARGET // (3 if target == "video" else 2)
