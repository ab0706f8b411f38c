"""Where over the pick object the open gripper can come down without landing on a neighbour.

On LIBERO's real meshes a moved object can end up beside a taller one (cream_cheese at ``pick_y`` -2 sits 5 mm from
the tomato-sauce can): the Panda hand, 20 cm wide along the fingers' closing axis, then rests on the can's top while
the fingers are still 2 cm above the cheese, and closes on air. ``grasp_offset`` moves the grasp point over the
object, by as little as it can and only where the centred grasp is blocked, to the nearest point where no gripper
geom at the grasp pose overlaps a neighbour's bounding box. A centred grasp that is clear stays centred (offset 0).
"""

from __future__ import annotations

import numpy as np

MARGIN = 0.003  # clearance between the gripper's boxes and a neighbour's (m)
STEP = 0.002  # candidate grid spacing (m)
PAD_HALF = 0.009  # about half the finger pads' width across the closing axis: they stay on the object
OPEN_HALF = 0.04  # the open Panda fingers' inner faces from the grip site, along the closing axis (m)


def blocked(
    grip_lo: np.ndarray, grip_hi: np.ndarray, obs_lo: np.ndarray, obs_hi: np.ndarray, at: np.ndarray
) -> bool:
    """Do the gripper's boxes (relative to the grip site), put at ``at``, overlap any obstacle box (+ margin)?"""
    lo, hi = grip_lo + at, grip_hi + at
    over = (lo[:, None, :] < obs_hi[None] + MARGIN) & (hi[:, None, :] > obs_lo[None] - MARGIN)
    return bool(np.any(np.all(over, axis=2)))


def grasp_offset(
    grip_lo: np.ndarray, grip_hi: np.ndarray, obs_lo: np.ndarray, obs_hi: np.ndarray, centre: np.ndarray,
    pick_half: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """World (dx, dy) from the object's centre to grasp at: (0, 0) when that is clear, else the smallest clear
    offset that keeps the pads on the object (x) and the object between the open fingers (y), else (0, 0).

    ``grip_lo``/``grip_hi``: (G, 3) gripper geom boxes relative to the grip site, fingers open, pointing down,
    closing along world y; ``obs_lo``/``obs_hi``: (M, 3) neighbour boxes; ``centre``: the grip site at the centred
    grasp (object xy, grasp height); ``pick_half``: the object's world half extents (x, y).
    """
    if len(obs_lo) == 0 or not blocked(grip_lo, grip_hi, obs_lo, obs_hi, centre):
        return np.zeros(2)
    lim_x = max(0.0, float(pick_half[0]) - PAD_HALF)
    lim_y = max(0.0, OPEN_HALF - float(pick_half[1]) - MARGIN)
    xs = np.arange(-np.floor(lim_x / STEP), np.floor(lim_x / STEP) + 1) * STEP
    ys = np.arange(-np.floor(lim_y / STEP), np.floor(lim_y / STEP) + 1) * STEP
    cands = sorted(((x, y) for x in xs for y in ys), key=lambda c: (c[0] ** 2 + c[1] ** 2, c))
    for dx, dy in cands:
        if not blocked(grip_lo, grip_hi, obs_lo, obs_hi, centre + np.array([dx, dy, 0.0])):
            return np.array([dx, dy])
    return np.zeros(2)
