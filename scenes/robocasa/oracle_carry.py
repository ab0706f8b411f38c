"""Where the RoboCasa oracle's carry that drives twice (``RoboCasaOracle._carry`` with ``carry_drives``) keeps its
hand clear of the place point beside the pick object (CheesyBread's bread next to the cheese): the cramped grasp's
sideways tip and the hand's twist pointing down; kept apart from ``oracle.py`` for its length."""

from __future__ import annotations

import numpy as np

from scenes.privileged import PrivilegedState
from scenes.robocasa.oracle_base import rz, to_base

# the hand's body: about HAND_BACK behind the grip site when tipped 1 rad (none pointing down) and HAND_HALF to each
# side along the fingers' axis; where the place point (the bread) stands within TURN_CLEAR of it (beside the cheese:
# the hand, tipped forward or pointing down, came down on the bread's top 14-15 cm over the cheese and pushed it
# away), the grasp turns: the tipped hand a quarter turn sideways (back to the heading once lifted), the hand
# pointing down across a square object's other side
HAND_BACK, HAND_HALF, TURN_CLEAR = 0.08, 0.1, 0.08


def clearance(rel, along, centre=(0.0, 0.0)) -> float:
    """How far the point ``rel`` (base frame xy) lies from the hand's body: a segment ``HAND_HALF`` each way along
    the unit ``along`` (the fingers' axis) through ``centre``."""
    d = np.asarray(rel) - np.asarray(centre)
    return float(np.linalg.norm(d - np.clip(d @ along, -HAND_HALF, HAND_HALF) * np.asarray(along)))


def _place_from_pick(s: PrivilegedState) -> np.ndarray:
    return to_base(s, [*s.target.place_xy, 0.0]) - to_base(s, s.pick.pos)


def side_turn(s: PrivilegedState) -> float:
    """The quarter turn about the vertical (0, +pi/2 left, -pi/2 right) the cramped grasp tips the hand toward: 0
    unless the place point stands within ``TURN_CLEAR`` of the tipped hand's body (``HAND_BACK`` behind the grip
    site, ``HAND_HALF`` to each side), else the side that keeps it farthest."""
    rel = _place_from_pick(s)

    def clear(turn: float) -> float:
        tip = np.array([np.cos(turn), np.sin(turn)])
        return clearance(rel, np.array([-tip[1], tip[0]]), -HAND_BACK * tip)

    return 0.0 if clear(0.0) >= TURN_CLEAR else max((np.pi / 2, -np.pi / 2), key=clear)


def clear_twist(o, s: PrivilegedState) -> float:
    """The grasp's twist pointing down (``o``: the ``RoboCasaOracle``, its square-grasp ``_twist``), a square
    object's other side where the hand's fingers would come down within ``TURN_CLEAR`` of the place point."""
    ext, g = s.pick.half_extents, o._twist or 0.0
    if ext is None or abs(float(ext[0]) - float(ext[1])) >= 0.005:
        return g
    rel, to_base_xy = _place_from_pick(s), rz(-float(s.robot_base[2]))[:2, :2]
    clear = lambda t: clearance(rel, to_base_xy @ o._hand(s, 0.0, t)[:2, 0])  # noqa: E731
    if clear(g) >= TURN_CLEAR:
        return g
    other = g - np.sign(g or 1.0) * np.pi / 2  # within +-pi/2, as the square grasp's
    return other if clear(other) > clear(g) else g
