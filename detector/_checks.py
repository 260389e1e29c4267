"""Input checks shared by the detector's public functions (never inside numba)."""

from __future__ import annotations

import threading
from contextlib import contextmanager

import numpy as np

from evedge._validate import check_positive  # noqa: F401  (the detector's parameter classes import it from here)
from evedge.events import EVENT_DTYPE, SensorSize, validate_events

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
    O(1) for an array inside a :func:`validated` block (already checked, read-only).
    """
    if _is_validated(events, sensor_size):
        return events
    return validate_events(events, sensor_size, name=name)


#: The arrays of the open :func:`validated` blocks of each thread: ``(array, SensorSize)``.
_VALIDATED = threading.local()


@contextmanager
def validated(events: np.ndarray, sensor_size: SensorSize):
    """Within the block, :func:`check_events` of ``events`` (or of a contiguous slice of it) is O(1).

    For a pipeline that checked ``events`` once (it must be :func:`check_events`'
    result, or an array made from such a one that keeps its order and range,
    such as a boolean subset) and hands it, or slices of it, to its stages:
    their own checks then skip the O(n) pass over the same memory. The marker
    stays honest: ``events`` is made read-only for the block (and writeable
    again after it, if it was), so nothing can change it between the check and
    the stages that rely on it; a stage that tries gets numpy's "read-only"
    error (only through ``events`` and views of it: another writeable view of the
    same memory made before the block, e.g. its base, is not locked; the
    pipelines hand their stages ``events`` and slices of it). Thread-local:
    another thread's checks are not affected (blocks of two threads on the same
    array: the first to close makes it writeable again).

    Examples
    --------
    >>> import numpy as np
    >>> from evedge.events import SensorSize, make_events
    >>> size = SensorSize(4, 4)
    >>> ev = check_events(make_events([0, 1], [0, 1], [0, 5], [True, False]), size)
    >>> with validated(ev, size):
    ...     check_events(ev[1:], size) is not None, ev.flags.writeable
    (True, False)
    >>> ev.flags.writeable
    True
    """
    if not (isinstance(events, np.ndarray) and events.dtype == EVENT_DTYPE and events.ndim == 1):
        raise TypeError("validated: expected a checked 1-D array of EVENT_DTYPE (check_events' result)")
    stack = getattr(_VALIDATED, "stack", None)
    if stack is None:
        stack = _VALIDATED.stack = []
    unlock = events.flags.writeable
    if unlock and not _relockable(events):
        # locking could not be undone (a writeable view of memory made read-only since):
        # leave the array as it is; the stages then check it themselves (O(n), same results)
        yield events
        return
    events.flags.writeable = False
    stack.append((events, sensor_size))
    try:
        yield events
    finally:
        stack.pop()
        if unlock:
            events.flags.writeable = True


def _relockable(events: np.ndarray) -> bool:
    """Whether a writeable ``events`` can be made writeable again after :func:`validated` locks it.

    numpy refuses ``writeable = True`` when a base of the array is read-only (e.g. a
    view taken before its base was locked, or memory of an immutable buffer).
    """
    base = events.base
    while isinstance(base, np.ndarray):
        if not base.flags.writeable:
            return False
        base = base.base
    if base is None:
        return True
    try:
        return not memoryview(base).readonly
    except TypeError:
        return False


def _is_validated(events, sensor_size: SensorSize) -> bool:
    """Whether ``events`` is (a step-1 slice of) an array of an open :func:`validated` block.

    The block's sensor must lie within ``sensor_size`` (its events are then in range).
    """
    stack = getattr(_VALIDATED, "stack", None)
    if not stack or not isinstance(events, np.ndarray) or events.dtype != EVENT_DTYPE or events.ndim != 1:
        return False
    start = None
    for arr, size in stack:
        if size.width > sensor_size.width or size.height > sensor_size.height:
            continue
        if events is arr:
            return True
        if events.size == 0 or events.strides != arr.strides or arr.strides[0] <= 0 or events.flags.writeable:
            continue  # a slice of an array of the block is read-only, as the array
        if start is None:
            start = events.__array_interface__["data"][0]
        lo = arr.__array_interface__["data"][0]
        step = arr.strides[0]
        off = start - lo
        if 0 <= off and off % step == 0 and off // step + events.size <= arr.size:
            return True
    return False


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
    """Contiguous plain columns for numba: x, y (int64), t (int64), p (int64 0/1).

    Always writeable arrays (a read-only field that is already contiguous, as a
    one-event chunk of a locked array, is copied): numba compiles one
    specialisation per argument type, and read-only is a type of its own.
    """
    return tuple(_writeable(np.ascontiguousarray(events[f], dtype=np.int64)) for f in ("x", "y", "t", "p"))


def _writeable(a: np.ndarray) -> np.ndarray:
    return a if a.flags.writeable else a.copy()
