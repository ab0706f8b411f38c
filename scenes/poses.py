"""Object poses read off a privileged state: MimicGen's source poses and the low-dim "object" observation."""

from __future__ import annotations

import numpy as np

from indgen_vla.core.protocol.interface import OBJECT_DIM
from scenes.privileged import PrivilegedState


def object_poses(priv: PrivilegedState) -> dict[str, list[float]]:
    """World poses [x, y, z, qw, qx, qy, qz] of the pick object and the receptacle from a privileged state.

    Scenes without a free receptacle body (e.g. ``cabinet_pick``) use the placement target, unrotated.
    """
    poses = {"pick": [*map(float, priv.pick.pos), *map(float, priv.pick.quat_wxyz)]}
    if priv.goal is not None:
        poses["goal"] = [*map(float, priv.goal.pos), *map(float, priv.goal.quat_wxyz)]
    else:
        x, y = (float(v) for v in priv.target.place_xy)
        poses["goal"] = [x, y, float(priv.target.place_bottom), 1.0, 0.0, 0.0, 0.0]
    return poses


def object_vector(poses: dict[str, list[float]]) -> np.ndarray:
    """``Observation.objects`` from ``object_poses``: pick then target, position + quaternion xyzw with w >= 0."""
    out = []
    for key in ("pick", "goal"):
        x, y, z, qw, qx, qy, qz = poses[key]
        q = np.array([qx, qy, qz, qw])
        out += [x, y, z, *(q if qw >= 0 else -q)]
    vec = np.asarray(out, dtype=np.float32)
    assert vec.shape == (OBJECT_DIM,)
    return vec
