"""Known answers for the small statistics."""

import numpy as np
import pytest

from evedge.bench.stats import f_measure, histogram_peaks, mad, relative_errors


def test_f_measure_known_values():
    pred = np.array([1, 1, 0, 0, 1], bool)
    truth = np.array([1, 0, 1, 0, 1], bool)
    # TP 2, FP 1, FN 1 -> P = R = 2/3 -> F = 2/3
    assert f_measure(pred, truth) == pytest.approx(2 / 3)
    assert f_measure(truth, truth) == 1.0
    assert f_measure(np.zeros(3, bool), np.zeros(3, bool)) == 1.0
    assert f_measure(np.zeros(3, bool), np.ones(3, bool)) == 0.0
    assert f_measure(np.ones(3, bool), np.zeros(3, bool)) == 0.0
    with pytest.raises(ValueError, match="shape"):
        f_measure(np.zeros(3, bool), np.zeros(4, bool))
    # 0/1 numbers are decisions; NaN or scores were silently cast to True (F = 1 against all-True truth)
    assert f_measure([1, 0, 1], [1.0, 0.0, 0.0]) == pytest.approx(2 / 3)
    with pytest.raises(ValueError, match="predicted must hold only 0/1"):
        f_measure(np.full(3, np.nan), np.ones(3, bool))
    with pytest.raises(ValueError, match="truth must hold only 0/1"):
        f_measure(np.ones(3, bool), [0.2, 0.9, 1.0])
    with pytest.raises(TypeError, match="predicted must be boolean"):
        f_measure(np.array(["a", "b", "c"]), np.ones(3, bool))


def test_relative_errors_drop_invalid():
    e = relative_errors([110.0, np.nan, 50.0, 10.0], [100.0, 100.0, np.nan, 0.0])
    assert e.tolist() == pytest.approx([0.1])


def test_mad():
    assert mad([1, 2, 3, 4, 100]) == 1.0
    assert np.isnan(mad([]))


def test_histogram_peaks_finds_two_lognormal_modes():
    rng = np.random.default_rng(0)
    a = 10 ** rng.normal(3.0, 0.05, 20000)   # 1 ms
    b = 10 ** rng.normal(4.0, 0.10, 10000)   # 10 ms, twice as wide
    peaks = histogram_peaks(np.concatenate([a, b]))
    assert len(peaks) == 2
    assert peaks[0]["median"] == pytest.approx(1000, rel=0.03)
    assert peaks[1]["median"] == pytest.approx(10000, rel=0.05)
    assert peaks[0]["fraction"] == pytest.approx(2 / 3, abs=0.02)
    # FWHM of a Gaussian = 2.355 sigma (in decades); the wider peak is wider
    assert peaks[0]["fwhm_log10"] == pytest.approx(2.355 * 0.05, rel=0.25)
    assert peaks[1]["fwhm_log10"] > 1.5 * peaks[0]["fwhm_log10"]
    # MAD of a Gaussian = 0.6745 sigma
    assert peaks[0]["mad_log10"] == pytest.approx(0.6745 * 0.05, rel=0.1)


def test_histogram_peaks_single_mode_and_tiny_input():
    rng = np.random.default_rng(1)
    peaks = histogram_peaks(10 ** rng.normal(3.5, 0.05, 5000))
    assert len(peaks) == 1
    assert peaks[0]["fraction"] == 1.0
    assert histogram_peaks([1.0, 2.0]) == []


def test_log_spread_known_answers():
    from evedge.bench.stats import log_spread

    s = log_spread([100.0, 200.0, 300.0, 400.0, 500.0], mode=300.0, within=0.25, truth=250.0)
    assert s["n"] == 5 and s["median"] == 300.0 and s["mode"] == 300.0
    assert s["iqr_over_median"] == pytest.approx(200.0 / 300.0)       # q25 200, q75 400
    assert s["frac_within"] == pytest.approx(1 / 5)                   # only 300 within 300 +- 25 %
    assert s["median_rel_error"] == pytest.approx(0.6)                # |v - 250| / 250 = .6 .2 .2 .6 1
    assert s["frac_within_truth"] == pytest.approx(2 / 5)
    assert s["mad_log10"] == pytest.approx(np.median(np.abs(np.log10([1, 2, 3, 4, 5]) - np.log10(3))))
    const = log_spread(np.full(50, 7000.0))
    assert const["mad_log10"] == 0.0 and const["iqr_over_median"] == 0.0 and const["frac_within"] == 1.0
    # log-normal: MAD of log10 = 0.6745 sigma; the share within +-20 % of the mode
    # is P(log10 0.8 <= log10 v - mu <= log10 1.2)
    rng = np.random.default_rng(2)
    sigma = 0.05
    ln = log_spread(10 ** rng.normal(4.0, sigma, 40000))
    assert ln["mad_log10"] == pytest.approx(0.6745 * sigma, rel=0.03)
    assert ln["mode"] == pytest.approx(1e4, rel=0.02)
    from scipy.stats import norm

    expect = norm.cdf(np.log10(1.2) / sigma) - norm.cdf(np.log10(0.8) / sigma)
    assert ln["frac_within"] == pytest.approx(expect, abs=0.02)
    empty = log_spread([np.nan, -1.0], truth=5.0)
    assert empty["n"] == 0 and np.isnan(empty["mad_log10"]) and np.isnan(empty["median_rel_error"])
    with pytest.raises(ValueError, match="within"):
        log_spread([1.0], within=0.0)


def test_shoulder_peaks_sees_a_shoulder_the_peak_finder_misses():
    from evedge.bench.stats import shoulder_peaks

    rng = np.random.default_rng(0)
    # a large component at 10^3.8 and a smaller one at 10^4.05 that is only a shoulder
    v = np.concatenate([10 ** rng.normal(3.8, 0.08, 24000), 10 ** rng.normal(4.05, 0.06, 6000)])
    assert len(histogram_peaks(v)) == 1
    comp = shoulder_peaks(v)
    assert len(comp) == 2
    assert [c["kind"] for c in comp] == ["peak", "shoulder"]
    assert np.log10(comp[0]["mode"]) == pytest.approx(3.8, abs=0.04)
    assert np.log10(comp[1]["mode"]) == pytest.approx(4.05, abs=0.04)
    assert comp[0]["fraction"] == pytest.approx(0.8, abs=0.06)


def test_shoulder_peaks_on_separate_modes_and_tiny_input():
    from evedge.bench.stats import shoulder_peaks

    rng = np.random.default_rng(0)
    v = np.concatenate([10 ** rng.normal(3.0, 0.05, 20000), 10 ** rng.normal(4.0, 0.10, 10000)])
    comp = shoulder_peaks(v)
    assert [c["kind"] for c in comp] == ["peak", "peak"]
    assert comp[0]["median"] == pytest.approx(1000, rel=0.03)
    assert comp[1]["median"] == pytest.approx(10000, rel=0.05)
    # well-separated Gaussians: MAD of each component = 0.6745 sigma, FWHM-equivalent 2.355 sigma
    assert comp[0]["mad_log10"] == pytest.approx(0.6745 * 0.05, rel=0.1)
    assert comp[1]["fwhm_log10"] == pytest.approx(2.355 * 0.10, rel=0.1)
    assert shoulder_peaks([1.0, 2.0]) == []
