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

from concurrent.futures import ThreadPoolExecutor

import pytest

from evedge._fuzz import FAILURES, TARGETS, Limits, Tally, run

CASES_PER_TARGET = 80


@pytest.fixture(scope="module")
def tally():
    """The campaign, in two runs side by side (each its own worker process and folder; a case depends only
    on the seed, its target and its index, so the cases are those of one run over every target)."""
    targets = sorted(TARGETS)
    with ThreadPoolExecutor(2) as pool:  # the parent mostly waits for its worker: the two share the cores
        parts = list(pool.map(lambda group: run(group, CASES_PER_TARGET, seed=20261201,
                                                limits=Limits(2 * 2**30, 20.0)), (targets[::2], targets[1::2])))
    out = Tally()
    for part in parts:
        out.counts.update(part.counts)
        out.failures.extend(part.failures)
    assert sorted(out.counts) == sorted(TARGETS)
    return out


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
