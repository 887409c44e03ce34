"""One registry type for every pluggable component: name -> object, plus a little metadata.

Policies, path-loss models, rate tables, trace formats, executors, exporters and scenario
presets are all looked up by a name a user typed. A :class:`Registry` keeps them in
registration order and turns a wrong name into the one line every CLI error has::

    unknown path-loss model 'fsp'; allowed: fspl, log-distance, two-ray; did you mean 'fspl'?

Registries are built once at import time of the module that owns the components and are not
changed afterwards by skymule itself (a plug-in may ``register`` its own entry).
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

from skymule.errors import SkymuleError

T = TypeVar("T")


def did_you_mean(name: str, choices: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest of ``choices`` to ``name``, else ``""``."""
    names = list(choices)
    close = difflib.get_close_matches(name, names, n=1, cutoff=0.6)
    if not close and name:
        # a unique prefix ("aadm" for "aadm-default") is a likely meant name as well
        close = [n for n in names if n.startswith(name)][:2]
        close = close if len(close) == 1 else []
    return f"; did you mean {close[0]!r}?" if close else ""


def unknown_name_message(kind: str, name: str, choices: Iterable[str], extra: str = "") -> str:
    """The one-line "unknown <kind> 'x'; allowed: a, b; did you mean 'y'?" message."""
    names = list(choices)
    allowed = ", ".join(names) + (f" {extra}" if extra else "")
    return f"unknown {kind} {name!r}; allowed: {allowed}{did_you_mean(name, names)}"


@dataclass(frozen=True)
class Entry(Generic[T]):
    """One registered component: its name, the object, and free-form metadata."""

    name: str
    obj: T
    meta: dict[str, Any] = field(default_factory=dict)


class Registry(Generic[T]):
    """Named components of one kind (``kind`` is what error messages call them).

    ``registry[name]`` and :meth:`get` return the object; :meth:`entry` returns it with its
    metadata (e.g. a path-loss model's ``monotone`` flag or a policy's parameter model).
    """

    def __init__(self, kind: str, *, extra_allowed: str = "") -> None:
        self.kind = kind
        self._extra_allowed = extra_allowed
        self._entries: dict[str, Entry[T]] = {}

    def register(self, name: str, obj: T, **meta: Any) -> T:
        """Add ``obj`` under ``name`` (a name can be registered once) and return ``obj``."""
        if name in self._entries:
            raise ValueError(f"{self.kind} {name!r} is already registered")
        self._entries[name] = Entry(name, obj, dict(meta))
        return obj

    def names(self) -> list[str]:
        """Registered names, in registration order."""
        return list(self._entries)

    def error(self, name: str) -> SkymuleError:
        """The one-line error for a name that is not registered."""
        return SkymuleError(unknown_name_message(self.kind, name, self, self._extra_allowed))

    def entry(self, name: str) -> Entry[T]:
        """The entry for ``name``; raises the one-line :class:`SkymuleError` if unknown."""
        try:
            return self._entries[name]
        except KeyError:
            raise self.error(name) from None

    def get(self, name: str) -> T:
        return self.entry(name).obj

    def meta(self, name: str, key: str, default: Any = None) -> Any:
        return self.entry(name).meta.get(key, default)

    def __getitem__(self, name: str) -> T:
        return self.get(name)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def items(self) -> list[tuple[str, T]]:
        return [(name, entry.obj) for name, entry in self._entries.items()]

    def where(self, predicate: Callable[[Entry[T]], bool]) -> list[str]:
        """Names of the entries for which ``predicate(entry)`` is true."""
        return [name for name, entry in self._entries.items() if predicate(entry)]

    def __repr__(self) -> str:
        return f"Registry({self.kind!r}: {', '.join(self._entries)})"
