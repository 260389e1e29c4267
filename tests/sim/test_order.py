"""The flush order kernel equals numpy's stable sort of the combined key."""

import numpy as np
import pytest

from evedge.sim._order import _time_pixel_order


@pytest.mark.parametrize("n, npix, span", [(0, 5, 1), (1, 5, 1), (2000, 64, 30), (5000, 1000, 5000)])
def test_time_pixel_order_is_the_stable_argsort(n, npix, span):
    rng = np.random.default_rng(n)
    t_us = rng.integers(10_000, 10_000 + span, n).astype(np.int64)
    pix = rng.integers(0, npix, n).astype(np.int64)
    order = np.empty(n, dtype=np.int64)
    ties = _time_pixel_order(t_us, pix, npix, order)
    key = t_us * npix + pix
    want = np.argsort(key, kind="stable")
    np.testing.assert_array_equal(order, want)
    assert ties == bool(np.any(np.diff(key[want]) == 0))
