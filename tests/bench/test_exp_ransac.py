"""The RANSAC study on tiny sizes: window synthesis, 2-means restatement, outputs."""

import json

import numpy as np
import pytest

from evedge.bench.exp_ransac import (
    NOISE_KINDS,
    RansacStudyParams,
    kept_cluster,
    make_window,
    run_ransac_study,
)


def test_clean_window_lies_on_the_plane():
    params = RansacStudyParams(lifetime_us=2000.0)
    rng = np.random.default_rng(0)
    win = make_window(rng, params, 0.0, "global", t_e_us=1e6)
    ys, xs = np.mgrid[-2:3, -2:3]
    along = np.cos(win.theta) * xs + np.sin(win.theta) * ys
    fired = np.isfinite(win.t_us)
    assert np.array_equal(fired, along <= 1e-12)
    assert np.allclose(win.t_us[fired], 1e6 + 2000.0 * along[fired])
    assert win.true_inlier[win.fired_past].all()
    assert not win.fired_past[2, 2]


def test_scattered_noise_touches_only_n_pixels_and_never_exceeds_current_time():
    params = RansacStudyParams(n_scattered=3)
    rng = np.random.default_rng(1)
    for _ in range(20):
        win = make_window(rng, params, 1.0, "scattered", t_e_us=1e6)
        assert np.count_nonzero(win.deviation_us > 0) <= 3
        assert np.nanmax(win.t_us) <= 1e6
    with pytest.raises(ValueError, match="kind"):
        make_window(rng, params, 1.0, "other")


def test_kept_cluster_contains_the_detector_inliers():
    # The restated 2-means must agree with the detector: RANSAC's inliers are
    # always inside the cluster it was given.
    from evedge.detector.intra import IntraParams, fit_windows

    params = RansacStudyParams()
    rng = np.random.default_rng(2)
    wins = [make_window(rng, params, lv, kind) for lv in (0.0, 0.3, 1.0) for kind in NOISE_KINDS
            for _ in range(30)]
    stack = np.stack([w.t_us for w in wins])
    defaults = IntraParams()
    _, _, ok, inl = fit_windows(stack, defaults, seed=3)
    for k, w in enumerate(wins):
        cl = kept_cluster(w.t_us, min_points=defaults.min_points,
                          fallback_all_points=defaults.fallback_all_points)
        cl[2, 2] = True
        assert not np.any(inl[k] & ~cl)
    # a window with a clear gap splits into the recent group
    t = np.full((5, 5), np.nan)
    t[2, 2] = 100.0
    t[2, 1] = 90.0
    t[2, 0] = 80.0
    t[0, 0] = 0.0
    cl = kept_cluster(t, fallback_all_points=False, min_points=3)
    assert cl[2, 1] and cl[2, 0] and not cl[0, 0]


def test_tiny_study_outputs(tmp_path):
    p = RansacStudyParams(repetitions=8, noise_levels_px=(0.0, 0.5), deltas_px=(0.0, 0.25, 0.5))
    res = run_ransac_study(tmp_path, params=p, progress=False)
    for kind in NOISE_KINDS:
        per = res["fmeasure"][kind]
        assert set(per) == {"no_intra", "intra_delta_0", "intra_delta_0.25", "intra_delta_0.5"}
        for r in per.values():
            assert len(r["f_measure"]) == 2
            f = np.asarray(r["f_measure"], float)
            assert np.all((f >= 0) & (f <= 1))
        # no noise: RANSAC recovers every point and the exact lifetime
        assert per["no_intra"]["f_measure"][0] == pytest.approx(1.0)
        assert per["no_intra"]["lifetime_rel_error_mean"][0] == pytest.approx(0.0, abs=1e-9)
        # delta 0 is plain RANSAC
        assert np.allclose(per["no_intra"]["f_measure"], per["intra_delta_0"]["f_measure"])
    for name in ("ransac_study.csv", "ransac_study.json", "ransac_global.png", "ransac_scattered.png"):
        assert (tmp_path / name).stat().st_size > 0
    data = json.loads((tmp_path / "ransac_study.json").read_text())
    assert "fmeasure" in data and "truth_tolerance_sensitivity" in data


def test_same_seed_same_numbers(tmp_path):
    p = RansacStudyParams(repetitions=5, noise_levels_px=(0.3,), deltas_px=(0.25,))
    a = run_ransac_study(tmp_path / "a", params=p, progress=False)
    b = run_ransac_study(tmp_path / "b", params=p, progress=False)
    assert a["fmeasure"]["global"]["intra_delta_0.25"]["f_measure"].tolist() == \
        b["fmeasure"]["global"]["intra_delta_0.25"]["f_measure"].tolist()
