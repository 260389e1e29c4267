"""Never half-written output: write a temp file beside the target, then rename it.

:func:`tempfile.mkstemp` creates files readable by their owner only (mode
0600) and :func:`tempfile.mkdtemp` folders of mode 0700; renamed into place
they would keep those modes, so the helpers here give them the modes a plain
``open(..., "w")`` / ``mkdir`` would (0666 / 0777 minus the umask).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def current_umask() -> int:
    """The process umask (read by setting it and restoring it at once)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def check_output_file(target: Path, who: str) -> None:
    """Raise a clear ``OSError`` when ``target`` cannot be written as a file.

    Parameters
    ----------
    target : Path
        The file to be written.
    who : str
        The writer, for the message (``"write_recording"``).

    Raises
    ------
    FileNotFoundError
        When the folder of ``target`` does not exist.
    IsADirectoryError
        When ``target`` is an existing folder.
    """
    parent = target.parent
    if not parent.is_dir():
        raise FileNotFoundError(f"{who}: cannot write {target}: folder {parent} does not exist")
    if target.is_dir():
        raise IsADirectoryError(f"{who}: cannot write {target}: it is an existing folder")


@contextmanager
def atomic_path(target: Path, suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a temp path beside ``target``; on success rename it to ``target``.

    On any exception the temp file is removed and ``target`` is untouched.
    The temp name starts with a dot and ends in ``suffix`` (``.tmp``; a
    writer that picks its container by extension, as OpenCV's video writer
    does, passes e.g. ``".tmp.mp4"``).
    """
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=suffix)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~current_umask())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def make_temp_dir(parent: Path, name: str) -> Path:
    """A new folder ``parent/.name.XXXX.tmp`` with the mode ``mkdir`` would give it."""
    tmp = Path(tempfile.mkdtemp(dir=parent, prefix=f".{name}.", suffix=".tmp"))
    os.chmod(tmp, 0o777 & ~current_umask())
    return tmp
