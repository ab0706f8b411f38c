"""``--env.type=indgen``: LeRobot's ``EnvConfig`` for one indgen level (registered on import; the
``lerobot_env_indgen`` plugin distribution imports this module when ``register_third_party_plugins()`` runs)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from functools import partial

import gymnasium as gym
from lerobot.configs import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.envs.utils import FreezeAfterEpisodeEnd
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_IMAGES, OBS_STATE

from indgen_vla.app.engine.config import PlanConfig
from indgen_vla.app.lerobot_bridge.level_env import (
    FIRST_SEED,
    LevelEnv,
    LevelRequest,
    LevelSetup,
    resolve_levels,
)
from indgen_vla.core.protocol.interface import OBJECT_DIM
from scenes.family import Scene, get_scene

os.environ.setdefault(
    "MUJOCO_GL", "egl"
)  # as the indgen command sets it: offscreen rendering without a display


def _make(setup: LevelSetup) -> gym.Env:
    """One sub-env; frozen after its episode ends, as LeRobot's own benchmarks are (``FreezeAfterEpisodeEnd``)."""
    return FreezeAfterEpisodeEnd(LevelEnv(setup))


def _family_of(plan: PlanConfig) -> Scene:
    """The level's scene family, configured with its options: looked up here, the plugin's entry (an edge)."""
    return get_scene(plan.scene, plan.scene_options())


@EnvConfig.register_subclass("indgen")
@dataclass
class IndgenEnv(EnvConfig):
    """One level of an indgen axis: ``--env.scene --env.task --env.axis --env.level`` (and ``--env.config``, evaluate's
    preset) build the environment and initial states ``indgen evaluate`` builds for that level; the reset seed
    ``first_seed + i`` is indgen's episode i of ``indgen evaluate --seed run_seed`` (docs/lerobot.md)."""

    task: str | None = None  # the scene's task (None: its first; "all": one task group per task)
    fps: int = 20
    scene: str = "pick_place"
    axis: str = "pick_y"
    level: int = 0
    config: str | None = None  # indgen evaluate's --config: a preset name or YAML path
    run_seed: int = 0  # indgen evaluate's --seed
    first_seed: int = FIRST_SEED  # the lerobot reset seed that is indgen's episode 0
    step: float | None = None
    axes_preset: str | None = None
    max_steps: int | None = None
    cameras: list[str] = field(default_factory=list)  # e.g. [agentview,wrist]; none for a state-only policy
    image_size: int | None = None  # rendered side in pixels (default: the preset's, else 128)
    warmup_steps: int | None = None  # no-op steps before the first observation (default: the preset's)
    object_poses: bool = False  # also observe indgen's object poses as environment_state (low-dim policies)
    allow_infeasible: bool = False
    video_size: int = 256  # lerobot-eval's episode videos (render())

    def __post_init__(self) -> None:
        self._setups, self._warnings = resolve_levels(
            LevelRequest(scene=self.scene, task=self.task, axis=self.axis, level=self.level, config=self.config,
                         run_seed=self.run_seed, first_seed=self.first_seed, step=self.step,
                         axes_preset=self.axes_preset, max_steps=self.max_steps, cameras=tuple(self.cameras),
                         image_size=self.image_size, warmup_steps=self.warmup_steps, object_poses=self.object_poses,
                         allow_infeasible=self.allow_infeasible, video_size=self.video_size),
            _family_of,
        )  # fmt: skip
        for line in self._warnings:
            print(f"[indgen] warning: {line}")
        first = self._setups[0]
        h, w = first.runner.image_size
        self.features = {
            ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(first.action_dim,)),
            "agent_pos": PolicyFeature(type=FeatureType.STATE, shape=(first.state_dim,)),
        }
        self.features_map = {ACTION: ACTION, "agent_pos": OBS_STATE}
        for cam in self.cameras:
            self.features[f"pixels/{cam}"] = PolicyFeature(type=FeatureType.VISUAL, shape=(h, w, 3))
            self.features_map[f"pixels/{cam}"] = f"{OBS_IMAGES}.{cam}"
        if self.object_poses:
            self.features["environment_state"] = PolicyFeature(type=FeatureType.ENV, shape=(OBJECT_DIM,))
            self.features_map["environment_state"] = OBS_ENV_STATE

    @property
    def levels(self) -> list[LevelSetup]:
        """The resolved level of each task (one lerobot task group each)."""
        return list(self._setups)

    @property
    def gym_kwargs(self) -> dict:
        return {}

    def create_envs(
        self, n_envs: int, use_async_envs: bool = False
    ) -> dict[str, dict[int, gym.vector.VectorEnv]]:
        """One vector env of ``n_envs`` sub-envs per task, keyed by ``LevelSetup.group`` (the level, read back by
        ``indgen import lerobot-eval``)."""
        out: dict[str, dict[int, gym.vector.VectorEnv]] = {}
        for setup in self._setups:
            fns = [partial(_make, setup) for _ in range(n_envs)]
            if use_async_envs and n_envs > 1:
                vec = gym.vector.AsyncVectorEnv(
                    fns, context="forkserver", autoreset_mode=gym.vector.AutoresetMode.NEXT_STEP
                )
            else:
                vec = gym.vector.SyncVectorEnv(fns, autoreset_mode=gym.vector.AutoresetMode.NEXT_STEP)
            out[setup.group] = {0: vec}
        return out
