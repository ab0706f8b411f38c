"""Where an evaluation's policy comes from and what the scene must give it: loading it from its spec or adopting an
object in memory, starting the workers while it loads, refusing in one line a policy the scene cannot serve, and the
workers' ``RunnerConfig`` for what it reads."""

from __future__ import annotations

from pathlib import Path

from indgen_vla.app.engine import local
from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.app.engine.rollout import RunnerConfig
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.plan import EvalPlan
from policy_wrappers import specs
from policy_wrappers.objects import adopt


def _refused_on_placeholders(cfg: EvalConfig, plan: EvalPlan, cameras) -> bool:
    """An image policy on placeholder assets without ``--smoke``: its cameras would see boxes."""
    return bool(cameras) and getattr(plan.builder, "placeholder_assets", False) and not cfg.run.smoke


def check_policy_contract(cfg: EvalConfig, plan: EvalPlan, policy) -> None:
    """Before any episode: the policy's cameras and action size must be the scene family's (``EnvSpec``), and an
    image policy runs on placeholder assets only with ``--smoke`` (its cameras would see boxes). One line each."""
    spec = policy.spec
    env_spec = getattr(plan.builder, "env_spec", None)
    try:
        if env_spec is not None:
            env_spec.check_policy(spec, cfg.plan.scene)
        if _refused_on_placeholders(cfg, plan, spec.cameras):
            raise ConfigError(
                f"scene {cfg.plan.scene} runs on placeholder assets (boxes, flat textures): an image policy's "
                f"success there is not a measurement; point the scene at its real assets, or pass --smoke to run "
                f"{spec.name} anyway (the manifest records 'not a measurement')"
            )
    except ConfigError:
        policy.close()
        raise


class PolicySource:
    """Where a run's policy comes from (its spec, or an object in memory) and what starts while it loads."""

    def __init__(self, cfg: EvalConfig, plan: EvalPlan, given: object | None):
        self.cfg, self.plan, self.given = cfg, plan, given
        # what the policy's family is told besides its spec: the scene family's contract, precision/compile options
        self.env_spec, self.options = getattr(plan.builder, "env_spec", None), cfg.policy_options()
        self.early: local.EarlyWorkers | None = None

    def load(self):
        """A new instance of the policy (the engine asks for one per worker when it is not batched)."""
        if self.given is not None:
            return adopt_object(self.given, self.cfg, self.env_spec)

        cfg = self.cfg
        return specs.load_policy(
            cfg.policy.spec, trust_remote_code=cfg.policy.trust_remote_code, device=cfg.policy.device,
            scene=cfg.plan.scene, env_spec=self.env_spec, scene_family=getattr(self.plan.builder, "family", None),
            **self.options,
        )  # fmt: skip

    def checked(self, jobs: list):
        """Start what ``jobs`` need while the policy loads (``prestart``), load it, and refuse it in one line when
        the scene cannot serve it (``check_policy_contract``)."""
        self.early = self.prestart(jobs)
        probe = self.load()
        check_policy_contract(self.cfg, self.plan, probe)
        return probe

    def prestart(self, jobs: list) -> local.EarlyWorkers | None:
        """Start what the run needs while the policy loads: the workers' forkserver (its preload imports the
        simulator) and, when the policy's files say which scenes it will ask for, the workers themselves with
        their first scenes built and reset (``local.EarlyWorkers``; checked against the loaded policy)."""
        cfg, plan = self.cfg, self.plan
        if cfg.run.backend != "local" or not jobs:
            return None

        n = local.worker_processes(len(jobs), cfg.run.workers, cfg.run.pipeline)
        view = None if self.given is not None else specs.preview_policy(
            cfg.policy.spec, device=cfg.policy.device, env_spec=self.env_spec, **self.options)  # fmt: skip
        if view is not None and _refused_on_placeholders(cfg, plan, view.cameras):
            return None  # the loaded policy will be refused: no scene to build (and wait for) meanwhile
        if view is not None:
            return local.EarlyWorkers(runner_config(cfg, plan, view), jobs, max(1, n))
        if n:
            local.start_forkserver(plan.builder, jobs[0].task if n > 1 else None)
        return None

    def close_unused(self) -> None:
        """Close early workers nobody took (a refused policy, an interrupted load)."""
        if self.early is not None:
            self.early.close()


def check_object_run(cfg: EvalConfig) -> None:
    """What a run of a policy object in memory cannot do, refused in one line before anything starts."""
    if cfg.run.backend != "local":
        raise ConfigError(f"a policy object in memory runs on the local backend only (--backend {cfg.run.backend} "
                          "would ship it to other processes); save it (save_pretrained) and pass lerobot:DIR")  # fmt: skip
    if cfg.policy.compile != "off":
        raise ConfigError("compile is for policies loaded from a spec; a policy object in memory runs uncompiled "
                          "(compile it yourself before passing it)")  # fmt: skip


def adopt_object(obj: object, cfg: EvalConfig, env_spec):
    """The engine's policy for an object in memory (``policy_wrappers.objects.adopt``); one per run: a policy
    with per-episode state serves one environment, so it refuses more than one worker."""
    p = adopt(obj, name=cfg.policy.spec, device=cfg.policy.device, env_spec=env_spec,
              precision=cfg.policy.precision, replan_steps=cfg.policy.replan_steps)  # fmt: skip
    if not p.spec.batched and (cfg.run.workers > 1 or cfg.run.pipeline):
        p.close()
        raise ConfigError(f"policy object {cfg.policy.spec} keeps per-episode state (not batched), so one instance "
                          "serves one environment: run it with workers=1 and no pipeline")  # fmt: skip
    return p


def runner_config(cfg: EvalConfig, plan: EvalPlan, view) -> RunnerConfig:
    """How the workers build scenes for a policy that asks for ``view`` (its ``PolicySpec``, or the
    ``ScenePreview`` read before it loaded): one function for both, so equal views give equal configs."""
    side = cfg.policy.image_size or (view.image_size[0] if view.image_size else 128)
    return RunnerConfig(
        levels=plan.builder, cameras=tuple(view.cameras), image_size=(side, side), max_steps=cfg.plan.max_steps,
        privileged=view.privileged, warmup_steps=cfg.policy.warmup_steps, objects=view.observes_objects,
        video_dir=str(Path(cfg.run.out) / "videos") if cfg.run.video else None, history_steps=view.history_steps,
    )  # fmt: skip
