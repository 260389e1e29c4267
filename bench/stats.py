"""Small statistics used by the experiments: F-measure, relative error, histogram peaks.

Each function is pure and documented with its conventions for empty input.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import find_peaks, peak_widths


def f_measure(predicted, truth) -> float:
    """F1 score of a boolean decision against the truth.

    ``F = 2 P R / (P + R)`` with precision ``P = TP / (TP + FP)`` and recall
    ``R = TP / (TP + FN)`` (the paper's equation 5). Conventions: when there
    are no true and no predicted positives the decision is perfect (1.0); when
    only one side is empty, F = 0.

    Parameters
    ----------
    predicted, truth : array_like of bool, same shape
    """
    p = np.asarray(predicted, dtype=bool)
    t = np.asarray(truth, dtype=bool)
    if p.shape != t.shape:
        raise ValueError(f"f_measure: predicted {p.shape} and truth {t.shape} differ in shape")
    tp = int(np.count_nonzero(p & t))
    fp = int(np.count_nonzero(p & ~t))
    fn = int(np.count_nonzero(~p & t))
    if tp + fp + fn == 0:
        return 1.0
    return 2.0 * tp / (2.0 * tp + fp + fn)


def relative_errors(estimate, truth) -> np.ndarray:
    """``|estimate - truth| / truth`` where both are finite and truth > 0 (1-D, others dropped)."""
    e = np.asarray(estimate, dtype=np.float64)
    t = np.asarray(truth, dtype=np.float64)
    if e.shape != t.shape:
        raise ValueError(f"relative_errors: estimate {e.shape} and truth {t.shape} differ in shape")
    ok = np.isfinite(e) & np.isfinite(t) & (t > 0)
    return np.abs(e[ok] - t[ok]) / t[ok]


def mad(values) -> float:
    """Median absolute deviation (unscaled); NaN for empty input."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return float("nan")
    return float(np.median(np.abs(v - np.median(v))))


def histogram_peaks(values, *, n_peaks: int = 2, bins: int = 120, log10: bool = True,
                    smooth_bins: float = 2.0, min_prominence: float = 0.1) -> list[dict]:
    """The main peaks of a (log-)histogram, found robustly, with their spread.

    The histogram of ``log10(values)`` (or of ``values``) is smoothed with a
    Gaussian of ``smooth_bins`` bins; peaks are local maxima whose prominence
    is at least ``min_prominence`` of the highest bin; the ``n_peaks`` most
    prominent are kept, ordered by location. Each peak's *basin* runs to the
    lowest points of the smoothed histogram between it and its neighbours;
    the samples in the basin give the robust location (median) and spread
    (MAD), the smoothed curve gives the full width at half maximum.

    Parameters
    ----------
    values : array_like
        Positive samples (non-finite and non-positive ones are dropped in log mode).

    Returns
    -------
    list of dict
        Per peak: ``mode`` (bin centre of the maximum, in value units),
        ``median`` and ``mad`` of the basin samples (value units; in log mode
        also ``mad_log10``), ``fwhm_log10`` or ``fwhm`` (width at half height),
        ``fraction`` (share of all samples in the basin).
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    if log10:
        v = v[v > 0]
        z = np.log10(v)
    else:
        z = v
    if z.size < 10:
        return []
    lo, hi = np.quantile(z, [0.001, 0.999])
    if hi <= lo:
        hi = lo + 1e-6
    # a margin so that a peak at either end of the range is a whole peak
    margin = 0.05 * (hi - lo)
    lo, hi = lo - margin, hi + margin
    counts, edges = np.histogram(z, bins=bins, range=(lo, hi))
    centres = 0.5 * (edges[:-1] + edges[1:])
    smooth = gaussian_filter1d(counts.astype(np.float64), smooth_bins, mode="constant")
    idx, props = find_peaks(smooth, prominence=min_prominence * smooth.max())
    if idx.size == 0:
        return []
    keep = np.sort(idx[np.argsort(props["prominences"])[::-1][:n_peaks]])
    widths = peak_widths(smooth, keep, rel_height=0.5)[0] * (edges[1] - edges[0])
    # basins: split at the lowest smoothed bin between consecutive kept peaks
    bounds = [lo - 1.0]
    for a, b in zip(keep[:-1], keep[1:]):
        m = a + int(np.argmin(smooth[a:b + 1]))
        bounds.append(edges[m + 1])
    bounds.append(hi + 1.0)
    out = []
    for k, i in enumerate(keep):
        sel = z[(z >= bounds[k]) & (z < bounds[k + 1])]
        med = float(np.median(sel)) if sel.size else float("nan")
        peak = {"fraction": float(sel.size / z.size)}
        if log10:
            vals = 10.0 ** sel
            peak.update(mode=float(10.0 ** centres[i]), median=float(10.0 ** med),
                        mad=mad(vals), mad_log10=mad(sel), fwhm_log10=float(widths[k]))
        else:
            peak.update(mode=float(centres[i]), median=med, mad=mad(sel), fwhm=float(widths[k]))
        out.append(peak)
    return out
