"""CPU stand-ins: ``random``, ``noop``, tiny checkpoint directories, and any stand-in the application registers
(``registry.register_standin``: the scenes' privileged oracle)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from indgen_vla.errors import PolicyError, UnknownNameError
from indgen_vla.interface import ACTION_DIM, NOOP_ACTION, Observation, PolicySpec, validate_chunk


class NoopPolicy:
    """Zero motion with the gripper open; stateless and batched, renders no cameras."""

    def __init__(self, name: str = "standin:noop", chunk_size: int = 8):
        self.spec = PolicySpec(
            "standin", name, chunk_size=chunk_size, replan_steps=chunk_size, cameras=(), batched=True
        )

    def reset(self, instruction: str, seed: int | None = None) -> None:
        pass

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        shape = (len(observations), self.spec.chunk_size, ACTION_DIM)
        return np.broadcast_to(np.asarray(NOOP_ACTION, np.float32), shape).copy()

    def close(self) -> None:
        pass


class RandomPolicy:
    """Uniform random deltas in [-scale, scale], gripper ±1; the same episode seed gives the same actions."""

    def __init__(self, name: str = "standin:random", chunk_size: int = 8, scale: float = 0.5):
        self.spec = PolicySpec("standin", name, chunk_size=chunk_size, replan_steps=chunk_size, cameras=())
        self.scale = float(scale)
        self._rng = np.random.default_rng(0)

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self._rng = np.random.default_rng(0 if seed is None else seed)

    def act(self, observations: Sequence[Observation]) -> np.ndarray:
        shape = (len(observations), self.spec.chunk_size, ACTION_DIM)
        chunk = self._rng.uniform(-self.scale, self.scale, size=shape).astype(np.float32)
        chunk[..., -1] = np.where(self._rng.random(shape[:2]) < 0.5, -1.0, 1.0)
        return validate_chunk(chunk, len(observations), self.spec.name)

    def close(self) -> None:
        pass


def load(parsed, options, *, trust_remote_code: bool = False, device: str = "cpu"):
    """``standin:NAME`` or ``standin:PATH`` (a LeRobot checkpoint directory, loaded by the lerobot adapter)."""
    from policy_wrappers.registry import STANDINS

    name = parsed.target
    if name == "noop":
        return NoopPolicy(parsed.spec, **options.fields(NoopPolicy, {"chunk_size": "chunk"}))
    if name == "random":
        return RandomPolicy(
            parsed.spec, **options.fields(RandomPolicy, {"chunk_size": "chunk", "scale": "scale"})
        )
    if name in STANDINS:
        try:
            cls = STANDINS.load(name)
        except ModuleNotFoundError as e:
            raise PolicyError(
                f"policy {parsed.spec}: needs the {e.name!r} package, which is not installed yet"
            ) from None
        return cls()
    if Path(name).expanduser().is_dir():
        from policy_wrappers import lerobot_policy

        return lerobot_policy.load(
            parsed, options, trust_remote_code=trust_remote_code, device=device, family="standin"
        )
    raise UnknownNameError("stand-in policy (or checkpoint directory)", name, STANDINS.names())
