"""One entry point for writing: :func:`write_events`, dispatching through the format registry."""

from __future__ import annotations

import os
from pathlib import Path

from ..events import Recording
from .registry import get_format, output_format

__all__ = ["write_events"]


def write_events(path: str | os.PathLike, recording: Recording, *, format: str | None = None) -> Path:
    """Write ``recording`` in the format named by ``format`` or by the extension of ``path``.

    Parameters
    ----------
    path : path-like
        The output file (a folder for the Event Camera Dataset format, chosen
        when ``path`` has no extension). ``.raw`` writes EVT 3.
    recording : Recording
    format : str, optional
        A registered format that can write (``"evt3"``, ``"aedat4"``, ``"hdf5"``, ``"ecd"``, ...).

    Returns
    -------
    Path
        What was written. Every writer is atomic: a temp file beside the
        target, renamed on success, so a failure leaves no half-written output.

    Raises
    ------
    ValueError
        Unknown format or extension, or events the format cannot hold (the
        message says which event and why).

    Examples
    --------
    >>> from evedge.io import read_events, write_events
    >>> write_events("out.raw", read_events("in.aedat4"))  # doctest: +SKIP
    """
    if not isinstance(recording, Recording):
        raise TypeError(f"write_events: expected a Recording, got {type(recording).__name__}")
    name = format if format is not None else output_format(path)
    try:
        fmt = get_format(name, need="write")
    except ValueError as err:
        raise ValueError(f"write_events: {err}") from None
    return fmt.write(Path(path), recording)
