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
