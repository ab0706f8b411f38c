"""MuJoCo geometry both scene backends read (built-in ``scenes.sim`` and ``scenes.libero.env``): a body's
collision geoms, world bounding boxes, contacts between geom sets, the arm's grip site and the grasp height.

Functions take raw ``mujoco.MjModel``/``MjData`` (``sim.model._model``, ``sim.data._data``); importing this
module imports only NumPy.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

# the eight corners of a unit box, as sign vectors
_CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])


def named_geoms(model, names: Iterable[str]) -> np.ndarray:
    """Geom ids of ``names`` (e.g. a gripper's or an object's ``contact_geoms``)."""
    return np.array([model.geom(n).id for n in names], dtype=int)


def body_geoms(model, body: int) -> np.ndarray:
    """Colliding geoms of the kinematic tree rooted at ``body`` (a free object with all its child bodies)."""
    root, gbody = model.body_rootid, model.geom_bodyid
    return np.array(
        [
            g
            for g in range(model.ngeom)
            if root[gbody[g]] == body and (model.geom_contype[g] or model.geom_conaffinity[g])
        ],
        dtype=int,
    )


def geom_corners(model, data, geoms: Iterable[int]) -> np.ndarray:
    """World positions (8 per geom, stacked) of the corners of each geom's local bounding box."""
    pts = [
        data.geom_xpos[g]
        + (data.geom_xmat[g].reshape(3, 3) @ (model.geom_aabb[g][:3] + _CORNERS * model.geom_aabb[g][3:]).T).T
        for g in geoms
    ]
    return np.concatenate(pts)


def world_aabb(model, data, geoms: Iterable[int]) -> tuple[np.ndarray, np.ndarray]:
    """World axis-aligned bounding box (min corner, max corner) of ``geoms``."""
    pts = geom_corners(model, data, geoms)
    return pts.min(axis=0), pts.max(axis=0)


def geom_mask(model, geoms: np.ndarray) -> np.ndarray:
    """Boolean mask over the model's geoms, True at ``geoms`` (for ``touching``)."""
    mask = np.zeros(model.ngeom, dtype=bool)
    mask[geoms] = True
    return mask


def touching(data, mask_a: np.ndarray, mask_b: np.ndarray) -> bool:
    """Does any geom of ``mask_a`` touch any geom of ``mask_b`` in the current contacts (~2 us per call)?"""
    n = data.ncon
    if n == 0:
        return False
    g = data.contact.geom[:n]
    return bool(np.any((mask_a[g[:, 0]] & mask_b[g[:, 1]]) | (mask_a[g[:, 1]] & mask_b[g[:, 0]])))


def grip_site(data, robot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A robosuite robot's grip-site position, its 3x3 orientation and the finger joint positions (copies)."""
    site = robot.eef_site_id
    return (
        np.array(data.site_xpos[site]),
        np.array(data.site_xmat[site]).reshape(3, 3),
        np.array(data.qpos[robot._ref_gripper_joint_pos_indexes]),
    )


def grasp_height(bottom: float, top: float, frac: float) -> float:
    """Grip-site z for grasping an object spanning ``bottom``..``top`` at ``frac`` of its height.

    The Panda hand sits ~2.7 cm above the grip site: the object's top never reaches it.
    """
    z = bottom + frac * (top - bottom)
    return float(max(min(z, top - 0.012), top - 0.02, bottom + 0.01))
