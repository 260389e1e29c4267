"""detector._borrow: an array without a reference count is the same memory, shape and strides."""

import numpy as np
import pytest
from numba import njit
from numba.core.errors import TypingError

from evedge.detector._borrow import _borrowed


@njit(cache=False)
def _write_through(a, v):
    b = _borrowed(a)
    b[1] = v  # the original's memory
    return b.shape[0], b.strides[0], b[0], b.sum()


@njit(cache=False)
def _not_an_array(x):
    return _borrowed(x)


def test_borrowed_array_is_the_same_memory():
    a = np.arange(10.0)
    n, stride, first, total = _write_through(a, 100.0)
    assert a[1] == 100.0 and (n, stride, first) == (10, 8, 0.0) and total == a.sum()
    view = np.arange(20, dtype=np.int64)[::3]  # a strided view: its strides are kept
    n, stride, first, total = _write_through(view, -1)
    assert view[1] == -1 and (n, stride) == (view.shape[0], 24) and total == view.sum()
    with pytest.raises(TypingError):
        _not_an_array(3.0)
