"""Policies already in memory (a training loop's current weights): a LeRobot ``PreTrainedPolicy`` with its pre/post
processors, or any object with the ``Policy`` protocol, served by the engine as if loaded from a spec string.

A LeRobot policy is served by the same ``LeRobotPolicy`` as ``lerobot:DIR``, so the episodes equal those of the same
weights saved and loaded from disk. The caller keeps its objects: closing the run restores the module's train/eval
mode and never closes a ``Policy`` it was handed; torch's global random state is left as it was
(``LeRobotPolicy._own_rng``).
"""

from __future__ import annotations

from collections.abc import Sequence

from indgen_vla.core.errors import ConfigError, PolicyError
from indgen_vla.core.protocol.interface import EnvSpec, Observation, Policy
from policy_wrappers.lerobot_checkpoint import LeRobotConfig
from policy_wrappers.lerobot_policy import LeRobotPolicy

RECIPE = "pass (policy, preprocessor, postprocessor) as lerobot's make_pre_post_processors builds them"


def describe(obj: object) -> str:
    """The label a run records for an object (its manifest's ``policy``): ``object:ACTPolicy``."""
    inner = obj[0] if isinstance(obj, tuple) and obj else obj
    return f"object:{type(inner).__name__}"


def _is_lerobot(obj: object) -> bool:
    """A LeRobot ``PreTrainedPolicy`` (without importing lerobot: its config and chunk prediction)."""
    return hasattr(obj, "config") and callable(getattr(obj, "predict_action_chunk", None))


class LeRobotObjectPolicy(LeRobotPolicy):
    """``LeRobotPolicy`` over a policy and processors in memory instead of a checkpoint directory."""

    def __init__(self, name: str, config: LeRobotConfig, policy, pre, post):
        self._given = (policy, pre, post)
        self._was_training = bool(getattr(policy, "training", False))
        super().__init__(name, config)

    def _load(self) -> None:
        policy, pre, post = self._given
        steps = getattr(pre, "steps", None)
        if steps is None or not callable(pre) or not callable(post):
            raise PolicyError(f"policy {self._name}: the preprocessor and postprocessor must be lerobot processor "
                              f"pipelines; {RECIPE}")  # fmt: skip

        def saved_step(name: str) -> bool:
            return any(name in (getattr(type(s), "_registry_name", None), f"{type(s).__module__}.{type(s).__name__}")
                       for s in steps)  # fmt: skip

        policy.eval()
        self._adopt(policy.config, policy, pre, post, saved_step)

    def close(self) -> None:
        """Hand the module back in the mode it came in (a training loop's ``train()``), keeping its weights."""
        policy = self._given[0]
        if self._was_training:
            policy.train()
        super().close()


class BorrowedPolicy:
    """A caller's ``Policy``: served as is, but the run's ``close`` leaves it open (the caller owns it)."""

    def __init__(self, policy: Policy):
        self._policy = policy
        self.spec = policy.spec

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self._policy.reset(instruction, seed=seed)

    def act(self, observations: Sequence[Observation], **kw):
        return self._policy.act(observations, **kw)

    @property
    def pads_batches(self) -> bool:
        return bool(getattr(self._policy, "pads_batches", False))

    @property
    def conventions(self):
        return getattr(self._policy, "conventions", None)

    def close(self) -> None:
        """Nothing: the caller closes its own policy."""


def adopt(
    obj: object, *, name: str, device: str, env_spec: EnvSpec | None = None, precision: str = "fp32",
    replan_steps: int | None = None,
):  # fmt: skip
    """The engine's ``Policy`` for ``obj``: ``(policy, preprocessor, postprocessor)`` of LeRobot, or any ``Policy``.

    ``device`` must be where the module's weights are (the engine's observations cross to it); one line refuses
    anything else.
    """
    if isinstance(obj, tuple):
        if len(obj) != 3 or not _is_lerobot(obj[0]):
            raise ConfigError(f"policy object: a tuple must be (policy, preprocessor, postprocessor) with a LeRobot "
                              f"PreTrainedPolicy first, got {len(obj)} item(s) starting with "
                              f"{type(obj[0]).__name__ if obj else 'nothing'}")  # fmt: skip
        policy, pre, post = obj
        at = _device_of(policy)
        if at is not None and at != device and not (at == "cuda:0" and device == "cuda"):
            raise ConfigError(f"policy object {name}: its weights are on {at} but the run's device is {device}; "
                              f"pass device={at!r}")  # fmt: skip
        config = LeRobotConfig(path=f"<{name}>", device=device, precision=precision, replan_steps=replan_steps,
                               env_spec=env_spec)  # fmt: skip
        return LeRobotObjectPolicy(name, config, policy, pre, post)
    if _is_lerobot(obj):
        raise ConfigError(
            f"policy object {name}: a LeRobot policy needs its processors (normalisation); {RECIPE}"
        )
    if isinstance(obj, Policy):
        return BorrowedPolicy(obj)
    raise ConfigError(f"policy object of type {type(obj).__name__} is neither a LeRobot PreTrainedPolicy with its "
                      "processors nor a Policy (spec, reset, act, close: indgen_vla.core.protocol.interface.Policy)")  # fmt: skip


def _device_of(module) -> str | None:
    """Where the module's first parameter lives ("cpu", "cuda:0"), None without parameters."""
    params = getattr(module, "parameters", None)
    first = next(iter(params()), None) if callable(params) else None
    return None if first is None else str(first.device)
