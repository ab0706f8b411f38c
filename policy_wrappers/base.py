"""The tiny ``Policy`` protocol every family adapter implements (DESIGN.md)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from indgen_vla.errors import ConfigError
from indgen_vla.interface import CAMERAS, Observation


@dataclass(frozen=True)
class PolicySpec:
    """What a policy needs and returns, declared by its adapter so the engine can serve it.

    Attributes:
        family: adapter family (``lerobot``, ``openpi``, ``openvla-oft``, ``groot``, ``standin``).
        name: the full spec string the user passed.
        chunk_size: actions per returned chunk (T).
        replan_steps: actions the engine executes from each chunk before asking again.
        cameras: our camera names the policy reads (empty for state-only policies: nothing is rendered).
        image_size: (H, W) the engine should render at, or None for the scene default.
        batched: one ``act`` call may carry several environments' observations.
        privileged: reads simulator state (oracles only); the engine passes it in ``Observation.extras``.
        flip_180: the model was trained on 180°-rotated images (LIBERO); the adapter applies it.
        observes_objects: a low-dimensional policy that reads ``Observation.objects`` (robomimic's "object"
            observation); never an image policy.
    """

    family: str
    name: str
    chunk_size: int = 1
    replan_steps: int = 1
    cameras: tuple[str, ...] = CAMERAS
    image_size: tuple[int, int] | None = None
    batched: bool = False
    privileged: bool = False
    flip_180: bool = False
    observes_objects: bool = False

    def __post_init__(self) -> None:
        if self.chunk_size < 1:
            raise ConfigError(f"policy {self.name}: chunk_size must be >= 1, got {self.chunk_size}")
        if not 1 <= self.replan_steps <= self.chunk_size:
            raise ConfigError(
                f"policy {self.name}: replan_steps must be in 1..chunk_size ({self.chunk_size}), got {self.replan_steps}"
            )
        unknown = [c for c in self.cameras if c not in CAMERAS]
        if unknown:
            raise ConfigError(f"policy {self.name}: unknown camera(s) {unknown}; cameras are {list(CAMERAS)}")
        if self.observes_objects and self.cameras:
            raise ConfigError(
                f"policy {self.name}: object poses are for low-dimensional policies only; drop its cameras "
                "or observes_objects"
            )


@runtime_checkable
class Policy(Protocol):
    """Observation batch in, (B, T, 7) float32 action chunk out.

    ``reset`` starts a new episode. Policies that keep per-episode state declare ``batched=False``
    and the engine gives each environment its own instance; batched policies must be stateless
    between ``act`` calls.
    """

    spec: PolicySpec

    def reset(self, instruction: str, seed: int | None = None) -> None: ...

    def act(self, observations: Sequence[Observation]) -> np.ndarray: ...

    def close(self) -> None: ...
