"""The per-event output of every lifetime estimator.

One row per input event, aligned with it:

``lifetime_us`` (float64)
    Time for the edge to move one pixel along its normal, in microseconds;
    NaN when the estimator gave no estimate.
``vx_px_s``, ``vy_px_s`` (float64)
    Normal flow in pixels per second; NaN when no estimate.
``valid`` (bool)
    True when the event has an estimate.
"""

import numpy as np

LIFETIME_DTYPE = np.dtype(
    [("lifetime_us", np.float64), ("vx_px_s", np.float64), ("vy_px_s", np.float64), ("valid", bool)]
)


def empty_lifetimes(n: int) -> np.ndarray:
    """An all-invalid lifetime array of length ``n`` (NaN values, ``valid`` False)."""
    out = np.empty(n, dtype=LIFETIME_DTYPE)
    out["lifetime_us"] = np.nan
    out["vx_px_s"] = np.nan
    out["vy_px_s"] = np.nan
    out["valid"] = False
    return out
