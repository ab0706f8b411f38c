"""The RoboCasa oracle's script for a hinged lid standing open (CloseElectricKettleLid), from the hinge facts of
``worker_facts.hinged_facts`` (``oracle_state.hinge_goal``); kept apart from ``oracle.py`` for its length.

Opening the lid is the lid button's press (placeholder tree 6), turning the kettle on its lever's
(``oracle_lever.py``), lifting the stand mixer's head ``oracle_lift.py``."""

from __future__ import annotations

import numpy as np

from scenes.privileged import PrivilegedState
from scenes.robocasa.oracle_base import base_goal, drive_phase

CLOSED = 1.0  # robosuite's gripper action: fingers shut
MAX_PRESS_TILT = 1.3  # radians: the most a press tips the hand while its reach falls short
BEHIND = 0.03  # m the grip site stays behind a standing lid's back face before sweeping it shut
CLOSED_BELOW = 0.3  # how open (RoboCasa's 0..1) a lid may still be when the sweep hands over to the press
# m in front of the base the base phase brings a lid's hinge between: a tipped hand (LID_TILT) sweeps it from
# 0.43-0.48 m (at 0.35 m its press stalled short, near the base; at 0.54 m it did not get behind the lid); a hand
# pointing down from 0.61 m (nearer, its fingers stalled 4 cm over their mark, or on a coffee machine behind)
TIPPED_AHEAD = (0.47, 0.50)
LID_AHEAD = (0.30, 0.65)  # the hand pointing down: where the room keeps the hinge beyond TIPPED_AHEAD
# radians a kettle may be turned from facing the base for the tipped hand (fixture_x level 1 episode 2, turned 57
# deg: the tipped hand swept past the lid's side; pointing down it closes it)
FACING = np.pi / 4
LID_ROOM = 0.3  # m over a lid's top under which the hand tips from the start (LID_TILT)
LID_TILT = 1.0  # radians: a hand tipped toward the lid keeps its wrist low and back, under a wall cabinet


def hinge_frame(s: PrivilegedState) -> tuple[np.ndarray, np.ndarray, float, float, float]:
    """The lid's hinge, the horizontal way the fixture faces, the lid's length, half thickness and angle (rad)."""
    w, _, _, z = (float(q) for q in s.goal.quat_wxyz)
    yaw = 2.0 * np.arctan2(z, w)
    u = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    d = np.array([*s.target.place_xy, s.target.grasp_z]) - s.goal.pos
    along, up = float(d @ u), float(d[2])
    return s.goal.pos, u, float(np.hypot(along, up)), float(s.goal.top), float(np.arctan2(up, along))


def _reach(o, s: PrivilegedState, target, tol: float) -> bool:
    """At ``target``; stalled short of it, tips the hand 0.2 rad further (a tipped hand reaches farther; the
    press's rule, up to its ``MAX_PRESS_TILT``) and is done when it cannot tip more."""
    if np.linalg.norm(np.asarray(target) - s.eef_pos) < tol:
        return True
    if o._near(s, target, tol) and o._count > 20:
        if o._tilt >= MAX_PRESS_TILT:
            return True
        o._tilt, o._count = min(MAX_PRESS_TILT, o._tilt + 0.2), 1
    return False


def _start(o, s: PrivilegedState, hinge, u, top: float) -> None:
    """The first action's choices: where the base drives (``oracle_base.base_goal``: the hinge straight ahead, as far
    as the room allows) and the hand's tilt: ``LID_TILT`` under something hanging less than ``LID_ROOM`` over the
    lid's top (a wall cabinet: a hand pointing down meets it with its wrist), or with the kettle facing the base
    (within ``FACING``; the hand tips toward the base's front) and the hinge within ``TIPPED_AHEAD`` (2 cm beyond
    it too); else pointing down, the hinge within ``LID_AHEAD``."""
    o._base_goal, o._tilt = base_goal(s, hinge, *TIPPED_AHEAD), LID_TILT
    goal = s.robot_base[:2] if o._base_goal is None else o._base_goal
    yaw = float(s.robot_base[2])
    fwd = np.array([np.cos(yaw), np.sin(yaw)])
    ahead = float(np.dot(np.asarray(hinge[:2]) - goal, fwd))  # after the drive
    low = s.facts.ceiling is not None and s.facts.ceiling - top < LID_ROOM
    if not low and (ahead > TIPPED_AHEAD[1] + 0.02 or -float(np.dot(u[:2], fwd)) < np.cos(FACING)):
        o._base_goal, o._tilt = base_goal(s, hinge, *LID_AHEAD), 0.0
    o._next("drive" if o._base_goal is not None else "approach")


def close_lid(o, s: PrivilegedState) -> np.ndarray:
    """A standing lid: down behind its top edge (hand pointing down, fingers closed; tipped further while the reach
    falls short), swept toward the fixture's front faster than RoboCasa's hold pulls it back open, then pushed down
    near its free end until RoboCasa reads it shut, then up; ``o`` is the ``RoboCasaOracle`` (phase, motion).
    Dragging the edge by friction from above instead lost the edge at once (0/1 where the sweep succeeds)."""
    hinge, u, length, t, _ = hinge_frame(s)
    z = np.array([0.0, 0.0, 1.0])
    behind = hinge - u * (t + BEHIND)
    if o._tilt is None:
        _start(o, s, hinge, u, float(hinge[2]) + length)
    if (a := drive_phase(o, s, CLOSED)) is not None:
        return a
    if o.phase == "approach":
        target = behind + z * (length + (0.03 if o._tilt >= LID_TILT else 0.08))
        if _reach(o, s, target, 0.02) or o._count > 150:
            o._next("lower")
        return o._goto(s, target, CLOSED, tilt=o._tilt)
    if o.phase == "lower":  # the fingertips 3 cm below the lid's top edge, behind it
        target = behind + z * (length - 0.03)
        if _reach(o, s, target, 0.015) or o._count > 60:
            o._next("sweep")
        return o._goto(s, target, CLOSED, speed=0.5, tilt=o._tilt)
    if o.phase == "sweep":
        target = hinge + u * (0.9 * length) + z * (t + 0.02)
        if s.target.clear_z < CLOSED_BELOW or o._near(s, target, 0.015) or o._count > 80:
            o._next("press")
        return o._goto(s, target, CLOSED, tilt=o._tilt)
    if o.phase == "press":  # down near the free end at full force until RoboCasa says it is shut
        if s.bddl_success or o._count > 120:
            o._next("retreat")
        return o._goto(s, hinge + u * (0.8 * length) - z * 0.1, CLOSED, tilt=o._tilt)
    return o._goto(s, hinge + u * (0.8 * length) + z * 0.2, CLOSED, speed=0.5, tilt=o._tilt)
