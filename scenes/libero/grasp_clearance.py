"""Where over the pick object the open gripper can come down without landing on a neighbour.

On LIBERO's real meshes a moved object can end up beside a taller one (cream_cheese at ``pick_y`` -2 sits 5 mm from
the tomato-sauce can): the Panda hand, 20 cm wide along the fingers' closing axis, then rests on the can's top while
the fingers are still 2 cm above the cheese, and closes on air. ``grasp_offset`` moves the grasp point over the
object, by as little as it can and only where the centred grasp is blocked, to the nearest point where no gripper
geom at the grasp pose overlaps a neighbour's bounding box. A centred grasp that is clear stays centred (offset 0).
An open-topped object wider than the open fingers (LIBERO-Spatial's black bowl, 10.6 cm) closes them on air over
its centre: ``rim_offset`` pinches its wall instead, one finger inside and one outside.
"""

from __future__ import annotations

import numpy as np

MARGIN = 0.003  # clearance between the gripper's boxes and a neighbour's (m)
STEP = 0.002  # candidate grid spacing (m)
PAD_HALF = 0.009  # about half the finger pads' width across the closing axis: they stay on the object
OPEN_HALF = 0.04  # the open Panda fingers' inner faces from the grip site, along the closing axis (m)
HOLLOW = 0.02  # an object whose own surface lies this far below its top at its centre is open-topped (m)
RIM_DOWN = (
    0.025  # rim grasp: the grip site this far below the rim's top (the real bowl's hull is lower on a side)
)


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


def rim_offset(
    grip_lo: np.ndarray, grip_hi: np.ndarray, obs_lo: np.ndarray, obs_hi: np.ndarray, centre: np.ndarray,
    walls: list[float],
) -> np.ndarray | None:  # fmt: skip
    """World (dx, dy) from an open-topped object's centre to the middle of its wall to pinch, on the fingers'
    closing axis (world y), or None without a wall. ``walls``: the wall's middle on each side where one was found
    (dy from the centre); the first whose grasp is clear of the neighbours wins, else the first. ``centre``: the
    grip site over the object's centre at the rim grasp's height."""
    sides = [np.array([0.0, dy]) for dy in walls]
    for dxy in sides:
        if len(obs_lo) == 0 or not blocked(grip_lo, grip_hi, obs_lo, obs_hi, centre + np.array([*dxy, 0.0])):
            return dxy
    return sides[0] if sides else None


def wall_middles(m, d, body: int, c: np.ndarray, top: float, z: float) -> list[float]:
    """Body ``body``'s wall middles (dy from ``c``, on the +y then -y side) at height ``z``, from rays on its
    collision geoms (MuJoCo ``m``, ``d``); [] when its own surface at the centre is not ``HOLLOW`` below ``top``."""
    import mujoco

    hit, group = np.full(1, -1, np.int32), np.array([1, 0, 0, 0, 0, 0], np.uint8)

    def ray(start, direction) -> float | None:
        dist = mujoco.mj_ray(m, d, np.asarray(start, float), np.asarray(direction, float), group, 1, -1, hit)
        return float(dist) if dist >= 0 and m.geom_bodyid[hit[0]] == body else None

    depth = ray([c[0], c[1], top + 0.002], [0, 0, -1])
    if depth is None or depth - 0.002 < HOLLOW:
        return []
    walls = []
    for sign in (1.0, -1.0):  # the inner face from the centre, the outer face from 20 cm out
        inner, outer = ray([c[0], c[1], z], [0, sign, 0]), ray([c[0], c[1] + sign * 0.2, z], [0, -sign, 0])
        if inner is not None and outer is not None and inner < 0.2 - outer:
            walls.append(sign * (inner + 0.2 - outer) / 2)
    return walls
