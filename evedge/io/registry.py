"""The registry of event file formats: one entry per format, by name, extension and content.

Each format module (``ecd``, ``hdf5``, ``prophesee``, ...) registers a
:class:`Format` naming its reader and writer; :func:`evedge.io.read_events`,
:func:`evedge.io.write_events`, ``evedge info`` and ``evedge convert`` find
them here, so adding a format is one module plus one :func:`register_format`
call, and the dispatch has no list of formats of its own.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ._checks import EventFileError

#: Modules that register the built-in formats (imported on first use of the registry).
BUILTIN_MODULES = ("ecd", "matlab", "hdf5", "aedat4", "aedat", "prophesee", "es")

#: Bytes read from the start of a file to recognise its format.
HEAD_BYTES = 4096


@dataclass(frozen=True)
class Format:
    """One event file format.

    Attributes
    ----------
    name : str
        Registry key (``"evt3"``), used by ``format=`` and ``--format``.
    description : str
        One line for help texts (``"Prophesee EVT 3.0 (.raw)"``).
    extensions : tuple of str
        Lower-case suffixes with the dot (``(".raw",)``); several formats may
        share one, the content then decides.
    read : callable or None
        ``read(path, *, sensor_size, sort) -> Recording``.
    write : callable or None
        ``write(path, recording) -> Path``; atomic (temp file, then rename).
    sniff : callable or None
        ``sniff(head) -> bool`` on the first :data:`HEAD_BYTES` bytes: True
        when the content is this format.
    folder : bool
        The format is a folder (read when given a directory).
    holds : tuple of str
        What the format keeps besides events (``"frames"``, ``"truth"``, ``"edges"``);
        ``evedge convert`` says what it drops.
    """

    name: str
    description: str
    extensions: tuple[str, ...] = ()
    read: Callable | None = None
    write: Callable | None = None
    sniff: Callable[[bytes], bool] | None = None
    folder: bool = False
    holds: tuple[str, ...] = ()


_REGISTRY: dict[str, Format] = {}
_loaded = False


def register_format(fmt: Format) -> Format:
    """Add ``fmt`` to the registry (a later registration of the same name replaces it)."""
    if not isinstance(fmt, Format):
        raise TypeError(f"register_format: expected a Format, got {type(fmt).__name__}")
    _REGISTRY[fmt.name] = fmt
    return fmt


def formats() -> dict[str, Format]:
    """Every registered format, by name (built-ins first, in registration order)."""
    global _loaded
    if not _loaded:
        _loaded = True
        for module in BUILTIN_MODULES:
            importlib.import_module(f"{__package__}.{module}")
    return dict(_REGISTRY)


def get_format(name: str, *, need: str | None = None) -> Format:
    """The format called ``name``; ``need="read"``/``"write"`` also checks it can do that.

    Raises
    ------
    ValueError
        Unknown name, or a format that cannot read/write, listing those that can.
    """
    table = formats()
    able = sorted(n for n, f in table.items() if need is None or getattr(f, need) is not None)
    fmt = table.get(name)
    if fmt is None or (need is not None and getattr(fmt, need) is None):
        what = "format" if fmt is None else f"format that can {need}"
        raise ValueError(f"format={name!r} is not a known {what}; expected one of {', '.join(able)}")
    return fmt


def _head(path: Path) -> bytes:
    with open(path, "rb") as fh:
        return fh.read(HEAD_BYTES)


def _sniffed(candidates: list[Format], head: bytes) -> list[Format]:
    return [f for f in candidates if f.sniff is not None and f.sniff(head)]


def detect_format(path: str | os.PathLike, *, need: str = "read") -> str:
    """Name the format of ``path``: a folder format for a folder, else by extension, else by content.

    When several formats share the extension (``.raw``: EVT 2 or 3;
    ``.aedat``: AEDAT 2 or 3), the content decides.

    Parameters
    ----------
    path : path-like
        A file, or a folder of a folder format (Event Camera Dataset).
    need : {"read", "write"}
        Only formats that can do this are considered.

    Returns
    -------
    str
        A registered format name.

    Raises
    ------
    EventFileError
        When the path does not exist or the format cannot be told.
    """
    path = Path(path)
    table = {n: f for n, f in formats().items() if getattr(f, need) is not None}
    if path.is_dir():
        folders = [n for n, f in table.items() if f.folder]
        if folders:
            return folders[0]
    if not path.exists():
        raise EventFileError(f"{path}: no such file or directory")
    suffix = path.suffix.lower()
    by_ext = [f for f in table.values() if suffix in f.extensions]
    head = _head(path)
    if len(by_ext) == 1:
        return by_ext[0].name
    if by_ext:
        found = _sniffed(by_ext, head)
        if len(found) == 1:
            return found[0].name
        names = ", ".join(f.name for f in by_ext)
        raise EventFileError(
            f"{path}: the extension {suffix!r} is used by {names} and the header does not say which "
            f"this is; pass format=... (CLI: --format)"
        )
    found = _sniffed(list(table.values()), head)
    if len(found) == 1:
        return found[0].name
    known = "; ".join(f"{f.name} ({'/'.join(f.extensions) or 'folder'})" for f in table.values())
    raise EventFileError(
        f"{path}: unknown event file type (extension {suffix or 'none'!r}, content not recognised); "
        f"supported: {known}; pass format=... to choose"
    )


def output_format(path: str | os.PathLike) -> str:
    """The format to write ``path`` in, from its extension (a path without one: a folder format).

    Raises
    ------
    ValueError
        When no writable format has that extension, listing those that do.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    table = {n: f for n, f in formats().items() if f.write is not None}
    if not suffix:
        folders = [n for n, f in table.items() if f.folder]
        if folders:
            return folders[0]
    found = [n for n, f in table.items() if suffix in f.extensions]
    if found:
        # the first registered writer of an extension is its default (.raw: EVT 3)
        return found[0]
    known = ", ".join(f"{n} ({'/'.join(f.extensions) or 'folder'})" for n, f in table.items())
    raise ValueError(f"{path}: cannot tell the output format from {suffix or 'no extension'!r}; "
                     f"writable: {known}; pass format=... (CLI: --format)")
