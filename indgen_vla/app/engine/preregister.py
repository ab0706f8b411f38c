"""``evaluate --preregistered plan.lock``: the run's resolved protocol against its lock, checked before anything
loads or runs (``indgen_vla.core.protocol.plan_lock``; docs/budget.md)."""

from __future__ import annotations

from typing import Any

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.fingerprint import build_fingerprint
from indgen_vla.core.protocol.plan import EvalPlan
from indgen_vla.core.protocol.plan_lock import LOCKED_FINGERPRINT, protocol_deviations, read_lock


def pre_policy_fingerprint(cfg, plan: EvalPlan, versions: dict[str, str]) -> dict[str, Any]:
    """The fingerprint fields that change outcomes and are known before the policy loads (``plan_lock``);
    ``versions``: ``engine.run.package_versions()``."""
    fp = build_fingerprint(plan.record(), versions, max_steps=cfg.plan.max_steps,
                           warmup_steps=cfg.policy.warmup_steps, cameras=(), image_size=(0, 0), render_backend="",
                           policy={})  # fmt: skip
    return {k: fp[k] for k in LOCKED_FINGERPRINT}


def manifest_plan(cfg, plan: EvalPlan) -> dict[str, Any]:
    """The ``plan`` the manifest will record for ``cfg`` (``engine.run.build_manifest``)."""
    return cfg.plan_dict(list(plan.tasks), {a: list(v) for a, v in plan.levels.items()}, cfg.plan.max_steps,
                         plan.scene_plan.task_steps)  # fmt: skip


def check_preregistered(cfg, plan: EvalPlan, versions: dict[str, str]) -> dict[str, Any]:
    """The manifest's ``preregistered`` entry ({path, hash, lock}); a deviation raises one line naming it."""
    lock = read_lock(cfg.plan.preregistered)
    fingerprint = pre_policy_fingerprint(cfg, plan, versions)
    bad = protocol_deviations(lock, manifest_plan(cfg, plan), plan.jobs_hash(), fingerprint)
    if bad:
        more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
        raise ConfigError(f"--preregistered {cfg.plan.preregistered}: {bad[0]}{more}; run the locked protocol, or "
                          "write a new lock with 'indgen budget ... --write' before any episode runs")  # fmt: skip
    return {"path": str(cfg.plan.preregistered), "hash": lock["hash"], "lock": lock}
