"""The one event type of the project, its sensor size and its containers.

Events are a numpy structured array with the field names and types of tonic's
``events_struct``: ``x`` and ``y`` (int16, pixel column and row, images are
indexed ``[y, x]``), ``t`` (int64, microseconds) and ``p`` (bool, True = ON,
brightness up). Everything in evedge takes and returns this array; numba
kernels receive its columns as plain contiguous 1-D arrays.

References
----------
.. [1] G. Lenz et al., "Tonic: event-based datasets and transformations",
       https://github.com/neuromorphs/tonic (``tonic.io.events_struct``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .sensors import SENSOR_MODELS

#: The event dtype, identical to ``tonic.io.events_struct``.
EVENT_DTYPE = np.dtype([("x", np.int16), ("y", np.int16), ("t", np.int64), ("p", bool)])


@dataclass(frozen=True)
class SensorSize:
    """Sensor size in pixels: ``width`` columns (x) by ``height`` rows (y)."""

    width: int
    height: int

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise TypeError(f"SensorSize.{name} must be an integer, got {value!r}")
            if not 1 <= int(value) <= 32767:
                raise ValueError(f"SensorSize.{name} must be in 1..32767, got {value}")
            object.__setattr__(self, name, int(value))

    @property
    def shape(self) -> tuple[int, int]:
        """Image shape ``(height, width)``."""
        return (self.height, self.width)

    def as_tonic(self) -> tuple[int, int, int]:
        """tonic's ``sensor_size`` convention ``(width, height, polarities)``."""
        return (self.width, self.height, 2)

    @classmethod
    def parse(cls, text: str) -> "SensorSize":
        """Parse ``"240x180"`` or a preset name (``dvs128``, ``davis346``, ``gen4``, ... see :mod:`evedge.sensors`)."""
        key = text.strip().lower()
        if key in SENSOR_PRESETS:
            return SENSOR_PRESETS[key]
        parts = key.split("x")
        if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
            raise ValueError(
                f"sensor size {text!r}: expected WIDTHxHEIGHT (e.g. 240x180) or one of "
                f"{sorted(SENSOR_PRESETS)}"
            )
        return cls(int(parts[0]), int(parts[1]))


#: Sensor sizes by preset name (the presets themselves: :data:`evedge.sensors.SENSOR_MODELS`).
SENSOR_PRESETS = {name: SensorSize(m.width, m.height) for name, m in SENSOR_MODELS.items()}


def make_events(x, y, t, p) -> np.ndarray:
    """Build an event array from columns.

    Parameters
    ----------
    x, y : array_like of int
        Pixel column and row.
    t : array_like of int
        Timestamps in microseconds (integers; use :func:`seconds_to_us` first
        for float seconds).
    p : array_like
        Polarity: bool, {0, 1} or {-1, +1}; anything > 0 is ON.

    Returns
    -------
    numpy.ndarray
        Structured array of dtype :data:`EVENT_DTYPE`.
    """
    cols = [np.asarray(c) for c in (x, y, t, p)]
    n = cols[0].shape[0] if cols[0].ndim else 1
    for name, c in zip("xytp", cols):
        if c.ndim != 1 or c.shape[0] != n:
            raise ValueError(f"make_events: column {name!r} must be 1-D of length {n}, got shape {c.shape}")
        if c.dtype.kind == "f" and not np.all(np.isfinite(c)):
            bad = int(np.flatnonzero(~np.isfinite(c))[0])
            raise ValueError(f"make_events: column {name!r} has a non-finite value at index {bad}")
        if name != "p" and c.dtype.kind == "f" and np.any(c != np.round(c)):
            bad = int(np.flatnonzero(c != np.round(c))[0])
            raise ValueError(f"make_events: column {name!r} must hold integers, index {bad} is {c[bad]}")
    out = np.empty(n, dtype=EVENT_DTYPE)
    for name in "xy":
        c = cols["xy".index(name)]
        if c.size and (c.min() < -32768 or c.max() > 32767):
            raise ValueError(f"make_events: column {name!r} out of int16 range")
        out[name] = c
    t = cols[2]
    # a float beyond +-2**63 or a uint64 above int64 max would wrap silently in the cast
    if t.size and ((t.dtype.kind == "f" and np.abs(t).max() >= 2.0**63)
                   or (t.dtype.kind == "u" and int(t.max()) > np.iinfo(np.int64).max)):
        raise ValueError("make_events: column 't' out of int64 range")
    out["t"] = t
    out["p"] = cols[3] > 0
    return out


def seconds_to_us(t_s) -> np.ndarray:
    """Convert seconds (float) to int64 microseconds, rounding to nearest.

    Raises
    ------
    ValueError
        On a non-finite value, or one whose microseconds do not fit int64
        (about +-292,000 years), naming its index.
    """
    t_s = np.asarray(t_s, dtype=np.float64)
    if not np.all(np.isfinite(t_s)):
        bad = int(np.flatnonzero(~np.isfinite(t_s))[0])
        raise ValueError(f"timestamps: non-finite value at index {bad}")
    t_us = np.rint(t_s * 1e6)
    # 2**63 is exact in float64; beyond it the cast to int64 silently wraps
    big = np.flatnonzero(np.abs(t_us) >= 2.0**63)
    if big.size:
        bad = int(big[0])
        raise ValueError(f"timestamps: value {float(t_s.flat[bad])!r} s at index {bad} is out of the int64 microsecond range")
    return t_us.astype(np.int64)


def find_out_of_sensor(x, y, sensor_size: SensorSize) -> tuple[str, int, int] | None:
    """The first coordinate outside ``sensor_size``, x checked before y.

    Parameters
    ----------
    x, y : array_like of int
        Pixel columns and rows (event columns, or raw columns before
        :func:`make_events`).
    sensor_size : SensorSize

    Returns
    -------
    tuple of (str, int, int) or None
        ``(axis, index, count)``: the axis name (``"x"`` or ``"y"``), the
        index of its first out-of-range value and how many values of that
        axis are out of range; None when every coordinate is inside.
    """
    for axis, col, limit in (("x", x, sensor_size.width), ("y", y, sensor_size.height)):
        col = np.asarray(col)
        bad = np.flatnonzero((col < 0) | (col >= limit))
        if bad.size:
            return axis, int(bad[0]), int(bad.size)
    return None


def find_time_decrease(t) -> tuple[int, int] | None:
    """The first timestamp earlier than the one before it.

    Parameters
    ----------
    t : array_like of int
        Timestamps (microseconds).

    Returns
    -------
    tuple of (int, int) or None
        ``(index, count)``: the index ``i`` of the first ``t[i] < t[i - 1]``
        and the number of such decreases; None when ``t`` is non-decreasing.
    """
    t = np.asarray(t)
    # compare neighbours, not np.diff: a difference of extreme int64 values wraps around
    dec = np.flatnonzero(t[1:] < t[:-1])
    if dec.size:
        return int(dec[0]) + 1, int(dec.size)
    return None


def validate_events(events: np.ndarray, sensor_size: SensorSize | None = None, *, name: str = "events") -> np.ndarray:
    """Check an event array and return it unchanged.

    Parameters
    ----------
    events : numpy.ndarray
        Events of :data:`EVENT_DTYPE`, 1-D.
    sensor_size : SensorSize, optional
        When given, every ``x`` must lie in ``[0, width)`` and ``y`` in ``[0, height)``.
    name : str
        What to call the array in messages.

    Returns
    -------
    numpy.ndarray
        ``events`` itself.

    Raises
    ------
    TypeError
        When ``events`` is not a structured array of :data:`EVENT_DTYPE`.
    ValueError
        When coordinates fall outside ``sensor_size`` or timestamps decrease
        (call :func:`sort_events` to sort explicitly). The message names
        ``name`` and the first offending index.
    """
    if not isinstance(events, np.ndarray) or events.dtype != EVENT_DTYPE:
        got = getattr(events, "dtype", type(events).__name__)
        raise TypeError(f"{name}: expected a structured array of dtype {EVENT_DTYPE}, got {got}")
    if events.ndim != 1:
        raise ValueError(f"{name}: expected a 1-D event array, got shape {events.shape}")
    if events.size == 0:
        return events
    outside = find_out_of_sensor(events["x"], events["y"], sensor_size) if sensor_size is not None else None
    if outside is not None:
        axis, i, count = outside
        raise ValueError(
            f"{name}: event {i} has {axis}={int(events[axis][i])} outside the sensor "
            f"({sensor_size.width}x{sensor_size.height}); {count} events out of range"
        )
    decrease = find_time_decrease(events["t"])
    if decrease is not None:
        i, count = decrease
        raise ValueError(
            f"{name}: timestamps are not sorted: event {i} has t={int(events['t'][i])} us < "
            f"t={int(events['t'][i - 1])} us of event {i - 1} ({count} decreases); "
            f"use evedge.events.sort_events to sort explicitly"
        )
    return events


def sort_events(events: np.ndarray) -> np.ndarray:
    """Return the events sorted by time (stable: equal timestamps keep their order).

    Parameters
    ----------
    events : numpy.ndarray
        Events of :data:`EVENT_DTYPE`.

    Returns
    -------
    numpy.ndarray
        A sorted copy.
    """
    return events[np.argsort(events["t"], kind="stable")]


@dataclass
class Frames:
    """A stack of images with timestamps.

    Attributes
    ----------
    t_us : numpy.ndarray
        int64 timestamps in microseconds, shape (n,).
    images : numpy.ndarray
        Shape (n, height, width): grey frames (uint8 or float in [0, 1]) or
        boolean edge maps.
    """

    t_us: np.ndarray
    images: np.ndarray

    def __post_init__(self) -> None:
        self.t_us = np.asarray(self.t_us, dtype=np.int64)
        self.images = np.asarray(self.images)
        if self.t_us.ndim != 1 or self.images.ndim != 3 or self.images.shape[0] != self.t_us.shape[0]:
            raise ValueError(
                f"Frames: t_us of shape {self.t_us.shape} and images of shape {self.images.shape} "
                "do not match (expected (n,) and (n, height, width))"
            )

    def __len__(self) -> int:
        return int(self.t_us.shape[0])


@dataclass
class Recording:
    """Events with everything that may come with them.

    Attributes
    ----------
    events : numpy.ndarray
        Events of dtype :data:`EVENT_DTYPE`, sorted by time.
    sensor_size : SensorSize
    frames : Frames or None
        Grey frames (real APS frames, or the simulator's clean renders).
    truth : numpy.ndarray or None
        Per-event ground truth (structured, one row per event), from the simulator.
    edges : Frames or None
        Exact edge maps (boolean images) with their timestamps, from the simulator.
    metadata : dict
        JSON-serialisable facts: source file, how the sensor size was found, scene, versions.
    """

    events: np.ndarray
    sensor_size: SensorSize
    frames: Frames | None = None
    truth: np.ndarray | None = None
    edges: Frames | None = None
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        validate_events(self.events, self.sensor_size)
        if self.truth is not None and self.truth.shape != self.events.shape:
            raise ValueError(
                f"Recording: truth has {self.truth.shape[0]} rows but there are {self.events.shape[0]} events"
            )
        for label, stack in (("frames", self.frames), ("edges", self.edges)):
            if stack is not None and stack.images.shape[1:] != self.sensor_size.shape:
                raise ValueError(
                    f"Recording: {label} are {stack.images.shape[2]}x{stack.images.shape[1]} but the "
                    f"sensor is {self.sensor_size.width}x{self.sensor_size.height}"
                )
