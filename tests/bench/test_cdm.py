"""Known answers for the Closest Distance Metric."""


import numpy as np
import pytest

from evedge.bench.cdm import DEFAULT_WEIGHTS, cdm, cdm_details


def brute_force_cdm(f, g, eta=3, weights=DEFAULT_WEIGHTS):
    """Exhaustive minimum-cost one-to-one matching (tiny maps only)."""
    fp = list(zip(*np.nonzero(f)))
    gp = list(zip(*np.nonzero(g)))
    union = int(np.count_nonzero(f | g))
    if not fp and not gp:
        return 100.0
    best = [float("inf")]

    def rec(i, used, cost):
        if cost >= best[0]:
            return
        if i == len(fp):
            total = cost + (len(gp) - len(used))
            best[0] = min(best[0], total)
            return
        rec(i + 1, used, cost + 1.0)  # f pixel i unmatched
        for j, q in enumerate(gp):
            if j in used:
                continue
            d = max(abs(fp[i][0] - q[0]), abs(fp[i][1] - q[1]))
            if d <= eta:
                rec(i + 1, used | {j}, cost + 1.0 - weights[d])

    rec(0, frozenset(), 0.0)
    return 100.0 * (1.0 - best[0] / union)


def test_identical_maps_score_100():
    rng = np.random.default_rng(1)
    f = rng.random((40, 50)) < 0.1
    assert cdm(f, f) == 100.0


def test_disjoint_far_apart_maps_score_0():
    f = np.zeros((30, 30), bool)
    g = np.zeros((30, 30), bool)
    f[2, 2:10] = True
    g[20, 15:25] = True
    r = cdm_details(f, g)
    assert r.score == 0.0
    assert r.n_matched == 0 and r.cost == 18 and r.union == 18


@pytest.mark.parametrize("shift, weight", [(1, 0.9), (2, 0.69), (3, 0.5)])
def test_line_shifted_by_d_pixels(shift, weight):
    # A horizontal line of L pixels and the same line shifted down by `shift`:
    # every pixel matches its shifted twin at chessboard distance `shift`,
    # cost L (1 - w); union 2L; CDM = 100 (1 - (1 - w) / 2).
    length = 20
    f = np.zeros((20, 40), bool)
    g = np.zeros((20, 40), bool)
    f[5, 10:10 + length] = True
    g[5 + shift, 10:10 + length] = True
    expected = 100.0 * (1.0 - length * (1.0 - weight) / (2 * length))
    r = cdm_details(f, g)
    assert r.score == pytest.approx(expected, abs=1e-9)
    assert r.n_matched == length
    assert r.matched_distance_counts[shift] == length


def test_one_pixel_shift_is_95_not_greedy_dependent():
    f = np.zeros((10, 10), bool)
    g = np.zeros((10, 10), bool)
    f[4, 1:9] = True
    g[5, 1:9] = True
    assert cdm(f, g) == pytest.approx(95.0, abs=1e-9)


def test_beyond_eta_is_unmatched():
    f = np.zeros((20, 20), bool)
    g = np.zeros((20, 20), bool)
    f[5, 5] = True
    g[5, 9] = True  # chessboard distance 4 > eta = 3
    assert cdm(f, g) == 0.0
    assert cdm(f, g, eta=4, weights=(1, 0.9, 0.69, 0.5, 0.3)) == pytest.approx(100 * (1 - 0.7 / 2))


def test_partial_overlap_known_value():
    # f: 4 pixels; g: the same 4 plus 2 extra pixels far away.
    f = np.zeros((20, 20), bool)
    f[3, 3:7] = True
    g = f.copy()
    g[15, 15] = g[15, 17] = True
    # union 6, cost 2 (two unmatched), CDM = 100 (1 - 2 / 6)
    assert cdm(f, g) == pytest.approx(100 * (1 - 2 / 6))


def test_empty_maps():
    z = np.zeros((8, 8), bool)
    one = z.copy()
    one[3, 3] = True
    assert cdm(z, z) == 100.0
    assert cdm(z, one) == 0.0
    assert cdm(one, z) == 0.0


def test_symmetric_and_bounded_on_random_maps():
    rng = np.random.default_rng(7)
    for _ in range(20):
        f = rng.random((30, 30)) < rng.uniform(0.01, 0.3)
        g = rng.random((30, 30)) < rng.uniform(0.01, 0.3)
        a, b = cdm_details(f, g), cdm_details(g, f)
        assert a.score == pytest.approx(b.score, abs=1e-9)
        assert a.n_unmatched_f == b.n_unmatched_g and a.n_unmatched_g == b.n_unmatched_f
        assert 0.0 <= a.score <= 100.0


def test_matches_brute_force_on_tiny_random_maps():
    rng = np.random.default_rng(3)
    for _ in range(60):
        shape = (6, 7)
        f = np.zeros(shape, bool)
        g = np.zeros(shape, bool)
        for m in (f, g):
            k = int(rng.integers(0, 6))
            idx = rng.choice(m.size, size=k, replace=False)
            m.flat[idx] = True
        assert cdm(f, g) == pytest.approx(brute_force_cdm(f, g), abs=1e-9)


def test_optimal_beats_a_bad_greedy_order():
    # f pixel A at (0,1) could take g's (0,0) or (0,2); B at (0,3) only (0,2).
    # Optimal: A-(0,0) d=1, B-(0,2) d=1 -> cost 0.2, union 4 -> 95.
    f = np.zeros((5, 8), bool)
    g = np.zeros((5, 8), bool)
    f[0, 1] = f[0, 3] = True
    g[0, 0] = g[0, 2] = True
    assert cdm(f, g) == pytest.approx(100 * (1 - 0.2 / 4))


def test_input_checks():
    with pytest.raises(ValueError, match="same shape"):
        cdm(np.zeros((3, 3), bool), np.zeros((3, 4), bool))
    with pytest.raises(ValueError, match="2-D"):
        cdm(np.zeros(3, bool), np.zeros(3, bool))
    with pytest.raises(ValueError, match="0/1"):
        cdm(np.full((3, 3), 2), np.zeros((3, 3), bool))
    with pytest.raises(ValueError, match="weights"):
        cdm(np.zeros((3, 3), bool), np.zeros((3, 3), bool), eta=2)
    # 0/1 integers are accepted
    assert cdm(np.eye(4, dtype=int), np.eye(4, dtype=bool)) == 100.0
