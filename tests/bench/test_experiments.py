"""Each experiment on tiny inputs: output structure, files, sane values."""

import json

import numpy as np
import pytest

from evedge.bench.exp_lifetime import lifetime_image, run_lifetime
from evedge.bench.exp_qualitative import PANEL_METHODS, rows_from_maps, run_qualitative
from evedge.bench.exp_real import frames_inside_events, run_real
from evedge.bench.exp_similarity import run_similarity, sections_us
from evedge.bench.methods import DIAGNOSTIC_METHODS, METHODS


@pytest.fixture(scope="module")
def similarity(moving_edge, tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")
    return out, run_similarity(out, recording=moving_edge, scene="edge", quick=True, progress=False,
                               keep_maps=True)


def test_similarity_structure_and_values(similarity):
    out, res = similarity
    s = res["scenes"]["edge"]
    assert set(s["cdm"]) == {"canny_matlab_0.3", "exact"}
    for ref, per in s["cdm"].items():
        assert set(per) == set(METHODS) | set(DIAGNOSTIC_METHODS)
        for m, summ in per.items():
            assert summ["slow"]["n"] > 0 and summ["fast"]["n"] > 0
            vals = np.asarray(s["cdm_per_frame"][ref][m])
            assert np.all((vals >= 0) & (vals <= 100))
    # diagnostics: exact straight edge -> the proposed lifetimes match the truth,
    # its maps are about as large as the reference, 1 ms maps much smaller
    d = s["diagnostics"]
    assert d["lifetime"]["proposed"]["slow"]["median_rel_error"] < 0.05
    assert d["lifetime"]["proposed"]["slow"]["over_2x"] < 0.05
    assert 0.5 < d["pixel_ratio"]["exact"]["proposed"]["slow"] < 2.0
    assert d["pixel_ratio"]["exact"]["acc_1ms"]["slow"] < 0.5
    # frames before the 30 ms warm-up are skipped
    assert min(s["frame_t_us"]) >= 30_000
    # a clean, sharp edge: the lifetime method draws a thin line where the edge is,
    # 1 ms accumulation (the edge needs 3.3-10 ms per pixel) is mostly empty
    assert s["cdm"]["exact"]["proposed"]["slow"]["median"] > 80
    assert s["cdm"]["exact"]["acc_1ms"]["slow"]["median"] < s["cdm"]["exact"]["proposed"]["slow"]["median"]
    for name in ("similarity_edge.csv", "similarity_edge.json", "similarity_edge_over_time.png",
                 "similarity_edge_boxplots.png"):
        assert (out / name).stat().st_size > 0
    data = json.loads((out / "similarity_edge.json").read_text())
    assert "scenes" in data and "_maps" not in data


def test_sections_parsing():
    assert sections_us({"sections": [{"name": "slow", "start_us": 0, "end_us": 10}]}, 5) == {"slow": (0, 10)}
    assert sections_us({"sections": [{"name": "a", "start_s": 0.5, "end_s": 1.0}]}, 5) == {"a": (500000, 1000000)}
    assert sections_us({"sections": {"b": [0.0, 0.001]}}, 5) == {"b": (0, 1000)}
    assert sections_us({}, 99) == {"all": (0, 100)}


def test_lifetime_experiment_on_known_lifetimes(moving_edge, tmp_path):
    res = run_lifetime(tmp_path, recordings={"stripes_sim": moving_edge}, datasets=("stripes_sim",),
                       progress=False)
    per = res["lifetime"]["stripes_sim"]
    assert set(per) == {"proposed", "mueggler", "truth"}
    # truth: two speeds -> two peaks at 1e6/300 and 1e6/100 us
    tp = per["truth"]["peaks"]
    assert len(tp) == 2
    assert tp[0]["median"] == pytest.approx(1e6 / 300, rel=1e-6)
    assert tp[1]["median"] == pytest.approx(1e6 / 100, rel=1e-6)
    for m in ("proposed", "mueggler"):
        assert 0 <= per[m]["median_rel_error"] < 1.0
        assert per[m]["n_with_truth"] > 0
    # exact plane data: the proposed estimator recovers the lifetimes closely
    assert per["proposed"]["median_rel_error"] < 0.05
    for name in ("lifetime_peaks.csv", "lifetime.json", "lifetime_hist_stripes_sim.png",
                 "lifetime_image_stripes_sim.png"):
        assert (tmp_path / name).stat().st_size > 0


def test_lifetime_image_median_per_pixel():
    from evedge.detector.result import empty_lifetimes
    from evedge.events import make_events

    ev = make_events([0, 0, 0, 1], [0, 0, 0, 1], [1, 2, 3, 4], [1, 1, 1, 1])
    lt = empty_lifetimes(4)
    lt["lifetime_us"] = [10.0, 30.0, 20.0, np.nan]
    lt["valid"] = [True, True, True, False]
    img = lifetime_image(ev, lt, (2, 2))
    assert img[0, 0] == 20.0
    assert np.isnan(img[1, 1]) and np.isnan(img[0, 1])


def test_real_experiment_on_written_ecd_folder(moving_edge, tmp_path):
    from evedge.io import write_ecd

    from evedge.bench.canny import CANNY_SETTINGS, canny_edges
    from evedge.bench.cdm import cdm
    from evedge.bench.methods import DISPLAY_CLEAR_BEHIND, compared
    from evedge.detector import detect
    from evedge.detector.edges import edge_frames
    from evedge.io import read_events

    folder = write_ecd(tmp_path / "rec", moving_edge)
    res = run_real(tmp_path / "out", path=folder, quick=True, progress=False, name="edge", keep_maps=True)
    r = res["recordings"]["edge"]
    idx = frames_inside_events(moving_edge)
    assert list(r["frame_index"]) == list(idx) and len(idx) > 5
    np.testing.assert_array_equal(r["frame_t_us"], moving_edge.frames.t_us[idx])
    assert set(r["cdm"]) == {"canny_matlab_0.3"}
    # every stored number is the CDM of the proposed method's map (rebuilt here from the detector)
    # against Canny of the grey frame with the same index: catches frame/time misalignment
    kept = res["_maps"]
    grey = read_events(folder).frames.images[idx]  # as written to disk (PNG), not the float originals
    np.testing.assert_array_equal(kept["grey"], grey)
    det = detect(moving_edge.events, moving_edge.sensor_size)
    for m in METHODS:
        v = np.asarray(r["cdm"]["canny_matlab_0.3"][m])
        assert v.shape == (len(idx),)
        base, display = compared(m).base, compared(m).display
        if base == "proposed":
            want = edge_frames(moving_edge.events[det.kept], det.lifetimes[det.kept], moving_edge.sensor_size,
                               moving_edge.frames.t_us[idx], clear_behind=DISPLAY_CLEAR_BEHIND[display])
            np.testing.assert_array_equal(kept["maps"][m], want)
        for i in range(len(idx)):
            ref = canny_edges(grey[i], CANNY_SETTINGS[0])
            assert v[i] == cdm(kept["maps"][m][i], ref), (m, i)
    # and the maps mean something: the proposed edge tracks the frame's edge, 1 ms accumulation misses it
    med = {m: np.median(r["cdm"]["canny_matlab_0.3"][m]) for m in METHODS}
    assert med["proposed"] > 60 and med["acc_1ms"] < 10
    assert (tmp_path / "out" / "real_edge.png").stat().st_size > 0


def test_real_experiment_on_slider_depth(realdata_dir, tmp_path):
    path = realdata_dir / "slider_depth"
    if not path.exists():
        pytest.skip(f"real data absent: {path}")
    res = run_real(tmp_path, path=path, quick=True, progress=False)
    r = res["recordings"]["slider_depth"]
    # the 4 frames inside the 0.0038-0.1742 s of events
    assert list(r["frame_index"]) == [1, 2, 3, 4]
    cdms = {m: np.asarray(r["cdm"]["canny_matlab_0.3"][m]) for m in METHODS}
    for m in METHODS:
        assert cdms[m].shape == (4,) and np.all((cdms[m] >= 0) & (cdms[m] <= 100)), m
    # measured 2026-11-23 (regression pins; the accumulations do not depend on any estimator):
    # proposed 36.7 45.0 48.4 47.2, acc_1ms 28.9 29.0 36.4 30.8, acc_30ms 40.7 37.1 35.6 35.9
    np.testing.assert_allclose(cdms["proposed"], [36.7, 45.0, 48.4, 47.2], atol=1.0)
    np.testing.assert_allclose(cdms["acc_1ms"], [28.9, 29.0, 36.4, 30.8], atol=0.1)
    np.testing.assert_allclose(cdms["acc_30ms"], [40.7, 37.1, 35.6, 35.9], atol=0.1)


def test_qualitative_panel(similarity, tmp_path):
    _, res = similarity
    kept = res["_maps"]
    rows = rows_from_maps("edge", kept, [0, len(kept["times"]) - 1])
    out = run_qualitative(tmp_path, rows=rows, progress=False)
    assert len(out["rows"]) == 2
    assert set(out["edge_pixels"][out["rows"][0]]) == {"canny", *PANEL_METHODS}
    assert (tmp_path / "qualitative.png").stat().st_size > 0
    with pytest.raises(ValueError, match="no rows"):
        run_qualitative(tmp_path, rows=[])


def test_lifetime_experiment_per_speed_region(two_bands, tmp_path):
    res = run_lifetime(tmp_path, recordings={"stripes_sim": two_bands}, datasets=("stripes_sim",),
                       progress=False)
    reg = res["datasets"]["stripes_sim"]["regions"]
    # with truth the regions come from it; the estimator-free split agrees on every row
    assert reg["rows"] == {"slow": list(range(8)), "fast": list(range(8, 16))}
    assert reg["truth_lifetime_us"] == {"slow": 10_000.0, "fast": 4_000.0}
    assert reg["data_driven_row_agreement"] == 1.0
    keys = {"n", "median", "mode", "mad_log10", "iqr_over_median", "frac_within", "n_events",
            "share_estimated", "median_rel_error", "frac_within_truth", "share_estimated_signal",
            "truth_lifetime_us", "frac_of_events_within", "frac_of_signal_within_truth"}
    for m in ("proposed", "mueggler"):
        r = res["lifetime"]["stripes_sim"][m]
        assert 0 < r["share_estimated"] <= 1 and 0 <= r["median_rel_error"] < 1
        assert isinstance(r["shoulder_peaks"], list)
        assert set(r["regions"]) == {"slow", "fast"}
        for name, q in r["regions"].items():
            assert keys <= set(q), name
            assert q["n_events"] > 0 and 0 < q["share_estimated"] <= 1
            assert q["truth_lifetime_us"] == reg["truth_lifetime_us"][name]
    # exact, noise-free stripes: the proposed lifetimes are the truth in each band
    prop = res["lifetime"]["stripes_sim"]["proposed"]["regions"]
    assert prop["slow"]["median"] == pytest.approx(10_000, rel=0.01)
    assert prop["fast"]["median"] == pytest.approx(4_000, rel=0.01)
    assert prop["fast"]["median_rel_error"] < 0.01
    for q in prop.values():  # the coverage-aware share is the plain share times the share estimated
        assert q["frac_of_events_within"] == pytest.approx(q["frac_within"] * q["n"] / q["n_events"])
        assert q["frac_of_signal_within_truth"] <= q["frac_within_truth"] + 1e-12
    core = res["lifetime"]["stripes_sim"]["proposed"]["regions_core"]
    # 8-row bands are too thin for 4 rows a side: the middle row only
    assert core["slow"]["n_events"] < prop["slow"]["n_events"]
    assert core["slow"]["median"] == pytest.approx(10_000, rel=0.01)
    diag = res["lifetime"]["stripes_sim"]["mueggler"]["on_buffered_events"]
    assert set(diag["regions"]) == {"slow", "fast"} and 0 < diag["share_estimated"] <= 1
    for name in ("lifetime_regions.csv", "lifetime_regions_stripes_sim.png"):
        assert (tmp_path / name).stat().st_size > 0
    header = (tmp_path / "lifetime_regions.csv").read_text().splitlines()[0]
    assert header.startswith("dataset,region,method") and "mad_log10" in header
    data = json.loads((tmp_path / "lifetime.json").read_text())
    assert data["lifetime"]["stripes_sim"]["proposed"]["regions"]["slow"]["mad_log10"] is not None


def _trail_case():
    """A vertical edge moving +x at 100 px/s over a 10 x 3 sensor: one event per pixel every 10 ms,
    each with a lifetime of 30 ms (three times too long, so trails are visible)."""
    from evedge.bench.methods import LifetimeRun
    from evedge.detector.result import empty_lifetimes
    from evedge.events import SensorSize, make_events

    xs = np.repeat(np.arange(6), 3)
    ys = np.tile(np.arange(3), 6)
    ev = make_events(xs, ys, xs * 10_000, np.ones(xs.size, bool))
    lt = empty_lifetimes(ev.size)
    lt["lifetime_us"], lt["vx_px_s"], lt["vy_px_s"], lt["valid"] = 30_000.0, 100.0, 0.0, True
    return ev, SensorSize(10, 3), LifetimeRun(ev, lt)


def test_display_policy_known_answer():
    from evedge.bench.methods import edge_maps

    ev, size, run = _trail_case()
    maps, runs = edge_maps(ev, size, [55_000], methods=("proposed", "mueggler", "proposed_noclear",
                                                       "mueggler_noclear", "acc_30ms"),
                           lifetime_runs={"proposed": run, "mueggler": run})
    assert runs["proposed"] is run  # the given lifetimes are reused, not recomputed
    cols = {m: sorted(set(np.flatnonzero(v[0].any(axis=0)))) for m, v in maps.items()}
    # lifetime only: alive while t_e <= 55 ms < t_e + 30 ms -> the events at 30, 40, 50 ms (x = 3, 4, 5)
    assert cols["proposed_noclear"] == cols["mueggler_noclear"] == [3, 4, 5]
    # predecessor display: each event clears the pixel behind it (x - 1), only the front stays
    assert cols["proposed"] == cols["mueggler"] == [5]
    assert maps["proposed"][0].sum() == 3 and maps["proposed_noclear"][0].sum() == 9
    # accumulation ignores the policy: events in (25, 55] ms
    assert cols["acc_30ms"] == [3, 4, 5]


def test_display_keys_and_validation():
    from evedge.bench.methods import DISPLAYS, PRIMARY_DISPLAY, check_displays, compared, display_view, method_key

    assert PRIMARY_DISPLAY == DISPLAYS[0] == "predecessor"
    assert method_key("proposed", "predecessor") == "proposed"
    assert method_key("mueggler", "lifetime_only") == "mueggler_noclear"
    assert method_key("acc_1ms", "lifetime_only") == "acc_1ms"
    for key in METHODS + DIAGNOSTIC_METHODS:
        c = compared(key)
        assert c.display is None or method_key(c.base, c.display) == key
    view = display_view({"proposed": 1, "proposed_noclear": 2, "acc_1ms": 3, "mueggler_t0_noclear": 4}, "lifetime_only")
    assert view == {"proposed": 2, "acc_1ms": 3, "mueggler_t0": 4}
    with pytest.raises(ValueError, match="displays"):
        check_displays(("nope",), "f")
    with pytest.raises(ValueError, match="unknown method"):
        method_key("canny", "predecessor")


def test_similarity_runs_both_display_policies(similarity):
    _, res = similarity
    s = res["scenes"]["edge"]
    rec = s["displays"]
    assert rec["primary"] == "predecessor"
    assert rec["policies"]["predecessor"] == {"clear_behind": True, "label": rec["policies"]["predecessor"]["label"],
                                              "methods": {"proposed": "proposed", "mueggler": "mueggler"}}
    assert rec["policies"]["lifetime_only"]["clear_behind"] is False
    assert rec["policies"]["lifetime_only"]["methods"] == {"proposed": "proposed_noclear",
                                                           "mueggler": "mueggler_noclear"}
    maps = res["_maps"]["maps"]
    # clearing only ever removes pixels: the predecessor map is a subset of the lifetime-only map
    for base in ("proposed", "mueggler"):
        assert not np.any(maps[base] & ~maps[base + "_noclear"])
    assert maps["proposed"].sum() < maps["proposed_noclear"].sum()
    out, _ = similarity
    header_ok = (out / "similarity_edge.csv").read_text()
    assert ",proposed_noclear," in header_ok and ",mueggler_noclear," in header_ok
