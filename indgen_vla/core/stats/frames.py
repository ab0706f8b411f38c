"""Grouped reductions of episode tables as plain Python: one pass over the rows instead of one filter per cell."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any


def py(value: Any) -> Any:
    """A numpy scalar as the Python value it holds (``np.int64(3)`` prints as such inside a tuple); others as is."""
    return value.item() if hasattr(value, "item") and not isinstance(value, str) else value


def group_items(reduced) -> Iterator[tuple[tuple, Any]]:
    """(key, value) of each group of a grouped reduction (``df.groupby(keys).size()``, ``.sum()``), the key always a
    tuple and key and value Python scalars, so they compare, hash and print like values read row by row."""
    for key, value in reduced.items():
        yield tuple(py(k) for k in (key if isinstance(key, tuple) else (key,))), py(value)
