"""The RoboCasa oracle's script for the electric kettle's power lever (TurnOnElectricKettle): pressed down at its
free end, low beside the kettle (``worker_facts.kettle_switch_facts``); kept apart from ``oracle.py`` for its length.
"""

from __future__ import annotations

import numpy as np

from scenes.oracles import R_DOWN, _axis_angle
from scenes.privileged import PrivilegedState
from scenes.robocasa.oracle_base import base_goal, drive_phase, rz
from scenes.robocasa.oracle_fixtures import CLOSED

LEVER_AHEAD = (0.40, 0.50)  # m in front of the base the base phase brings the lever's press point between
LEVER_TILT = 0.5  # radians the hand tips, its fingertips toward the kettle: the wrist stays out beside it
MAX_TILT = 1.1  # radians it tips at most, 0.2 more at each stalled press
# m from the press point, along the tipped hand's axis, where the hand comes in from (out beside the kettle: the
# lid button stands 0.2 m over the lever)
IN = 0.15
ABOVE = 0.03  # m from the press point, along that axis, where the descent ends and the press begins
PUSH = 0.03  # m under the press point the press aims (the lever's free end drops 9 mm to "on")


def lever_heading(s: PrivilegedState) -> float:
    """The lever's heading (yaw, rad): from its hinge toward its free end (the pick's pose)."""
    w, _, _, z = (float(q) for q in s.pick.quat_wxyz)
    return float(2.0 * np.arctan2(z, w))


def lever_hand(s: PrivilegedState, tilt: float) -> np.ndarray:
    """The grip site's world orientation for the lever: pointing down, tipped by ``tilt`` so its fingertips lean
    toward the kettle (against the lever's heading) and its wrist away from it, the fingers' axis across the lever
    (the hand's long side along the kettle's); of the two turns about the approach axis that give it, the one nearer
    the base's untwisted hand (fewer radians on the wrist)."""
    inward = lever_heading(s) + np.pi
    c, sn = np.cos(-tilt), np.sin(-tilt)
    pitch = np.array([[c, 0.0, sn], [0.0, 1.0, 0.0], [-sn, 0.0, c]])
    rest = rz(float(s.robot_base[2])) @ R_DOWN
    options = [rz(inward) @ pitch @ R_DOWN @ rz(t) for t in (0.0, np.pi)]
    return min(options, key=lambda m: float(np.linalg.norm(_axis_angle(m @ rest.T))))


def _act(o, s: PrivilegedState, target, speed: float) -> np.ndarray:
    """``o._goto``'s move toward ``target`` (fingers closed), with the lever's hand (``lever_hand``)."""
    return o._goto(s, target, CLOSED, speed=speed, hand=lever_hand(s, o._tilt))


def press_lever(o, s: PrivilegedState) -> np.ndarray:
    """The base driven until the lever's press point stands ``LEVER_AHEAD`` in front (as far as the room allows);
    the hand (``lever_hand``) in ``IN`` from it along its own axis (from up and out beside the kettle), in along
    that axis to ``ABOVE``, then straight down onto it at 0.4 of full
    speed until RoboCasa reads the kettle on, then straight up; ``o`` is the ``RoboCasaOracle``."""
    press = np.array([*s.target.place_xy, s.target.grasp_z])
    z = np.array([0.0, 0.0, 1.0])
    if o._tilt is None:
        o._tilt = LEVER_TILT
        o._base_goal = base_goal(s, press, *LEVER_AHEAD) if s.facts.base_room is not None else None
        o._next("drive" if o._base_goal is not None else "approach")
    if (a := drive_phase(o, s, CLOSED)) is not None:
        return a
    heading = lever_heading(s)
    up = np.array([np.cos(heading) * np.sin(o._tilt), np.sin(heading) * np.sin(o._tilt), np.cos(o._tilt)])
    if o.phase == "approach":  # out beside the lever along the hand's own axis, clear of the kettle's top
        if o._near(s, press + up * IN, 0.03) or o._count > 120:
            o._next("descend")
        return _act(o, s, press + up * IN, 1.0)
    if o.phase == "descend":  # in along that axis
        if o._near(s, press + up * ABOVE, 0.01) or o._count > 120:
            o._next("press")
        return _act(o, s, press + up * ABOVE, 0.5)
    if o.phase == "press":  # straight down
        if s.pick.touching_gripper or o._count > 150:  # RoboCasa reads it on (or the press gave up)
            o._hold_release = s.eef_pos.copy()
            o._next("lift_off")
        elif o._count > 20 and o._near(s, press - z * PUSH, 0.002) and o._tilt < MAX_TILT:
            # stalled short (the forearm on the kettle): tipped further, in again
            o._tilt = min(MAX_TILT, o._tilt + 0.2)
            o._next("descend")
        return _act(o, s, press - z * PUSH, 0.4)
    return _act(o, s, o._hold_release + up * IN, 0.5)
