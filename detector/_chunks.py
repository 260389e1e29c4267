"""Chunks of events for the parallel passes over whole event arrays (numba ``prange`` over chunks).

A pass over all events (row counts, the strips' index and gather, the kept
events' columns, their expansion, the buffer's final or) is cut into chunks of
:data:`CHUNK_EVENTS` consecutive events. A chunk's work touches only its own
events and its own place in the output, fixed by counts taken first, so the
result is the serial one for any number of threads.
"""

from numba import njit

#: Events per chunk: large enough that a chunk's work outweighs scheduling it, small enough that
#: a few million events make many chunks for the threads to share.
CHUNK_EVENTS = 1 << 15


@njit(cache=True, inline="always")
def n_chunks(n):
    """Chunks of ``n`` events."""
    return (n + CHUNK_EVENTS - 1) // CHUNK_EVENTS


@njit(cache=True, inline="always")
def chunk_bounds(c, n):
    """Events ``[lo, hi)`` of chunk ``c`` of ``n`` events."""
    return c * CHUNK_EVENTS, min(n, (c + 1) * CHUNK_EVENTS)
