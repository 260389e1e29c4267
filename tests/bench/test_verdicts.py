"""Verdicts are computed from the numbers: both outcomes on synthetic results."""

import pytest

from evedge.bench.verdicts import (all_verdicts, cdm_verdicts, display_summary, intra_verdicts, lifetime_verdicts,
                                   real_verdicts)

from evedge.bench.results import ResultsTable, lifetime_rows, real_rows

PRIMARY_ONLY = ("predecessor",)


def _summ(median, n=5):
    return {"median": median, "q1": median - 1, "q3": median + 1, "mean": median, "n": n}


def _cdm(prop_slow, prop_fast, others):
    per = {"proposed": {"slow": _summ(prop_slow), "fast": _summ(prop_fast), "all": _summ(0)}}
    for m, (s, f) in others.items():
        per[m] = {"slow": _summ(s), "fast": _summ(f), "all": _summ(0)}
    return {"scene": {"exact": per}}


def test_cdm_claims_hold_and_fail():
    good = _cdm(80, 78, {"mueggler": (70, 50), "acc_1ms": (20, 40), "acc_30ms": (60, 30)})
    v = cdm_verdicts(good, displays=PRIMARY_ONLY)
    assert [x["status"] for x in v] == ["holds", "holds"]
    bad = _cdm(80, 60, {"mueggler": (70, 85), "acc_1ms": (20, 40), "acc_30ms": (60, 30)})
    v = cdm_verdicts(bad, displays=PRIMARY_ONLY)
    assert v[0]["status"] == "fails" and "mueggler in the fast section" in v[0]["evidence"]
    # gap proposed 20 vs mueggler 15 -> not the most consistent
    assert v[1]["status"] == "fails" and "mueggler" in v[1]["evidence"]
    assert cdm_verdicts({})[0]["status"] == "not checked"


def test_cdm_verdict_explains_a_loss_and_checks_the_count_baseline():
    bad = _cdm(80, 60, {"mueggler": (70, 85), "acc_1ms": (20, 40), "acc_30ms": (60, 30), "acc_count": (70, 70)})
    diag = {"scene": {"pixel_ratio": {"exact": {"proposed": {"fast": 1.8}, "mueggler": {"fast": 0.9}}},
                      "lifetime": {"proposed": {"fast": {"coverage": 0.9, "median_rel_error": 0.2,
                                                         "over_2x": 0.07, "under_2x": 0.01}}}}}
    v = cdm_verdicts(bad, diag, displays=PRIMARY_ONLY)
    assert "Why:" in v[0]["evidence"] and "1.80" in v[0]["evidence"] and "7.0% more than 2x" in v[0]["evidence"]
    count = [x for x in v if "fixed-count" in x["claim"]]
    assert count and count[0]["status"] == "fails"  # 60 < 70 in the fast section


def _fm(f_no, f_yes, e_no, e_yes):
    def res(use_intra, delta, f, e):
        return {"use_intra": use_intra, "delta_px": delta, "noise_px": [0.0, 0.5],
                "f_measure": [1.0, f], "lifetime_rel_error_mean": [0.0, e]}
    return {"no_intra": res(False, 0.0, f_no, e_no), "intra_delta_0.25": res(True, 0.25, f_yes, e_yes)}


def test_intra_claims():
    v = intra_verdicts({"global": _fm(0.5, 0.7, 0.2, 0.2), "scattered": _fm(0.9, 0.9, 0.02, 0.05)})
    assert [x["status"] for x in v] == ["holds", "holds"]
    v = intra_verdicts({"global": _fm(0.7, 0.5, 0.2, 0.2), "scattered": _fm(0.9, 0.95, 0.05, 0.02)})
    assert [x["status"] for x in v] == ["fails", "fails"]
    assert intra_verdicts({})[0]["status"] == "not checked"


def test_lifetime_and_real_claims():
    lt = {"d": {"proposed": {"peaks": [{"fwhm_log10": 0.1, "mode": 1000.0}], "median_rel_error": 0.05},
                "mueggler": {"peaks": [{"fwhm_log10": 0.2, "mode": 1100.0}], "median_rel_error": 0.1}}}
    assert lifetime_verdicts(lt)[0]["status"] == "holds"
    assert "lower error" in lifetime_verdicts(lt)[0]["claim"]
    no_truth = {"d": {m: {"peaks": v["peaks"]} for m, v in lt["d"].items()}}
    assert "lower error" not in lifetime_verdicts(no_truth)[0]["claim"]
    lt["d"]["proposed"]["median_rel_error"] = 0.5
    assert lifetime_verdicts(lt)[0]["status"] == "fails"
    real = {"r": {"proposed": {"median": {"c": 50.0}}, "acc_30ms": {"median": {"c": 60.0}}}}
    v = real_verdicts(real, displays=PRIMARY_ONLY)
    assert v[0]["status"] == "fails" and "acc_30ms" in v[0]["evidence"]
    table = ResultsTable()
    table.extend(lifetime_rows(lt), experiment="lifetime")
    table.extend(real_rows("r", real), experiment="real")
    assert len(all_verdicts(table)) >= 4


def test_consistency_verdict_flags_the_mueggler_time_origin_quirk():
    cdm = _cdm(80, 70, {"mueggler": (40, 85), "acc_1ms": (20, 40), "acc_30ms": (60, 30), "mueggler_t0": (86, 87)})
    v = cdm_verdicts(cdm, displays=PRIMARY_ONLY)
    consistent = [x for x in v if "consistent" in x["claim"]][0]
    assert consistent["status"] == "holds"
    assert "absolute-time quirk" in consistent["evidence"]


def test_intra_verdict_says_when_the_truth_definition_reverses_it():
    sens = {"truth_tol_0.1px": {"global": {"no_intra": [1.0, 0.6], "intra_delta_0.25": [1.0, 0.5]}}}
    v = intra_verdicts({"global": _fm(0.5, 0.7, 0.2, 0.2)}, sens)
    assert v[0]["status"] == "holds" and "NOT ROBUST" in v[0]["evidence"]
    sens = {"truth_tol_0.1px": {"global": {"no_intra": [1.0, 0.5], "intra_delta_0.25": [1.0, 0.6]}}}
    assert "NOT ROBUST" not in intra_verdicts({"global": _fm(0.5, 0.7, 0.2, 0.2)}, sens)[0]["evidence"]


def _reg(mad, frac, iqr, err=None, share=0.9):
    r = {"n": 100, "mode": 5000.0, "median": 5000.0, "mad_log10": mad, "iqr_over_median": iqr,
         "frac_within": frac, "share_estimated": share, "n_events": 110}
    if err is not None:
        r.update(median_rel_error=err, frac_within_truth=frac)
    return r


def _lt_regions(prop, mueg):
    # a single global peak for the proposed method: the old rule would compare one FWHM
    return {"d": {"proposed": {"peaks": [{"fwhm_log10": 0.3, "mode": 5000.0}], "regions": prop},
                  "mueggler": {"peaks": [{"fwhm_log10": 0.1, "mode": 5000.0}], "regions": mueg}}}


def test_lifetime_verdict_uses_the_region_spread_not_the_global_peaks():
    lt = _lt_regions({"slow": _reg(0.04, 0.7, 0.2), "fast": _reg(0.05, 0.6, 0.3)},
                     {"slow": _reg(0.06, 0.6, 0.3), "fast": _reg(0.09, 0.5, 0.4)})
    v = lifetime_verdicts(lt, {"d": {"regions": {"method": "my split"}}})[0]
    assert v["status"] == "holds"  # global FWHM says otherwise (0.3 > 0.1): not the measure
    assert v["detail"]["measure"] == "region_mad_log10"
    assert "my split" in v["evidence"] and "Global view (not used" in v["evidence"]
    assert "disagree" not in v["evidence"]
    # sharper in one region only -> fails
    lt["d"]["proposed"]["regions"]["fast"]["mad_log10"] = 0.1
    v = lifetime_verdicts(lt)[0]
    assert v["status"] == "fails"
    # a secondary measure that disagrees is named
    lt = _lt_regions({"slow": _reg(0.04, 0.5, 0.2)}, {"slow": _reg(0.06, 0.6, 0.3)})
    v = lifetime_verdicts(lt)[0]
    assert v["status"] == "holds" and "within +-20% of the mode in the slow region" in v["evidence"]
    assert v["detail"]["secondary_disagree"] == ["share within +-20% of the mode in the slow region"]


def test_lifetime_verdict_with_truth_needs_lower_error_in_every_region():
    lt = _lt_regions({"slow": _reg(0.01, 0.9, 0.04, err=0.02), "fast": _reg(0.01, 0.9, 0.04, err=0.02)},
                     {"slow": _reg(0.02, 0.9, 0.1, err=0.05), "fast": _reg(0.02, 0.9, 0.1, err=0.07)})
    v = lifetime_verdicts(lt)[0]
    assert v["status"] == "holds" and "lower error vs truth" in v["claim"]
    lt["d"]["proposed"]["regions"]["fast"]["median_rel_error"] = 0.08
    assert lifetime_verdicts(lt)[0]["status"] == "fails"


def test_lifetime_verdict_says_when_the_band_ends_matter():
    lt = _lt_regions({"slow": _reg(0.04, 0.7, 0.2)}, {"slow": _reg(0.06, 0.6, 0.3)})
    lt["d"]["proposed"]["regions_core"] = {"slow": _reg(0.03, 0.7, 0.2)}
    lt["d"]["mueggler"]["regions_core"] = {"slow": _reg(0.05, 0.6, 0.3)}
    v = lifetime_verdicts(lt)[0]
    assert "(same MAD outcome)" in v["evidence"] and v["detail"]["core_mad_holds"] is True
    lt["d"]["proposed"]["regions_core"]["slow"]["mad_log10"] = 0.06
    v = lifetime_verdicts(lt)[0]
    assert v["status"] == "holds"  # the verdict's regions are the whole bands
    assert "depends on where the bands end" in v["evidence"] and v["detail"]["core_mad_holds"] is False


def _two_policies(prim, sec):
    """CDM results with both display policies: prim/sec = (proposed, mueggler) medians as (slow, fast)."""
    others = {"mueggler": prim[1], "proposed_noclear": sec[0], "mueggler_noclear": sec[1],
              "acc_1ms": (20, 40), "acc_30ms": (60, 30), "acc_count": (60, 60)}
    return _cdm(*prim[0], others)


def test_cdm_claims_are_checked_under_both_display_policies():
    # predecessor display: proposed wins everywhere; lifetime only: Mueggler wins the fast section
    cdm = _two_policies(((88, 89), (40, 86)), ((74, 54), (43, 62)))
    v = cdm_verdicts(cdm)
    assert {x["display"] for x in v} == {"predecessor", "lifetime_only"}
    prim = [x for x in v if x["display"] == "predecessor"]
    sec = [x for x in v if x["display"] == "lifetime_only"]
    assert len(prim) == len(sec) == 3  # beats baselines, beats fixed count, consistency
    assert all(x["claim"].startswith("[predecessor display (primary); scene, vs exact]") for x in prim)
    assert all(x["claim"].startswith("[lifetime_only display; scene, vs exact]") for x in sec)
    beats = {x["display"]: x for x in v if "beats Mueggler" in x["claim"]}
    assert beats["predecessor"]["status"] == "holds"
    assert "fast: proposed 89.0 vs mueggler 86.0" in beats["predecessor"]["evidence"]
    # the secondary view reads the _noclear keys, never the primary ones
    assert beats["lifetime_only"]["status"] == "fails"
    assert "mueggler in the fast section (62.0 >= 54.0)" in beats["lifetime_only"]["evidence"]
    assert beats["lifetime_only"]["detail"]["medians"]["proposed"] == {"slow": 74, "fast": 54}
    count = {x["display"]: x["status"] for x in v if "fixed-count" in x["claim"]}
    assert count == {"predecessor": "holds", "lifetime_only": "fails"}
    assert all("favourable to this baseline" in x["evidence"] for x in v if "fixed-count" in x["claim"])
    # swapping the policies' numbers swaps the outcomes: nothing is hard-coded
    swapped = _two_policies(((74, 54), (43, 62)), ((88, 89), (40, 86)))
    w = {x["display"]: x["status"] for x in cdm_verdicts(swapped) if "beats Mueggler" in x["claim"]}
    assert w == {"predecessor": "fails", "lifetime_only": "holds"}


def test_a_policy_not_run_is_not_checked():
    v = cdm_verdicts(_cdm(80, 78, {"mueggler": (70, 50), "acc_1ms": (20, 40), "acc_30ms": (60, 30)}))
    sec = [x for x in v if x["display"] == "lifetime_only"]
    assert [x["status"] for x in sec] == ["not checked"]
    with pytest.raises(ValueError, match="display"):
        cdm_verdicts(_cdm(80, 78, {}), displays=("nope",))


def test_real_claim_under_both_policies_and_the_headline():
    real = {"r": {"proposed": {"median": {"c": 70.0}}, "mueggler": {"median": {"c": 60.0}},
                  "proposed_noclear": {"median": {"c": 50.0}}, "mueggler_noclear": {"median": {"c": 55.0}},
                  "acc_30ms": {"median": {"c": 65.0}}, "mueggler_t0": {"median": {"c": 99.0}}}}
    v = real_verdicts(real)
    st = {x["display"]: x for x in v}
    assert st["predecessor"]["status"] == "holds"  # the diagnostic 99 is not ranked
    assert st["lifetime_only"]["status"] == "fails" and "best: acc_30ms" in st["lifetime_only"]["evidence"]
    assert "proposed 50.0" in st["lifetime_only"]["evidence"]
    cdm = _two_policies(((88, 89), (40, 86)), ((74, 54), (43, 62)))
    summ = display_summary(cdm_verdicts(cdm) + v)
    assert summ["primary"] == "predecessor"
    pol = summ["policies"]
    assert (pol["predecessor"]["holds"], pol["predecessor"]["fails"]) == (4, 0)
    assert (pol["lifetime_only"]["holds"], pol["lifetime_only"]["fails"]) == (0, 4)
    text = summ["text"]
    assert "primary comparison uses the predecessor display" in text and "fork" in text
    assert "lifetime-only display (nothing cleared; a burst lives from its first event), 0 of 4 CDM claims hold and 4 fail" in text
    assert "scene, vs exact: slow 74.0 vs 43.0, fast 54.0 vs 62.0" in text
    assert "r, vs c: 70.0 vs 60.0" in text


def test_real_claim_names_the_favourable_fixed_count():
    real = {"r": {"proposed": {"median": {"c": 47.0}}, "mueggler": {"median": {"c": 7.0}},
                  "acc_30ms": {"median": {"c": 36.0}}, "acc_count": {"median": {"c": 49.0}}}}
    v = real_verdicts(real, displays=PRIMARY_ONLY)[0]
    assert v["status"] == "fails"
    assert "best: acc_count (its count is set from the Canny maps' size" in v["evidence"]
    assert "without it the best is proposed" in v["evidence"]


def test_real_verdict_does_not_depend_on_method_order_ties_or_nan():
    """Regression: the best method was max() over the dict, so all-NaN medians, or a tie with the
    proposed method listed first, gave "holds"."""
    nan = float("nan")
    all_nan = {"r": {"proposed": {"median": {"c": nan}}, "mueggler": {"median": {"c": nan}},
                     "acc_1ms": {"median": {"c": nan}}}}
    assert real_verdicts(all_nan, displays=PRIMARY_ONLY)[0]["status"] == "not checked"
    for order in (("proposed", "mueggler"), ("mueggler", "proposed")):
        tie = {"r": {m: {"median": {"c": 50.0}} for m in order}}
        tie["r"]["acc_1ms"] = {"median": {"c": 10.0}}
        v = real_verdicts(tie, displays=PRIMARY_ONLY)[0]
        assert v["status"] == "fails" and "tied with mueggler" in v["evidence"], order
    others_nan = {"r": {"proposed": {"median": {"c": 50.0}}, "mueggler": {"median": {"c": nan}},
                        "acc_1ms": {"median": {"c": 49.0}}}}
    assert real_verdicts(others_nan, displays=PRIMARY_ONLY)[0]["status"] == "holds"


def test_missing_baselines_are_not_beaten_vacuously():
    """Regression: with a baseline absent the CDM claims held without comparing to it."""
    only_1ms = _cdm(80, 78, {"acc_1ms": (20, 40)})
    v = cdm_verdicts(only_1ms, displays=PRIMARY_ONLY)
    assert [x["status"] for x in v] == ["not checked", "not checked"]
    assert all("Not run, so not compared: mueggler, acc_30ms" in x["evidence"] for x in v)
    lost = _cdm(30, 28, {"acc_1ms": (40, 45)})  # a comparison that was made and lost still fails
    assert cdm_verdicts(lost, displays=PRIMARY_ONLY)[0]["status"] == "fails"
    alone = {"r": {"proposed": {"median": {"c": 50.0}}}}
    assert real_verdicts(alone, displays=PRIMARY_ONLY)[0]["status"] == "not checked"


def test_a_plugin_is_never_ranked_in_the_real_frames_claim():
    from evedge.bench.verdicts import real_verdicts

    per = {"proposed": {"median": {"c": 50.0}}, "mueggler": {"median": {"c": 10.0}},
           "acc_1ms": {"median": {"c": 20.0}}, "some.plugin:Method": {"median": {"c": 90.0}}}
    (v,) = real_verdicts({"rec": per}, displays=("predecessor",))
    assert v["status"] == "holds"
    assert "some.plugin:Method 90.0" in v["evidence"] and "other methods (not ranked)" in v["evidence"]


def _region(mad, err=None, **kw):
    q = {"n": 100, "n_events": 110, "share_estimated": 0.9, "mode": 5000.0, "median": 5000.0, "mad_log10": mad,
         "iqr_over_median": 2 * mad, "frac_within": 0.9 - mad, "frac_of_events_within": 0.8 - mad}
    if err is not None:
        q.update(median_rel_error=err, frac_within_truth=0.9, frac_of_signal_within_truth=0.8)
    return dict(q, **kw)


def _lifetime_table(regions: bool) -> ResultsTable:
    peaks = {"proposed": [{"mode": 1000.0, "median": 1000.0, "mad": 10.0, "mad_log10": 0.01, "fwhm_log10": 0.1,
                           "fraction": 0.6}],
             "mueggler": [{"mode": 1100.0, "median": 1100.0, "mad": 30.0, "mad_log10": 0.03, "fwhm_log10": 0.2,
                           "fraction": 0.5}]}
    lt = {"d": {m: {"peaks": p, "shoulder_peaks": [dict(p[0], kind="shoulder")], "median_rel_error": e,
                    **({"regions": {"slow": _region(mad, e), "fast": _region(mad, e)}} if regions else {})}
                for (m, p), mad, e in zip(peaks.items(), (0.02, 0.05), (0.05, 0.1))}}
    info = {"d": {"regions": {"from_truth": True, "method": "rows grouped by their median true lifetime "
                                                            "(simulator truth)"}}}
    table = ResultsTable()
    table.extend(lifetime_rows(lt, info), experiment="lifetime")
    return table


def _set(table, value, **where):
    (hit,) = table.query(**where)
    hit["value"] = value


@pytest.mark.parametrize("regions", [True, False])
def test_lifetime_verdict_reads_the_table(regions):
    """Changing one row of the table (a region's MAD, a histogram peak's FWHM, an error) flips the verdict:
    the lifetime check computes from the rows, histogram peaks and regions included."""
    table = _lifetime_table(regions)
    (v,) = [x for x in all_verdicts(table) if "lifetimes are sharper" in x["claim"]]
    assert v["status"] == "holds"
    assert "1.00 ms" in v["evidence"] and "shoulder" in v["evidence"]  # the peaks, read back from rows
    if regions:
        assert "simulator truth" in v["evidence"] and v["detail"]["measure"] == "region_mad_log10"
        _set(table, 0.09, experiment="lifetime", variant="proposed", section="fast", metric="mad_log10")
    else:
        assert v["detail"]["measure"] == "global_fwhm"
        _set(table, 0.3, experiment="lifetime", variant="proposed", section="all", metric="peak_0_fwhm_log10")
    (w,) = [x for x in all_verdicts(table) if "lifetimes are sharper" in x["claim"]]
    assert w["status"] == "fails"
    if regions:
        assert "0.0900 vs Mueggler 0.0500" in w["evidence"]
    else:
        assert "proposed 0.300" in w["evidence"]
    table = _lifetime_table(regions)  # the error vs truth decides too
    _set(table, 0.5, experiment="lifetime", variant="proposed",
         section="slow" if regions else "all", metric="median_rel_error")
    (w,) = [x for x in all_verdicts(table) if "lifetimes are sharper" in x["claim"]]
    assert w["status"] == "fails"


def test_cdm_why_reads_the_diagnostic_rows():
    """The explanation of a lost CDM comparison comes from the similarity experiment's diagnostic rows."""
    from evedge.bench.results import cdm_rows, diagnostic_rows

    cdm = {"exact": {k: {"slow": _summ(m), "fast": _summ(m), "all": _summ(m)} for k, m in
                     (("proposed", 50.0), ("mueggler", 60.0), ("acc_1ms", 10.0), ("acc_30ms", 20.0))}}
    diag = {"pixel_ratio": {"exact": {"proposed": {"slow": 0.5, "fast": 0.6}, "mueggler": {"slow": 0.9, "fast": 1.0}}},
            "lifetime": {"proposed": {s: {"n_signal": 10, "coverage": 0.4, "median_rel_error": 0.3, "over_2x": 0.1,
                                          "under_2x": 0.2} for s in ("slow", "fast")}}}
    table = ResultsTable()
    table.extend(cdm_rows("similarity", "s", cdm) + diagnostic_rows("s", diag), experiment="similarity")
    (v,) = [x for x in all_verdicts(table) if "beats Mueggler" in x["claim"] and x["display"] == "predecessor"]
    assert v["status"] == "fails" and "proposed 0.50, mueggler 0.90" in v["evidence"]
    assert "40% of signal events estimated" in v["evidence"]
    _set(table, 0.25, experiment="similarity", variant="proposed", section="slow", metric="edge_pixel_ratio")
    (w,) = [x for x in all_verdicts(table) if "beats Mueggler" in x["claim"] and x["display"] == "predecessor"]
    assert "proposed 0.25, mueggler 0.90" in w["evidence"]
