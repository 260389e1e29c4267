"""Small statistics used by the experiments: F-measure, relative error, histogram peaks.

Each function is pure and documented with its conventions for empty input.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.signal import find_peaks, peak_widths


def _as_decision(values, name: str) -> np.ndarray:
    """Bool, or numbers that are all 0/1; anything else (NaN, scores) would be cast to True silently."""
    v = np.asarray(values)
    if v.dtype == bool:
        return v
    if v.dtype.kind not in "iuf":
        raise TypeError(f"f_measure: {name} must be boolean (or 0/1 numbers), got dtype {v.dtype}")
    if not np.all((v == 0) | (v == 1)):
        raise ValueError(f"f_measure: {name} must hold only 0/1 (or bool) values")
    return v.astype(bool)


def f_measure(predicted, truth) -> float:
    """F1 score of a boolean decision against the truth.

    ``F = 2 P R / (P + R)`` with precision ``P = TP / (TP + FP)`` and recall
    ``R = TP / (TP + FN)`` (the paper's equation 5). Conventions: when there
    are no true and no predicted positives the decision is perfect (1.0); when
    only one side is empty, F = 0.

    Parameters
    ----------
    predicted, truth : array_like of bool (or 0/1 numbers), same shape
    """
    p = _as_decision(predicted, "predicted")
    t = _as_decision(truth, "truth")
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
    n_peaks : int
        Most peaks returned (the most prominent ones).
    bins : int
        Histogram bins over the range of the (log) samples.
    log10 : bool
        Histogram of ``log10(values)`` (True) or of ``values``.
    smooth_bins : float
        Standard deviation, in bins, of the Gaussian smoothing.
    min_prominence : float
        Least prominence of a peak, as a fraction of the highest smoothed bin.

    Returns
    -------
    list of dict
        Empty when fewer than 10 usable samples or no peak. Per peak: ``mode`` (bin centre of the maximum, in value units),
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
    counts, edges, centres, lo, hi = _log_histogram(z, bins)
    smooth = gaussian_filter1d(counts, smooth_bins, mode="constant")
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


def _log_histogram(z: np.ndarray, bins: int):
    """Histogram of ``z`` over its 0.1-99.9 % range plus a 5 % margin each side.

    The margin makes a peak at either end of the range a whole peak.
    """
    lo, hi = np.quantile(z, [0.001, 0.999])
    if hi <= lo:
        hi = lo + 1e-6
    margin = 0.05 * (hi - lo)
    lo, hi = lo - margin, hi + margin
    counts, edges = np.histogram(z, bins=bins, range=(lo, hi))
    centres = 0.5 * (edges[:-1] + edges[1:])
    return counts.astype(np.float64), edges, centres, lo, hi


def histogram_mode(values, *, bins: int = 120, smooth_bins: float = 2.0) -> float:
    """Mode of positive samples: the maximum of their smoothed log10 histogram (value units).

    Same histogram as :func:`histogram_peaks` (``bins`` bins over the
    0.1-99.9 % range of ``log10(values)``, Gaussian smoothing of
    ``smooth_bins`` bins). NaN for fewer than 10 positive finite samples.
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v) & (v > 0)]
    if v.size < 10:
        return float("nan")
    z = np.log10(v)
    counts, _, centres, _, _ = _log_histogram(z, bins)
    smooth = gaussian_filter1d(counts, smooth_bins, mode="constant")
    return float(10.0 ** centres[int(np.argmax(smooth))])


def log_spread(values, *, mode: float | None = None, within: float = 0.2, truth: float | None = None) -> dict:
    """Robust spread of positive samples that should share one value (one speed region).

    Parameters
    ----------
    values : array_like
        Positive samples (non-finite and non-positive ones are dropped).
    mode : float, optional
        Reference value for ``frac_within``; default :func:`histogram_mode` of the samples.
    within : float
        Relative half-width of the band around the mode (0.2: +-20 %).
    truth : float, optional
        The true value, if known: adds ``median_rel_error`` (median of
        ``|v - truth| / truth``) and ``frac_within_truth``.

    Returns
    -------
    dict
        ``n``; ``median``; ``mode``; ``mad_log10``: median absolute deviation of
        ``log10(v)`` about its median (decades; scale-free, 0.6745 sigma for a
        log-normal); ``iqr_over_median``: ``(q75 - q25) / median``;
        ``frac_within``: share of samples with ``|v / mode - 1| <= within``.
        Empty input: ``n`` 0 and NaN elsewhere.
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v) & (v > 0)]
    if not within > 0:
        raise ValueError(f"log_spread: within must be > 0, got {within!r}")
    nan = float("nan")
    out = {"n": int(v.size), "median": nan, "mode": nan, "mad_log10": nan, "iqr_over_median": nan,
           "frac_within": nan, "within": float(within)}
    if truth is not None:
        out.update(truth=float(truth), median_rel_error=nan, frac_within_truth=nan)
    if v.size == 0:
        return out
    med = float(np.median(v))
    ref = float(mode) if mode is not None else histogram_mode(v)
    if not np.isfinite(ref):  # too few samples for a histogram: the median stands in
        ref = med
    q1, q3 = np.quantile(v, [0.25, 0.75])
    out.update(median=med, mode=ref, mad_log10=mad(np.log10(v)), iqr_over_median=float((q3 - q1) / med),
               frac_within=float(np.mean(np.abs(v / ref - 1.0) <= within)))
    if truth is not None and truth > 0:
        rel = np.abs(v - truth) / truth
        out.update(median_rel_error=float(np.median(rel)), frac_within_truth=float(np.mean(rel <= within)))
    return out


def shoulder_peaks(values, *, n_peaks: int = 2, bins: int = 120, smooth_bins: float = 3.0,
                   min_height: float = 0.1, min_prominence: float = 0.05) -> list[dict]:
    """Peaks *and shoulders* of a log10 histogram, from its curvature.

    A component of a mixture shows as a maximum of the negative second
    derivative of the smoothed density even when it is only a shoulder of a
    larger neighbour (no local maximum of its own), which
    :func:`histogram_peaks` cannot see. The histogram of ``log10(values)``
    (as in :func:`histogram_peaks`) is smoothed with a Gaussian of
    ``smooth_bins`` bins and differentiated twice (Gaussian derivative
    filter); candidates are maxima of ``c = -f''`` where ``c > 0``, the
    smoothed density is at least ``min_height`` of its maximum (no tail
    wiggles) and the prominence of ``c`` is at least ``min_prominence`` of
    ``max(c)``. The ``n_peaks`` most prominent are kept, ordered by location.
    Samples are split between neighbouring components at the most convex
    point (minimum of ``c``) between them.

    Returns
    -------
    list of dict
        Per component: ``mode`` (location of the curvature maximum, value
        units), ``median``, ``mad_log10`` (of the component's samples),
        ``fwhm_log10`` (Gaussian-equivalent: ``2.3548 * 1.4826 * mad_log10``),
        ``fraction`` (share of samples), ``kind`` (``"peak"`` when the
        smoothed density has a local maximum (prominence at least 10 % of the
        highest bin, height at least ``min_height`` of it) among the component's samples, else ``"shoulder"``).

    Notes
    -----
    For a Gaussian component of standard deviation sigma the curvature
    maximum lies at its mean; for two overlapping components the split
    point and the widths are approximate (each component's far tail is
    counted in its neighbour).
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v) & (v > 0)]
    if v.size < 10:
        return []
    z = np.log10(v)
    counts, edges, centres, lo, hi = _log_histogram(z, bins)
    smooth = gaussian_filter1d(counts, smooth_bins, mode="constant")
    curv = -gaussian_filter1d(counts, smooth_bins, order=2, mode="constant")
    if not (curv.max() > 0):
        return []
    idx, props = find_peaks(curv, prominence=min_prominence * curv.max())
    ok = (curv[idx] > 0) & (smooth[idx] >= min_height * smooth.max())
    idx, prom = idx[ok], props["prominences"][ok]
    if idx.size == 0:
        return []
    keep = np.sort(idx[np.argsort(prom)[::-1][:n_peaks]])
    bounds = [lo - 1.0]
    for a, b in zip(keep[:-1], keep[1:]):
        m = a + int(np.argmin(curv[a:b + 1]))
        bounds.append(edges[m + 1])
    bounds.append(hi + 1.0)
    # maxima of the density itself; prominence as histogram_peaks, so that wiggles on a shoulder do not count
    local_max = find_peaks(np.r_[0.0, smooth, 0.0], prominence=0.1 * smooth.max())[0] - 1
    out = []
    for k, i in enumerate(keep):
        sel = z[(z >= bounds[k]) & (z < bounds[k + 1])]
        m_log = mad(sel)
        in_basin = (centres[local_max] >= bounds[k]) & (centres[local_max] < bounds[k + 1])
        is_peak = bool(np.any(in_basin & (smooth[local_max] >= min_height * smooth.max())))
        out.append({"mode": float(10.0 ** centres[i]),
                    "median": float(10.0 ** np.median(sel)) if sel.size else float("nan"),
                    "mad_log10": m_log, "fwhm_log10": float(2.3548 * 1.4826 * m_log),
                    "fraction": float(sel.size / z.size), "kind": "peak" if is_peak else "shoulder"})
    return out
