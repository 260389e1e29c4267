"""Never half-written output: write a temp file beside the target, then rename it.

:func:`tempfile.mkstemp` creates files readable by their owner only (mode
0600) and :func:`tempfile.mkdtemp` folders of mode 0700; renamed into place
they would keep those modes, so the helpers here give them the modes a plain
``open(..., "w")`` / ``mkdir`` would (0666 / 0777 minus the umask).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
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


def temp_prefix(target: Path) -> str:
    """Prefix of the temp files and folders made for ``target``: ``.NAME.PID.`` (the writer's process id)."""
    return f".{target.name}.{os.getpid()}."


def remove_stale_temps(target: Path) -> None:
    """Remove temp files and folders beside ``target`` left by writers that were killed.

    A temp entry is stale when the process id in its name (:func:`temp_prefix`)
    no longer runs; entries of running writers are left alone.
    """
    try:
        entries = list(target.parent.glob(f".{glob_escape(target.name)}.*.tmp"))
    except OSError:
        return
    for entry in entries:
        parts = entry.name[len(target.name) + 2:].split(".")
        if not parts or not parts[0].isdigit() or int(parts[0]) == os.getpid():
            continue
        try:
            os.kill(int(parts[0]), 0)
            continue  # its writer still runs
        except ProcessLookupError:
            pass
        except (PermissionError, OverflowError):
            continue
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            entry.unlink(missing_ok=True)


def glob_escape(name: str) -> str:
    """``name`` with glob metacharacters escaped."""
    return "".join(f"[{c}]" if c in "*?[" else c for c in name)


@contextmanager
def atomic_path(target: Path, suffix: str = ".tmp") -> Iterator[Path]:
    """Yield a temp path beside ``target``; on success rename it to ``target``.

    On any exception the temp file is removed and ``target`` is untouched.
    The temp name starts with a dot and ends in ``suffix`` (``.tmp``; a
    writer that picks its container by extension, as OpenCV's video writer
    does, passes e.g. ``".tmp.mp4"``); temp files of killed writers of the
    same target are removed first.
    """
    remove_stale_temps(target)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=temp_prefix(target), suffix=suffix)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~current_umask())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_hdf5_atomic(target: Path, fill: Callable) -> Path:
    """Build an HDF5 file in memory with ``fill(h5py.File)``, then write it through a temp file.

    HDF5 itself does not survive a full disk: when its own writes fail with
    ``ENOSPC``, closing the file raises from a destructor and the process can
    die of SIGSEGV (h5py 3.x). Built in a :class:`io.BytesIO` (the bytes are
    the same as on disk), the file reaches the disk through plain writes that
    fail with an ``OSError``, and the temp file is removed.

    Parameters
    ----------
    target : Path
        The file to write (renamed into place at the end).
    fill : callable
        Called with the open ``h5py.File`` (mode ``"w"``, creation order tracked).

    Returns
    -------
    Path
        ``target``.
    """
    import io

    import h5py

    buf = io.BytesIO()
    with h5py.File(buf, "w", track_order=True) as f:
        fill(f)
    with atomic_path(target) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(buf.getbuffer())
    return target


def make_temp_dir(parent: Path, name: str) -> Path:
    """A new folder ``parent/.name.PID.XXXX.tmp`` with the mode ``mkdir`` would give it.

    Stale folders of killed writers (:func:`remove_stale_temps`) are removed first.
    """
    remove_stale_temps(parent / name)
    tmp = Path(tempfile.mkdtemp(dir=parent, prefix=temp_prefix(parent / name), suffix=".tmp"))
    os.chmod(tmp, 0o777 & ~current_umask())
    return tmp
