"""SE(3) math for ``indgen mimicgen``: pure functions on 4x4 homogeneous matrices and OSC_POSE delta actions."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from indgen_vla.core.protocol.interface import ACTION_DIM, POS_SCALE, ROT_SCALE


def pose_matrix(pos, rot: Rotation) -> np.ndarray:
    """4x4 pose from a position and a scipy ``Rotation``."""
    t = np.eye(4)
    t[:3, :3] = rot.as_matrix()
    t[:3, 3] = np.asarray(pos, dtype=float)
    return t


def pose_from_pq(pq) -> np.ndarray:
    """4x4 pose from [x, y, z, qw, qx, qy, qz] (MuJoCo's scalar-first quaternion)."""
    pq = np.asarray(pq, dtype=float)
    return pose_matrix(pq[:3], Rotation.from_quat(pq[[4, 5, 6, 3]]))


def pose_from_state(state) -> np.ndarray:
    """4x4 end-effector pose from the 8-d LIBERO state (position + axis-angle + gripper)."""
    state = np.asarray(state, dtype=float)
    return pose_matrix(state[:3], Rotation.from_rotvec(state[3:6]))


def invert_pose(t: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform: (R, p)^-1 = (R^T, -R^T p)."""
    inv = np.eye(4)
    inv[:3, :3] = t[:3, :3].T
    inv[:3, 3] = -t[:3, :3].T @ t[:3, 3]
    return inv


def transform_segment(poses: np.ndarray, src_obj: np.ndarray, new_obj: np.ndarray) -> np.ndarray:
    """Move eef poses (N, 4, 4) rigidly with their reference object: ``new_obj @ inv(src_obj) @ pose``."""
    return (new_obj @ invert_pose(src_obj))[None] @ np.asarray(poses)


def interpolate_poses(start: np.ndarray, end: np.ndarray, n: int) -> np.ndarray:
    """``n`` poses from just after ``start`` to ``end`` inclusive: linear in position, slerp in rotation."""
    if n < 1:
        return np.zeros((0, 4, 4))
    fr = np.arange(1, n + 1) / n
    rots = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([start[:3, :3], end[:3, :3]])))(fr)
    out = np.tile(np.eye(4), (n, 1, 1))
    out[:, :3, :3] = rots.as_matrix()
    out[:, :3, 3] = start[:3, 3] + fr[:, None] * (end[:3, 3] - start[:3, 3])
    return out


def target_poses(states: np.ndarray, actions: np.ndarray) -> np.ndarray:
    """The absolute goal poses robosuite's delta OSC_POSE controller set for each recorded step.

    The controller's goal is ``p + POS_SCALE * a[:3]`` and ``Rot(ROT_SCALE * a[3:6]) @ R`` (world frame).
    """
    pos_scale, rot_scale = POS_SCALE, ROT_SCALE
    states, actions = np.asarray(states, dtype=float), np.asarray(actions, dtype=float)
    rots = Rotation.from_rotvec(rot_scale * actions[:, 3:6]) * Rotation.from_rotvec(states[:, 3:6])
    out = np.tile(np.eye(4), (len(states), 1, 1))
    out[:, :3, :3] = rots.as_matrix()
    out[:, :3, 3] = states[:, :3] + pos_scale * actions[:, :3]
    return out


def pose_to_action(target: np.ndarray, current: np.ndarray, gripper: float) -> np.ndarray:
    """The 7-d OSC_POSE delta action that sets the controller's goal to ``target`` from ``current`` (clipped)."""
    pos_scale, rot_scale = POS_SCALE, ROT_SCALE
    a = np.zeros(ACTION_DIM)
    a[:3] = (target[:3, 3] - current[:3, 3]) / pos_scale
    a[3:6] = Rotation.from_matrix(target[:3, :3] @ current[:3, :3].T).as_rotvec() / rot_scale
    a[6] = gripper
    return np.clip(a, -1.0, 1.0)
