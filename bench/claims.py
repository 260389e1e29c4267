"""The paper's claims as declarative rules over the long results table.

Each :class:`Claim` names an experiment, the sections it looks at, a subject
(the proposed method, as a compared method's base key), what it is compared
against and one or more :class:`Test` s (a metric and a direction). It is
evaluated per group of rows (dataset and reference, and, for the CDM claims,
per display policy: the lifetime methods under that policy and the
accumulation baselines, which have none). A claim *holds* in a group when its
tests pass (all of them, or any with ``combine="any"``), is *not checked* when
the subject or a named competitor has no number there, and the paper's claim
holds when it holds in every group it was checked in.

Only the paper's methods are ranked (plug-ins given with ``--method`` and the
diagnostic variants never enter). :mod:`evedge.bench.verdicts` holds the
detailed checks with their explanations; the tests check that both agree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .methods import COMPARED, DISPLAYS
from .results import ResultsTable

__all__ = ["CLAIMS", "Claim", "Test", "evaluate"]

BASELINES = ("mueggler", "acc_1ms", "acc_30ms")


@dataclass(frozen=True)
class Test:
    """``subject`` vs each competitor on ``metric``: ``higher``, ``lower`` (per section) or ``smaller_gap``
    (|value in the last section - value in the first|). ``optional``: skipped where it has no numbers."""

    metric: str
    compare: str
    optional: bool = False


@dataclass(frozen=True)
class Claim:
    """One claim of the paper, checked per group of the results table."""

    name: str
    text: str
    experiment: str
    tests: tuple[Test, ...]
    sections: tuple[str, ...] | None = None      # None: the regions present (not "all", not "*_core")
    subject: str = "proposed"
    against: tuple[str, ...] | None = BASELINES   # None: every other paper method in the group
    combine: str = "all"
    per_display: bool = False
    aggregate: str = "section"                    # "mean_noisy": mean over the sections with noise > 0
    dataset: str | None = None                    # only this dataset's rows (None: every dataset)


CLAIMS = (
    Claim("cdm_beats_baselines", "Proposed beats Mueggler, 1 ms and 30 ms (median CDM) in both the slow and the "
          "fast section", "similarity", (Test("cdm_median", "higher"),), ("slow", "fast"), per_display=True),
    Claim("cdm_beats_count", "Proposed beats fixed-count accumulation (median CDM) in both sections", "similarity",
          (Test("cdm_median", "higher"),), ("slow", "fast"), against=("acc_count",), per_display=True),
    Claim("cdm_consistent", "Proposed CDM is more consistent across speeds than Mueggler, 1 ms and 30 ms",
          "similarity", (Test("cdm_median", "smaller_gap"),), ("slow", "fast"), per_display=True),
    Claim("intra_global", "Under global noise, intra-pixel-area events (delta 0.25) help the F-measure of RANSAC's "
          "inlier decision", "ransac", (Test("f_measure", "higher"),), subject="intra_delta_0.25",
          against=("no_intra",), aggregate="mean_noisy", dataset="ransac_global"),
    Claim("intra_scattered", "Under scattered noise, intra-pixel-area events (delta 0.25) hurt (higher lifetime "
          "error or lower F-measure)", "ransac",
          (Test("lifetime_rel_error_mean", "higher"), Test("f_measure", "lower")), subject="intra_delta_0.25",
          against=("no_intra",), aggregate="mean_noisy", combine="any", dataset="ransac_scattered"),
    Claim("lifetime_sharper", "Proposed lifetimes are sharper than Mueggler's (smaller spread of log lifetime in "
          "each speed region; with truth, lower error too)", "lifetime",
          (Test("mad_log10", "lower"), Test("median_rel_error", "lower", optional=True)), None,
          against=("mueggler",)),
    Claim("real_cdm", "Proposed has the highest median CDM on the real frames", "real",
          (Test("cdm_median", "higher"),), ("all",), against=None, per_display=True),
)


def _base(variant: str) -> tuple[str, bool]:
    """(base key, ranked) of a row's variant: ranked = one of the paper's, non-diagnostic methods."""
    c = COMPARED.get(variant)
    if c is None:  # rows of the RANSAC study: its variants are no compared methods
        return variant, True
    return c.base, c.builtin and not c.diagnostic


def _values(rows, metric, aggregate, sections):
    """base -> section -> value (``mean_noisy``: one pseudo-section ``noisy``)."""
    out: dict[str, dict[str, float]] = {}
    for r in rows:
        if r["metric"] != metric:
            continue
        base, ranked = _base(r["variant"])
        if not ranked:
            continue
        out.setdefault(base, {})[r["section"]] = r["value"]
    if aggregate == "mean_noisy":
        agg = {}
        for base, per in out.items():
            v = [x for s, x in per.items() if s.startswith("noise_") and float(s[6:]) > 0 and math.isfinite(x)]
            agg[base] = {"noisy": sum(v) / len(v) if v else math.nan}
        return agg, ("noisy",)
    if sections is None:
        names = [s for s in dict.fromkeys(s for per in out.values() for s in per)
                 if s != "all" and not s.endswith("_core")]
        sections = tuple(names)
    return out, sections


def _test(test: Test, claim: Claim, vals: dict, sections) -> tuple[bool | None, list[str]]:
    subj = vals.get(claim.subject)
    against = claim.against if claim.against is not None else tuple(b for b in vals if b != claim.subject)
    if subj is None or any(s not in subj or not math.isfinite(subj[s]) for s in sections):
        return None, [f"{claim.subject} has no {test.metric}"]
    present = [b for b in against if b in vals]
    if claim.against is None:  # "every other method": only those with a finite number
        present = [b for b in present if all(math.isfinite(vals[b].get(s, math.nan)) for s in sections)]
        if not present:
            return None, ["nothing to compare"]
    missing = [b for b in against if b not in vals]
    parts, ok = [], True
    for b in present:
        other = vals[b]
        if test.compare == "smaller_gap":
            g0 = abs(subj[sections[-1]] - subj[sections[0]])
            g1 = abs(other.get(sections[-1], math.nan) - other.get(sections[0], math.nan))
            parts.append(f"gap {claim.subject} {g0:.3g} vs {b} {g1:.3g}")
            ok &= g0 < g1
            continue
        for s in sections:
            a, q = subj[s], other.get(s, math.nan)
            parts.append(f"{s}: {claim.subject} {a:.3g} vs {b} {q:.3g}")
            ok &= (a > q) if test.compare == "higher" else (a < q)
    if not ok:
        return False, parts
    return (None if missing else True), parts + ([f"not run: {', '.join(missing)}"] if missing else [])


def _groups(table: ResultsTable, claim: Claim):
    rows = table.query(experiment=claim.experiment, **({"dataset": claim.dataset} if claim.dataset else {}))
    # only the rows of the claim's metrics (and the frame counts): other numbers of the experiment, e.g.
    # its diagnostics, form no group of their own
    metrics = {t.metric for t in claim.tests} | {"cdm_n"}
    rows = [r for r in rows if r["metric"] in metrics]
    keys = list(dict.fromkeys((r["dataset"], r["reference"]) for r in rows))
    for dataset, ref in keys:
        sub = [r for r in rows if r["dataset"] == dataset and r["reference"] == ref]
        if not claim.per_display:
            yield (dataset, ref, ""), sub
            continue
        for d in DISPLAYS:
            view = [r for r in sub if r["display"] in (d, "")]
            if any(r["display"] == d for r in view):
                yield (dataset, ref, d), view


def evaluate(table: ResultsTable, claims=CLAIMS) -> list[dict]:
    """Every claim, per group and overall, from the table.

    Returns
    -------
    list of dict
        One per claim: ``name``, ``claim``, ``status`` (holds / fails / not
        checked), ``n_holds``, ``n_fails``, ``n_checks`` and ``groups``: per
        group (dataset, reference, display) its ``status`` and ``numbers``.
    """
    out = []
    for claim in claims:
        groups = []
        for (dataset, ref, display), rows in _groups(table, claim):
            results, numbers = [], []
            for test in claim.tests:
                vals, sections = _values(rows, test.metric, claim.aggregate, claim.sections)
                if test.optional and (not sections or not all(
                        math.isfinite(vals.get(b, {}).get(s, math.nan))
                        for b in (claim.subject, *(claim.against or ())) for s in sections)):
                    continue  # an optional test without numbers (e.g. no truth) does not count
                if not sections:
                    results.append(None)
                    numbers.append(f"{test.metric}: no sections (speed regions) to compare in")
                    continue
                if claim.sections is not None and claim.aggregate == "section":
                    n_rows = {r["section"]: r["value"] for r in rows if r["metric"] == "cdm_n"
                              and _base(r["variant"])[0] == claim.subject}
                    if n_rows and any(n_rows.get(s, 0) <= 0 for s in sections):
                        results.append(None)
                        numbers.append("the recording lacks a section with frames")
                        continue
                res, parts = _test(test, claim, vals, sections)
                results.append(res)
                numbers.append(f"{test.metric}: " + "; ".join(parts))
            if not results:
                continue
            if claim.combine == "any":
                status = True if any(r is True for r in results) else (
                    False if all(r is False for r in results) else None)
            else:
                status = False if any(r is False for r in results) else (
                    None if any(r is None for r in results) else True)
            groups.append({"dataset": dataset, "reference": ref, "display": display,
                           "status": {True: "holds", False: "fails", None: "not checked"}[status],
                           "numbers": " | ".join(numbers)})
        n_h = sum(g["status"] == "holds" for g in groups)
        n_f = sum(g["status"] == "fails" for g in groups)
        out.append({"name": claim.name, "claim": claim.text, "n_holds": n_h, "n_fails": n_f, "n_checks": n_h + n_f,
                    "status": "fails" if n_f else ("holds" if n_h else "not checked"), "groups": groups})
    return out
