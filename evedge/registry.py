"""One small generic registry: name -> factory, with a display name, a colour, a kind and metadata.

Every extension point of evedge (methods, metrics, experiments) is one
:class:`Registry`. Built-ins register themselves in their own module (the
registry imports those modules the first time it is asked), third parties
through a Python entry-point group (``[project.entry-points."evedge.methods"]``
in their ``pyproject.toml``) or, without installing anything, by naming
``package.module:factory`` wherever a registered name is accepted.

Examples
--------
>>> reg = Registry("widget", kinds=("round", "square"))
>>> e = reg.register("disc", lambda r=1.0: ("disc", r), kind="round", display_name="a disc")
>>> reg.get("disc").factory(2.0)
('disc', 2.0)
>>> reg.names(kind="round")
('disc',)
>>> reg.get("os.path:join").name      # any importable ``module:attribute``
'os.path:join'
"""

from __future__ import annotations

import importlib
import re
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Mapping

__all__ = ["Entry", "Registry", "RegistryError", "resolve_target"]

#: Colours handed, in order, to entries registered without one (matplotlib's tab10 minus the
#: built-ins' hues, so a plug-in never looks like a built-in).
_PALETTE = ("#1f77b4", "#ff7f0e", "#d62728", "#9467bd", "#8c564b", "#bcbd22", "#393b79", "#637939")

_TARGET = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_][\w.]*$")


class RegistryError(ValueError, LookupError):
    """An unknown name, an unresolvable ``module:factory`` or an entry of the wrong kind."""


@dataclass(frozen=True)
class Entry:
    """One registered thing.

    Parameters
    ----------
    name : str
        The one name it is known by (CLI choices, results, figures).
    factory : callable
        Builds (or is) the thing; its signature is the registry's convention.
    kind : str
        What protocol it follows (e.g. ``"estimator"``).
    display_name : str
        Human-readable name for legends and tables.
    colour : str
        Matplotlib colour for figures.
    metadata : mapping
        Anything else the users of this registry agree on (e.g. default parameters).
    source : str
        ``"builtin"``, ``"entry point"`` or ``"module:factory"``: where it came from.
    """

    name: str
    factory: Callable
    kind: str
    display_name: str
    colour: str
    metadata: Mapping[str, Any] = field(default_factory=dict)
    source: str = "builtin"


def resolve_target(target: str) -> Any:
    """The object named by ``"package.module:attribute"`` (attribute may be dotted).

    Raises
    ------
    RegistryError
        Naming the target and what failed (malformed, module not importable, no such attribute).
    """
    if not isinstance(target, str) or not _TARGET.match(target):
        raise RegistryError(f"{target!r} is not of the form 'package.module:factory'")
    module_name, attr = target.split(":")
    try:
        obj = importlib.import_module(module_name)
    except ImportError as exc:
        raise RegistryError(f"{target!r}: cannot import module {module_name!r}: {exc}") from None
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise RegistryError(f"{target!r}: module {module_name!r} has no attribute {attr!r}") from None
    return obj


class Registry:
    """A registry of named factories of several kinds.

    Parameters
    ----------
    what : str
        What is registered, for messages (``"method"``).
    kinds : sequence of str, optional
        The allowed kinds; any kind when omitted.
    entry_point_group : str, optional
        Entry-point group read on first use (each entry point loads an
        :class:`Entry` or a factory, see :meth:`entry_from_object`).
    builtins : sequence of str, optional
        Modules imported on first use; they register the built-ins.
    """

    def __init__(self, what: str, *, kinds: Iterable[str] | None = None, entry_point_group: str | None = None,
                 builtins: Iterable[str] = ()) -> None:
        self.what = what
        self.kinds = tuple(kinds) if kinds is not None else None
        self.entry_point_group = entry_point_group
        self._builtins = tuple(builtins)
        self._entries: dict[str, Entry] = {}
        self._loaded = False
        self._loading = False

    # -- registration -------------------------------------------------------------------------
    def register(self, name: str, factory: Callable | None = None, *, kind: str, display_name: str | None = None,
                 colour: str | None = None, source: str = "builtin", **metadata):
        """Register ``factory`` under ``name``; without ``factory``, a decorator.

        Raises
        ------
        ValueError
            For an empty or already registered name or an unknown kind.
        """
        if factory is None:
            return lambda f: (self.register(name, f, kind=kind, display_name=display_name, colour=colour,
                                            source=source, **metadata), f)[1]
        if not isinstance(name, str) or not name or ":" in name:
            raise ValueError(f"{self.what} name must be a non-empty string without ':', got {name!r}")
        if self.kinds is not None and kind not in self.kinds:
            raise ValueError(f"{self.what} {name!r}: kind must be one of {self.kinds}, got {kind!r}")
        if not callable(factory):
            raise TypeError(f"{self.what} {name!r}: factory must be callable, got {type(factory).__name__}")
        if name in self._entries:
            raise ValueError(f"{self.what} {name!r} is already registered (by {self._entries[name].source})")
        entry = Entry(name, factory, kind, display_name or name, colour or self._next_colour(), dict(metadata), source)
        self._entries[name] = entry
        return entry

    def _next_colour(self) -> str:
        used = {e.colour for e in self._entries.values()}
        free = [c for c in _PALETTE if c not in used]
        return free[0] if free else _PALETTE[len(self._entries) % len(_PALETTE)]

    def entry_from_object(self, name: str, obj: Any, source: str) -> Entry:
        """An :class:`Entry` for ``obj``: an Entry as it is, or a factory described by its attributes.

        A factory (class or function) may carry ``kind``, ``display_name``,
        ``colour`` and ``metadata`` attributes; ``kind`` is required when the
        registry has several kinds.
        """
        if isinstance(obj, Entry):
            return obj
        if not callable(obj):
            raise RegistryError(f"{self.what} {name!r} ({source}): expected a factory or an Entry, "
                                f"got {type(obj).__name__}")
        kind = getattr(obj, "kind", None)
        if kind is None:
            if self.kinds is not None and len(self.kinds) > 1:
                raise RegistryError(f"{self.what} {name!r} ({source}): the factory has no 'kind' attribute; "
                                    f"set one of {self.kinds}")
            kind = self.kinds[0] if self.kinds else "default"
        if self.kinds is not None and kind not in self.kinds:
            raise RegistryError(f"{self.what} {name!r} ({source}): kind must be one of {self.kinds}, got {kind!r}")
        used = {e.colour for e in self._entries.values()}
        colour = getattr(obj, "colour", None) or next((c for c in _PALETTE if c not in used), _PALETTE[0])
        return Entry(name, obj, kind, getattr(obj, "display_name", None) or name, colour,
                     dict(getattr(obj, "metadata", None) or {}), source)

    # -- loading ------------------------------------------------------------------------------
    def _load(self) -> None:
        if self._loaded or self._loading:
            return
        self._loading = True
        try:
            for module in self._builtins:
                importlib.import_module(module)
            if self.entry_point_group:
                from importlib.metadata import entry_points

                for ep in entry_points(group=self.entry_point_group):
                    if ep.name in self._entries:
                        warnings.warn(f"{self.what} entry point {ep.name!r} ({ep.value}) ignored: the name is "
                                      f"already registered by {self._entries[ep.name].source}", stacklevel=3)
                        continue
                    try:
                        entry = self.entry_from_object(ep.name, ep.load(), "entry point")
                    except Exception as exc:  # a broken plug-in must not take the built-ins down
                        warnings.warn(f"{self.what} entry point {ep.name!r} ({ep.value}) ignored: {exc}",
                                      stacklevel=3)
                        continue
                    self._entries[ep.name] = Entry(ep.name, entry.factory, entry.kind, entry.display_name,
                                                   entry.colour, entry.metadata, f"entry point {ep.value}")
            self._loaded = True
        finally:
            self._loading = False

    # -- queries ------------------------------------------------------------------------------
    def get(self, name: str, *, kind: str | Iterable[str] | None = None) -> Entry:
        """The entry registered as ``name``, or the one ``"package.module:factory"`` names.

        A ``module:factory`` target is registered under its full text the first
        time, so later look-ups (results, figures) find the same entry.

        Raises
        ------
        RegistryError
            Unknown name (listing the known ones), unresolvable target, or not of ``kind``.
        """
        self._load()
        entry = self._entries.get(name)
        if entry is None and isinstance(name, str) and ":" in name:
            entry = self.entry_from_object(name, resolve_target(name), "module:factory")
            entry = Entry(name, entry.factory, entry.kind, entry.display_name, entry.colour, entry.metadata,
                          "module:factory")
            self._entries[name] = entry
        if entry is None:
            raise RegistryError(f"unknown {self.what} {name!r}; registered: {', '.join(self.names()) or 'none'} "
                                f"(or give 'package.module:factory')")
        if kind is not None:
            kinds = (kind,) if isinstance(kind, str) else tuple(kind)
            if entry.kind not in kinds:
                raise RegistryError(f"{self.what} {name!r} is of kind {entry.kind!r}, not {' or '.join(map(repr, kinds))}")
        return entry

    def names(self, kind: str | Iterable[str] | None = None) -> tuple[str, ...]:
        """Registered names (registration order), optionally of some kinds only."""
        self._load()
        kinds = None if kind is None else ((kind,) if isinstance(kind, str) else tuple(kind))
        return tuple(n for n, e in self._entries.items() if kinds is None or e.kind in kinds)

    def entries(self, kind: str | Iterable[str] | None = None) -> tuple[Entry, ...]:
        """Registered entries (registration order), optionally of some kinds only."""
        return tuple(self._entries[n] for n in self.names(kind))

    def __contains__(self, name: object) -> bool:
        self._load()
        return name in self._entries

    def __iter__(self):
        return iter(self.names())

    def __len__(self) -> int:
        return len(self.names())
