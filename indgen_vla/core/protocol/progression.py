"""Inductive difficulty progressions (paper §4): levels, successors and the three conditions.

A progression is a base task spec T0 plus a successor f; level k is f applied |k| times in the
direction of k's sign. The validators here are generic over any frozen-dataclass scene spec.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.axis_ref import AxisRef


class ProgressionError(ConfigError):
    """A progression that violates one of the paper's three conditions."""


@dataclass(frozen=True)
class AxisSpec:
    """What an axis is: the field it edits, its atomic step, and its level range.

    Attributes:
        name: registry name, e.g. ``pick_y``.
        description: one line for ``indgen axes``.
        field: dotted path of the scene-spec field the successor is allowed to change.
        step: size of one atomic step in ``unit``.
        unit: ``m``, ``fraction``, ``objects``...
        signed: levels are -K..K when True, 0..K otherwise.
        max_level: K, the largest |level| evaluated by default.
        base: the parameter's value at level 0 (e.g. 1.0 for a scale factor).
    """

    name: str
    description: str
    field: str
    step: float
    unit: str
    signed: bool
    max_level: int
    base: float = 0.0

    def __post_init__(self) -> None:
        if not all(part.replace("_", "").isalnum() for part in AxisRef.parse(self.name).axes()):
            raise ConfigError(f"axis name {self.name!r} must be alphanumeric with '_' or '+' (or A@B=j)")
        if not (self.step > 0 and math.isfinite(self.step)):
            raise ConfigError(f"axis {self.name}: step must be a positive number, got {self.step}")
        if self.max_level < 1:
            raise ConfigError(f"axis {self.name}: max_level must be >= 1, got {self.max_level}")

    @property
    def min_level(self) -> int:
        return -self.max_level if self.signed else 0

    def default_levels(self) -> list[int]:
        return list(range(self.min_level, self.max_level + 1))

    def with_step(self, step: float) -> AxisSpec:
        return dataclasses.replace(self, step=step)

    def param(self, level: int) -> float:
        """The axis parameter at ``level``: its level-0 value plus ``level`` atomic steps."""
        return self.base + level * self.step


def expand_axes(names: Sequence[str]) -> tuple[str, ...]:
    """``--axis`` names with each range ``A@B=i:j`` expanded to the held axes ``A@B=i``, ..., ``A@B=j`` (a 2-D grid
    as a family of 1-D ladders); other names as given, in order. Refuses a backwards range and repeated axes."""
    out: list[str] = []
    for name in names:
        head, eq, at = name.rpartition("=")
        if "@" not in head or not eq or ":" not in at:
            out.append(name)
            continue
        lo_s, _, hi_s = at.partition(":")
        try:
            lo, hi = int(lo_s), int(hi_s)
        except ValueError:
            raise ConfigError(
                f"axis {name!r}: a held range is A@B=i:j with integers i <= j, e.g. pick_y@distractor=0:3"
            ) from None
        if lo > hi:
            raise ConfigError(f"axis {name!r}: start {lo} is after end {hi}; write it as {head}={hi}:{lo}")
        out += [f"{head}={j}" for j in range(lo, hi + 1)]
    repeated = sorted({a for a in out if out.count(a) > 1})
    if repeated:
        raise ConfigError(f"--axis names {', '.join(repeated)} more than once; name each axis once")
    return tuple(out)


def parse_levels(text: str | Sequence[int] | None, axis: AxisSpec) -> list[int]:
    """Parse ``-3:3`` (inclusive), ``0,2,4`` or ``2`` and check the levels lie in the axis range."""
    if text is None:
        return axis.default_levels()
    if isinstance(text, str):
        s = text.strip()
        if re.fullmatch(r"-?\d+\.\.-?\d+", s):
            raise ConfigError(
                f"--levels {text!r}: write a range with a colon, --levels {s.replace('..', ':')}"
            )
        try:
            if ":" in s:
                lo_s, hi_s = s.split(":", 1)
                lo, hi = int(lo_s), int(hi_s)
                levels = list(range(lo, hi + 1))
            else:
                levels = [int(p) for p in s.split(",") if p.strip()]
        except ValueError:
            raise ConfigError(f"--levels {text!r} is not a range like -3:3 or a list like 0,1,2") from None
        if ":" in s and lo > hi:
            raise ConfigError(f"--levels {s!r}: start {lo} is after end {hi}; write it as {hi}:{lo}")
    else:
        levels = [int(x) for x in text]
    if not levels:
        raise ConfigError(f"--levels {text!r} selects no level")
    bad = [k for k in levels if not axis.min_level <= k <= axis.max_level]
    if bad:
        raise ConfigError(
            f"level {bad[0]} is outside axis {axis.name}'s range {axis.min_level}..{axis.max_level}; "
            f"use --levels {axis.min_level}:{axis.max_level} or a sub-range"
        )
    return sorted(set(levels))


def apply_level[S](base: S, successor: Callable[..., S], level: int) -> S:
    """T_k = f^|k|(T0), stepping in the direction of k's sign."""
    spec = base
    direction = 1 if level >= 0 else -1
    for _ in range(abs(level)):
        spec = successor(spec, direction)
    return spec


def flatten_spec(spec: Any, prefix: str = "") -> dict[str, Any]:
    """Flatten nested dataclasses / mappings / tuples into ``{dotted.path: leaf}`` for diffing."""
    out: dict[str, Any] = {}
    if dataclasses.is_dataclass(spec) and not isinstance(spec, type):
        items: Iterable[tuple[str, Any]] = ((f.name, getattr(spec, f.name)) for f in dataclasses.fields(spec))
    elif isinstance(spec, Mapping):
        items = ((str(k), v) for k, v in spec.items())
    elif isinstance(spec, (tuple, list)) and any(dataclasses.is_dataclass(x) for x in spec):
        items = ((str(i), v) for i, v in enumerate(spec))
    else:
        return {prefix: spec}
    for key, value in items:
        out.update(flatten_spec(value, f"{prefix}.{key}" if prefix else key))
    if not out:
        out[prefix] = spec
    return out


def spec_diff(a: Any, b: Any) -> set[str]:
    """Dotted paths whose values differ between two specs (a path present in one only counts)."""
    fa, fb = flatten_spec(a), flatten_spec(b)
    return {k for k in fa.keys() | fb.keys() if k not in fa or k not in fb or not _equal(fa[k], fb[k])}


def _equal(x: Any, y: Any) -> bool:
    try:
        import numpy as np

        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            return bool(np.array_equal(x, y))
    except ImportError:  # pragma: no cover - numpy is a core dependency
        pass
    return bool(x == y)


def _under(path: str, allowed: str) -> bool:
    return path == allowed or path.startswith(allowed + ".")


def check_single_axis(before: Any, after: Any, allowed_fields: Iterable[str], axis: str = "?") -> set[str]:
    """Condition 3: one step changes only the axis's own field(s), and changes something."""
    allowed = list(allowed_fields)
    changed = spec_diff(before, after)
    if not changed:
        raise ProgressionError(f"axis {axis}: the successor left the scene spec unchanged")
    stray = sorted(p for p in changed if not any(_under(p, a) for a in allowed))
    if stray:
        raise ProgressionError(
            f"axis {axis}: the successor changed {', '.join(stray)} besides its own field(s) {', '.join(allowed)}"
        )
    return changed


def check_semantics_preserved(predicates: Sequence[object], axis: str = "?") -> None:
    """Condition 1: every level is judged by the very same success predicate object."""
    if not predicates:
        return
    first = predicates[0]
    for i, p in enumerate(predicates[1:], start=1):
        if p is not first and p != first:
            raise ProgressionError(f"axis {axis}: level index {i} uses a different success predicate ({p!r})")


def _covered(interval: tuple[float, float], others: Sequence[tuple[float, float]], tol: float) -> bool:
    """Is ``interval`` inside the union of ``others`` (closed intervals, tolerance ``tol``)?"""
    merged: list[list[float]] = []
    for a, b in sorted(others):
        if merged and a <= merged[-1][1] + tol:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    lo, hi = interval
    return any(a - tol <= lo and hi <= b + tol for a, b in merged)


def check_strictly_harder(
    supports: Mapping[int, tuple[float, float]], axis: str = "?", strict: bool = True, tol: float = 1e-9
) -> None:
    """Condition 2: level k's parameter support leaves the support of the easier levels.

    ``supports`` maps each level to the closed interval its axis parameter can take (lo == hi for a
    deterministic parameter). Signed axes are checked per direction: level -2 is compared to 0 and -1.
    With ``strict`` (condition 2, docs/contracts.md) level k's support must be disjoint from the union of the easier ones;
    otherwise (the paper's wording) it must merely contain values outside that union.
    """
    for k in sorted(
        supports, key=lambda k: (abs(k), k < 0)
    ):  # +k before -k: the side a one-sided run asked for
        if k == 0:
            continue
        lo, hi = supports[k]
        if lo > hi:
            raise ProgressionError(f"axis {axis}: level {k} support ({lo}, {hi}) is empty")
        easier = [supports[j] for j in supports if abs(j) < abs(k) and (j == 0 or (j > 0) == (k > 0))]
        if not easier:
            continue
        if strict:
            hit = next(((a, b) for a, b in easier if lo <= b + tol and a - tol <= hi), None)
            if hit is not None:
                raise ProgressionError(
                    f"axis {axis}: level {k}'s parameter support [{lo:g}, {hi:g}] overlaps an easier level's "
                    f"[{hit[0]:g}, {hit[1]:g}]; use a step larger than the placement jitter (a level's support is "
                    f"{max(hi - lo, hit[1] - hit[0]):.3g} wide here, so the step must exceed that)"
                )
        elif _covered((lo, hi), easier, tol):
            raise ProgressionError(
                f"axis {axis}: level {k}'s parameter support [{lo:g}, {hi:g}] lies inside the easier levels' "
                "support; increase the step so every level leaves the previous support"
            )
