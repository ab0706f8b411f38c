"""The one observation/action interface every policy and scene shares (DESIGN.md)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

CAMERAS = ("agentview", "wrist")
STATE_DIM = 8  # eef pos (3) + eef axis-angle (3) + gripper qpos (2): the LIBERO convention
ACTION_DIM = 7  # delta eef pos (3) + delta rotation (3) + gripper (-1 open, +1 close)
# robomimic's "object" observation for low-dim policies that declare it: pick then target, pos + quat (xyzw, w >= 0)
OBJECT_NAMES = tuple(f"{o}_{c}" for o in ("pick", "goal") for c in ("x", "y", "z", "qx", "qy", "qz", "qw"))
OBJECT_DIM = len(OBJECT_NAMES)
# why an episode failed (episodes.parquet "failure"), classified by the scene from privileged state; "" = older runs
FAILURE_MODES = ("none", "no_contact", "no_grasp", "dropped", "misplaced", "timeout_holding", "error")


@dataclass(frozen=True)
class Observation:
    """What a learned policy may see: raw-orientation camera images, 8-d state and the instruction.

    Privileged simulator state never appears here; oracles read it from the scene directly. ``objects``
    (the pick object's and the target's pose, ``OBJECT_NAMES``) is filled only for low-dimensional policies
    whose spec declares ``observes_objects``; image policies never get it.
    """

    images: dict[str, np.ndarray]
    state: np.ndarray
    instruction: str
    extras: dict[str, object] = field(default_factory=dict)
    objects: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.state.shape != (STATE_DIM,):
            raise ValueError(f"state must have shape ({STATE_DIM},), got {self.state.shape}")
        if self.objects is not None and np.shape(self.objects) != (OBJECT_DIM,):
            raise ValueError(f"objects must have shape ({OBJECT_DIM},), got {np.shape(self.objects)}")
        for name, img in self.images.items():
            if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
                raise ValueError(f"image {name!r} must be uint8 HxWx3, got {img.dtype} {img.shape}")


def validate_chunk(chunk: np.ndarray, batch: int, who: str) -> np.ndarray:
    """Check a policy's (B, T, 7) action chunk; raise ``PolicyError`` naming the policy otherwise."""
    from indgen_vla.errors import PolicyError

    arr = np.asarray(chunk)
    if arr.ndim == 2 and batch == 1:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[0] != batch or arr.shape[2] != ACTION_DIM or arr.shape[1] < 1:
        raise PolicyError(
            f"policy {who} returned actions of shape {arr.shape}; expected ({batch}, T, {ACTION_DIM})"
        )
    if not np.all(np.isfinite(arr)):
        raise PolicyError(f"policy {who} returned non-finite actions (NaN or inf)")
    return arr.astype(np.float32, copy=False)
