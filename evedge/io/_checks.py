"""Shared checks of the readers: one error type, sensor range and time order.

Every reader turns raw columns into events through :func:`finish_events`, so
the messages for out-of-sensor coordinates and unsorted timestamps read the
same for every format and always name the file and the line (text) or the
event index (binary formats).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..events import SensorSize, find_out_of_sensor, find_time_decrease, make_events, sort_events


class EventFileError(ValueError):
    """A file that cannot be read as events; the message names the file and the place."""


def locate_index(i: int) -> str:
    """Describe event ``i`` of a binary file (0-based)."""
    return f"event index {i}"


def finish_events(
    path: Path,
    x: np.ndarray,
    y: np.ndarray,
    t_us: np.ndarray,
    p_on: np.ndarray,
    sensor_size: SensorSize,
    size_from: str,
    locate: Callable[[int], str],
    sort: bool,
) -> tuple[np.ndarray, bool]:
    """Check coordinates and time order, then build the event array.

    Parameters
    ----------
    path : Path
        The file, for messages.
    x, y, t_us, p_on : numpy.ndarray
        Integer-valued columns (already checked finite and integral) and
        boolean polarity.
    sensor_size : SensorSize
    size_from : str
        How the sensor size was found, quoted in the out-of-range message.
    locate : callable
        Maps an event index to a place in the file (``"line 12"``).
    sort : bool
        Sort stably by time instead of raising on decreasing timestamps.

    Returns
    -------
    events : numpy.ndarray
        Events of :data:`evedge.events.EVENT_DTYPE`.
    sorted_on_load : bool
        True when the events had to be sorted.
    """
    outside = find_out_of_sensor(x, y, sensor_size)
    if outside is not None:
        axis, i, count = outside
        col = np.asarray(x if axis == "x" else y)
        raise EventFileError(
            f"{path}: {locate(i)}: {axis}={int(col[i])} is outside the sensor "
            f"{sensor_size.width}x{sensor_size.height} (size from {size_from}); "
            f"{count} events out of range. If the size is wrong, pass the right one "
            f"(sensor_size=..., CLI: --sensor WxH)"
        )
    t_us = np.asarray(t_us)
    decrease = find_time_decrease(t_us)
    was_sorted = False
    events = make_events(x, y, t_us, p_on)
    if decrease is not None:
        i, count = decrease
        if not sort:
            raise EventFileError(
                f"{path}: {locate(i)}: timestamps are not sorted: t={int(t_us[i])} us is earlier "
                f"than t={int(t_us[i - 1])} us just before it ({count} decreases in the file); "
                f"pass sort=True to read_events (CLI: --sort) to sort stably by time on load"
            )
        events = sort_events(events)
        was_sorted = True
    return events, was_sorted
