"""Closest Distance Metric (CDM) between two binary edge maps.

The similarity of Prieto & Allen (2003) as the BMVC 2019 paper uses it
(its equation 6):

    CDM_eta(f, g) = 100 (1 - C(M_cd(f, g)) / |f union g|)

``f`` and ``g`` are boolean edge maps on one pixel grid.

* ``|f union g|`` is the number of pixel positions that are edge in ``f`` or
  in ``g`` (a set on the common grid: a pixel that is edge in both counts once).
* ``M_cd(f, g)`` is a one-to-one matching between the edge pixels of ``f`` and
  those of ``g``; a pair may be matched only when its chessboard (8-connected)
  distance ``d = max(|dx|, |dy|)`` is at most ``eta`` (3).
* ``C`` charges a matched pair ``1 - w(d)`` with the weights
  ``w = (1, 0.9, 0.69, 0.5)`` for ``d = 0..3`` (those of the authors'
  evaluation code) and every unmatched edge pixel, of either map, 1.

Which matching? The authors' code matched "closest first" greedily; its result
depends on the order in which ties are broken (a line shifted by one pixel can
score 9.5 or 95). Here ``M_cd`` is the matching of minimum total cost ``C``
(an optimal assignment), which is unique in its cost, symmetric in ``f`` and
``g`` and never worse than any greedy order. Each matched pair replaces two
unmatched pixels (cost 2) by ``1 - w(d) <= 0.5``, so the optimal matching is
the maximum-weight matching with pair weight ``1 + w(d)``; it is solved exactly
with SciPy's sparse Jonker-Volgenant solver (LAPJVsp) on the graph of pairs
within ``eta``, with one "unmatched" option per pixel of ``f``.

Since the optimal ``C`` is at most the cost of matching only the common pixels
to themselves, ``C <= |f union g|`` and ``0 <= CDM <= 100``.

Empty maps: when both maps are empty there is nothing to disagree about and
CDM is 100 (defined); when exactly one is empty, every pixel of the other is
unmatched and CDM is 0 (this is also what the formula gives).

References
----------
.. [1] M. S. Prieto and A. R. Allen, "A similarity metric for edge images",
       IEEE TPAMI 25(10), 2003.
.. [2] S. Lee, H. Kim and H. J. Kim, "Edge Detection for Event Cameras using
       Intra-pixel-area Events", BMVC 2019, section 3.2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_array
from scipy.sparse.csgraph import min_weight_full_bipartite_matching

#: Match weights of the authors' evaluation code for chessboard distance 0..3.
DEFAULT_WEIGHTS = (1.0, 0.9, 0.69, 0.5)


@dataclass(frozen=True)
class CDMResult:
    """The CDM score with the numbers it is made of.

    Attributes
    ----------
    score : float
        CDM in [0, 100] (100 = identical).
    cost : float
        ``C``: sum of ``1 - w(d)`` over matched pairs plus the unmatched count.
    union : int
        ``|f union g|``.
    n_matched : int
        Number of matched pairs.
    n_unmatched_f, n_unmatched_g : int
        Edge pixels of ``f`` (of ``g``) left unmatched.
    matched_distance_counts : tuple of int
        Number of matched pairs at chessboard distance 0, 1, ..., eta.
    """

    score: float
    cost: float
    union: int
    n_matched: int
    n_unmatched_f: int
    n_unmatched_g: int
    matched_distance_counts: tuple[int, ...]


def _check_map(name: str, m) -> np.ndarray:
    m = np.asarray(m)
    if m.ndim != 2:
        raise ValueError(f"cdm: {name} must be a 2-D edge map, got shape {m.shape}")
    if m.dtype != bool:
        if m.dtype.kind not in "biuf":
            raise TypeError(f"cdm: {name} must be boolean (or 0/1 numbers), got dtype {m.dtype}")
        if not np.all((m == 0) | (m == 1)):
            raise ValueError(f"cdm: {name} must hold only 0/1 (or bool) values")
        m = m.astype(bool)
    return m


def _check_weights(eta: int, weights) -> np.ndarray:
    if isinstance(eta, bool) or not isinstance(eta, (int, np.integer)) or eta < 0:
        raise ValueError(f"cdm: eta must be a non-negative integer, got {eta!r}")
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or w.shape[0] != eta + 1:
        raise ValueError(f"cdm: weights must have eta + 1 = {eta + 1} entries, got {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0) or np.any(w > 1):
        raise ValueError(f"cdm: weights must lie in [0, 1], got {weights!r}")
    return w


def _candidate_pairs(f: np.ndarray, g: np.ndarray, eta: int):
    """All (i, j, d) with pixel i of f and pixel j of g at chessboard distance d <= eta."""
    h, w = f.shape
    id_g = np.full(f.shape, -1, dtype=np.int64)
    id_g[g] = np.arange(int(g.sum()))
    fy, fx = np.nonzero(f)
    fi = np.arange(fy.shape[0])
    rows, cols, dists = [], [], []
    for dy in range(-eta, eta + 1):
        for dx in range(-eta, eta + 1):
            ty, tx = fy + dy, fx + dx
            inside = (ty >= 0) & (ty < h) & (tx >= 0) & (tx < w)
            j = np.full(fy.shape[0], -1, dtype=np.int64)
            j[inside] = id_g[ty[inside], tx[inside]]
            hit = j >= 0
            rows.append(fi[hit])
            cols.append(j[hit])
            dists.append(np.full(int(hit.sum()), max(abs(dx), abs(dy)), dtype=np.int64))
    return np.concatenate(rows), np.concatenate(cols), np.concatenate(dists)


def cdm_details(f, g, *, eta: int = 3, weights=DEFAULT_WEIGHTS) -> CDMResult:
    """Closest Distance Metric with its parts (see the module docstring).

    Parameters
    ----------
    f, g : array_like of bool, shape (H, W)
        Edge maps on the same grid.
    eta : int
        Neighbourhood radius (chessboard distance) within which pixels may match.
    weights : sequence of float, length ``eta + 1``
        Match weight per chessboard distance; a match costs ``1 - weight``.

    Returns
    -------
    CDMResult
    """
    f = _check_map("f", f)
    g = _check_map("g", g)
    if f.shape != g.shape:
        raise ValueError(f"cdm: f and g must have the same shape, got {f.shape} and {g.shape}")
    w = _check_weights(eta, weights)
    nf, ng = int(f.sum()), int(g.sum())
    union = int(np.count_nonzero(f | g))
    zero_counts = (0,) * (eta + 1)
    if nf == 0 and ng == 0:
        return CDMResult(100.0, 0.0, 0, 0, 0, 0, zero_counts)
    if nf == 0 or ng == 0:
        return CDMResult(0.0, float(nf + ng), union, 0, nf, ng, zero_counts)

    # The metric is symmetric; put the smaller map on the rows (fewer nodes).
    swapped = nf > ng
    if swapped:
        f, g, nf, ng = g, f, ng, nf
    rows, cols, dists = _candidate_pairs(f, g, eta)
    # Rows: pixels of f. Columns: pixels of g, then one "unmatched" column per
    # pixel of f. A full matching covers every row. Minimising
    #   sum_pairs (2 - w(d)) + 3 * (#f unmatched)  =  3 nf - sum_pairs (1 + w(d))
    # maximises the total pair weight 1 + w(d), i.e. minimises C; the +2 shift
    # keeps every weight non-zero, as the solver requires.
    pair_weight = 2.0 - w[dists]
    all_rows = np.concatenate([rows, np.arange(nf)])
    all_cols = np.concatenate([cols, ng + np.arange(nf)])
    all_w = np.concatenate([pair_weight, np.full(nf, 3.0)])
    graph = coo_array((all_w, (all_rows, all_cols)), shape=(nf, ng + nf)).tocsr()
    r, c = min_weight_full_bipartite_matching(graph)
    real = c < ng
    r, c = r[real], c[real]
    # distance of each chosen pair: look it up among the candidates
    key_cand = rows * ng + cols
    order = np.argsort(key_cand)
    pos = np.searchsorted(key_cand[order], r * ng + c)
    d = dists[order][pos]
    n_matched = int(r.shape[0])
    counts = tuple(int(k) for k in np.bincount(d, minlength=eta + 1))
    cost = float(np.sum(1.0 - w[d])) + (nf - n_matched) + (ng - n_matched)
    score = 100.0 * (1.0 - cost / union)
    unmatched_f, unmatched_g = nf - n_matched, ng - n_matched
    if swapped:
        unmatched_f, unmatched_g = unmatched_g, unmatched_f
    return CDMResult(score, cost, union, n_matched, unmatched_f, unmatched_g, counts)


def cdm(f, g, *, eta: int = 3, weights=DEFAULT_WEIGHTS) -> float:
    """Closest Distance Metric ``CDM_eta(f, g)`` in [0, 100] (100 = identical).

    Parameters
    ----------
    f, g : array_like of bool, shape (H, W)
        Edge maps on the same grid.
    eta : int
        Neighbourhood radius (chessboard distance), 3 as in the paper.
    weights : sequence of float, length ``eta + 1``
        Match weight for chessboard distance 0..eta; default (1, 0.9, 0.69, 0.5).

    Returns
    -------
    float
        See the module docstring for the exact definition (optimal one-to-one
        matching, union as a pixel set, empty maps).

    References
    ----------
    .. [1] Prieto & Allen, TPAMI 2003; Lee, Kim & Kim, BMVC 2019, eq. 6.
    """
    return cdm_details(f, g, eta=eta, weights=weights).score
