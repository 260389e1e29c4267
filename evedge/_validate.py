"""Field checks of the frozen parameter dataclasses, defined once (used by their ``__post_init__``).

Every check names the field as ``Owner.field`` and raises ``TypeError`` for a
value of the wrong kind, ``ValueError`` for one out of range; the ``check_*``
functions that convert return the value as the field stores it.

Examples
--------
>>> check_finite("Lens", "fx_px", 3)
3.0
>>> check_positive("Lens", "fx_px", 0)
Traceback (most recent call last):
...
ValueError: Lens.fx_px must be > 0, got 0
>>> check_real("Lens", "k", 2.0, 0.0, 1.0, low_open=True, high_open=False)
Traceback (most recent call last):
...
ValueError: Lens.k must be in (0.0, 1.0], got 2.0
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["check_bool", "check_finite", "check_integer", "check_number", "check_positive", "check_real"]


def check_number(owner: str, name: str, value) -> None:
    """``TypeError`` unless ``value`` is an int or a float (Python or NumPy; a bool is not a number)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{owner}.{name} must be a number, got {value!r}")


def _check_finite(owner: str, name: str, value) -> None:
    # Python ints may exceed every float/int64 (np.isfinite would fail on them); they are finite
    if not isinstance(value, (int, np.integer)) and not np.isfinite(value):
        raise ValueError(f"{owner}.{name} must be finite, got {value!r}")


def check_finite(owner: str, name: str, value) -> float:
    """A finite number, as a float."""
    check_number(owner, name, value)
    _check_finite(owner, name, value)
    return float(value)


def check_positive(owner: str, name: str, value, *, integer: bool = False, allow_zero: bool = False) -> None:
    """Raise a clear error unless ``value`` is a finite positive (or non-negative) number."""
    check_number(owner, name, value)
    if integer and not float(value).is_integer():
        raise TypeError(f"{owner}.{name} must be an integer, got {value!r}")
    _check_finite(owner, name, value)
    if value < 0 or (value == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{owner}.{name} must be {bound}, got {value!r}")


def check_real(owner: str, name: str, value, low: float, high: float, *, low_open: bool, high_open: bool) -> float:
    """A real number in the interval from ``low`` to ``high`` (each end open or closed), as a float."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{owner}.{name} must be a real number, got {value!r}")
    v = float(value)
    lo_bad = v <= low if low_open else v < low
    hi_bad = v >= high if high_open else v > high
    if not math.isfinite(v) or lo_bad or hi_bad:
        lo = "(" if low_open else "["
        hi = ")" if high_open else "]"
        raise ValueError(f"{owner}.{name} must be in {lo}{low}, {high}{hi}, got {value!r}")
    return v


def check_integer(owner: str, name: str, value) -> None:
    """``TypeError`` unless ``value`` is an int (Python or NumPy; a bool is not one)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{owner}.{name} must be an integer, got {value!r}")


def check_bool(owner: str, name: str, value) -> None:
    """``TypeError`` unless ``value`` is a bool (Python or NumPy)."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{owner}.{name} must be a bool, got {value!r}")
