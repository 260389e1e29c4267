"""The shared field checks of evedge/_validate.py: kinds, bounds, the field named in the message."""

import doctest
import math

import numpy as np
import pytest

from evedge import _validate
from evedge._validate import check_bool, check_finite, check_integer, check_positive, check_real


def test_docstring_examples():
    assert doctest.testmod(_validate).failed == 0


@pytest.mark.parametrize("value", [True, "1", None, [1.0]])
def test_not_a_number_is_a_type_error(value):
    with pytest.raises(TypeError, match=r"^P\.f must be a number"):
        check_finite("P", "f", value)
    with pytest.raises(TypeError, match=r"^P\.f must be a number"):
        check_positive("P", "f", value)


def test_finite_and_positive():
    assert check_finite("P", "f", np.int64(-3)) == -3.0 and isinstance(check_finite("P", "f", 2), float)
    assert check_finite("P", "f", 10**400 // 10**399) == 10.0
    for bad in (math.nan, math.inf, np.float32("-inf")):
        with pytest.raises(ValueError, match=r"^P\.f must be finite"):
            check_finite("P", "f", bad)
    check_positive("P", "f", 10**30, integer=True)  # a Python int beyond int64 is finite
    check_positive("P", "f", 0, allow_zero=True)
    with pytest.raises(ValueError, match=r"^P\.f must be > 0, got 0$"):
        check_positive("P", "f", 0)
    with pytest.raises(ValueError, match=r"^P\.f must be >= 0, got -0\.5$"):
        check_positive("P", "f", -0.5, allow_zero=True)
    with pytest.raises(TypeError, match=r"^P\.f must be an integer, got 2\.5$"):
        check_positive("P", "f", 2.5, integer=True)


def test_real_interval_ends():
    assert check_real("P", "r", 0, 0.0, 1.0, low_open=False, high_open=True) == 0.0
    for value, lo_open, hi_open in ((0.0, True, False), (1.0, False, True), (math.nan, False, False), (2, False, False)):
        with pytest.raises(ValueError, match=r"^P\.r must be in "):
            check_real("P", "r", value, 0.0, 1.0, low_open=lo_open, high_open=hi_open)
    with pytest.raises(TypeError, match=r"^P\.r must be a real number, got True$"):
        check_real("P", "r", True, 0.0, 1.0, low_open=False, high_open=False)


def test_integer_and_bool():
    check_integer("P", "n", np.uint8(3))
    for bad in (True, 3.0, "3"):
        with pytest.raises(TypeError, match=r"^P\.n must be an integer"):
            check_integer("P", "n", bad)
    check_bool("P", "b", np.bool_(False))
    for bad in (0, 1.0, "yes", None):
        with pytest.raises(TypeError, match=r"^P\.b must be a bool"):
            check_bool("P", "b", bad)
