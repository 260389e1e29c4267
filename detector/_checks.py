"""Input checks shared by the detector's public functions (never inside numba)."""

from __future__ import annotations

import numpy as np

from evedge._validate import check_positive  # noqa: F401  (the detector's parameter classes import it from here)
from evedge.events import SensorSize, validate_events

from .result import LIFETIME_DTYPE

#: "This pixel never fired": the SAE and edge maps use it instead of 0, which is a valid time.
NEVER_US = np.iinfo(np.int64).min


def check_sensor_size(sensor_size, name: str = "sensor_size") -> SensorSize:
    """Accept a :class:`SensorSize` or a ``(width, height)`` pair."""
    if isinstance(sensor_size, SensorSize):
        return sensor_size
    if isinstance(sensor_size, str):
        return SensorSize.parse(sensor_size)
    if isinstance(sensor_size, (tuple, list)) and len(sensor_size) == 2:
        return SensorSize(*sensor_size)
    raise TypeError(f"{name}: expected SensorSize or (width, height), got {sensor_size!r}")


def check_events(events, sensor_size: SensorSize, name: str = "events") -> np.ndarray:
    """Convert to the event dtype (losslessly, :func:`evedge.events.as_events`), check range and order.

    The detector's one validation point: callers must use the returned array,
    which is ``events`` itself when it already has :data:`~evedge.events.EVENT_DTYPE`.
    """
    return validate_events(events, sensor_size, name=name)


def check_not_before(events: np.ndarray, last_t_us: int | None, name: str = "events") -> None:
    """A chunk must not start before the previous chunk ended (streams are time-sorted)."""
    if last_t_us is not None and events.size and int(events["t"][0]) < last_t_us:
        raise ValueError(
            f"{name}: chunk starts at t={int(events['t'][0])} us, before the previous chunk's last "
            f"event at t={last_t_us} us; chunks must arrive in time order"
        )


def check_lifetimes(lifetimes, n: int, name: str = "lifetimes") -> np.ndarray:
    """A :data:`LIFETIME_DTYPE` array of length ``n``."""
    if not isinstance(lifetimes, np.ndarray) or lifetimes.dtype != LIFETIME_DTYPE:
        got = getattr(lifetimes, "dtype", type(lifetimes).__name__)
        raise TypeError(f"{name}: expected a structured array of dtype {LIFETIME_DTYPE}, got {got}")
    if lifetimes.shape != (n,):
        raise ValueError(f"{name}: expected shape ({n},) aligned with the events, got {lifetimes.shape}")
    return lifetimes


def columns(events: np.ndarray):
    """Contiguous plain columns for numba: x, y (int64), t (int64), p (int64 0/1)."""
    return (
        np.ascontiguousarray(events["x"], dtype=np.int64),
        np.ascontiguousarray(events["y"], dtype=np.int64),
        np.ascontiguousarray(events["t"], dtype=np.int64),
        np.ascontiguousarray(events["p"], dtype=np.int64),
    )
