"""CPU stand-ins: ``random``, ``noop``, tiny checkpoint directories, and any stand-in the application registers
(``specs.register_standin``: the scenes' privileged oracle)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from indgen_vla.core.errors import PolicyError, UnknownNameError
from indgen_vla.core.protocol.interface import (
    ACTION_DIM,
    NOOP_ACTION,
    Observation,
    PolicySpec,
    validate_chunk,
)
from policy_wrappers import lerobot_policy, specs

GRIPPER = 6  # the gripper's index in the tabletop 7-d action and in RoboCasa's 12-d (convert_action order)


def _noop(action_dim: int) -> np.ndarray:
    """No motion, gripper open; on RoboCasa's 12-d action the control mode is the arm's (-1: base still)."""
    if action_dim == ACTION_DIM:
        return np.asarray(NOOP_ACTION, np.float32)
    a = np.zeros(action_dim, np.float32)
    a[GRIPPER] = -1.0
    a[-1] = -1.0
    return a


class NoopPolicy:
    """Zero motion with the gripper open; stateless and batched, renders no cameras, reads no observation."""

    def __init__(self, name: str = "standin:noop", chunk_size: int = 8, action_dim: int = ACTION_DIM):
        self.spec = PolicySpec(
            "standin", name, chunk_size=chunk_size, replan_steps=chunk_size, cameras=(), batched=True,
            action_dim=action_dim, reads_observations=False,
        )  # fmt: skip

    def reset(self, instruction: str, seed: int | None = None) -> None:
        pass

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        shape = (len(observations), self.spec.chunk_size, self.spec.action_dim)
        return np.broadcast_to(_noop(self.spec.action_dim), shape).copy()

    def close(self) -> None:
        pass


class RandomPolicy:
    """Uniform random deltas in [-scale, scale], gripper ±1; the same episode seed gives the same actions (it reads
    no observation: chance, the floor a scene's levels give a blind policy)."""

    def __init__(
        self,
        name: str = "standin:random",
        chunk_size: int = 8,
        scale: float = 0.5,
        action_dim: int = ACTION_DIM,
    ):
        self.spec = PolicySpec(
            "standin", name, chunk_size=chunk_size, replan_steps=chunk_size, cameras=(), action_dim=action_dim,
            reads_observations=False,
        )  # fmt: skip
        self.scale = float(scale)
        self._rng = np.random.default_rng(0)

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self._rng = np.random.default_rng(0 if seed is None else seed)

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        shape = (len(observations), self.spec.chunk_size, self.spec.action_dim)
        chunk = self._rng.uniform(-self.scale, self.scale, size=shape).astype(np.float32)
        chunk[..., GRIPPER] = np.where(self._rng.random(shape[:2]) < 0.5, -1.0, 1.0)
        return validate_chunk(chunk, len(observations), self.spec.name, self.spec.action_dim)

    def close(self) -> None:
        pass


def load(
    parsed, options, *, trust_remote_code: bool = False, device: str = "cpu", env_spec=None, scene_family=None
):
    """``standin:NAME`` or ``standin:PATH`` (a LeRobot checkpoint directory, loaded by the lerobot adapter);
    ``random`` and ``noop`` act in the scene's action space (``env_spec``: 7-d tabletop, 12-d RoboCasa365)."""
    name = parsed.target
    dim = {"action_dim": env_spec.action_dim} if env_spec is not None else {}
    if name == "noop":
        return NoopPolicy(parsed.spec, **options.fields(NoopPolicy, {"chunk_size": "chunk"}), **dim)
    if name == "random":
        return RandomPolicy(
            parsed.spec, **options.fields(RandomPolicy, {"chunk_size": "chunk", "scale": "scale"}), **dim
        )
    if name in specs.STANDINS:
        try:
            cls = specs.STANDINS.load(name)
        except ModuleNotFoundError as e:
            raise PolicyError(
                f"policy {parsed.spec}: needs the {e.name!r} package, which is not installed yet"
            ) from None
        import inspect

        try:
            takes_scene = "scene" in inspect.signature(cls).parameters
        except (TypeError, ValueError):
            takes_scene = False
        return (
            cls(scene=scene_family) if takes_scene and scene_family is not None else cls()
        )  # its own oracle
    if Path(name).expanduser().is_dir():
        return lerobot_policy.load(
            parsed, options, trust_remote_code=trust_remote_code, device=device, family="standin"
        )
    raise UnknownNameError("stand-in policy (or checkpoint directory)", name, specs.STANDINS.names())
