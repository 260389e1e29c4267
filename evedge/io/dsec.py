"""Write events in the DSEC layout, so DSEC's loaders (and anything built on them) read them.

Layout of DSEC's ``events/left/events.h5`` (Gehrig et al., RA-L 2021), as its
``EventSlicer`` reads it::

    /events/x   uint16    /events/y   uint16
    /events/t   uint32    microseconds since t_offset
    /events/p   uint8     polarity, 0 or 1
    /ms_to_idx  uint64    ms_to_idx[k] = index of the first event with t >= 1000 k
    /t_offset   int64     add to events/t for the absolute time (us)

``ms_to_idx`` has ``t[-1] // 1000 + 2`` entries (the last one is past every
event); absolute time is ``events/t + t_offset``. DSEC compresses with blosc
through ``hdf5plugin``; this writer uses gzip, which plain ``h5py`` reads.
Writes are deterministic (no HDF5 timestamps) and atomic (temp file, rename).

References
----------
.. [1] M. Gehrig, W. Aarents, D. Gehrig and D. Scaramuzza, "DSEC: A Stereo
       Event Camera Dataset for Driving Scenarios", IEEE RA-L 2021
       (github.com/uzh-rpg/DSEC, ``scripts/utils/eventslicer.py``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..events import validate_events
from ._atomic import check_output_file, write_hdf5_atomic

_CHUNK = 1 << 18


def ms_to_idx(t_us: np.ndarray) -> np.ndarray:
    """``out[k]`` = index of the first event with ``t_us >= 1000 k``, for ``k = 0 .. t_us[-1] // 1000 + 1``."""
    t = np.asarray(t_us, dtype=np.int64)
    n = int(t[-1]) // 1000 + 2 if t.size else 1
    return np.searchsorted(t, np.arange(n, dtype=np.int64) * 1000, side="left").astype(np.uint64)


def write_dsec_events(path: str | os.PathLike, events: np.ndarray) -> Path:
    """Write ``events`` (EVENT_DTYPE, sorted by time) as a DSEC ``events.h5``.

    ``t_offset`` is the first event's time rounded down to a millisecond, so
    the relative times start within the first millisecond of ``ms_to_idx``.

    Parameters
    ----------
    path : path-like
        The file to write (its folder must exist).
    events : numpy.ndarray of EVENT_DTYPE
        Sorted by time; negative coordinates are refused by the event checks.

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        The events are not sorted, or span more than ``2**32 - 1`` us
        (``events/t`` is uint32 in DSEC).

    Examples
    --------
    >>> from evedge.events import make_events
    >>> ev = make_events([1, 2], [0, 0], [1500, 2600], [1, 0])
    >>> ms_to_idx(ev["t"]).tolist()
    [0, 0, 1, 2]
    """

    events = validate_events(events, name="write_dsec_events: events")
    t = events["t"].astype(np.int64)
    if t.size and np.any(np.diff(t) < 0):
        raise ValueError("write_dsec_events: events must be sorted by time (DSEC's ms_to_idx needs it)")
    t_offset = int(t[0]) // 1000 * 1000 if t.size else 0
    rel = t - t_offset
    if rel.size and rel[-1] > np.iinfo(np.uint32).max:
        raise ValueError(f"write_dsec_events: events span {rel[-1]} us; DSEC's uint32 events/t holds at most "
                         f"{np.iinfo(np.uint32).max} us (~71 min)")
    path = Path(path)
    check_output_file(path, "write_dsec_events")
    def fill(f):
        g = f.create_group("events", track_order=True)
        opts = dict(track_times=False)
        if t.size:
            opts.update(chunks=(min(t.size, _CHUNK),), compression="gzip", compression_opts=4, shuffle=True)
        for name, col in (("p", events["p"].astype(np.uint8)), ("t", rel.astype(np.uint32)),
                          ("x", events["x"].astype(np.uint16)), ("y", events["y"].astype(np.uint16))):
            # flushed at once: the file layout must not depend on when the dataset object is freed
            g.create_dataset(name, data=col, **opts).flush()
        f.create_dataset("ms_to_idx", data=ms_to_idx(rel), track_times=False)
        f.create_dataset("t_offset", data=np.int64(t_offset), track_times=False)

    # built in memory, then written with plain writes: HDF5 can crash the process on a full disk
    return write_hdf5_atomic(path, fill)
