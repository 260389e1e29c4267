"""detector._prefetch: a cache hint that compiles to ``llvm.prefetch``, changes no value and never faults."""

import numpy as np
import pytest
from numba import njit
from numba.core.errors import TypingError

from evedge.detector._prefetch import _prefetch


@njit(cache=False)
def _hinted_sum(a, offsets):
    s = 0.0
    for i in range(a.shape[0]):
        for o in offsets:
            _prefetch(a, i + o)  # far outside the array too: only hinted, never read
        s += a[i]
    return s


@njit(cache=False)
def _not_an_array(x):
    _prefetch(x, 0)


def test_prefetch_is_a_hint():
    a = np.arange(1000.0)
    offsets = np.array([0, 4, 999, 10**9, -(10**9)], np.int64)
    assert _hinted_sum(a, offsets) == a.sum()
    ir = next(iter(_hinted_sum.inspect_llvm().values()))
    assert "llvm.prefetch" in ir  # the hint is emitted, not dropped
    small = np.zeros(3, np.int8)
    assert _hinted_sum(small, offsets) == 0.0 and not small.any()


def test_prefetch_refuses_a_non_array():
    with pytest.raises(TypingError):
        _not_an_array(3.0)
