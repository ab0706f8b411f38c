"""Scene-side rollout: an ``EnvRunner`` owns scene instances and executes action chunks; ``run_episode``
is the plain single-episode loop (used by the Ray backend and by tests as the reference)."""

from __future__ import annotations

import dataclasses
import sys
import time
import traceback
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from indgen_vla.app.engine.reconnect import Outage
from indgen_vla.core.errors import EpisodeUnavailableError, PolicyConnectionError
from indgen_vla.core.protocol.interface import ACTION_DIM, QUERY_KEY, Observation, validate_chunk
from indgen_vla.core.protocol.plan import EpisodeJob, LevelBuilder
from indgen_vla.core.runs.records import EpisodeRecord
from indgen_vla.core.runs.video import write_mp4

WARMUP_ACTION = np.array([0, 0, 0, 0, 0, 0, -1], dtype=np.float32)  # openpi's LIBERO client waits like this


@dataclass(frozen=True)
class RunnerConfig:
    """How a worker builds scenes: identical in every worker so outcomes do not depend on placement."""

    levels: LevelBuilder  # the plan's builder (``EvalPlan.builder``): builds each (task, axis, level)
    cameras: tuple[str, ...]
    image_size: tuple[int, int]
    max_steps: int | None
    privileged: bool
    warmup_steps: int = 0
    objects: bool = False  # attach Observation.objects (low-dim policies that declare observes_objects)
    video_dir: str | None = None
    video_size: tuple[int, int] = (256, 256)
    lazy_render: bool = True  # render cameras only for the observation a chunk slice ends on (the one read)
    history_steps: int = 0  # also render the steps before each query (PolicySpec.history_steps)

    @property
    def scene(self) -> str:
        return self.levels.scene


@dataclass
class Transition:
    """What a worker reports after a reset or an executed chunk."""

    key: tuple[str, str, int, int]
    obs: Observation | None
    done: bool = False
    success: bool = False
    steps: int = 0
    error: str = ""
    video: str = ""
    wall_s: float = 0.0
    failure: str = ""  # scenes.failure mode, set when the episode ends
    progress: int | None = None  # scenes.failure progress score 0..5, set when the episode ends (None: none)
    param: float | None = None  # the episode's own axis parameter (``env.episode_param``; None: the plan's)
    final: bool = False  # an error its seed decides (EpisodeUnavailableError): recorded once, not retried
    # the worker's own seconds, set when the episode ends (engine/timing.py: indgen budget reads them back)
    sim_s: float = 0.0  # executing chunk slices: physics and the renders read
    reset_s: float = 0.0  # its reset, a scene build included
    build_s: float = 0.0
    builds: int = 0


@dataclass(frozen=True)
class RunMeta:
    """Run-level fields copied into every episode record."""

    run_id: str
    policy: str
    data_regime: str
    scene: str


class EnvRunner:
    """Owns the scene instance of the current (task, axis, level) and steps it chunk by chunk."""

    def __init__(self, cfg: RunnerConfig):
        self.cfg = cfg
        self._env: Any = None
        self._env_key: tuple | None = None
        self._job: EpisodeJob | None = None
        self._steps = 0
        self._t0 = 0.0
        self._frames: list[np.ndarray] = []
        # the images of the last history_steps + 1 steps, the current one last (None: a step not rendered)
        self._recent: deque[dict[str, np.ndarray] | None] = deque(maxlen=cfg.history_steps + 1)
        self._can_skip_render = False
        # prepare(): (the job, its reset's transition, the reset's seconds)
        self._prepared: tuple[EpisodeJob, Transition, float] | None = None
        self._clock = [0.0, 0.0, 0.0, 0]  # this episode's seconds: stepping, reset, build; builds

    @property
    def env(self) -> Any:
        """The current level's scene env (None before the first reset and once closed): its horizon, video frames."""
        return self._env

    def _env_for(self, job: EpisodeJob):
        key = (job.task, job.axis, job.level)
        if key != self._env_key:
            self.close()
            t = time.perf_counter()
            self._env = self.cfg.levels.make_env(
                job.task, job.axis, job.level, cameras=tuple(self.cfg.cameras), image_size=self.cfg.image_size,
                max_steps=self.cfg.max_steps,
            )  # fmt: skip
            self._env_key = key
            self._can_skip_render = _takes_observe(self._env)
            self._clock[2:] = [time.perf_counter() - t, 1]
        return self._env

    def prepare(self, job: EpisodeJob) -> None:
        """Build ``job``'s scene and reset it ahead of the request (while the policy loads); ``reset(job)`` then
        answers at once. The state is the same: nothing runs on this runner between the two."""
        t = time.perf_counter()
        first = self.reset(job)
        self._prepared = (job, first, time.perf_counter() - t) if not first.error else None

    def _observe(self, obs: Observation) -> Observation:
        """Attach privileged state for oracles only (learned policies never see it), object poses for
        the low-dim policies that declare them, the earlier steps' images for those that declare history; and the
        query's identity (``QUERY_KEY``) for policies that sample."""
        add: dict = {"extras": {**obs.extras, QUERY_KEY: (self._job.seed, self._steps)}}
        if self.cfg.history_steps:
            earlier = tuple(self._recent)[:-1]
            assert all(f is not None for f in earlier), "a history step was not rendered"
            add["history"] = earlier
        if self.cfg.objects:
            add["objects"] = self._env.object_observation()
        obs = dataclasses.replace(obs, **add)  # one copy (and one validation) per query
        if self.cfg.privileged:
            obs = self._env.with_privileged(obs)
        return obs

    def _record_frame(self) -> None:
        if self._job is not None and self._job.video:
            self._frames.append(self._env.render_frame("agentview", self.cfg.video_size))

    def reset(self, job: EpisodeJob) -> Transition:
        """Start ``job``'s episode from its seed; warm-up no-op steps do not count as policy steps."""
        prepared, self._prepared = self._prepared, None
        if prepared is not None and prepared[0] == job:  # prepare() did this reset already
            self._t0 = time.perf_counter() - prepared[2]
            return prepared[1]
        self._t0 = time.perf_counter()
        self._job, self._steps, self._frames = job, 0, []
        self._clock = [0.0, 0.0, 0.0, 0]
        try:
            env = self._env_for(job)
            obs, _ = env.reset(seed=job.seed, options={"episode": job.episode})  # LIBERO: fixed init state
            lazy = self.cfg.lazy_render and self._can_skip_render
            for i in range(self.cfg.warmup_steps):  # only the last warm-up step's images are read
                observe = not lazy or i == self.cfg.warmup_steps - 1
                obs, _, _, _, _ = (
                    env.step(WARMUP_ACTION, observe=observe) if lazy else env.step(WARMUP_ACTION)
                )
            # the warm-up's frames are no history: RynnVLA-002's eval keeps only the frames it acted on
            self._recent.clear()
            self._recent.append(obs.images)
            self._record_frame()
            self._clock[1] = time.perf_counter() - self._t0
            return Transition(job.key, self._observe(obs))
        except EpisodeUnavailableError as e:  # the seed rules this level out: the env stays, no retry
            return Transition(job.key, None, done=True, error=_describe(e), final=True)
        except Exception as e:  # a simulator failure becomes an episode error, retried by the engine
            self._env_key = None
            return Transition(job.key, None, done=True, error=_describe(e))

    def execute(self, actions: np.ndarray) -> Transition:
        """Execute a (n, 7) slice of a chunk; stop early on success or the step limit."""
        job = self._job
        assert job is not None, "execute() before reset()"
        started = time.perf_counter()
        try:
            env = self._env
            obs, done, success = None, False, False
            rows = np.asarray(actions, dtype=np.float32).reshape(-1, env.action_space.shape[0])
            lazy = self.cfg.lazy_render and self._can_skip_render
            first_read = len(rows) - 1 - self.cfg.history_steps  # the query's step and its history are read
            for j, a in enumerate(rows):
                if lazy and j < first_read:  # nobody reads this step's images: physics only
                    obs, _, terminated, truncated, info = env.step(a, observe=False)
                    self._recent.append(None)
                else:
                    obs, _, terminated, truncated, info = env.step(a)
                    self._recent.append(obs.images)
                self._steps += 1
                success = bool(info.get("success", False))
                self._record_frame()
                if terminated or truncated or success:
                    done = True
                    break
            t = Transition(job.key, None if done else self._observe(obs), done, success, self._steps)
        except Exception as e:
            return Transition(job.key, None, done=True, error=_describe(e), steps=self._steps)
        if done:
            t.failure = env.failure_mode(success)
            t.progress = env.progress(success) if hasattr(env, "progress") else None
            t.param = getattr(env, "episode_param", None)
            t.video = self._write_video(job, success)
            t.wall_s = time.perf_counter() - self._t0
        self._clock[0] += time.perf_counter() - started
        if done:
            t.sim_s, t.reset_s, t.build_s, t.builds = self._clock
        return t

    def _write_video(self, job: EpisodeJob, success: bool) -> str:
        if not job.video or not self._frames or not self.cfg.video_dir:
            return ""

        name = f"{job.axis}_L{job.level}_{job.task}_ep{job.episode}_{'success' if success else 'fail'}.mp4"
        path = Path(self.cfg.video_dir) / name
        path.parent.mkdir(parents=True, exist_ok=True)
        frames, self._frames = self._frames, []
        try:
            write_mp4(frames, path, fps=20)
        except OSError as error:  # the video is optional; the episode's outcome stands
            print(f"[indgen] warning: {error}; episode recorded without its video", file=sys.stderr)
            return ""
        return str(Path("videos") / name)

    def close(self) -> None:
        if self._env is not None:
            try:
                self._env.close()
            finally:
                self._env, self._env_key = None, None


def action_dim(levels) -> int:
    """The action size of the planned scene family (``LevelBuilder.action_dim``; 7 when a builder has none)."""
    return int(getattr(levels, "action_dim", ACTION_DIM))


def _takes_observe(env) -> bool:
    """Whether the scene can step without rendering (``step(action, observe=False)``)."""
    import inspect

    try:
        return "observe" in inspect.signature(env.step).parameters
    except (TypeError, ValueError):
        return False


def _describe(e: BaseException) -> str:
    """One line for the ``error`` column: exception type, message and where it was raised (an exception that
    crossed a process keeps the line described where it was raised, ``remote_description``)."""
    if isinstance(getattr(e, "remote_description", None), str):
        return e.remote_description
    tb = traceback.extract_tb(e.__traceback__)
    where = f" at {Path(tb[-1].filename).name}:{tb[-1].lineno}" if tb else ""
    msg = str(e).strip().splitlines()[0] if str(e).strip() else ""
    return f"{type(e).__name__}: {msg}{where}"


def make_record(
    meta: RunMeta, job: EpisodeJob, t: Transition, status: str = "ok", error: str = ""
) -> EpisodeRecord:
    """The episode's row; an error its seed decides (``Transition.final``) is recorded as ``unavailable``."""
    if status == "error" and t.final:
        status = "unavailable"
    return EpisodeRecord(
        run_id=meta.run_id, policy=meta.policy, data_regime=meta.data_regime, scene=meta.scene, task=job.task,
        axis=job.axis, level=job.level, param=job.param if t.param is None else float(t.param),
        episode=job.episode, seed=job.seed,
        success=bool(t.success) and status == "ok", steps=int(t.steps), status=status, error=error,
        wall_s=float(t.wall_s), video=t.video, failure=status if status != "ok" else t.failure,
        progress=None if status != "ok" else t.progress,
    )  # fmt: skip


def run_episode(
    runner: EnvRunner,
    policy,
    job: EpisodeJob,
    meta: RunMeta,
    replan_steps: int,
    max_retries: int = 2,
    server_patience_s: float = 600.0,
):
    """The reference loop: reset, then act → execute ``replan_steps`` of each chunk until done.

    A policy or simulator failure retries the episode from its seed up to ``max_retries`` times, then
    returns a record with status "error" and the message (never a silent failure); an error the seed decides
    (``Transition.final``) is recorded at once. A connection fault
    (``PolicyConnectionError``) waits with backoff and re-runs the episode without using up a retry; past
    ``server_patience_s`` it raises ``ServerUnreachableError``.
    """
    outage, faults, attempt, last_error = Outage(patience_s=server_patience_s), 0, 0, ""
    while attempt <= max_retries:
        t = runner.reset(job)
        try:
            if not t.error:
                policy.reset(t.obs.instruction, seed=job.seed)
            while not t.done and not t.error:
                chunk = validate_chunk(policy.act([t.obs]), 1, meta.policy, action_dim(runner.cfg.levels))
                outage.ok()
                t = runner.execute(chunk[0, :replan_steps])
        except PolicyConnectionError as e:
            faults += 1
            time.sleep(outage.fault(faults, _describe(e)))
            continue  # the same attempt again, from the seed
        except Exception as e:  # PolicyError and anything the model raises
            t = Transition(job.key, None, done=True, error=_describe(e))
        if not t.error:
            return make_record(meta, job, t)
        attempt += 1
        last_error = f"attempt {attempt}: {t.error}"
        if t.final:
            break
    return make_record(meta, job, t, status="error", error=last_error)
