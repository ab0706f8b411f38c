"""Success predicates: one frozen object per scene family (its ``Scene.success_predicate``), evaluated on
``privileged_state()`` at every level.

The same instance judges every level of every axis (the paper's semantics-preservation condition);
anything level-dependent (where the basket is, how tall the target stack is) is read from the state.
``over_goal`` is the horizontal part of a predicate: where the progress score's ``transport`` stage holds
(``scenes.failure``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenes.privileged import PrivilegedState


def _released_and_still(s: PrivilegedState, max_speed: float) -> bool:
    return (not s.pick.touching_gripper) and float(np.linalg.norm(s.pick.linvel)) < max_speed


def _in_frame(point_xy: np.ndarray, centre: np.ndarray, quat_wxyz: np.ndarray) -> np.ndarray:
    """``point_xy`` in the yaw frame of a body at ``centre`` with orientation ``quat_wxyz``."""
    w, x, y, z = quat_wxyz
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    c, s = np.cos(-yaw), np.sin(-yaw)
    d = np.asarray(point_xy) - np.asarray(centre)[:2]
    return np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]])


@dataclass(frozen=True)
class InReceptacle:
    """The pick object rests inside the receptacle: within its walls, below its rim, released and still."""

    margin: float = 0.003
    max_speed: float = 0.05

    def __call__(self, s: PrivilegedState) -> bool:
        rel = _in_frame(s.pick.pos[:2], s.goal.pos, s.goal.quat_wxyz)
        ix, iy = s.facts.receptacle_inner
        inside = abs(rel[0]) <= ix - self.margin and abs(rel[1]) <= iy - self.margin
        low = s.target.floor_z - 0.01 <= s.pick.bottom <= s.goal.top
        return bool(inside and low and _released_and_still(s, self.max_speed))

    def over_goal(self, s: PrivilegedState) -> bool:
        """The object's centre is within the receptacle's walls (in its frame), at any height."""
        rel = _in_frame(s.pick.pos[:2], s.goal.pos, s.goal.quat_wxyz)
        ix, iy = s.facts.receptacle_inner
        return bool(abs(rel[0]) <= ix and abs(rel[1]) <= iy)


@dataclass(frozen=True)
class OnTarget:
    """The pick block rests on top of the target block, released and still."""

    xy_tol: float = 0.02
    z_tol: float = 0.01
    max_speed: float = 0.05

    def __call__(self, s: PrivilegedState) -> bool:
        rel = _in_frame(s.pick.pos[:2], s.goal.pos, s.goal.quat_wxyz)
        on_top = abs(rel[0]) <= self.xy_tol and abs(rel[1]) <= self.xy_tol
        touching = abs(s.pick.bottom - s.goal.top) <= self.z_tol
        return bool(on_top and touching and _released_and_still(s, self.max_speed))

    def over_goal(self, s: PrivilegedState) -> bool:
        """The block's centre is within twice the placement tolerance of the target's centre (footprints overlap)."""
        rel = _in_frame(s.pick.pos[:2], s.goal.pos, s.goal.quat_wxyz)
        return bool(abs(rel[0]) <= 2 * self.xy_tol and abs(rel[1]) <= 2 * self.xy_tol)


@dataclass(frozen=True)
class OnTableOutside:
    """The pick object rests on the table top outside the fixture's footprint, released and still."""

    z_tol: float = 0.012
    max_speed: float = 0.05

    def __call__(self, s: PrivilegedState) -> bool:
        on_table = s.pick.bottom <= s.table_top + self.z_tol
        rel = np.abs(np.asarray(s.pick.pos[:2]) - np.asarray(s.facts.fixture_centre[:2]))
        hx, hy = s.facts.fixture_half
        outside = rel[0] > hx or rel[1] > hy
        return bool(on_table and outside and _released_and_still(s, self.max_speed))

    def over_goal(self, s: PrivilegedState) -> bool:
        """The object's centre has left the fixture's footprint (carried out of the cabinet)."""
        rel = np.abs(np.asarray(s.pick.pos[:2]) - np.asarray(s.facts.fixture_centre[:2]))
        hx, hy = s.facts.fixture_half
        return bool(rel[0] > hx or rel[1] > hy)


@dataclass(frozen=True)
class BddlGoal:
    """LIBERO's own BDDL goal check (``env.check_success()``, read into the state as ``bddl_success``)."""

    def __call__(self, s: PrivilegedState) -> bool:
        return bool(s.bddl_success)
