"""A fuzz harness for the public readers: malformed inputs in limited child processes.

:func:`run` builds seeded cases per target (:mod:`.corpus`: mutations of real
and generated files, crafted HDF5, ``.mat``, AEDAT 4, PNG and scene
structures), runs them in worker processes under an address-space and a time
limit (:mod:`.runner`) and tallies the outcomes. The test suite runs a few
hundred cases per target (``tests/fuzz``); ``benchmarks/fuzz_campaign.py``
runs the long campaign and prints the counts.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from .corpus import REALDATA, Seeds, cases
from .runner import FAILURES, OUTCOMES, Limits, Result, Tally, run_cases
from .targets import TARGETS


def run(targets=None, n: int = 200, seed: int = 0, limits: Limits = Limits(), progress=None,
        realdata: Path | None = REALDATA) -> Tally:
    """Run ``n`` seeded cases for each target and tally them.

    Parameters
    ----------
    targets : list of str, optional
        Keys of :data:`TARGETS` (default: all).
    n : int
        Cases per target.
    seed : int
        Case ``i`` of a target depends only on ``(seed, target, i)``.
    limits : Limits
        Address space and time per case.
    progress : callable, optional
        Called with each :class:`Result`.
    realdata : Path, optional
        Folder of real recordings used as seeds when present.

    Returns
    -------
    Tally

    Examples
    --------
    >>> tally = run(["ecd_text"], n=5)          # doctest: +SKIP
    >>> tally.total("traceback")                # doctest: +SKIP
    0
    """
    targets = list(TARGETS) if targets is None else list(targets)
    unknown = sorted(set(targets) - set(TARGETS))
    if unknown:
        raise ValueError(f"run: unknown targets {unknown}; known: {sorted(TARGETS)}")
    with tempfile.TemporaryDirectory(prefix="evedge-fuzz-") as tmp:
        seeds = Seeds(Path(tmp) / "seeds", realdata)

        def all_cases():
            for target in targets:
                yield from cases(target, n, seed, Path(tmp) / "cases", seeds)

        return run_cases(all_cases(), limits, progress)


__all__ = ["FAILURES", "OUTCOMES", "TARGETS", "Limits", "Result", "Tally", "run"]
