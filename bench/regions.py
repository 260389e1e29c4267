"""Speed regions of the stripes recordings, found without any lifetime estimator.

The stripes sequences have bands of rows moving at different speeds (the
real ``stripes.mat``: two bands; the simulated ``stripes`` scene: top and
bottom half). Comparing how sharp two estimators' lifetimes are needs those
bands, and they must not come from either estimator (or the comparison would
favour it). Two sources:

* :func:`regions_from_delays` (no truth): the *model-free neighbour delay*
  of each event (time since the latest event of the same polarity at the
  left or right neighbouring pixel, whichever is more recent; the flow of both
  stripes recordings is horizontal, a fact of the scenes) gives a per-row
  median delay; rows with enough events are split in two by 1-D 2-means
  (exact) on the log10 of those medians, and each group keeps its longest
  run of consecutive rows (the regions are bands); groups whose median
  delays differ by less than a factor 1.25 are not distinct bands (no regions).
* :func:`regions_from_truth` (simulation): rows grouped by their true lifetime.

A region is a set of rows; the names are ``"slow"`` (longer lifetimes) and
``"fast"``.
"""

from __future__ import annotations

import numpy as np

REGION_NAMES = ("slow", "fast")


class NoRegionsError(ValueError):
    """The data hold no two distinct speed bands of rows (a finding about the data, not a bad argument)."""


def neighbour_delays(events: np.ndarray, sensor_size) -> np.ndarray:
    """Per event, the time since the latest earlier event of its polarity at x - 1 or x + 1.

    Parameters
    ----------
    events : numpy.ndarray of EVENT_DTYPE
        Sorted by time.
    sensor_size : SensorSize

    Returns
    -------
    numpy.ndarray of float64
        Microseconds; the smaller of the two delays (the neighbour the edge
        came from fired most recently); NaN when neither neighbour has fired
        before (same timestamp counts as before: delay 0).

    Notes
    -----
    For an edge moving horizontally at ``v`` px/s, neighbouring pixels fire
    ``1/v`` s apart, which is the lifetime; the delay is a crude, estimator-
    free version of it (bursts of events per crossing shorten it), good for
    telling speed bands apart, not for measuring them.
    """
    from evedge.events import validate_events

    events = validate_events(events, sensor_size, name="neighbour_delays: events")
    n = events.size
    out = np.full(n, np.nan)
    if n == 0:
        return out
    w, h = int(sensor_size.width), int(sensor_size.height)
    x = events["x"].astype(np.int64)
    y = events["y"].astype(np.int64)
    p = events["p"].astype(np.int64)
    t = events["t"].astype(np.int64) - int(events["t"][0])
    span = int(t[-1]) + 1
    # one sorted key per event: (polarity, pixel) then time; the latest event of
    # pixel q at or before t is the last key <= q * span + t
    key = ((p * h + y) * w + x) * span + t
    sk = np.sort(key, kind="stable")
    best = np.full(n, np.inf)
    for dx in (-1, 1):
        nx = x + dx
        inside = (nx >= 0) & (nx < w)
        npix = (p * h + y) * w + np.clip(nx, 0, w - 1)
        j = np.searchsorted(sk, npix * span + t, side="right") - 1
        jj = np.clip(j, 0, None)
        good = inside & (j >= 0) & (sk[jj] // span == npix)
        best = np.minimum(best, np.where(good, t - sk[jj] % span, np.inf))
    ok = np.isfinite(best)
    out[ok] = best[ok]
    return out


def two_means_1d(values) -> tuple[float, np.ndarray]:
    """Optimal split of 1-D values into two groups (minimum within-group sum of squares).

    Exact: every split of the sorted values is tried.

    Returns
    -------
    threshold : float
        Midpoint between the two groups; values above it form the upper group.
    upper : numpy.ndarray of bool
        Membership of the upper group, aligned with ``values``.
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    if v.size < 2 or not np.all(np.isfinite(v)):
        raise ValueError(f"two_means_1d: need at least 2 finite values, got {v.size} "
                         f"({int(np.sum(~np.isfinite(v)))} non-finite)")
    s = np.sort(v)
    k = np.arange(1, s.size)  # size of the lower group
    c1, c2 = np.cumsum(s), np.cumsum(s ** 2)
    lo_ss = c2[:-1] - c1[:-1] ** 2 / k
    hi_n = s.size - k
    hi_ss = (c2[-1] - c2[:-1]) - (c1[-1] - c1[:-1]) ** 2 / hi_n
    # ties: splitting between equal values is not a split; forbid it
    cost = np.where(s[1:] > s[:-1], lo_ss + hi_ss, np.inf)
    if not np.isfinite(cost).any():
        raise ValueError("two_means_1d: all values are equal, nothing to split")
    i = int(np.argmin(cost))
    thr = 0.5 * (s[i] + s[i + 1])
    return float(thr), v > thr


def longest_run(rows) -> np.ndarray:
    """The longest run of consecutive integers in sorted ``rows`` (the first one on ties)."""
    r = np.asarray(rows, dtype=np.int64)
    if r.size == 0:
        return r
    breaks = np.flatnonzero(np.diff(r) != 1) + 1
    starts = np.r_[0, breaks]
    ends = np.r_[breaks, r.size]
    k = int(np.argmax(ends - starts))
    return r[starts[k]:ends[k]]



def _split_rows(log_delays: np.ndarray, who: str):
    """:func:`two_means_1d` on the rows; rows that cannot be split (all equal) have no speed bands."""
    try:
        return two_means_1d(log_delays)
    except ValueError as err:
        raise NoRegionsError(f"{who}: {err}") from None

#: How :func:`regions_from_truth` finds the regions (shown as the verdict's evidence).
TRUTH_METHOD = "rows grouped by their median true lifetime (simulator truth)"


def delays_method(min_row_share: float) -> str:
    """How :func:`regions_from_delays` finds the regions with this ``min_row_share`` (evidence text)."""
    return (f"per-row median of the model-free horizontal neighbour delay; rows with at least "
            f"{min_row_share:g} x the median row's events; 1-D 2-means on log10 of the row medians; "
            f"each region keeps its longest run of consecutive rows")


def regions_from_delays(events: np.ndarray, sensor_size, *, min_row_share: float = 0.25,
                        min_ratio: float = 1.25) -> dict:
    """Two speed regions (sets of rows) from the per-row median neighbour delay.

    Parameters
    ----------
    events : numpy.ndarray of EVENT_DTYPE
    sensor_size : SensorSize
    min_row_share : float
        Rows with fewer delays than this share of the median row's count are
        left out (too few events to be part of a moving band; on the real
        recording this drops the sparse object above the stripes).
    min_ratio : float
        The two groups must differ: the ratio of their median delays at least
        this, else there are no distinct speed bands (``ValueError``).

    Returns
    -------
    dict
        ``{"method": ..., "rows": {"slow": [...], "fast": [...]},
        "row_median_delay_us": [per row, None when left out],
        "threshold_delay_us": float, "median_delay_us": {region: float}}``.
    """
    if not 0 <= min_row_share < 1:
        raise ValueError(f"regions_from_delays: min_row_share must be in [0, 1), got {min_row_share!r}")
    d = neighbour_delays(events, sensor_size)
    ok = np.isfinite(d) & (d > 0)
    h = int(sensor_size.height)
    y = events["y"][ok].astype(np.int64)
    dv = d[ok]
    counts = np.bincount(y, minlength=h)
    row_med = np.full(h, np.nan)
    order = np.lexsort((dv, y))
    ys, ds = y[order], dv[order]
    starts = np.searchsorted(ys, np.arange(h), side="left")
    ends = np.searchsorted(ys, np.arange(h), side="right")
    for r in range(h):
        if ends[r] > starts[r]:
            row_med[r] = np.median(ds[starts[r]:ends[r]])
    busy = counts[counts > 0]
    need = min_row_share * (np.median(busy) if busy.size else 0.0)
    use = np.flatnonzero((counts >= max(need, 1)) & np.isfinite(row_med))
    if use.size < 2:
        raise NoRegionsError("regions_from_delays: fewer than 2 rows with enough events to find speed regions")
    thr, upper = _split_rows(np.log10(row_med[use]), "regions_from_delays")
    # the regions are bands of rows: each keeps its longest run of consecutive rows
    # (drops stray rows of other objects whose delays happen to fall in its group)
    rows = {"slow": longest_run(use[upper]).tolist(), "fast": longest_run(use[~upper]).tolist()}
    med = {k: float(np.median(dv[np.isin(y, r)])) for k, r in rows.items()}
    if not med["slow"] >= min_ratio * med["fast"]:
        raise NoRegionsError(f"regions_from_delays: no distinct speed bands (median delays {med['slow']:.0f} and "
                         f"{med['fast']:.0f} us differ by less than a factor {min_ratio:g})")
    return {"method": delays_method(min_row_share), "min_row_share": float(min_row_share), "from_truth": False,
            "rows": rows, "row_median_delay_us": [None if not np.isfinite(v) else float(v) for v in row_med],
            "threshold_delay_us": float(10.0 ** thr),
            "median_delay_us": med}


def regions_from_truth(events: np.ndarray, truth_lifetime_us, sensor_size) -> dict:
    """Speed regions of a simulated recording: rows grouped by their median true lifetime.

    Parameters
    ----------
    events : numpy.ndarray of EVENT_DTYPE
    truth_lifetime_us : array_like
        Per event (NaN for noise).
    sensor_size : SensorSize

    Returns
    -------
    dict
        As :func:`regions_from_delays` plus ``"truth_lifetime_us": {region: float}``.
        Rows whose median true lifetime is the longest of the two distinct
        values (rounded to 1 us) form ``slow``, the others ``fast``; with other
        than two distinct values, 2-means on their log10 decides.
    """
    tr = np.asarray(truth_lifetime_us, dtype=np.float64)
    if tr.shape != events.shape:
        raise ValueError(f"regions_from_truth: truth_lifetime_us {tr.shape} and events {events.shape} differ")
    h = int(sensor_size.height)
    ok = np.isfinite(tr) & (tr > 0)
    y = events["y"][ok].astype(np.int64)
    tv = tr[ok]
    row_med = np.full(h, np.nan)
    for r in np.unique(y):
        row_med[r] = np.round(np.median(tv[y == r]))
    use = np.flatnonzero(np.isfinite(row_med))
    if use.size < 2:
        raise NoRegionsError("regions_from_truth: fewer than 2 rows with a true lifetime")
    thr, upper = _split_rows(np.log10(row_med[use]), "regions_from_truth")
    rows = {"slow": use[upper].tolist(), "fast": use[~upper].tolist()}
    truth = {k: float(np.median(tv[np.isin(y, r)])) for k, r in rows.items()}
    return {"method": TRUTH_METHOD, "from_truth": True, "rows": rows,
            "row_median_truth_us": [None if not np.isfinite(v) else float(v) for v in row_med],
            "threshold_delay_us": float(10.0 ** thr), "truth_lifetime_us": truth}


def row_agreement(a: dict, b: dict) -> float:
    """Share of the rows labelled by both region sets that get the same label."""
    lab_a = {r: k for k, rows in a["rows"].items() for r in rows}
    lab_b = {r: k for k, rows in b["rows"].items() for r in rows}
    both = set(lab_a) & set(lab_b)
    if not both:
        return float("nan")
    return float(np.mean([lab_a[r] == lab_b[r] for r in both]))
