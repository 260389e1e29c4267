"""MATLAB ``.mat`` event files of Mueggler et al.'s lifetime code (DVS128).

One variable ``events``: an N x 4 integer matrix with columns
``[x, y, polarity, t]``, polarity in {-1, +1}, ``t`` in microseconds.

References
----------
.. [1] E. Mueggler, C. Forster, N. Baumli, G. Gallego, D. Scaramuzza,
       "Lifetime estimation of events from dynamic vision sensors", ICRA 2015
       (github.com/uzh-rpg/rpg_event_lifetime, ``matlab/data/*.mat``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..events import SENSOR_PRESETS, Recording, SensorSize
from ._checks import EventFileError, finish_events
from ._isolated import DecoderError, run_isolated
from .registry import Format, register_format

_COLUMNS = ("x", "y", "p", "t")


def _load_variables(path: Path, variable: str) -> dict:
    """``{name: value}`` with ``variable``'s value, or ``{name: None}`` for the other variables."""
    import scipy.io  # heavy; only .mat reading needs it

    names = [name for name, _, _ in scipy.io.whosmat(path)]
    if variable not in names:
        return dict.fromkeys(names)
    return {variable: scipy.io.loadmat(path, variable_names=[variable])[variable]}


def read_mat(
    path: str | os.PathLike,
    *,
    sensor_size: SensorSize | None = None,
    sort: bool = False,
    variable: str = "events",
) -> Recording:
    """Read a ``.mat`` file holding an ``events`` matrix ``[x, y, p(+-1), t(us)]``.

    Parameters
    ----------
    path : path-like
    sensor_size : SensorSize, optional
        Defaults to DVS128 (128 x 128), the camera of these recordings.
    sort : bool
        Sort by time (stable) instead of raising on decreasing timestamps.
    variable : str
        Name of the matrix in the file.

    Returns
    -------
    Recording
        ``metadata["sensor_size_from"]`` is ``"dvs128 .mat convention"`` or ``"option"``.

    Raises
    ------
    EventFileError
        File not a MATLAB v5 file, variable missing, wrong shape, non-integer
        values, polarity outside {-1, +1}, coordinates outside the sensor,
        unsorted timestamps (unless ``sort``). Messages name the file, the
        variable and the row (0-based).
    """
    import scipy.io  # noqa: F401 - heavy; imported here once, not in every child process

    path = Path(path)
    if path.is_dir():
        raise EventFileError(f"{path}: is a folder, not a MATLAB .mat file")
    try:
        # scipy's parser segfaults on some corrupt files: it runs in a child process
        content = run_isolated(path, "scipy .mat", _load_variables, path, variable)
    except DecoderError as err:
        message = str(err)
        if message.startswith("NotImplementedError"):  # v7.3 files are HDF5 inside
            raise EventFileError(f"{path}: MATLAB v7.3 files are not supported; save with -v7: {message}") from None
        # scipy fails on garbage in many ways (MatReadError, IndexError, struct.error, ...);
        # all mean the same to the user: this is not a .mat file it can read
        raise EventFileError(f"{path}: not a readable MATLAB .mat file: {message}") from None
    if variable not in content:
        found = sorted(k for k in content if not k.startswith("__")) or ["none"]
        raise EventFileError(f"{path}: no variable {variable!r} (variables: {', '.join(found)})")
    matrix = np.asarray(content[variable])
    if matrix.size == 0:
        matrix = np.empty((0, 4), dtype=np.int64)
    if matrix.ndim != 2 or matrix.shape[1] != 4:
        raise EventFileError(
            f"{path}: variable {variable!r} has shape {matrix.shape}, expected N x 4 columns [x, y, p, t]"
        )
    if matrix.dtype.kind not in "iuf":
        raise EventFileError(f"{path}: variable {variable!r} has dtype {matrix.dtype}, expected integers")

    def locate(i: int) -> str:
        return f"variable {variable!r} row {i} (0-based)"

    for j, name in enumerate(_COLUMNS):
        col = matrix[:, j]
        if col.dtype.kind == "f":
            bad = np.flatnonzero(~np.isfinite(col) | (col != np.rint(col)))
            if bad.size:
                i = int(bad[0])
                raise EventFileError(f"{path}: {locate(i)}: column {name!r} = {float(col[i])} is not an integer")
            # the cast to int64 below would wrap these
            big = np.flatnonzero(np.abs(col) >= 2.0**63)
            if big.size:
                i = int(big[0])
                raise EventFileError(f"{path}: {locate(i)}: column {name!r} = {float(col[i])} is out of the int64 range")
        elif col.dtype == np.uint64 and col.size and int(col.max()) > np.iinfo(np.int64).max:
            i = int(np.flatnonzero(col > np.iinfo(np.int64).max)[0])
            raise EventFileError(f"{path}: {locate(i)}: column {name!r} = {int(col[i])} is out of the int64 range")
    x, y, p, t = (matrix[:, j].astype(np.int64) for j in range(4))
    bad = np.flatnonzero((p != 1) & (p != -1))
    if bad.size:
        i = int(bad[0])
        raise EventFileError(f"{path}: {locate(i)}: polarity {int(p[i])}, expected -1 or +1")
    if sensor_size is None:
        sensor_size, size_from = SENSOR_PRESETS["dvs128"], "dvs128 .mat convention"
    else:
        size_from = "option"
    events, was_sorted = finish_events(path, x, y, t, p > 0, sensor_size, size_from, locate, sort)
    metadata = {"source": str(path), "format": "mat", "sensor_size_from": size_from}
    if was_sorted:
        metadata["sorted_on_load"] = True
    return Recording(events, sensor_size, metadata=metadata)


register_format(Format(
    "mat", "MATLAB .mat with an events matrix [x, y, p, t] (Mueggler et al.'s DVS128 data)",
    extensions=(".mat",), read=read_mat, sniff=lambda head: head.startswith(b"MATLAB 5.0 MAT-file"),
))
