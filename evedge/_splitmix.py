"""splitmix64, the counter-based hash behind every random draw inside numba kernels.

One home for the simulator and the detectors: a draw is ``_splitmix64`` of a
seed mixed with global indices (pixel, event, per-pixel counter), so results
never depend on how a stream is cut into chunks.

References
----------
.. [1] G. L. Steele, D. Lea and C. H. Flood, "Fast splittable pseudorandom
       number generators", OOPSLA 2014 (the splitmix64 finaliser constants).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: The golden-ratio increment of splitmix64 (2^64 / phi, odd).
GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


@njit(cache=True)
def _splitmix64(x):
    """One splitmix64 output for the state ``x`` (uint64 arithmetic, wraps modulo 2^64)."""
    z = x + GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))
