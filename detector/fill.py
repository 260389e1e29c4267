"""Neighbour fill: a lifetime for events the estimator left without one, from agreeing neighbours (issue 11).

At low contrast the intra-pixel-area estimator (:mod:`evedge.detector.intra`)
leaves many signal events without an estimate: a pixel that fires once per
passage sees a window with few points of the current passage, and the rules
that refuse stale levels and noise (linkage split, jump check, event on plane,
newer share, lifetime agreement) refuse such windows too. The pixels around it
usually did get an estimate of the same edge a moment earlier. The fill gives
such an event the lifetime its neighbours agree on.

The rule (streaming, in event order; state per pixel, per polarity plane when
the estimator runs per polarity, else one plane):

* an event **with** an estimate writes its pixel's state: its time, lifetime and
  normal flow;
* an event **without** one (and at least ``border_px`` inside the sensor, whose
  border the estimator leaves out on purpose) looks at its 8 neighbours (same
  plane; pixels outside the sensor do not count). A neighbour is *recent* when
  its state's time is at most ``agreement`` times its own lifetime before the
  event (an edge moving at one pixel per lifetime reaches the event's pixel
  about one lifetime after its upstream neighbours, 1.4 diagonally; the
  neighbours alongside fired at about the same time), and, with ``arrival > 0``,
  when its plane puts the edge at the event's pixel near the event's time: the
  neighbour at offset ``-d`` from the event, estimated at ``t_n`` with flow ``v``
  (px/s), predicts the edge here at ``t_n + 1e6 (d . v) / |v|^2``, and counts when
  that is within ``arrival`` times its lifetime of the event's time (the
  arrival check, our addition to the rule: recency alone accepts any event in
  the 1.5 lifetimes after an edge passed the neighbours, which is where
  background events near an edge fall; measured below). When at least
  ``neighbours`` neighbours count and all of them agree,
  ``(max - min) <= tolerance * median`` of their lifetimes, the event gets
  their median lifetime, and as normal flow the component-wise median of
  their flows rescaled to the speed ``1e6 / lifetime`` px/s (so flow and
  lifetime agree as the estimator's do; no fill when that median flow is zero,
  neighbours moving in opposite directions). Otherwise it stays without estimate.
* **A filled value never feeds the state**: only the estimator's own estimates
  do, so a fill cannot start a chain (a filled event cannot make its neighbour
  fillable), and an isolated event (noise) is filled only when its neighbours
  themselves hold recent, agreeing estimates, i.e. when an edge is passing there.

Every decision reads only what earlier events wrote, so chunks give the bytes
of one shot; the fill runs serially after the estimator (and its strips), on the
estimator's output, so the strips' bytes stay the serial ones.

In the estimator: ``IntraParams.fill_neighbours`` (0 = off, the default and the
paper: the output bytes are unchanged), ``fill_tolerance`` (0.5), ``fill_agreement``
(1.5), ``fill_arrival`` (0.5), applied by :class:`~evedge.detector.intra.IntraPixelLifetime` after its kernel;
:class:`NeighbourFill` / :func:`fill_lifetimes` apply it to any estimator's output.

Measured (2026-12-02, main's presets with the 9 x 9 ring refit) on
``benchmarks/robustness_grid.py --preset noise --workers 1`` (:func:`~evedge.detector.intra.noise_params`),
``--intra fill_neighbours=N`` on top. Full grid (210 cells at 96x72), cells within the goals
median error / > 2x off / signal estimated (of 210) / noise given a lifetime <= 10 % (of
100), median signal estimated over the clean r < 3 / noisy cells, noise given a lifetime
(median over the noisy cells): off 167 / 151 / 93 / 91, 68.4 / 78.5 %, 6.7 %; ``N = 2``
168 / 153 / 104 / 88, 69.5 / 85.2 %, 7.0 % (``fill_tolerance = 0.25``: 168 / 153 / 103 /
88); without the arrival check (``fill_arrival = 0``) 166 / 151 / 104 / 46, noise 10.7 %;
with the buffer's line rule (``--buffer-preset line``) 177 / 155 / 93 / 92 -> 178 / 158 /
104 / 88. The three noisy cells lost at ``N = 2`` go from 9.8-10.0 % to 10.3-10.7 %
(floors 7.9-9.3 %). The median errors per group do not move (0.8 / 1.8 / 1.9 %). Quick
grid (``--quick``, 72 cells at 64x48): off 53 / 43 / 25 / 28 of 30, 70.7 / 72.9 %, 6.4 %;
``N = 2`` 52 / 43 / 31 / 27, 71.4 / 84.2 %, 6.5 %; without the arrival check 52 / 43 / 32
/ 15, 10.1 % (at 0 degrees, 200 px/s, r = 5, 5 Hz: 9.5 -> 18.9 %, with the check 9.9 %).
Earlier, on the 7 x 7 ring presets (quick grid): ``N = 1`` 32 signal cells, 75.7 / 87.7 %,
noise 7.5 %, 24/30; ``N = 3`` 29, 70.8 / 80.6 %, 6.4 %, 27/30; ``fill_arrival = 0.75`` 32,
26/30; full grid ``fill_arrival = 0.25`` 102 signal cells, 89 noisy cells within 10 %
(0.5: 104, 87). No setting keeps every noisy cell
within 10 %, so :func:`~evedge.detector.intra.noise_params` leaves the fill off.

Clean low contrast hardly gains, whatever the rule, because the fill is causal and
sees only the estimator's input: at r = 1.3 a pixel skips about half the passages,
and of the signal events left without estimate (stripes, 0 degrees, 200 px/s, r = 1.3,
clean) 78 % have no neighbour estimated in the 1.5 lifetimes before them and 29 % no
neighbour that even fired then; at 10 px/s the event buffer drops up to 38 % of the
signal events, which never reach the estimator. Cost: ~14 ns per event (about 1 % of
the estimator).
"""

from __future__ import annotations

import numpy as np

from evedge._validate import check_bool, check_positive

from ._checks import check_events, check_lifetimes, check_not_before, check_sensor_size, columns
from ._fill_kernels import _fill_stream

__all__ = ["ARRIVAL", "NeighbourFill", "check_fill", "fill_lifetimes"]

#: Default ``arrival`` (lifetimes): the measured choice (module notes).
ARRIVAL = 0.5


def check_fill(owner: str, neighbours, tolerance, agreement, arrival, *, prefix: str = "") -> tuple:
    """Validate the fill's parameters (errors name ``owner.<prefix><name>``); ``(int, float, float, float)``.

    ``neighbours`` in 0..8 (0 = off), ``tolerance`` >= 0, ``agreement`` > 0, ``arrival`` >= 0 (0 = off).

    Examples
    --------
    >>> check_fill("NeighbourFill", 2, 0.5, 1.5, 0.5)
    (2, 0.5, 1.5, 0.5)
    >>> check_fill("IntraParams", 9, 0.5, 1.5, 0.5, prefix="fill_")
    Traceback (most recent call last):
    ...
    ValueError: IntraParams.fill_neighbours must be in 0..8 (0 = off; of the 8 neighbours), got 9
    """
    check_positive(owner, prefix + "neighbours", neighbours, integer=True, allow_zero=True)
    if neighbours > 8:
        raise ValueError(f"{owner}.{prefix}neighbours must be in 0..8 (0 = off; of the 8 neighbours), got {neighbours}")
    check_positive(owner, prefix + "tolerance", tolerance, allow_zero=True)
    check_positive(owner, prefix + "agreement", agreement)
    check_positive(owner, prefix + "arrival", arrival, allow_zero=True)
    return int(neighbours), float(tolerance), float(agreement), float(arrival)


class NeighbourFill:
    """Streaming neighbour fill of missing lifetimes (module notes: the rule).

    Parameters
    ----------
    sensor_size : SensorSize or (width, height)
    neighbours : int
        Least recent, agreeing neighbours (of 8) for a fill, 1..8 (0 = off: the
        lifetimes pass unchanged).
    tolerance : float
        >= 0. The recent neighbours agree when ``(max - min) <= tolerance * median``
        of their lifetimes.
    agreement : float
        > 0. A neighbour's estimate is recent when it is at most ``agreement``
        times its lifetime older than the event.
    arrival : float
        >= 0. Above 0, a recent neighbour counts only when its plane (time, flow)
        predicts the edge at the event's pixel within ``arrival`` times its
        lifetime of the event's time (module notes; 0 = off).
    per_polarity : bool
        One state per polarity (default; as the estimator's ``per_polarity``) or one shared.
    border_px : int
        >= 0. Events closer than this to the sensor's edge are not filled (as
        the estimator's ``border_px``).

    Notes
    -----
    :meth:`process` validates its chunk (events and aligned lifetimes) and
    returns a filled copy; chunks give the bytes of :func:`fill_lifetimes`.

    Examples
    --------
    Four pixels of an edge got 1000 us, their neighbour at (1, 1) got nothing:

    >>> from evedge.detector.result import empty_lifetimes
    >>> from evedge.events import make_events
    >>> ev = make_events([0, 1, 2, 0, 1], [0, 0, 0, 1, 1], [0, 10, 20, 1000, 1050], [True] * 5)
    >>> lt = empty_lifetimes(5)
    >>> lt["lifetime_us"][:4], lt["vx_px_s"][:4], lt["vy_px_s"][:4], lt["valid"][:4] = 1000.0, 0.0, 1000.0, True
    >>> fill = NeighbourFill((4, 3), neighbours=2)
    >>> out = fill.process(ev[:3], lt[:3])  # chunks: the state carries over
    >>> out = fill.process(ev[3:], lt[3:])
    >>> out["valid"].tolist(), float(out["lifetime_us"][1]), float(out["vy_px_s"][1])
    ([True, True], 1000.0, 1000.0)
    """

    def __init__(self, sensor_size, *, neighbours: int = 2, tolerance: float = 0.5, agreement: float = 1.5,
                 arrival: float = ARRIVAL, per_polarity: bool = True, border_px: int = 0) -> None:
        own = "NeighbourFill"
        self.sensor_size = check_sensor_size(sensor_size)
        self.neighbours, self.tolerance, self.agreement, self.arrival = check_fill(own, neighbours, tolerance,
                                                                                   agreement, arrival)
        check_bool(own, "per_polarity", per_polarity)
        check_positive(own, "border_px", border_px, integer=True, allow_zero=True)
        self.per_polarity = bool(per_polarity)
        self.border_px = int(border_px)
        self.reset()

    def reset(self) -> None:
        """Forget every pixel's estimate (as at construction)."""
        n = (2 if self.per_polarity else 1) * self.sensor_size.width * self.sensor_size.height
        self._t = np.zeros(n, dtype=np.int64)
        self._lt = np.full(n, np.nan)
        self._vx = np.zeros(n)
        self._vy = np.zeros(n)
        self._last_time: int | None = None

    def process(self, events: np.ndarray, lifetimes: np.ndarray) -> np.ndarray:
        """A copy of ``lifetimes`` (aligned with the time-sorted ``events``) with the fill applied."""
        events = check_events(events, self.sensor_size)
        check_lifetimes(lifetimes, events.shape[0])
        check_not_before(events, self._last_time)
        out = lifetimes.copy()
        if events.size == 0:
            return out
        lt = np.ascontiguousarray(out["lifetime_us"])
        vx = np.ascontiguousarray(out["vx_px_s"])
        vy = np.ascontiguousarray(out["vy_px_s"])
        valid = np.ascontiguousarray(out["valid"])
        self._apply(*columns(events), lt, vx, vy, valid)
        out["lifetime_us"], out["vx_px_s"], out["vy_px_s"], out["valid"] = lt, vx, vy, valid
        return out

    def _apply(self, x, y, t, p, lt, vx, vy, valid) -> int:
        """The kernel on checked columns, in place (the estimator's hook: its chunk is already checked)."""
        self._last_time = int(t[-1]) if t.size else self._last_time
        if self.neighbours == 0 or t.size == 0:
            return 0
        return int(_fill_stream(x, y, t, p, lt, vx, vy, valid, self._t, self._lt, self._vx, self._vy,
                                self.sensor_size.width, self.sensor_size.height, self.per_polarity,
                                self.neighbours, self.tolerance, self.agreement, self.border_px, self.arrival))


def fill_lifetimes(events: np.ndarray, lifetimes: np.ndarray, sensor_size, *, neighbours: int = 2,
                   tolerance: float = 0.5, agreement: float = 1.5, arrival: float = ARRIVAL,
                   per_polarity: bool = True, border_px: int = 0) -> np.ndarray:
    """One-shot neighbour fill (:class:`NeighbourFill` on the whole stream).

    Parameters
    ----------
    events : numpy.ndarray
        Time-sorted events of dtype :data:`evedge.events.EVENT_DTYPE`.
    lifetimes : numpy.ndarray
        :data:`~evedge.detector.result.LIFETIME_DTYPE`, aligned with ``events``
        (any estimator's output).
    sensor_size : SensorSize or (width, height)
    neighbours, tolerance, agreement, arrival, per_polarity, border_px
        As in :class:`NeighbourFill`.

    Returns
    -------
    numpy.ndarray
        A filled copy of ``lifetimes``; the filled events are
        ``out["valid"] & ~lifetimes["valid"]``.

    Examples
    --------
    An isolated event far from any estimate stays without one:

    >>> from evedge.detector.result import empty_lifetimes
    >>> from evedge.events import make_events
    >>> ev = make_events([0, 1, 5], [0, 0, 5], [0, 10, 500], [True] * 3)
    >>> lt = empty_lifetimes(3)
    >>> lt["lifetime_us"][:2], lt["vx_px_s"][:2], lt["vy_px_s"][:2], lt["valid"][:2] = 800.0, 1250.0, 0.0, True
    >>> fill_lifetimes(ev, lt, (8, 8), neighbours=1)["valid"].tolist()
    [True, True, False]
    """
    return NeighbourFill(sensor_size, neighbours=neighbours, tolerance=tolerance, agreement=agreement,
                         arrival=arrival, per_polarity=per_polarity, border_px=border_px).process(events, lifetimes)
