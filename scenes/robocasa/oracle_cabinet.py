"""The RoboCasa oracle's cabinet scripts (``RoboCasaOracle`` hands them itself as ``o``): counter to cabinet
(``pick_place``) and cabinet to counter (``unload``); kept apart from ``oracle.py`` for its length."""

from __future__ import annotations

import numpy as np

from scenes.privileged import PrivilegedState
from scenes.robocasa.oracle_base import base_goal, drive_phase
from scenes.robocasa.oracle_fixtures import CLOSED

OPEN = -1.0  # robosuite's gripper action (CLOSED, 1.0, comes with the lid script's module)
# m ahead of the base the counter-to-cabinet script puts the cabinet's place point at most: farther (a base moved
# back along base_y), the base drives straight nearer first, as far as the room allows (base_y level 2 episode 1
# of the pretrain split: at 0.85 m the held object stalled at the cabinet's front and fell)
CABINET_REACH = 0.75
# m the counter-to-cabinet script raises the grip site over the object's top once it let go, before backing out:
# the fingertips reach 1.5 cm under the grip site, and a flat 2.5 cm rise left them on the sides of a 10.5 cm tall
# object held 2.4 cm under its top, which they dragged back out of the cabinet (base_y level 2 episode 1, pretrain)
FINGERTIP = 0.03
GRASP_TILT = 0.45  # radians the hand tips toward the cabinet to grasp an object under its front
TILT = 0.7  # radians the hand tips toward the cabinet while carrying: a vertical hand and wrist do not fit in


def pick_place(o, s: PrivilegedState) -> np.ndarray:
    """Counter to cabinet: (a place point beyond ``CABINET_REACH``: the base drives nearer first) over the object,
    down, grasp, pull it out from under the cabinet's front, lift to the cabinet floor, slide in, set down, let go."""
    p, t = s.pick, s.target
    yaw = float(s.robot_base[2])
    fwd = np.array([np.cos(yaw), np.sin(yaw), 0.0])  # the base faces the cabinet
    front = float(np.dot(s.goal.pos, fwd)) - float(s.facts.receptacle_inner[1])  # the cabinet's front face
    carry_z = t.place_bottom + 0.025 + o._offset  # the object's bottom 2.5 cm above the cabinet floor
    if o._grasp_tilt is None:  # under the cabinet's front: tip the hand so the wrist stays out from under
        under = float(np.dot(p.pos, fwd)) + p.half_width + 0.08 > front
        o._grasp_tilt = GRASP_TILT if under else 0.0
    gt = o._grasp_tilt
    if o.phase == "approach" and not o._drove and s.facts.base_room is not None:
        o._drove = True  # straight ahead only: the place point's distance, not its side
        ahead = float(np.dot(np.array([*t.place_xy, 0.0]) - [*s.robot_base[:2], 0.0], fwd))
        o._base_goal = base_goal(s, [*(s.robot_base[:2] + ahead * fwd[:2]), 0.0], 0.0, CABINET_REACH)
        if o._base_goal is not None:
            o._next("drive")
    if (a := drive_phase(o, s, OPEN)) is not None:
        return a
    if o.phase == "approach":
        target = np.array([p.pos[0], p.pos[1], p.top + 0.06])
        if o._near(s, target, 0.015) or o._count > 120:
            o._next("descend")
        return o._goto(s, target, OPEN, tilt=gt)
    if o.phase == "descend":
        return o._descend(s, p, gt)
    if o.phase == "grasp":
        a, closed = o._grasp(s, p, gt)
        if closed:
            o._next("pull")
        return a
    if o.phase == "pull":  # out from under the cabinet, toward the robot, before lifting
        # fixed at the grasp: read live, the pull ended where the object came only halfway out
        if o._count == 1:
            out = min(0.0, front - 0.05 - p.half_width - float(np.dot(p.pos, fwd)))
            o._clear = o._hold + fwd * out + np.array([0.0, 0.0, 0.01])
        target = o._clear
        if o._near(s, target, 0.012) or o._count > 60:
            o._next("lift")
        return o._goto(s, target, CLOSED, speed=0.5, tilt=gt)
    if o.phase == "lift":  # up to the carry height, tipping the hand toward the cabinet on the way
        target = np.array([o._clear[0], o._clear[1], carry_z])
        if (o._near(s, target, 0.03) and o._count > 20) or o._count > 120:
            o._next("transport")
        return o._goto(s, target, CLOSED, tilt=min(TILT, gt + 0.03 * o._count))
    inside = np.array([t.place_xy[0], t.place_xy[1], carry_z])
    if o.phase == "transport":  # slide in at the carry height
        if o._near(s, inside, 0.03) or o._count > 150:
            o._next("lower")
        return o._goto(s, inside, CLOSED, speed=0.6, tilt=TILT)
    if o.phase == "lower":
        target = np.array([s.eef_pos[0], s.eef_pos[1], t.place_bottom + 0.005 + o._offset])
        if o._near(s, target, 0.015) or o._count > 40:
            o._next("release")
        return o._goto(s, target, CLOSED, speed=0.3, tilt=TILT)
    if o.phase == "rise" and o._rise is None:  # once: the grip site FINGERTIP over the object's top
        o._rise = max(0.025, p.top + FINGERTIP - float(o._hold_release[2]))
    return o._let_go(s, TILT, rise=o._rise or 0.025, tol=0.008, limit=20)


def unload(o, s: PrivilegedState) -> np.ndarray:
    """Hand tipped toward the cabinet: in over the object at the cabinet's mouth, down, grasp, lift 2 cm, pull
    straight back out past the face, lower onto the counter (``target``), release, rise, back out."""
    p, t = s.pick, s.target
    yaw = float(s.robot_base[2])
    fwd = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    front = float(np.dot(s.goal.pos, fwd)) - float(s.facts.receptacle_inner[1])
    over = min(p.top + 0.04, s.goal.top - 0.05)  # above the object, under the cabinet's ceiling
    if o.phase == "approach":  # at the mouth, the object's lateral position, above its top
        target = p.pos + fwd * (front - 0.08 - float(np.dot(p.pos, fwd)))
        target[2] = over
        if o._near(s, target, 0.015) or o._count > 120:
            o._next("enter")
        return o._goto(s, target, OPEN, tilt=TILT)
    if o.phase == "enter":
        target = np.array([p.pos[0], p.pos[1], over])
        if o._near(s, target, 0.012) or o._count > 80:
            o._next("descend")
        return o._goto(s, target, OPEN, speed=0.5, tilt=TILT)
    if o.phase == "descend":
        return o._descend(s, p, TILT)
    if o.phase == "grasp":
        a, closed = o._grasp(s, p, TILT)
        if closed:
            o._clear = np.array([*t.place_xy, o._hold[2] + 0.02])  # out past the face, same height
            o._next("lift")
        return a
    if o.phase == "lift":  # off the cabinet floor before pulling: dragging tips it over
        target = o._hold + np.array([0.0, 0.0, 0.02])
        if o._near(s, target, 0.008) or o._count > 20:
            o._next("pull")
        return o._goto(s, target, CLOSED, speed=0.4, tilt=TILT)
    if o.phase == "pull":
        if o._near(s, o._clear, 0.015) or o._count > 120:
            o._next("lower")
        return o._goto(s, o._clear, CLOSED, speed=0.5, tilt=TILT)
    if o.phase == "lower":  # onto the counter: the stall (the object on the counter) ends it
        target = np.array([*o._clear[:2], t.place_bottom + 0.005 + o._offset])
        if (o._near(s, target, 0.01) and o._count > 25) or o._count > 120:
            o._next("release")
        # out of the cabinet: the hand straightens (a tipped hand this close to the base hits a joint limit)
        return o._goto(s, target, CLOSED, speed=0.5, tilt=max(0.0, TILT - 0.03 * o._count))
    return o._let_go(s, 0.0, rise=0.06, tol=0.01, limit=25, back_up=0.05)
