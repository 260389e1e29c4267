"""Surface of Active Events (SAE): the latest timestamp of every pixel.

One surface per polarity by default (as Mueggler et al.'s code does), or one
shared by both polarities. Timestamps are int64 microseconds; a pixel that
never fired holds :data:`NEVER_US` (``INT64_MIN``), never 0, which is a valid time.

References
----------
.. [1] R. Benosman et al., "Event-based visual flow", IEEE TNNLS 2014.
.. [2] S. Lee, H. Kim, H. J. Kim, BMVC 2019, section 2.1.
"""

from __future__ import annotations

import numpy as np

from ._checks import NEVER_US, check_events, check_not_before, check_sensor_size

__all__ = ["NEVER_US", "SurfaceOfActiveEvents"]


class SurfaceOfActiveEvents:
    """Per-pixel latest timestamp, per polarity or shared.

    Parameters
    ----------
    sensor_size : SensorSize or (width, height)
    per_polarity : bool
        True (default): two surfaces, index 0 = OFF, 1 = ON. False: one surface.

    Attributes
    ----------
    times_us : numpy.ndarray
        int64, shape ``(2, height, width)`` or ``(1, height, width)``; :data:`NEVER_US`
        where the pixel never fired.
    """

    def __init__(self, sensor_size, per_polarity: bool = True) -> None:
        self.sensor_size = check_sensor_size(sensor_size)
        if not isinstance(per_polarity, (bool, np.bool_)):
            raise TypeError(f"per_polarity must be a bool, got {per_polarity!r}")
        self.per_polarity = bool(per_polarity)
        self.reset()

    def reset(self) -> None:
        """Every pixel back to 'never fired'."""
        planes = 2 if self.per_polarity else 1
        self.times_us = np.full((planes, *self.sensor_size.shape), NEVER_US, dtype=np.int64)
        self._last_time: int | None = None

    def plane(self, polarity: bool) -> np.ndarray:
        """The (height, width) surface used by events of ``polarity``."""
        return self.times_us[int(bool(polarity)) if self.per_polarity else 0]

    def fired(self) -> np.ndarray:
        """Boolean mask of pixels that fired at least once, same shape as :attr:`times_us`."""
        return self.times_us != NEVER_US

    def process(self, events: np.ndarray) -> None:
        """Write a time-sorted chunk of events into the surface (later events win)."""
        events = check_events(events, self.sensor_size)
        check_not_before(events, self._last_time)
        if events.size == 0:
            return
        h, w = self.sensor_size.shape
        plane = events["p"].astype(np.intp) if self.per_polarity else np.zeros(events.size, np.intp)
        flat = (plane * h + events["y"].astype(np.intp)) * w + events["x"].astype(np.intp)
        # numpy does not promise which write wins for repeated indices: take each
        # pixel's last event of the chunk explicitly (the newest)
        _, first_in_reversed = np.unique(flat[::-1], return_index=True)
        last = flat.size - 1 - first_in_reversed
        self.times_us.reshape(-1)[flat[last]] = events["t"][last]
        self._last_time = int(events["t"][-1])
