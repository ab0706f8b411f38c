"""The Ray backend: each actor owns a scene runner and its own policy; episodes are scheduled
dynamically across actors. Seeds come from the plan, so results equal the local backend's.

Connects to the cluster in ``RAY_ADDRESS`` when set, else starts a local Ray instance. Each actor waits out
a policy server outage on its own (``run_episode``'s backoff), with the same ``--server-patience``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from indgen_vla.engine.config import EpisodeJob, EvalConfig
from indgen_vla.engine.rollout import RunMeta, RunnerConfig
from indgen_vla.errors import ConfigError, ServerUnreachableError
from indgen_vla.records import EpisodeRecord


class _EpisodeActor:
    """Holds one EnvRunner and one policy instance for the actor's lifetime."""

    def __init__(self, runner_cfg: RunnerConfig, policy: str, trust_remote_code: bool, device: str):
        import logging
        import os

        os.environ.setdefault("MUJOCO_GL", "egl")
        logging.getLogger("robosuite").setLevel(logging.ERROR)
        from indgen_vla.engine.rollout import EnvRunner
        from policy_wrappers.registry import load_policy

        self.runner = EnvRunner(runner_cfg)
        self.policy = load_policy(
            policy, trust_remote_code=trust_remote_code, device=device, scene=runner_cfg.scene
        )

    def run(
        self, job: EpisodeJob, meta: RunMeta, replan: int, max_retries: int, patience: float
    ) -> EpisodeRecord:
        from indgen_vla.engine.rollout import run_episode

        return run_episode(self.runner, self.policy, job, meta, replan, max_retries, patience)

    def close(self) -> None:
        self.runner.close()
        self.policy.close()


def run_ray(
    jobs: Sequence[EpisodeJob],
    runner_cfg: RunnerConfig,
    cfg: EvalConfig,
    meta: RunMeta,
    on_record: Callable[[EpisodeRecord], None],
    replan: int,
) -> None:
    """Run ``jobs`` on ``cfg.workers`` Ray actors, recording each episode as it finishes."""
    try:
        import ray
        from ray.util import ActorPool
    except ImportError:
        raise ConfigError("--backend ray needs the 'ray' extra: pip install 'indgen-vla[ray]'") from None
    if not jobs:
        return
    started_here = not ray.is_initialized()
    if started_here:
        ray.init(num_cpus=max(cfg.workers, 1), include_dashboard=False, log_to_driver=False,
                 ignore_reinit_error=True)  # fmt: skip
    actor_cls = ray.remote(num_cpus=1)(_EpisodeActor)
    n = max(1, min(cfg.workers, len(jobs)))
    actors = [actor_cls.remote(runner_cfg, cfg.policy, cfg.trust_remote_code, cfg.device) for _ in range(n)]
    try:
        pool = ActorPool(actors)
        results = pool.map_unordered(
            lambda a, j: a.run.remote(j, meta, replan, cfg.max_retries, cfg.server_patience), list(jobs)
        )
        try:
            for record in results:
                on_record(record)
        except ray.exceptions.RayTaskError as e:  # an actor gave up on the server: one clear line
            if isinstance(getattr(e, "cause", None), ServerUnreachableError):
                raise ServerUnreachableError(str(e.cause)) from None
            raise
    finally:
        ray.get([a.close.remote() for a in actors], timeout=60)
        for a in actors:
            ray.kill(a)
        if started_here:
            ray.shutdown()
