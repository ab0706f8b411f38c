"""Name -> lazily imported factory, so the CLI lists everything without importing torch or robosuite."""

from __future__ import annotations

import importlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from indgen_vla.core.errors import UnknownNameError


@dataclass(frozen=True)
class Entry:
    """One registered name: where to import it from and a one-line description."""

    name: str
    target: str  # "package.module:attr"
    description: str


class Registry[T]:
    """A registry of lazily imported objects that suggests the right name on a typo."""

    def __init__(self, kind: str):
        self.kind = kind
        self._entries: dict[str, Entry] = {}

    def register(self, name: str, target: str, description: str) -> None:
        if name in self._entries and self._entries[name].target != target:
            raise ValueError(f"{self.kind} {name!r} already registered to {self._entries[name].target}")
        self._entries[name] = Entry(name, target, description)

    def entry(self, name: str) -> Entry:
        try:
            return self._entries[name]
        except KeyError:
            raise UnknownNameError(self.kind, name, list(self._entries)) from None

    def load(self, name: str) -> T:
        """Import and return the object registered under ``name``."""
        module, _, attr = self.entry(name).target.partition(":")
        obj: Any = importlib.import_module(module)
        for part in attr.split("."):
            obj = getattr(obj, part)
        return obj

    def names(self) -> list[str]:
        return sorted(self._entries)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[Entry]:
        return iter(sorted(self._entries.values(), key=lambda e: e.name))


def lookup[T](kind: str, name: str, table: dict[str, T]) -> T:
    """Dictionary lookup that raises ``UnknownNameError`` with suggestions."""
    try:
        return table[name]
    except KeyError:
        raise UnknownNameError(kind, name, list(table)) from None
