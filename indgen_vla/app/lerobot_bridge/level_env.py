"""One indgen level as a gymnasium env with LeRobot's observation keys: the road ``--env.type=indgen`` takes.

It is ``indgen evaluate``'s own road, not a copy of it: the options go through ``config_from_values`` and
``build_plan`` (the same preset, plan, certificates and seeds), and every episode runs in the engine's ``EnvRunner``
(the same scene build, reset options, warm-up and step contract). Only the policy loop is LeRobot's.

Seeds. ``lerobot-eval`` resets the i-th episode with ``seed = --seed + i`` (``eval_policy``: ``start_seed +
batch_ix * num_envs + j``, whatever the batch size), ``lerobot-train``'s evaluation the same with its ``--seed``; both
default to 1000. This env reads that reset seed as indgen's episode index ``episode = seed - first_seed`` and starts
the episode from ``evaluation_seed(run_seed, scene, task, episode)``, the seed ``indgen evaluate --seed run_seed``
gives episode ``episode`` (``indgen_vla.core.protocol.seeding``). With the defaults (``first_seed`` 1000, ``run_seed``
0) ``lerobot-eval --eval.n_episodes=N`` runs exactly the episodes 0..N-1 of ``indgen evaluate --episodes N``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from indgen_vla.app.engine.config import PlanConfig, config_from_values
from indgen_vla.app.engine.rollout import EnvRunner, RunnerConfig
from indgen_vla.app.engine.run import build_plan, check_feasible
from indgen_vla.core.errors import ConfigError, SceneError
from indgen_vla.core.protocol.interface import OBJECT_DIM, Observation
from indgen_vla.core.protocol.plan import EpisodeJob
from indgen_vla.core.protocol.seeding import evaluation_seed
from scenes.family import Scene

FIRST_SEED = (
    1000  # lerobot-eval's and lerobot-train's default --seed: the reset seed that is indgen's episode 0
)
GROUP_PREFIX = "indgen@"  # lerobot-eval's task_group of a level (group_name)
POLICY_LABEL = "lerobot-eval"  # the plan's policy field; nothing loads it (LeRobot brings its own policy)
FamilyOf = Callable[[PlanConfig], Scene]  # the edge's look-up: a plan section's scene family, configured


@dataclass(frozen=True)
class LevelSetup:
    """One (scene, task, axis, level) as ``indgen evaluate`` resolves it, plus the reset-seed mapping; picklable, so
    each sub-env of an async vector env rebuilds the same level in its own process."""

    runner: RunnerConfig
    scene: str
    task: str
    axis: str
    level: int
    param: float
    run_seed: int
    first_seed: int
    max_steps: (
        int | None
    )  # the plan's --max-steps; None: the task's own horizon (read from the env once built)
    state_dim: int
    action_dim: int
    certificate: str
    axis_spec: Any = None  # the axis's AxisSpec (the manifest of an imported run records it)
    video_size: int = 256

    @property
    def group(self) -> str:
        """lerobot-eval's task_group for this level: what ``indgen import lerobot-eval`` reads the level back from."""
        return group_name(
            self.scene, self.task, self.axis, self.level, self.param, self.run_seed, self.first_seed
        )

    def episode_of(self, reset_seed: int) -> int:
        """indgen's episode index of a lerobot reset seed."""
        episode = int(reset_seed) - self.first_seed
        if episode < 0:
            raise ConfigError(
                f"reset seed {reset_seed} is below --env.first_seed={self.first_seed} (indgen's episode i is reset "
                f"seed first_seed + i): run lerobot-eval with --seed >= {self.first_seed} or lower --env.first_seed"
            )
        return episode

    def job(self, episode: int) -> EpisodeJob:
        """The episode ``indgen evaluate --seed run_seed`` plans for this level (``plan_jobs``' seed)."""
        seed = evaluation_seed(self.run_seed, self.scene, self.task, episode)
        return EpisodeJob(self.task, self.axis, self.level, episode, seed, self.param)


def group_name(
    scene: str, task: str, axis: str, level: int, param: float, run_seed: int, first_seed: int
) -> str:
    """``indgen@scene@task@axis@level@pPARAM@seedR@firstF`` (``parse_group`` reads it back; the parameter carries
    what --env.step, --env.axes_preset or a preset made of the level)."""
    return (f"{GROUP_PREFIX}{scene}@{task}@{axis}@{int(level)}@p{float(param)!r}@seed{int(run_seed)}"
            f"@first{int(first_seed)}")  # fmt: skip


def parse_group(group: str) -> dict[str, Any] | None:
    """The level a ``group_name`` names, or None for another env's task group."""
    if not group.startswith(GROUP_PREFIX):
        return None
    parts = group[len(GROUP_PREFIX) :].split("@")
    if len(parts) != 7 or [p[:1] for p in parts[4:]] != ["p", "s", "f"]:
        return None
    try:
        return {"scene": parts[0], "task": parts[1], "axis": parts[2], "level": int(parts[3]),
                "param": float(parts[4][1:]), "run_seed": int(parts[5].removeprefix("seed")),
                "first_seed": int(parts[6].removeprefix("first"))}  # fmt: skip
    except ValueError:
        return None


@dataclass(frozen=True, kw_only=True)
class LevelRequest:
    """Which level ``--env.type=indgen`` builds (``IndgenEnv``'s fields, ``indgen import lerobot-eval``'s look-up):
    the scene, task (None: its first; "all": each task), axis and level, and the evaluate options that shape it
    (``config``: evaluate's preset, a name or YAML path; ``run_seed``: evaluate's --seed; None: the preset's, else
    evaluate's default); validated on construction."""

    scene: str
    axis: str
    level: int
    task: str | None = None
    config: str | None = None
    run_seed: int = 0
    first_seed: int = FIRST_SEED  # the lerobot reset seed that is indgen's episode 0
    step: float | None = None
    axes_preset: str | None = None
    max_steps: int | None = None
    cameras: tuple[str, ...] = ()
    image_size: int | None = None
    warmup_steps: int | None = None
    object_poses: bool = False  # also observe indgen's object poses as environment_state
    allow_infeasible: bool = False
    video_size: int = 256  # lerobot-eval's episode videos (render())

    def __post_init__(self) -> None:
        object.__setattr__(self, "cameras", tuple(self.cameras))
        if self.first_seed < 0:
            raise ConfigError(f"--env.first_seed must be >= 0, got {self.first_seed}")
        if self.video_size < 16:
            raise ConfigError(f"--env.video_size must be >= 16 pixels, got {self.video_size}")

    def options(self) -> dict[str, Any]:
        """The request as ``indgen evaluate``'s options (flat names) for one episode of the level."""
        return {"policy": POLICY_LABEL, "out": "(lerobot-eval: no run directory)", "scene": self.scene,
                "task": self.task, "axis": self.axis, "levels": f"{int(self.level)}:{int(self.level)}",
                "episodes": 1, "seed": int(self.run_seed), "step": self.step, "axes_preset": self.axes_preset,
                "max_steps": self.max_steps, "allow_infeasible": self.allow_infeasible,
                "image_size": self.image_size}  # fmt: skip


def resolve_levels(request: LevelRequest, family_of: FamilyOf) -> tuple[list[LevelSetup], list[str]]:
    """Each task's ``LevelSetup`` (``task`` "all": every task of the scene) and evaluate's warnings about the level
    (uncertified); a level whose certification failed is refused as ``evaluate`` refuses it. ``family_of``: the
    edge's look-up of the scene family (the request's options and preset name it)."""
    cfg = config_from_values(request.options(), request.config, strict=True)
    if request.warmup_steps is not None:
        cfg = dataclasses.replace(
            cfg, policy=dataclasses.replace(cfg.policy, warmup_steps=int(request.warmup_steps))
        )
    plan = build_plan(cfg, family_of(cfg.plan))
    if len(plan.axes) != 1:
        raise ConfigError(
            f"--env.axis names {len(plan.axes)} axes ({', '.join(plan.axes)}); give one axis per env"
        )
    warnings = check_feasible(cfg, plan)
    builder = plan.builder
    spec = getattr(builder, "env_spec", None)
    known = tuple(spec.cameras) if spec is not None else ("agentview", "wrist")
    unknown = [c for c in request.cameras if c not in known]
    if unknown:
        raise ConfigError(f"--env.cameras: {unknown} not among scene {plan.scene}'s cameras {list(known)}")
    side = cfg.policy.image_size or 128
    runner = RunnerConfig(levels=builder, cameras=request.cameras, image_size=(side, side),
                          max_steps=cfg.plan.max_steps, privileged=False, warmup_steps=cfg.policy.warmup_steps,
                          objects=request.object_poses)  # fmt: skip
    axis_name = next(iter(plan.axes))
    k = plan.levels[axis_name][0]
    setups = [
        LevelSetup(
            runner=runner,
            scene=plan.scene,
            task=t,
            axis=axis_name,
            level=k,
            param=plan.scene_plan.cell(t, axis_name, k).param,
            run_seed=cfg.plan.seed,
            first_seed=request.first_seed,
            max_steps=cfg.plan.max_steps,
            state_dim=spec.state_dim if spec else 8,
            action_dim=int(getattr(builder, "action_dim", 7)),
            certificate=plan.scene_plan.cell(t, axis_name, k).certificate,
            axis_spec=plan.axes[axis_name],
            video_size=request.video_size,
        )  # fmt: skip
        for t in plan.tasks
    ]
    return setups, warnings


class LevelEnv(gym.Env):
    """One level of one task; ``reset(seed=s)`` starts indgen's episode ``s - first_seed`` of that level.

    Observations are LeRobot's raw env keys: ``agent_pos`` (the robot state), ``pixels`` {camera: uint8 HxWx3, the
    simulator's raw orientation, as indgen hands images to policies} and, with ``object_poses``, ``environment_state``.
    ``info["is_success"]`` is the scene's success predicate; an episode ends on success (terminated) or at the
    level's step limit (truncated). A simulator error raises (indgen's engine would retry the episode; lerobot-eval
    has no retries).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}
    render_mode = "rgb_array"

    def __init__(self, setup: LevelSetup):
        super().__init__()
        self.setup = setup
        self.task = setup.task
        self.task_description = setup.task  # replaced by the scene's instruction at the first reset
        self._runner: EnvRunner | None = None
        self._job: EpisodeJob | None = None
        self._last: dict[str, Any] | None = None
        self._max_episode_steps = setup.max_steps or 10_000  # the task's own horizon once the scene is built
        h, w = setup.runner.image_size
        spaces: dict[str, gym.Space] = {
            "agent_pos": gym.spaces.Box(-np.inf, np.inf, (setup.state_dim,), np.float32)
        }
        if setup.runner.cameras:
            spaces["pixels"] = gym.spaces.Dict(
                {c: gym.spaces.Box(0, 255, (h, w, 3), np.uint8) for c in setup.runner.cameras}
            )
        if setup.runner.objects:
            spaces["environment_state"] = gym.spaces.Box(-np.inf, np.inf, (OBJECT_DIM,), np.float32)
        self.observation_space = gym.spaces.Dict(spaces)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (setup.action_dim,), np.float32)

    def _observation(self, obs: Observation) -> dict[str, Any]:
        out: dict[str, Any] = {"agent_pos": np.asarray(obs.state, dtype=np.float32)}
        if self.setup.runner.cameras:
            out["pixels"] = {c: obs.images[c] for c in self.setup.runner.cameras}
        if self.setup.runner.objects:
            out["environment_state"] = np.asarray(obs.objects, dtype=np.float32)
        return out

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if seed is None:
            raise ConfigError(
                "--env.type=indgen needs seeded resets (episode i is reset seed --env.first_seed + i): run "
                "lerobot-eval / lerobot-train with a --seed"
            )
        if self._runner is None:
            self._runner = EnvRunner(self.setup.runner)
        self._job = self.setup.job(self.setup.episode_of(seed))
        t = self._runner.reset(self._job)
        if t.error:
            raise SceneError(f"indgen {self.setup.group} episode {self._job.episode}: {t.error}")
        env = self._runner.env
        self._max_episode_steps = int(env.max_steps)
        self.task_description = t.obs.instruction
        self._last = self._observation(t.obs)
        return self._last, self._info(False)

    def _info(self, success: bool, steps: int = 0, failure: str = "") -> dict[str, Any]:
        job = self._job
        return {"is_success": bool(success), "episode": job.episode, "indgen_seed": job.seed, "steps": steps,
                "failure": failure}  # fmt: skip

    def step(self, action):
        if self._job is None or self._runner is None:
            raise SceneError("step() before reset(seed=...)")
        t = self._runner.execute(np.asarray(action, dtype=np.float32).reshape(1, -1))
        if t.error:
            raise SceneError(f"indgen {self.setup.group} episode {self._job.episode}: {t.error}")
        if not t.done:
            self._last = self._observation(t.obs)
        info = self._info(t.success, t.steps, t.failure if t.done else "")
        return self._last, float(t.success), bool(t.done and t.success), bool(t.done and not t.success), info

    def render(self) -> np.ndarray:
        """An upright agentview frame for lerobot-eval's videos (``--env.video_size``)."""
        size = (self.setup.video_size, self.setup.video_size)
        if self._runner is None or self._runner.env is None:
            raise SceneError("render() before reset(seed=...)")
        return self._runner.env.render_frame("agentview", size)

    def close(self) -> None:
        if self._runner is not None:
            self._runner.close()
            self._runner = None
