"""Readers and writers of event recordings, and their summary.

Every format is one module registered in :mod:`evedge.io.registry` by name,
extensions and content (``evedge.io.formats()`` lists them): Event Camera
Dataset folders (``events.txt`` + ``images.txt`` + PNG frames + ``calib.txt``),
MATLAB ``.mat`` (Mueggler et al.'s DVS128 lifetime data), the project's HDF5
format (events + truth + frames + edge maps), AEDAT 4 (``aedat``/faery),
AEDAT 2.0 and 3.1, Prophesee EVT 2/EVT 3 ``.raw`` and ``.dat``, and Event
Stream ``.es``. :func:`read_events` and :func:`write_events` dispatch through
the registry. Every reader returns a :class:`evedge.events.Recording` and
raises :class:`EventFileError` (a ``ValueError``) naming the file and the
line, index, byte offset or variable on bad input; every writer is atomic.
"""

from ._checks import EventFileError
from .aedat import read_aedat2, read_aedat3
from .aedat4 import read_aedat4, write_aedat4
from .ecd import read_ecd, write_ecd
from .es import read_es, write_es
from .hdf5 import iter_hdf5_events, read_hdf5, write_recording
from .matlab import read_mat
from .prophesee import read_dat, read_evt2, read_evt3, write_dat, write_evt2, write_evt3
from .read import read_events
from .registry import Format, detect_format, formats, get_format, register_format
from .summary import format_summary, summarize
from .write import write_events

__all__ = [
    "EventFileError",
    "Format",
    "detect_format",
    "format_summary",
    "formats",
    "get_format",
    "iter_hdf5_events",
    "read_aedat2",
    "read_aedat3",
    "read_aedat4",
    "read_dat",
    "read_ecd",
    "read_es",
    "read_events",
    "read_evt2",
    "read_evt3",
    "read_hdf5",
    "read_mat",
    "register_format",
    "summarize",
    "write_aedat4",
    "write_dat",
    "write_ecd",
    "write_es",
    "write_events",
    "write_evt2",
    "write_evt3",
    "write_recording",
]
