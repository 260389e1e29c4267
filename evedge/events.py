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

from ._validate import check_integer
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
            check_integer("SensorSize", name, value)
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
        if col.size == 0 or (col.min() >= 0 and col.max() < limit):
            continue  # (two reductions, no temporary array: the common case)
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
    """Convert an event array to :data:`EVENT_DTYPE` (see :func:`as_events`) and check it.

    Parameters
    ----------
    events : numpy.ndarray
        1-D structured array with fields x, y, t, p: :data:`EVENT_DTYPE`, or
        any array :func:`as_events` converts losslessly (tonic, faery,
        dv-processing, other integer widths).
    sensor_size : SensorSize, optional
        When given, every ``x`` must lie in ``[0, width)`` and ``y`` in ``[0, height)``.
    name : str
        What to call the array in messages.

    Returns
    -------
    numpy.ndarray
        ``events`` itself when already of :data:`EVENT_DTYPE`, else the
        converted copy: callers must use the returned array.

    Raises
    ------
    TypeError
        When ``events`` is not a structured array with fields x, y, t, p.
    ValueError
        When the conversion would be lossy (see :func:`as_events`),
        coordinates fall outside ``sensor_size`` or timestamps decrease
        (call :func:`sort_events` to sort explicitly). The message names
        ``name`` and the first offending index.

    Examples
    --------
    >>> import numpy as np
    >>> faery_like = np.zeros(2, dtype=[("t", "<u8"), ("x", "<u2"), ("y", "<u2"), ("on", "?")])
    >>> validate_events(faery_like, SensorSize(4, 4)).dtype == EVENT_DTYPE
    True
    """
    events = as_events(events, name=name)
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
    calibration : evedge.calibration.CameraCalibration or None
        Intrinsics and distortion of the camera (an ECD folder's ``calib.txt``);
        see :func:`evedge.calibration.undistort_events`.
    maps : dict of str to Frames
        Per-frame ground-truth images by name, from the simulator's 3-D scenes: ``depth_m``
        (z-depth, inf where nothing is seen), ``flow_x_px_s`` and ``flow_y_px_s`` (motion field).
    imu : numpy.ndarray or None
        IMU truth rows (structured: ``t_us`` and readings, see ``evedge.sim.trajectory.IMU_DTYPE``).
    """

    events: np.ndarray
    sensor_size: SensorSize
    frames: Frames | None = None
    truth: np.ndarray | None = None
    edges: Frames | None = None
    metadata: dict[str, Any] = field(default_factory=dict)
    calibration: Any = None
    maps: dict[str, Frames] = field(default_factory=dict)
    imu: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.events = validate_events(self.events, self.sensor_size, name="Recording: events")
        if self.calibration is not None:
            from .calibration import CameraCalibration  # it imports this module

            if not isinstance(self.calibration, CameraCalibration):
                raise TypeError(f"Recording: calibration must be a CameraCalibration, got {type(self.calibration).__name__}")
        if self.truth is not None and self.truth.shape != self.events.shape:
            raise ValueError(
                f"Recording: truth has {self.truth.shape[0]} rows but there are {self.events.shape[0]} events"
            )
        if not isinstance(self.maps, dict) or not all(isinstance(m, Frames) for m in self.maps.values()):
            raise TypeError("Recording: maps must be a dict of name to Frames")
        if self.imu is not None and (self.imu.dtype.names is None or "t_us" not in self.imu.dtype.names):
            raise TypeError("Recording: imu must be a structured array with a t_us field")
        stacks = [("frames", self.frames), ("edges", self.edges)] + [(f"maps[{k!r}]", m) for k, m in self.maps.items()]
        for label, stack in stacks:
            if stack is not None and stack.images.shape[1:] != self.sensor_size.shape:
                raise ValueError(
                    f"Recording: {label} are {stack.images.shape[2]}x{stack.images.shape[1]} but the "
                    f"sensor is {self.sensor_size.width}x{self.sensor_size.height}"
                )


#: Field names taken as each event field, in order of preference: tonic and
#: Prophesee use ``x, y, t, p``; dv-processing ``timestamp`` and ``polarity``;
#: faery and the ``aedat`` package ``on`` (faery titles it ``p``).
FIELD_ALIASES = {
    "x": ("x",),
    "y": ("y",),
    "t": ("t", "timestamp", "ts"),
    "p": ("p", "polarity", "on", "pol"),
}

#: faery's event dtype (``faery.EVENTS_DTYPE``): unsigned, ``t`` first, the
#: polarity field named ``on`` with the title ``p``.
FAERY_DTYPE = np.dtype([("t", "<u8"), ("x", "<u2"), ("y", "<u2"), (("p", "on"), "?")])


def _field(events: np.ndarray, key: str, name: str) -> np.ndarray:
    """The one column of ``events`` that stands for ``key`` (a name or a title)."""
    fields = events.dtype.fields
    found = [alias for alias in FIELD_ALIASES[key] if alias in fields]
    # a titled field is listed under its name and its title: count each column once
    columns = {fields[alias][1]: alias for alias in found}
    if not columns:
        raise TypeError(
            f"{name}: no field for {key!r} (looked for {', '.join(FIELD_ALIASES[key])}); "
            f"the array has fields {', '.join(events.dtype.names)}"
        )
    if len(columns) > 1:
        raise TypeError(f"{name}: fields {', '.join(found)} all could be {key!r}; keep one")
    return events[found[0]]


def _as_time_us(t: np.ndarray, name: str) -> np.ndarray:
    """Integer microseconds from an integer or datetime/timedelta column, exactly or not at all."""
    if t.dtype.kind in "mM":
        unit, count = np.datetime_data(t.dtype)
        if unit == "generic":
            raise ValueError(f"{name}: field 't' is {t.dtype} without a unit; give it one (e.g. 'm8[us]')")
        nat = np.flatnonzero(np.isnat(t))
        if nat.size:
            raise ValueError(f"{name}: field 't' is NaT (not a time) at index {int(nat[0])}")
        # exact to microseconds when converting there and back gives the same ticks
        in_us = t.astype(f"{t.dtype.kind}8[us]")
        lost = np.flatnonzero(in_us.astype(t.dtype).view(np.int64) != t.view(np.int64))
        if lost.size:
            i = int(lost[0])
            raise ValueError(
                f"{name}: field 't' ({t.dtype}) is not a whole number of microseconds at index {i} "
                f"({t[i]}); {lost.size} values would be rounded. Round explicitly first"
            )
        return in_us.view(np.int64)
    if t.dtype.kind == "f":
        raise ValueError(
            f"{name}: field 't' is {t.dtype}; evedge's timestamps are integer microseconds. "
            f"If these are seconds, convert with evedge.events.seconds_to_us"
        )
    if t.dtype.kind not in "iu":
        raise TypeError(f"{name}: field 't' must hold integer microseconds, got {t.dtype}")
    if t.size and t.dtype.kind == "u" and int(t.max()) > np.iinfo(np.int64).max:
        i = int(np.argmax(t))
        raise ValueError(f"{name}: field 't' at index {i} is {int(t[i])}, beyond int64 microseconds")
    return t.astype(np.int64)


def _as_polarity(p: np.ndarray, name: str) -> np.ndarray:
    """True for ON from bool, {0, 1} or {-1, +1}; anything else is an error."""
    if p.dtype.kind == "b":
        return p.astype(bool)
    if p.dtype.kind not in "iu":
        raise TypeError(f"{name}: field 'p' must be bool or integer (0/1 or -1/+1), got {p.dtype}")
    if p.size == 0:
        return np.zeros(0, dtype=bool)
    bad = np.flatnonzero((p != 0) & (p != 1) & (p != -1) if p.dtype.kind == "i" else (p > 1))
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"{name}: field 'p' at index {i} is {int(p[i])}; polarity must be 0/1, -1/+1 or bool "
            f"({bad.size} values are not)"
        )
    if p.dtype.kind == "i" and (p == -1).any() and (p == 0).any():
        i = int(np.flatnonzero(p == 0)[0]) if p[0] == -1 else int(np.flatnonzero(p == -1)[0])
        raise ValueError(
            f"{name}: field 'p' mixes -1 and 0 (index {i}): OFF cannot be both; use 0/1 or -1/+1"
        )
    return p > 0


def as_events(events, *, name: str = "events") -> np.ndarray:
    """Convert any x, y, t, p structured array to :data:`EVENT_DTYPE`, losslessly or not at all.

    Accepts the arrays of tonic (``tonic.io.events_struct``, the same dtype),
    faery and ``aedat`` (``t`` uint64, ``x``/``y`` uint16, ``on`` bool),
    dv-processing (``EventStore.numpy()``: ``timestamp``, ``polarity`` int8)
    and Prophesee's Metavision (``p`` int16), in any field order, byte order
    or integer width. Other fields are dropped.

    Parameters
    ----------
    events : numpy.ndarray
        1-D structured array with a field for each of x, y, t and p (names
        in :data:`FIELD_ALIASES`, or titles).
    name : str
        What to call the array in messages.

    Returns
    -------
    numpy.ndarray
        ``events`` itself when already of :data:`EVENT_DTYPE`, else a new
        array of that dtype.

    Raises
    ------
    TypeError
        When ``events`` is not a 1-D structured array with those fields, or a
        field's type cannot hold them (float coordinates, string polarity).
    ValueError
        When the conversion would lose information, naming the field and
        the first index: a coordinate outside int16, a float ``t`` (seconds?
        use :func:`seconds_to_us`), a ``datetime64``/``timedelta64`` ``t`` that
        is not a whole number of microseconds, a ``t`` beyond int64, a
        polarity that is not 0/1, -1/+1 or bool.

    Examples
    --------
    >>> import numpy as np
    >>> dv_like = np.array([(10, 1, 2, 1), (20, 3, 4, 0)],
    ...     dtype=[("timestamp", "<i8"), ("x", "<i2"), ("y", "<i2"), ("polarity", "i1")])
    >>> ev = as_events(dv_like)
    >>> ev.dtype == EVENT_DTYPE, ev["t"].tolist(), ev["p"].tolist()
    (True, [10, 20], [True, False])
    >>> as_events(np.zeros(1, dtype=[("x", "u2"), ("y", "u2"), ("t", "f8"), ("p", "?")]))
    Traceback (most recent call last):
    ...
    ValueError: events: field 't' is float64; evedge's timestamps are integer microseconds. If these are seconds, convert with evedge.events.seconds_to_us
    """
    if isinstance(events, np.ndarray) and events.dtype == EVENT_DTYPE:
        if events.ndim != 1:
            raise ValueError(f"{name}: expected a 1-D event array, got shape {events.shape}")
        return events
    if not isinstance(events, np.ndarray) or events.dtype.names is None:
        got = getattr(events, "dtype", type(events).__name__)
        raise TypeError(
            f"{name}: expected a structured array with fields x, y, t, p (e.g. dtype {EVENT_DTYPE}), got {got}"
        )
    if events.ndim != 1:
        raise ValueError(f"{name}: expected a 1-D event array, got shape {events.shape}")
    out = np.empty(events.shape[0], dtype=EVENT_DTYPE)
    for key in "xy":
        col = _field(events, key, name)
        if col.dtype.kind not in "iu":
            raise TypeError(f"{name}: field {key!r} must hold integer pixel coordinates, got {col.dtype}")
        info = np.iinfo(np.int16)
        bad = np.flatnonzero((col < info.min) | (col > info.max)) if col.size else col[:0]
        if bad.size:
            i = int(bad[0])
            raise ValueError(
                f"{name}: field {key!r} at index {i} is {int(col[i])}, outside int16 "
                f"({info.min}..{info.max}); {bad.size} values are"
            )
        out[key] = col
    out["t"] = _as_time_us(_field(events, "t", name), name)
    out["p"] = _as_polarity(_field(events, "p", name), name)
    return out


def to_tonic(events) -> np.ndarray:
    """Events as tonic takes them: an array of ``tonic.io.events_struct``.

    :data:`EVENT_DTYPE` is tonic's dtype, so this is :func:`as_events`; pair
    it with :meth:`SensorSize.as_tonic` for tonic's ``sensor_size``.

    Parameters
    ----------
    events : numpy.ndarray
        Any array :func:`as_events` accepts.

    Returns
    -------
    numpy.ndarray

    Examples
    --------
    >>> ev = make_events([1, 2], [3, 4], [10, 20], [1, 0])
    >>> to_tonic(ev) is ev, SensorSize(240, 180).as_tonic()
    (True, (240, 180, 2))

    With tonic installed: ``tonic.transforms.Denoise(filter_time=10000)(to_tonic(ev))``.
    """
    return as_events(events, name="to_tonic: events")


def to_faery(events) -> np.ndarray:
    """Events as faery takes them: a new array of :data:`FAERY_DTYPE`.

    Parameters
    ----------
    events : numpy.ndarray
        Any array :func:`as_events` accepts.

    Returns
    -------
    numpy.ndarray
        ``t`` uint64, ``x``/``y`` uint16, ``on`` bool, in the same order.

    Raises
    ------
    ValueError
        When a coordinate or a timestamp is negative (faery's are unsigned),
        naming the field and the first index.

    Examples
    --------
    >>> ev = make_events([1, 2], [3, 4], [10, 20], [1, 0])
    >>> to_faery(ev)["on"].tolist()
    [True, False]

    With faery installed, a stream for its renderers and encoders:
    ``faery.events_stream_from_array(to_faery(ev), dimensions=(240, 180))``.
    """
    events = as_events(events, name="to_faery: events")
    for key in "xyt":
        neg = np.flatnonzero(events[key] < 0)
        if neg.size:
            i = int(neg[0])
            raise ValueError(
                f"to_faery: events: field {key!r} at index {i} is {int(events[key][i])}; faery's "
                f"{key} is unsigned ({neg.size} negative values)"
            )
    out = np.empty(events.shape[0], dtype=FAERY_DTYPE)
    out["t"], out["x"], out["y"], out["on"] = events["t"], events["x"], events["y"], events["p"]
    return out
