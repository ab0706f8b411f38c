"""Whether one of LIBERO's fixed initial states holds a moved level: a state whose translated (or scaled) object
lands inside a neighbour is flung by MuJoCo during the settle, so the episode would not start from the level.

Checked only where the level moves or scales something (level 0 is LIBERO's own protocol, untouched); a state that
fails is an infeasible cell for that episode (``EpisodeUnavailableError``), as RoboCasa's placement check makes it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from indgen_vla.core.errors import EpisodeUnavailableError

OVERLAP_M = (
    0.005  # deeper than this inside another object at the level's pose: not a resting pose (RoboCasa's 5 mm)
)
MOVED_M = 0.01  # moved further than this (xy) by the settling steps: thrown, not settled
RULE = (
    f"placement check on levels that move or scale an object: a state is unavailable where the moved pick object or basket lies over "
    f"{OVERLAP_M * 1000:g} mm inside another object at the level's pose, or the settle moves it over "
    f"{MOVED_M * 100:g} cm (xy)"
)  # in the protocol's initial_states (``LiberoEnvironment.protocol_facts``): a run made without it does not resume


@dataclass(frozen=True)
class Body:
    """One object the level moved: its name, body id, geoms, and the geoms (with owners) it must not be inside."""

    name: str
    body: int
    geoms: frozenset[int]
    others: dict[int, str]  # geom id -> the object it belongs to


def overlap(data, body: Body) -> tuple[float, str]:
    """The deepest contact (m, >= 0) between ``body`` and another object, and that object's name ('' if none)."""
    deepest, who = 0.0, ""
    for c in data.contact[: data.ncon]:
        g1, g2 = int(c.geom1), int(c.geom2)
        other = g2 if g1 in body.geoms else g1 if g2 in body.geoms else None
        if other is not None and other in body.others and -float(c.dist) > deepest:
            deepest, who = -float(c.dist), body.others[other]
    return deepest, who


def moved(data, body: Body, pose_xy: np.ndarray) -> float:
    """How far (m, in xy) ``body`` now is from where the level put it."""
    return float(np.linalg.norm(np.asarray(data.xpos[body.body][:2]) - pose_xy))


def verdict(depth: float, neighbour: str, shift: float, name: str) -> str | None:
    """Why the state does not hold the level (one clause), or None when it does."""
    if depth > OVERLAP_M:
        return f"the level puts the {name} {depth * 1000:.1f} mm inside the {neighbour} (over {OVERLAP_M * 1000:g} mm)"
    if shift > MOVED_M:
        return f"the settling steps moved the {name} {shift * 100:.1f} cm (over {MOVED_M * 100:g} cm): it was thrown"
    return None


def body(name: str, objects: dict, body_id: Callable[[str], int], geoms: Callable[[str], np.ndarray]) -> Body:
    """The check's view of object ``name`` among LIBERO's ``objects`` (their geoms from ``geoms(name)``)."""
    others = {int(g): o for o in objects if o != name for g in geoms(o)}
    return Body(name, body_id(name), frozenset(int(g) for g in geoms(name)), others)


def check(
    bodies: list[Body], qpos: dict[str, int], data, state: np.ndarray, overlaps: list[tuple[float, str]], where: str
) -> None:  # fmt: skip
    """After the settle: ``EpisodeUnavailableError`` (one line, ``where`` first) when a moved object is not at rest
    where the level put it; ``overlaps`` were taken at the level's pose, ``state`` is that pose (qpos at ``1 + qpos``)."""
    for b, (depth, neighbour) in zip(bodies, overlaps, strict=True):
        q = 1 + qpos[b.name]
        why = verdict(depth, neighbour, moved(data, b, state[q : q + 2]), b.name)
        if why:
            raise EpisodeUnavailableError(f"{where}: {why} (placement check)")
