"""Lifetime of events by Mueggler et al. (ICRA 2015): the paper's main baseline.

For every event, a plane ``a x + b y + c t = 1`` is fitted by RANSAC to the
same-polarity Surface of Active Events (SAE) in the N x N window around it,
refined by least squares with a prior from the neighbouring pixel's
prediction, and turned into a lifetime (time for the edge to move one pixel)
``tau = sqrt(a^2 + b^2) / c`` and a normal flow.

The implementation follows the authors' public MATLAB code
(``uzh-rpg/rpg_event_lifetime``, ``calcVelocity.m``, ``fitPlane.m``,
``ransac.m``, ``calcNormalEstimate.m``), read to understand it, written anew.

Algorithm, per event ``e = (x, y, t, p)``
-----------------------------------------
1. ``SAE_p[y, x] = t`` (one SAE per polarity by default), also for events
   near the border; events with x or y within ``N // 2`` (2 px) of the
   border get no estimate.
2. Window: the N x N SAE values around ``e``. Median rejection: the median
   is taken over all N^2 values (never-fired pixels count as lowest, as the
   MATLAB zeros do); points below it and never-fired pixels are dropped.
   Points are ``(x_local, y_local, t)`` with local pixel coordinates 1..N
   (centre (3, 3)) and ``t`` the event time in microseconds since the time
   origin. Fewer than 3 points: no estimate.
3. RANSAC, ``m = ceil(log(1 - P) / log(1 - (1 - eps)^3)) = 19`` trials.
   As in ``ransac.m``, ``m + 1`` points are drawn uniformly *with
   replacement* from the kept points (the current event included) and trial
   ``i`` uses draws ``i`` and ``i + 1`` together with the current event
   (consecutive trials share a point). A sample collinear in (x, y) scores
   the plane ``theta = (0, 0, 1)`` through the current event (``t = t_e``)
   as the MATLAB code does; otherwise the plane through the three points.
   Residual ``(a x + b y + c t - 1)^2``, inlier when ``<= mu``; a candidate
   is acceptable with more than ``(1 - eps) N^2 / 2`` inliers (7.5, so at
   least 8); the first candidate with the largest inlier set wins. None
   acceptable: no estimate.
4. Refinement on the winner's inliers: minimise
   ``sum (a x + b y + c t - 1)^2 + lambda |theta - theta_prior|^2`` with
   ``lambda = 9 + 100 exp(-0.005 |t - t_pred|)`` (``t`` in us), where
   ``(theta_prior, t_pred)`` is what a neighbour stored for this pixel (no
   prior stored, or the "no prediction" marker ``(0, 0, 1)``: no prior
   term). The MATLAB code calls ``lsqnonlin`` from the RANSAC plane; the
   residuals are linear in theta, so the problem is convex and its unique
   minimum is solved here in closed form (3x3 normal equations, time column
   scaled by ``t_e`` for conditioning).
5. ``theta`` is flipped so that ``c >= 0``. Lifetime ``sqrt(a^2 + b^2) / c``
   (us), normal flow ``v = -c (a, b) / (a^2 + b^2)`` (px/us, reported in
   px/s).
6. Prediction: the flow direction rounded to 45 degrees (MATLAB ``round``,
   half away from zero) picks the 8-neighbour ``(x + dx, y + dy)``; it
   receives ``theta`` and ``t_pred = t + |d| / (v . d / |d|)``. An event
   without estimate writes the "no prediction" marker at its own pixel.

Units, and the absolute-time quirk
----------------------------------
The MATLAB code works in microseconds: ``loadEvents.m`` keeps the AER
timestamps (us) and only subtracts the first one, ``calcVelocity.m``
documents ``vx, vy`` in pixel/us and ``t_disp`` in us, and its histogram
script labels ticks 0..20000 as 0..20 ms. So the plane is fitted to
``(x_local, y_local, t_us)`` with ``t`` the time since the *first event of
the recording* (absolute time), not relative to the current event.

What this means. Write the local plane as ``t = t_e + g . (p - p_e)``
(``g`` = time gradient, us/px). Then ``a x + b y + c t = 1`` holds with
``(a, b, c) = (-g_x, -g_y, 1) / K`` and ``K = t_e - g . p_e``, i.e.
``c ~ 1 / t_e``. The RANSAC residual of a point is ``((t - t_plane) / K)^2``,
so ``mu = 1e-4`` is a *relative* tolerance: ``|t - t_plane| <= 0.01 K``,
about 1 % of the time since the recording began (0.1 ms after 10 ms,
10 ms after 1 s; on ``stripes`` 3-9 ms in the middle half of the
recording, about one pixel of motion). This residual is invariant to the
time unit (seconds or microseconds give the same inliers: mu does not
depend on it); what the unit changes is the prior term: ``a, b`` are unit-free while ``c`` scales as 1/unit, so the prior
mostly constrains ``a, b``, and ``lambda``'s decay of 0.005 per unit is
only meaningful in microseconds (a 200 us scale). Consequences reproduced
here (measured in the tests): early in a recording the inlier test is
strict (an edge with 400 us timestamp jitter gets estimates for 70 % of its
events 20-70 ms after the origin, 100 % after 0.1 s); later it grows lax,
so gross outliers (a pixel firing 600 us late) are accepted as inliers
and bias the fit. When ``K < 0`` (``t_e`` smaller than ``g . p_e``, only in
the first milliseconds) the flip to ``c >= 0`` negates the whole ``theta``,
which leaves the flow and lifetime right (but the stored prior is then the
negated plane); when ``K = 0`` exactly the plane passes through the origin,
cannot be written ``a x + b y + c t = 1``, and the event gets no estimate.

A second consequence concerns the prior. The predicted plane is stored as
``theta`` in the predicting event's window coordinates, but read by the
neighbour, whose window is shifted by ``(dx, dy)``: the same physical plane
there is ``theta / (1 - a dx - b dy)``, a relative mismatch of about
``g / K``. With ``lambda`` up to 109 against a data term of comparable
weight, the refinement pulls towards the wrong plane, and errors chain from
pixel to pixel along the motion. Measured on an exact straight edge at
2500 us/px (tests), normal at 0 deg: median lifetime +28 % 10 ms after
the time origin, +11 % after 0.1 s, +1.7 % after 1 s, +0.6 % after 3 s
(at 30 deg: +18 %, +6 %, +1 %, +0.4 %). This is reproduced by default;
``shift_prior_frame=True`` (not in the MATLAB code) stores the plane in the
neighbour's coordinates and removes the bias (exact planes then give exact
lifetimes at any time).

The time origin is the first event processed after construction or
:meth:`MuegglerLifetime.reset` (as ``calcVelocity.m``), or
``time_origin_us`` when given.

Deviations from the MATLAB code (all at its corner cases)
---------------------------------------------------------
- Never-fired pixels are marked explicitly; the MATLAB code uses time 0,
  which also hides a pixel whose only event is the recording's first one.
- A non-collinear sample whose plane passes through the origin (the
  sample matrix is singular, MATLAB returns Inf/NaN with a warning) is
  skipped.
- A refined plane with ``a = b = 0`` or ``c = 0`` (lifetime 0 or infinite;
  the MATLAB code would produce NaN flow) counts as no estimate.
- In ``ransac.m`` a collinear draw resets the best plane (not its inlier
  set); that plane only seeds ``lsqnonlin``, so it has no effect on the
  convex refinement and is not reproduced.
- The refinement is solved exactly; ``lsqnonlin`` stops at its default
  tolerances (1e-6), so MATLAB's planes can differ slightly.

Randomness: draw ``k`` of the event with global index ``i`` (counted from
construction / reset) is a splitmix64 hash of ``(seed, i, k)``, so results
do not depend on how the stream is cut into chunks.

References
----------
.. [1] E. Mueggler, C. Forster, N. Baumli, G. Gallego, D. Scaramuzza,
       "Lifetime Estimation of Events from Dynamic Vision Sensors",
       ICRA 2015. Code: https://github.com/uzh-rpg/rpg_event_lifetime
.. [2] METHOD.md, section 4 (facts from that code).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from evedge._validate import check_bool, check_integer, check_real
from evedge.events import SensorSize, validate_events

from ._mueggler_kernels import NEVER_FIRED, _mueggler_kernel
from ._checks import check_sensor_size
from .protocols import METHODS
from .result import LIFETIME_DTYPE

__all__ = ["MuegglerParams", "MuegglerLifetime", "estimate_lifetimes_mueggler"]


@dataclass(frozen=True)
class MuegglerParams:
    """Parameters of the Mueggler et al. (2015) estimator; defaults are the paper's.

    Parameters
    ----------
    window_size_px : int
        Side N of the SAE window (odd, >= 3). Default 5.
    outlier_fraction : float
        RANSAC's expected outlier fraction epsilon in (0, 1). Sets the number
        of trials and the minimum inlier count. Default 0.4.
    residual_threshold : float
        RANSAC threshold mu on ``(a x + b y + c t - 1)^2`` (unit-free, see the
        module notes: a relative time tolerance of ``sqrt(mu)``). Default 1e-4.
    stop_probability : float
        Probability P of drawing at least one outlier-free sample, in (0, 1).
        Default 0.99.
    regularize : bool
        Prior term in the refinement (``REG_ON``). Default True.
    lambda_base, lambda_gain, lambda_decay_per_us : float
        ``lambda = lambda_base + lambda_gain * exp(-lambda_decay_per_us |t - t_pred|)``.
        Defaults 9, 100, 0.005 per us.
    per_polarity : bool
        One SAE (and prior map) per polarity (True, as the MATLAB code) or
        one shared SAE. Default True.
    shift_prior_frame : bool
        Not in the MATLAB code: re-express the predicted plane in the target
        pixel's window coordinates before storing it, which removes the
        prior's frame mismatch (module notes). Default False (faithful).
    seed : int
        Seed of the counter-based RNG, in [0, 2**64). Default 0.

    Notes
    -----
    Derived: :attr:`n_trials` (19 with the defaults) and :attr:`min_inliers` (8).
    """

    window_size_px: int = 5
    outlier_fraction: float = 0.4
    residual_threshold: float = 1e-4
    stop_probability: float = 0.99
    regularize: bool = True
    lambda_base: float = 9.0
    lambda_gain: float = 100.0
    lambda_decay_per_us: float = 0.005
    per_polarity: bool = True
    shift_prior_frame: bool = False
    seed: int = 0

    def __post_init__(self) -> None:
        own = "MuegglerParams"
        n = self.window_size_px
        check_integer(own, "window_size_px", n)
        if n < 3 or n % 2 == 0 or n > 31:
            raise ValueError(f"MuegglerParams.window_size_px must be odd and in 3..31, got {n}")
        object.__setattr__(self, "window_size_px", int(n))
        inf = math.inf
        for name, low, high, lo_open, hi_open in (
            ("outlier_fraction", 0.0, 1.0, True, True),
            ("residual_threshold", 0.0, inf, True, True),
            ("stop_probability", 0.0, 1.0, True, True),
            ("lambda_base", 0.0, inf, False, True),
            ("lambda_gain", 0.0, inf, False, True),
            ("lambda_decay_per_us", 0.0, inf, False, True),
        ):
            object.__setattr__(
                self, name, check_real(own, name, getattr(self, name), low, high, low_open=lo_open, high_open=hi_open)
            )
        for name in ("regularize", "per_polarity", "shift_prior_frame"):
            check_bool(own, name, getattr(self, name))
            object.__setattr__(self, name, bool(getattr(self, name)))
        s = self.seed
        check_integer(own, "seed", s)
        if not 0 <= int(s) < 2**64:
            raise ValueError(f"MuegglerParams.seed must be in [0, 2**64), got {s}")
        object.__setattr__(self, "seed", int(s))
        if self.n_trials > 100_000:
            raise ValueError(
                f"MuegglerParams: outlier_fraction={self.outlier_fraction} and "
                f"stop_probability={self.stop_probability} need {self.n_trials} RANSAC trials (max 100000)"
            )

    @property
    def n_trials(self) -> int:
        """RANSAC trials ``ceil(log(1 - P) / log(1 - (1 - eps)^3))`` (19 by default)."""
        good = (1.0 - self.outlier_fraction) ** 3
        return max(1, math.ceil(math.log(1.0 - self.stop_probability) / math.log(1.0 - good)))

    @property
    def inlier_threshold(self) -> float:
        """A plane is acceptable with strictly more inliers than ``(1 - eps) N^2 / 2``."""
        return (1.0 - self.outlier_fraction) * self.window_size_px**2 / 2.0

    @property
    def min_inliers(self) -> int:
        """Smallest acceptable inlier count (8 by default)."""
        return math.floor(self.inlier_threshold) + 1


class MuegglerLifetime:
    """Streaming Mueggler et al. (2015) lifetime estimator.

    Parameters
    ----------
    sensor_size : SensorSize or (width, height)
        Sensor size; events must lie inside it.
    params : MuegglerParams, optional
        Defaults to the paper's values.
    time_origin_us : int, optional
        Time (us) from which the plane's absolute time is counted. Default:
        the first event processed after construction or :meth:`reset`, as
        the MATLAB code does. Events before it are rejected.

    Notes
    -----
    See the module docstring for the algorithm and its absolute-time quirk.
    Chunks must be time-ordered across calls; the output for a stream cut
    into chunks equals the one-shot output exactly.
    """

    def __init__(
        self, sensor_size: SensorSize, params: MuegglerParams | None = None, *, time_origin_us: int | None = None
    ) -> None:
        sensor_size = check_sensor_size(sensor_size)  # as every other detector entry point
        if params is None:
            params = MuegglerParams()
        if not isinstance(params, MuegglerParams):
            raise TypeError(f"params must be a MuegglerParams, got {type(params).__name__}")
        if time_origin_us is not None:
            if isinstance(time_origin_us, bool) or not isinstance(time_origin_us, (int, np.integer)):
                raise TypeError(f"time_origin_us must be an integer (microseconds), got {time_origin_us!r}")
            time_origin_us = int(time_origin_us)
        self.sensor_size = sensor_size
        self.params = params
        self._time_origin_arg = time_origin_us
        self.reset()

    def reset(self) -> None:
        """Forget all state: SAEs, predictions, time origin and event count."""
        n_pol = 2 if self.params.per_polarity else 1
        n_pix = n_pol * self.sensor_size.width * self.sensor_size.height
        self._sae = np.full(n_pix, NEVER_FIRED, dtype=np.int64)
        self._prior_theta = np.zeros(3 * n_pix, dtype=np.float64)
        self._prior_t = np.zeros(n_pix, dtype=np.float64)
        self._n_seen = 0
        self._last_t: int | None = None
        self.time_origin_us: int | None = self._time_origin_arg

    @property
    def n_events_seen(self) -> int:
        """Events processed since construction or the last :meth:`reset`."""
        return self._n_seen

    def process(self, chunk: np.ndarray) -> np.ndarray:
        """Estimate lifetimes for the next time-ordered chunk of events.

        Parameters
        ----------
        chunk : numpy.ndarray
            Events of :data:`evedge.events.EVENT_DTYPE`, sorted by time, not
            earlier than the previous chunk.

        Returns
        -------
        numpy.ndarray
            :data:`~evedge.detector.result.LIFETIME_DTYPE`, one row per event
            (``lifetime_us`` in us, flow in px/s; NaN and ``valid`` False
            when no estimate).
        """
        chunk = validate_events(chunk, self.sensor_size, name="chunk")
        n = chunk.shape[0]
        out = np.empty(n, dtype=LIFETIME_DTYPE)
        if n == 0:
            return out
        t = np.ascontiguousarray(chunk["t"], dtype=np.int64)
        if self._last_t is not None and t[0] < self._last_t:
            raise ValueError(
                f"chunk: first event has t={int(t[0])} us, earlier than the previous chunk's last "
                f"event (t={self._last_t} us); chunks must be time-ordered"
            )
        if self.time_origin_us is None:
            self.time_origin_us = int(t[0])
        if t[0] < self.time_origin_us:
            raise ValueError(
                f"chunk: event 0 has t={int(t[0])} us, before time_origin_us={self.time_origin_us}"
            )
        if int(t[-1]) - self.time_origin_us > np.iinfo(np.int64).max:  # t - origin would wrap around
            raise ValueError(
                f"time_origin_us={self.time_origin_us} is too far before the events (t={int(t[-1])} us): "
                "their difference does not fit in int64 microseconds"
            )
        t_rel = t - self.time_origin_us
        x = np.ascontiguousarray(chunk["x"], dtype=np.int64)
        y = np.ascontiguousarray(chunk["y"], dtype=np.int64)
        if self.params.per_polarity:
            pol = np.ascontiguousarray(chunk["p"], dtype=np.int64)
        else:
            pol = np.zeros(n, dtype=np.int64)
        life = np.empty(n, dtype=np.float64)
        vx = np.empty(n, dtype=np.float64)
        vy = np.empty(n, dtype=np.float64)
        valid = np.empty(n, dtype=np.bool_)
        p = self.params
        _mueggler_kernel(
            x, y, t_rel, pol, self._sae, self._prior_theta, self._prior_t,
            self.sensor_size.width, self.sensor_size.height, p.window_size_px, p.n_trials,
            p.inlier_threshold, p.residual_threshold, p.regularize, p.lambda_base, p.lambda_gain,
            p.lambda_decay_per_us, p.shift_prior_frame, np.uint64(p.seed), self._n_seen, life, vx, vy, valid,
        )  # fmt: skip
        self._n_seen += n
        self._last_t = int(t[-1])
        out["lifetime_us"] = life
        out["vx_px_s"] = vx
        out["vy_px_s"] = vy
        out["valid"] = valid
        return out


def estimate_lifetimes_mueggler(
    events: np.ndarray,
    sensor_size: SensorSize,
    params: MuegglerParams | None = None,
    *,
    time_origin_us: int | None = None,
) -> np.ndarray:
    """Mueggler et al. (2015) lifetimes of a whole event array.

    Parameters
    ----------
    events : numpy.ndarray
        Time-sorted events of :data:`evedge.events.EVENT_DTYPE`.
    sensor_size : SensorSize or (width, height)
    params : MuegglerParams, optional
        Defaults to the paper's values (N = 5, eps = 0.4, mu = 1e-4, prior on).
    time_origin_us : int, optional
        Origin of the absolute time; default the first event's time.

    Returns
    -------
    numpy.ndarray
        :data:`~evedge.detector.result.LIFETIME_DTYPE`, aligned with ``events``.

    See Also
    --------
    MuegglerLifetime : the streaming form (identical results).
    """
    return MuegglerLifetime(sensor_size, params, time_origin_us=time_origin_us).process(events)


def _registered(sensor_size, *, time_origin_us: int | None = None, **params) -> MuegglerLifetime:
    """Factory of the method registry: ``MuegglerLifetime(sensor_size, MuegglerParams(**params), time_origin_us=...)``."""
    return MuegglerLifetime(sensor_size, MuegglerParams(**params), time_origin_us=time_origin_us)


METHODS.register("mueggler", _registered, kind="estimator", display_name="Mueggler et al. 2015", colour="#c9a400",
                 params=MuegglerParams, filter=None, extra_params=("time_origin_us",))
