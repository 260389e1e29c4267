"""Readers and writers of event recordings, and their summary.

Formats: Event Camera Dataset text folders (``events.txt`` + ``images.txt`` +
PNG frames), MATLAB ``.mat`` (Mueggler et al.'s DVS128 lifetime data), the
project's HDF5 format (events + truth + frames + edge maps), and AEDAT 4
(read only, through the ``aedat`` package). Every reader returns a
:class:`evedge.events.Recording` and raises :class:`EventFileError` (a
``ValueError``) naming the file and the line, index or variable on bad input.
"""

from ._checks import EventFileError
from .aedat4 import read_aedat4
from .ecd import read_ecd, write_ecd
from .hdf5 import iter_hdf5_events, read_hdf5, write_recording
from .matlab import read_mat
from .read import FORMATS, detect_format, read_events
from .summary import format_summary, summarize

__all__ = [
    "EventFileError",
    "FORMATS",
    "detect_format",
    "format_summary",
    "iter_hdf5_events",
    "read_aedat4",
    "read_ecd",
    "read_events",
    "read_hdf5",
    "read_mat",
    "summarize",
    "write_ecd",
    "write_recording",
]
