"""The RoboCasa oracle's scripts for a hinged part lifted from under its free edge, from the hinge facts of
``worker_facts.hinged_facts``: the stand mixer's tilt head swung open (OpenStandMixerHead, ``open_hinge``) and the
toaster oven's door, lying open toward the base, swung up shut (CloseToasterOvenDoor, ``shut_door``); kept apart
from ``oracle.py``.

The hand, fingers shut and held nearly level, points into the fixture's front (``hinge_front`` reversed) so only
its fingers go under the part's free edge (the head's overhang, placeholder tree version 6; the open door's, tree
7), then follows the edge up along its arc. The head: sliding toward the hinge as it rises, past the joint's limit
until RoboCasa reads it open (``head`` > 0.99); the joint's frictionloss holds it there. The door: up to upright
and on against the oven's face until RoboCasa reads it shut (``ToasterOven.update_state`` then holds it at 0). A
base phase first brings the edge to where the arm reaches it."""

from __future__ import annotations

import numpy as np

from scenes.oracles import R_DOWN
from scenes.privileged import PrivilegedState
from scenes.robocasa.oracle_base import base_goal, drive_phase, rz
from scenes.robocasa.oracle_fixtures import CLOSED, hinge_frame

LIFT_TILT = 1.35  # radians from pointing down: the fingers point 12 deg below level, into the fixture's front
INSET = 0.025  # m from the free edge the fingertips push (the overhang is 4.6 cm deep on the placeholders)
BELOW = 0.012  # m the grip site stays under the part's underside going under it (a finger's half width)
OUT = 0.10  # m in front of the edge the hand lines up before going under it
AHEAD = (0.28, 0.34)  # m ahead of the base the drive brings the free edge (level 0's kitchens: 0.30-0.32)
LEFT = 0.0  # m to the base's side the base phase brings the point under the edge (straight ahead)
STEP = 0.3  # radians ahead of the part's angle the lift aims along the edge's arc
# m inward (toward the hinge) per radian the part has risen that the lift slides its push: nearer the hinge the push
# rises less (level 2's episode 1: the head's 0.36 m edge would end 0.26 m over its hinge, at 1.52 m; the hand
# stalled at 1.43 m with the head at 0.86 of open)
SLIDE = 0.6
# the toaster oven's door, its free edge ~6 cm over the counter (tree 7): m ahead of the base the drive brings the
# point under the edge (at level 0 RoboCasa's base stands 0.19 m from it); the hand's tilt (sent to 0.925 m in front
# of the edge 0.42 m out, tipped 0.9 and 1.2 rad the hand stopped at 1.00 and 1.055 m, tipped 0.6 it got there; tipped
# LIFT_TILT it stalled 8-14 cm over its mark under the edge 0.40-0.60 m out, touching nothing), how far
# in from the edge and how far under its underside the fingertips go under it (tipped 0.6 rad, a finger's top rises
# 1.4 cm a cm back out toward the hand), and radians past upright the push aims (RoboCasa reads the door shut
# within 0.0157 rad of upright: 0.01 of its range)
DOOR_AHEAD = (0.45, 0.50)
DOOR_TILT, DOOR_INSET, DOOR_BELOW = 0.6, 0.01, 0.025
PAST_UPRIGHT = 0.3


def _orient(direction, tilt: float) -> np.ndarray:
    """The grip site pointing down, tipped ``tilt`` toward the horizontal ``direction`` (fingers opening across)."""
    c, sn = np.cos(-tilt), np.sin(-tilt)
    pitch = np.array([[c, 0.0, sn], [0.0, 1.0, 0.0], [-sn, 0.0, c]])
    return rz(float(np.arctan2(direction[1], direction[0]))) @ pitch @ R_DOWN


def _goto(
    o, s: PrivilegedState, target, direction, speed: float = 1.0, tilt: float = LIFT_TILT
) -> np.ndarray:
    """One arm action toward ``target`` (fingers shut) with the hand tipped ``tilt`` toward ``direction``."""
    return o._goto(s, target, CLOSED, speed=speed, hand=_orient(direction, tilt))


def under_edge(hinge, u, length: float, thick: float, angle: float, below: float, inset: float = INSET):
    """The point ``inset`` in from the free edge of a part hinged at ``hinge`` (``length`` long, half ``thick``,
    lying toward the fixture's front ``u`` when shut) turned up by ``angle``, ``below`` under its underside."""
    z = np.array([0.0, 0.0, 1.0])
    along, normal = u * np.cos(angle) + z * np.sin(angle), -u * np.sin(angle) + z * np.cos(angle)
    return hinge + (length - inset) * along - (thick + below) * normal


def lift_hinge(o, s: PrivilegedState) -> np.ndarray:
    """``shut_door`` where the worker says lifting the part shuts it (``SceneFacts.lift`` "shuts": the toaster
    oven's door), else ``open_hinge`` (the mixer's head)."""
    return shut_door(o, s) if s.facts.lift == "shuts" else open_hinge(o, s)


def _drive_under(o, s: PrivilegedState, hinge, u, length: float, thick: float, ahead) -> None:
    """The first action: the base drives so the point under the free edge (the part lying flat, angle 0) stands
    straight ahead, ``ahead`` (near, far) m out; ``o._tilt`` set marks the plan made."""
    o._tilt = LIFT_TILT
    point = under_edge(hinge, u, length, thick, 0.0, 0.0)
    yaw = float(s.robot_base[2])
    left = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
    o._base_goal = base_goal(s, point - left * LEFT, *ahead)
    o._next("drive" if o._base_goal is not None else "approach")


def shut_door(o, s: PrivilegedState) -> np.ndarray:
    """A door lying open toward the base (hinged at its bottom edge): under its free edge from the front (fingers
    shut, the hand tipped ``DOOR_TILT``), then up along the edge's arc, aiming ``STEP`` ahead of the door's angle and
    at most ``PAST_UPRIGHT`` past upright, until RoboCasa reads it shut, then back out; ``o`` is the
    ``RoboCasaOracle``."""
    hinge, u, length, thick, angle = hinge_frame(s)
    into = -u[:2]
    if o._tilt is None:
        _drive_under(o, s, hinge, u, length, thick, DOOR_AHEAD)
    if (a := drive_phase(o, s, CLOSED)) is not None:
        return a
    out = np.array([*(-into * OUT), 0.0])
    under = under_edge(hinge, u, length, thick, angle, DOOR_BELOW, DOOR_INSET)
    if o.phase == "approach":  # in front of the edge, under its height
        if o._near(s, under + out, 0.015) or o._count > 120:
            o._next("under")
        return _goto(o, s, under + out, into, tilt=DOOR_TILT)
    if o.phase == "under":
        if o._near(s, under, 0.01) or o._count > 60:
            o._next("lift")
        return _goto(o, s, under, into, speed=0.5, tilt=DOOR_TILT)
    if o.phase == "lift":  # up along the arc and on against the oven until RoboCasa reads the door shut
        if s.bddl_success or o._count > 300:
            o._next("retreat")
        aim = min(angle + STEP, np.pi / 2 + PAST_UPRIGHT)
        return _goto(o, s, under_edge(hinge, u, length, thick, aim, 0.0), into, speed=0.6, tilt=DOOR_TILT)
    if o._hold_release is None:
        o._hold_release = s.eef_pos.copy()
    return _goto(o, s, o._hold_release + out, into, speed=0.5, tilt=DOOR_TILT)


def open_hinge(o, s: PrivilegedState) -> np.ndarray:
    """Under the free edge from the fixture's front (fingers shut), then up along the edge's arc until RoboCasa
    reads the part open, then back out; ``o`` is the ``RoboCasaOracle`` (phase, counters)."""
    hinge, u, length, thick, angle = hinge_frame(s)
    into = -u[:2]
    if o._tilt is None:  # first action: where the base drives (the edge straight ahead, AHEAD out)
        _drive_under(o, s, hinge, u, length, thick, AHEAD)
    if (a := drive_phase(o, s, CLOSED)) is not None:
        return a
    out = np.array([*(-into * OUT), 0.0])
    if o.phase == "approach":  # in front of the edge, under its height
        target = under_edge(hinge, u, length, thick, angle, BELOW + 0.01) + out
        if o._near(s, target, 0.015) or o._count > 120:
            o._next("under")
        return _goto(o, s, target, into)
    if o.phase == "under":
        target = under_edge(hinge, u, length, thick, angle, BELOW)
        if o._near(s, target, 0.01) or o._count > 60:
            o._next("lift")
        return _goto(o, s, target, into, speed=0.5)
    if o.phase == "lift":  # up along the arc, ahead of the edge, until RoboCasa reads it open
        if s.bddl_success or o._count > 200:
            o._next("retreat")
        inset = INSET + SLIDE * length * max(0.0, angle)  # slid toward the hinge as the part rises
        return _goto(o, s, under_edge(hinge, u, length, thick, angle + STEP, 0.0, inset), into, speed=0.6)
    if o._hold_release is None:
        o._hold_release = s.eef_pos.copy()
    return _goto(o, s, o._hold_release + out - np.array([0.0, 0.0, 0.05]), into, speed=0.5)
