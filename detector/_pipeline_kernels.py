"""numba kernel of the streaming detector's chunk check (see :class:`evedge.detector.pipeline.Detector`)."""

from numba import njit


@njit(cache=True)
def _chunk_ok(x, y, t, width, height, t_last):
    """Whether every event lies in the sensor and the times never decrease, starting at ``t_last`` or later.

    One pass over the event fields in place (strided views of the records): the
    streaming detector's check of a chunk; on False the caller runs the full
    checks, which name the offending event.
    """
    prev = t_last
    for k in range(x.shape[0]):
        if x[k] < 0 or x[k] >= width or y[k] < 0 or y[k] >= height or t[k] < prev:
            return False
        prev = t[k]
    return True
