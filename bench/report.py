"""One self-contained HTML page from the results: figures inlined as base64 PNG.

The page is the Jinja2 template ``bench/templates/report.html.j2``; the helpers here only format
tables of numbers computed elsewhere (results, verdicts).

The page carries the verdicts on the paper's claims (computed in
:mod:`evedge.bench.verdicts`), tables of the headline numbers, every
parameter, the versions of the software and the date.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

import numpy as np

from ._files import write_text_atomic
from .methods import label as method_label

def _e(x) -> str:
    return html.escape(str(x))


def _num(x, nd=2) -> str:
    if x is None:
        return "n/a"
    try:
        v = float(x)
    except (TypeError, ValueError):
        return _e(x)
    return "n/a" if not np.isfinite(v) else f"{v:.{nd}f}"


def _pct(x) -> str:
    return _num(None if x is None else 100 * float(x), 1)


def _img(path) -> str:
    p = Path(path)
    if not p.exists():
        return f"<p class='small'>(figure missing: {_e(p.name)})</p>"
    data = base64.b64encode(p.read_bytes()).decode("ascii")
    return f"<img alt='{_e(p.name)}' src='data:image/png;base64,{data}'>"


def _table(header, rows, left_cols=1) -> str:
    th = "".join(f"<th class='{'l' if i < left_cols else ''}'>{_e(h)}</th>" for i, h in enumerate(header))
    body = []
    for row in rows:
        tds = "".join(f"<td class='{'l' if i < left_cols else ''}'>{c}</td>" for i, c in enumerate(row))
        body.append(f"<tr>{tds}</tr>")
    return f"<table><tr>{th}</tr>{''.join(body)}</table>"


def _verdict_section(verdicts: list[dict], counts: dict) -> str:
    rows_html = [f"<tr class='{'holds' if v['status'] == 'holds' else 'fails' if v['status'] == 'fails' else 'nc'}'>"
                 f"<td class='l'>{_e(v['claim'])}</td><td class='l'><b>{_e(v['status'].upper())}</b></td>"
                 f"<td class='l'>{_e(v['evidence'])}</td></tr>" for v in verdicts]
    head = (f"<p>{counts.get('holds', 0)} claims hold, {counts.get('fails', 0)} fail, "
            f"{counts.get('not_checked', 0)} not checked in this run. "
            "Each verdict is computed from the numbers below (see <code>evedge.bench.verdicts</code> "
            "for the exact rules).</p>")
    return head + ("<table><tr><th class='l'>claim</th><th class='l'>verdict</th><th class='l'>evidence</th></tr>"
                   + "".join(rows_html) + "</table>")


def _policy_effect_text(effect: dict | None) -> str:
    """The display policy's and the estimator's effect on the median CDM (``results["policy_effect"]``,
    computed by :func:`evedge.bench.verdicts.policy_effect` from the table)."""
    if not effect:
        return ""
    e = effect
    return (f" (in this run, switching the policy moves a lifetime method's median CDM by up to "
            f"{e['policy_max']:.1f} points, median {e['policy_median']:.1f}; switching the estimator, proposed vs "
            f"Mueggler under one policy, by up to {e['estimator_max']:.1f}, median {e['estimator_median']:.1f})")


def _display_headline(results: dict) -> str:
    """The display policy in one paragraph, with the CDM outcome under each policy (``results["display"]``)."""
    summ = (results.get("display") or {}).get("summary")
    if not summ or not any(p["n"] for p in summ["policies"].values()):
        return ""
    rows = []
    for name, p in summ["policies"].items():
        rows.append([_e(name + (" (primary)" if name == summ["primary"] else "")), _e(p["label"]),
                     _e(p["holds"]), _e(p["fails"]), _e(p["not_checked"]),
                     _e("; ".join(p["failed_claims"]) or "none")])
    explain = ("<p class='small'>A lifetime method's edge map depends on its display policy"
               + _e(_policy_effect_text(results.get("policy_effect")))
               + "; both lifetime methods are therefore always shown "
               "under the same policy, and the CDM claims are checked under each. <i>Predecessor display</i>: "
               "each event keeps its pixel alive for its lifetime and clears the pixel behind it in its motion "
               "direction (Mueggler et al.'s MATLAB display, inherited by the authors' code). <i>Lifetime-only "
               "display</i>: a pixel is edge while its newest event is alive (t_e &le; T &lt; t_e + "
               "&tau;_e), nothing cleared. Accumulation baselines do not depend on it. The qualitative panel "
               "and the real-frames figure use the primary policy; the tables list both (keys ending in "
               "<code>_noclear</code>: lifetime-only).</p>")
    return (f"<p><b>{_e(summ['text'])}</b></p>" + explain
            + _table(["display policy", "meaning", "CDM claims hold", "fail", "not checked", "failed claims"],
                     rows, left_cols=2))


def _fmeasure_section(fm: dict) -> str:
    parts = []
    for kind, per in fm.items():
        any_res = next(iter(per.values()))
        levels = any_res["noise_px"]
        header = ["method"] + [f"F @ {lv:g}" for lv in levels] + [f"err @ {lv:g}" for lv in levels]
        rows = []
        for label, res in per.items():
            rows.append([_e(label)] + [_num(v, 3) for v in res["f_measure"]]
                        + [_num(v, 3) for v in res["lifetime_rel_error_mean"]])
        parts.append(f"<h3>{_e(kind)} noise</h3>" + _table(header, rows))
    return "".join(parts)


def _lifetime_figures(paths: list) -> str:
    """Per dataset: the histogram (fig. 5) and the accumulated lifetime images (fig. 4) side by side,
    then the per-region histograms; other figures after."""
    paths = [Path(p) for p in paths]
    by_ds: dict[str, dict[str, Path]] = {}
    rest = []
    for p in paths:
        for kind in ("hist", "image", "regions"):
            prefix = f"lifetime_{kind}_"
            if p.stem.startswith(prefix):
                by_ds.setdefault(p.stem[len(prefix):], {})[kind] = p
                break
        else:
            rest.append(p)
    parts = []
    for ds, figs in by_ds.items():
        pair = [figs[k] for k in ("hist", "image") if k in figs]
        parts.append(f"<h3>{_e(ds)}</h3><div class='row'>"
                     + "".join(f"<div>{_img(p)}</div>" for p in pair) + "</div>")
        if "regions" in figs:
            parts.append(_img(figs["regions"]))
    return "".join(parts) + "".join(_img(p) for p in rest)


def _lifetime_section(lt: dict, datasets: dict) -> str:
    rows = []
    for ds, per in lt.items():
        for m, res in per.items():
            peaks = res.get("peaks") or []
            ptxt = "; ".join(f"{p['mode'] / 1e3:.2f} ms (median {p['median'] / 1e3:.2f}, MAD {p['mad'] / 1e3:.2f} ms, "
                             f"FWHM {p['fwhm_log10']:.3f} dec, {100 * p['fraction']:.0f}%)" for p in peaks)
            stxt = "; ".join(f"{p['mode'] / 1e3:.2f} ms {p['kind']} (FWHM-eq {p['fwhm_log10']:.3f} dec, "
                             f"{100 * p['fraction']:.0f}%)" for p in res.get("shoulder_peaks") or [])
            share = res.get("share_estimated")
            rows.append([_e(ds), _e(method_label(m)), _num(res.get("median_lifetime_us", np.nan) / 1e3
                                                                  if res.get("median_lifetime_us") is not None
                                                                  else None, 2),
                         _num(None if share is None else 100 * share, 1),
                         _num(res.get("median_rel_error"), 3), _e(res.get("n_valid", res.get("n", ""))), _e(ptxt),
                         _e(stxt)])
    info_items = []
    for ds, d in datasets.items():
        d = dict(d)
        reg = d.pop("regions", None)
        txt = f"{_e(ds)}: {_e(d)}"
        if reg:
            spans = ", ".join(f"{k}: rows {v[0]}-{v[-1]} ({len(v)})" if v else f"{k}: none"
                              for k, v in reg["rows"].items())
            txt += f"<br>speed regions ({_e(reg.get('method', ''))}): {_e(spans)}"
            if reg.get("truth_lifetime_us"):
                txt += "; true lifetimes " + _e(", ".join(f"{k} {v / 1e3:.2f} ms"
                                                          for k, v in reg["truth_lifetime_us"].items()))
            if reg.get("data_driven_row_agreement") is not None:
                txt += (f"; the estimator-free split (used on real data) labels "
                        f"{_num(100 * reg['data_driven_row_agreement'], 1)}% of the rows as the truth does")
        info_items.append(f"<li>{txt}</li>")
    out = (f"<ul class='small'>{''.join(info_items)}</ul>"
           + _table(["dataset", "method", "median lifetime (ms)", "% of input events estimated",
                     "median rel. error", "n valid", "histogram peaks (log10 lifetime)",
                     "shoulder-aware components"], rows, left_cols=2))
    rrows = []
    for ds, per in lt.items():
        items = []
        for m, res in per.items():
            items += [(reg, method_label(m), q) for reg, q in (res.get("regions") or {}).items()]
            diag = (res.get("on_buffered_events") or {}).get("regions") or {}
            items += [(reg, f"{method_label(m)} on the event buffer's output (diagnostic)", q)
                      for reg, q in diag.items()]
        for reg, label, q in items:
            rrows.append([_e(ds), _e(reg), _e(label), _e(q["n_events"]),
                          _num(100 * q["share_estimated"], 1), _num(q["mode"] / 1e3 if q["n"] else None, 2),
                          _num(q["median"] / 1e3 if q["n"] else None, 2), _num(q["mad_log10"], 4),
                          _num(q["iqr_over_median"], 3), _num(100 * q["frac_within"], 1),
                          _pct(q.get("frac_of_events_within")), _num(q.get("median_rel_error"), 3),
                          _pct(q.get("frac_within_truth")), _pct(q.get("frac_of_signal_within_truth"))])
    if rrows:
        out += ("<p class='small'>Per speed region (the rows of one band; the verdict's measure is the MAD of "
                "log10 lifetime):</p>"
                + _table(["dataset", "region", "method", "events", "% estimated", "mode (ms)", "median (ms)",
                          "MAD log10 (dec)", "IQR / median", "% within 20% of mode",
                          "same, % of all events", "median rel. error", "% within 20% of truth",
                          "same, % of all signal events"], rrows, left_cols=3))
    return out


def _cdm_section(cdm: dict) -> str:
    parts = []
    for scene, per_truth in cdm.items():
        for truth, per_method in per_truth.items():
            sections = [s for s in next(iter(per_method.values())) if s != "all"]
            header = ["method"] + [f"{s}: median [q1, q3] (n)" for s in sections] + ["all: median"]
            rows = []
            for m, res in per_method.items():
                cells = [f"{_num(res[s]['median'], 1)} [{_num(res[s]['q1'], 1)}, {_num(res[s]['q3'], 1)}] "
                         f"({res[s]['n']})" for s in sections]
                rows.append([_e(method_label(m))] + cells + [_num(res["all"]["median"], 1)])
            parts.append(f"<h3>{_e(scene)} vs {_e(truth)}</h3>" + _table(header, rows))
    return "".join(parts)


def _diagnostics_section(diag: dict) -> str:
    parts = []
    for scene, d in diag.items():
        for ref, per in (d.get("pixel_ratio") or {}).items():
            sections = [s for s in next(iter(per.values()))]
            rows = [[_e(method_label(m))] + [_num(v.get(s), 2) for s in sections] for m, v in per.items()]
            parts.append(f"<h3>{_e(scene)}: edge pixels per pixel of {_e(ref)} (mean per section)</h3>"
                         + _table(["method"] + sections, rows))
        lt = d.get("lifetime") or {}
        if lt:
            rows = []
            for m, per in lt.items():
                for s, v in per.items():
                    rows.append([_e(method_label(m)), _e(s), _e(v["n_signal"]), _num(100 * v["coverage"], 1),
                                 _num(v["median_rel_error"], 3), _num(100 * v["over_2x"], 1),
                                 _num(100 * v["under_2x"], 1)])
            parts.append(f"<h3>{_e(scene)}: lifetimes against the simulator's truth</h3>"
                         + _table(["method", "section", "signal events", "% estimated", "median rel. error",
                                   "% > 2x too long", "% < half"], rows, left_cols=2))
    return "".join(parts)


def _real_section(real: dict, frames: dict) -> str:
    parts = []
    for rec, per_method in real.items():
        t = frames.get(rec, {}).get("frame_t_us", [])
        refs = list(next(iter(per_method.values()))["cdm_per_frame"])
        for ref in refs:
            header = ["method"] + [f"t={float(x) / 1e3:.1f} ms" for x in t] + ["median"]
            rows = [[_e(method_label(m))] + [_num(v, 1) for v in res["cdm_per_frame"][ref]]
                    + [_num(res["median"][ref], 1)] for m, res in per_method.items()]
            parts.append(f"<h3>{_e(rec)} vs {_e(ref)}</h3>" + _table(header, rows))
    return "".join(parts)


def _dict_block(d) -> str:
    import json

    from ._files import to_jsonable

    return f"<pre>{_e(json.dumps(to_jsonable(d), indent=1))}</pre>"


def write_report(path, results: dict, *, figures: dict[str, list], notes: list[str], board: dict | None = None) -> Path:
    """Write the HTML report (rendered through ``bench/templates/report.html.j2``).

    Parameters
    ----------
    path : path
        Output ``report.html``.
    results : dict
        As written to ``results.json`` (keys ``verdicts``, ``fmeasure``, ``lifetime``,
        ``cdm``, ``real``, ``params``, ``run``).
    figures : dict
        Experiment -> list of PNG paths (inlined); relative ones are relative to
        the folder of ``path`` (as ``results.json`` stores them).
    notes : list of str
        Caveats and definitions shown at the end.
    board : dict, optional
        The leaderboard (:func:`evedge.bench.results.leaderboard` of the run's table); the report
        opens with it. Nothing is computed here: the claim lines are ``results["claims"]``, the
        verdict counts ``results["verdict_counts"]``, the policy headline ``results["display"]``.
    """
    from markupsafe import Markup

    from .report_render import environment

    board = board or {"columns": [], "rows": [], "winners": {}}
    base = Path(path).parent
    figures = {k: [base / p for p in v] for k, v in figures.items()}
    sections = []
    if results.get("fmeasure"):
        sections.append(("1. RANSAC inlier decision and lifetime error (paper fig. 7)",
                         "F-measure of RANSAC's final inliers against the true inliers among the points it is given; "
                         "mean relative lifetime error of successful fits; x-axis: timestamp noise std in units of "
                         "the true lifetime.", figures.get("ransac", []), Markup(_fmeasure_section(results["fmeasure"]))))
    if results.get("lifetime"):
        sections.append(("2. Lifetimes on stripes (paper figs. 4-5)", "", [],
                         Markup(_lifetime_figures(figures.get("lifetime", []))
                                + _lifetime_section(results["lifetime"], results.get("lifetime_datasets", {})))))
    if results.get("cdm"):
        body = _cdm_section(results["cdm"])
        if results.get("cdm_diagnostics"):
            body += ("<p class='small'>Diagnostics (explain the CDM; not used to rank methods):</p>"
                     + _diagnostics_section(results["cdm_diagnostics"]))
        sections.append(("3. Similarity over time, slow then fast (paper fig. 9)",
                         "Lifetime methods under both display policies: solid lines and plain boxes, predecessor "
                         "display (primary); dashed lines and hatched boxes ('no clear'), lifetime-only display.",
                         figures.get("similarity", []), Markup(body)))
    if figures.get("qualitative"):
        sections.append(("4. Qualitative panel (paper figs. 1, 8)",
                         "Both lifetime methods shown with the primary display policy (predecessor display: the "
                         "pixel behind each event cleared).", figures["qualitative"], Markup("")))
    if results.get("real"):
        sections.append(("5. Real frames (slider_depth): CDM against Canny",
                         "The figure shows the lifetime methods with the primary display policy (predecessor "
                         "display); the tables below list both policies.", figures.get("real", []),
                         Markup(_real_section(results["real"], results.get("real_frames", {})))))
    html_text = environment().get_template("report.html.j2").render(
        run=results.get("run", {}), board=board, claims=results.get("claims") or [],
        display_headline=Markup(_display_headline(results)),
        verdict_table=Markup(_verdict_section(results.get("verdicts", []), results.get("verdict_counts") or {})),
        skipped=results.get("skipped") or {}, errors=results.get("errors") or {}, sections=sections, notes=notes,
        params=Markup(_dict_block(results.get("params", {}))), timing=Markup(_dict_block(results.get("run", {}).get("timing_s", {}))))
    return write_text_atomic(path, html_text)
