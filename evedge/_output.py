"""Outputs written as a whole and swapped in: a command's folder is never half old, half new.

Every command that writes an output (``simulate``, ``detect``, ``bench``,
``demo``) follows one policy:

- An output that exists (a file, or a folder that is not empty) is replaced
  only with ``--overwrite``; without it the command refuses before any work.
- A folder output is written into a fresh temporary folder beside it and
  swapped in at the end with one atomic ``renameat2(RENAME_EXCHANGE)`` (a
  plain rename when there was none), so a reader sees the old output or the
  new one, never a mix, and a killed run leaves the earlier output intact.
- Temporary files and folders carry the writer's process id; a later run
  removes those whose writer no longer runs (a killed run's leftovers).
- Nothing is written or deleted through a link: an output that is a symbolic
  link, or a folder holding links, is refused; the replaced folder is removed
  without following links.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import errno
import os
import shutil
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from .io._atomic import current_umask, remove_stale_temps, temp_prefix

_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


class OutputExistsError(FileExistsError):
    """The output exists and ``--overwrite`` was not given (or it is not ours to replace)."""


def check_output(path: Path, *, overwrite: bool, option: str = "--overwrite") -> bool:
    """Apply the replacement policy to ``path`` before any work; True when it will be replaced.

    Parameters
    ----------
    path : Path
        The output file or folder.
    overwrite : bool
        Whether the user asked to replace an existing output.
    option : str
        The option's name, for the message.

    Returns
    -------
    bool
        True when an existing output will be replaced.

    Raises
    ------
    OutputExistsError
        ``path`` exists (a file, or a non-empty folder) and not ``overwrite``;
        or ``path`` is a symbolic link.
    """
    if path.is_symlink():
        raise OutputExistsError(f"{path} is a symbolic link; give the folder or file it points to")
    if not path.exists():
        return False
    if path.is_dir() and not any(path.iterdir()):
        return False
    if not overwrite:
        raise OutputExistsError(f"{path} already exists; pass {option} to replace it")
    return True


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux ``renameat2``); False when the system cannot."""
    libc_name = ctypes.util.find_library("c")
    if sys.platform != "linux" or libc_name is None:
        return False
    libc = ctypes.CDLL(libc_name, use_errno=True)
    if not hasattr(libc, "renameat2"):
        return False
    rc = libc.renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    if rc == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP):
        return False
    raise OSError(err, f"cannot swap {a} and {b}: {os.strerror(err)}")


def _remove_tree(path: Path) -> None:
    """Remove a folder we made or replaced; ``rmtree`` unlinks links, never follows them."""
    shutil.rmtree(path, ignore_errors=True)


@contextmanager
def staged_folder(target: Path, *, allowed: tuple[str, ...] | None = None) -> Iterator[Path]:
    """Yield a fresh temporary folder beside ``target``; on success swap it in as ``target``.

    Parameters
    ----------
    target : Path
        The output folder (created, or replaced as a whole).
    allowed : tuple of str, optional
        Names an existing ``target`` may hold; anything else (or a link) means
        it is not an output of this command and it is not replaced.

    Yields
    ------
    Path
        The folder to write into.

    Raises
    ------
    OutputExistsError
        An existing ``target`` holds something else than ``allowed``, or a link.
    """
    target = Path(target)
    if target.is_symlink():
        raise OutputExistsError(f"{target} is a symbolic link; give the folder it points to")
    if target.exists():
        if not target.is_dir():
            raise OutputExistsError(f"{target} is an existing file, not an output folder")
        for entry in target.iterdir():
            if entry.is_symlink() or (allowed is not None and entry.name not in allowed):
                what = "a symbolic link" if entry.is_symlink() else "not written by this command"
                raise OutputExistsError(f"{entry} is {what}: {target} is not replaced; choose another output folder")
    target.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temps(target)  # what a killed run left
    stage = Path(tempfile.mkdtemp(dir=target.parent, prefix=temp_prefix(target), suffix=".tmp"))
    os.chmod(stage, 0o777 & ~current_umask())
    try:
        yield stage
        if target.exists():
            if _exchange(stage, target):
                _remove_tree(stage)  # now holds the old output
                return
            old = Path(tempfile.mkdtemp(dir=target.parent, prefix=temp_prefix(target) + "old.", suffix=".tmp"))
            os.replace(target, old / "old")
            os.replace(stage, target)
            _remove_tree(old)
        else:
            os.replace(stage, target)
    except BaseException:
        _remove_tree(stage)
        raise
