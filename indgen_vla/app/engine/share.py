"""T0 run once per task: the axes whose level 0 is one environment report the same level-0 rollouts.

Episode i of a task gets the same seed at every level and axis (``indgen_vla.core.protocol.seeding.evaluation_seed``), so where
the scene layer says two axes build the same level-0 environment (``plan.shared_t0``, from ``Cell.env_key``) their
level-0 episodes would be the same rollout twice. ``evaluate`` runs the first axis's (the owner's) and records each
of its level-0 episodes once more per sharing axis, marked ``shared_from`` = the owner, with the sharer's own level-0
parameter; ``episodes.parquet`` keeps one row per (task, axis, level, episode), so every reader works unchanged.

Under ``--adaptive`` too: every ladder's level-0 decision reads only its level-0 outcomes, in episode order, under the
run's one rule, and level 0 opens every direction of every mode, so the ladders of one task that share T0 ask for
the same level-0 episodes in every round; a round runs the owner's (``round_rollouts``) and records the copies.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

from indgen_vla.core.protocol.plan import SHARING_OFF, EpisodeJob, EvalPlan, shared_t0, sharing_record
from indgen_vla.core.runs.records import EpisodeRecord

if TYPE_CHECKING:
    from collections.abc import Iterable

    from indgen_vla.app.engine.config import EvalConfig
    from indgen_vla.core.runs.records import EpisodeRecord, RunDir


def with_sharing(cfg: EvalConfig, plan: EvalPlan) -> EvalPlan:
    """``plan`` with its shared level-0 cells, when ``cfg.plan.share_t0``."""
    return dataclasses.replace(plan, shared=shared_t0(plan.scene_plan)) if cfg.plan.share_t0 else plan


def sharing_entry(cfg: EvalConfig, plan: EvalPlan) -> dict[str, Any]:
    """The manifest's ``t0_sharing`` of a plan ``with_sharing`` made: what is shared, or why nothing is."""
    return sharing_record(plan, cfg.plan.share_t0, "" if cfg.plan.share_t0 else SHARING_OFF)


def round_rollouts(plan: EvalPlan, jobs: Iterable[EpisodeJob]) -> list[EpisodeJob]:
    """The rollouts that record ``jobs`` (an adaptive round's episodes): a sharer's level-0 episode is its owner's,
    whose copy ``copies`` records with it; each rollout once, in first-wanted order."""
    out: dict[tuple, EpisodeJob] = {}
    for j in jobs:
        owner = plan.shared.get((j.task, j.axis)) if j.level == 0 else None
        if owner is not None:
            j = plan.job((j.task, owner, 0, j.episode))
        out.setdefault(j.key, j)
    return list(out.values())


def copies(plan: EvalPlan, rec: EpisodeRecord, taken: set) -> list[EpisodeRecord]:
    """``rec`` as the level-0 episode of every axis that shares its axis's T0, except keys in ``taken`` (episodes
    such an axis already holds ``ok``: rolled out before sharing was on)."""
    if rec.level != 0:
        return []
    out = []
    for axis in plan.sharers(rec.task, rec.axis):
        if (rec.task, axis, 0, rec.episode) not in taken:
            param = plan.scene_plan.cell(rec.task, axis, 0).param
            out.append(dataclasses.replace(rec, axis=axis, param=param, wall_s=0.0, shared_from=rec.axis))
    return out


def fill_copies(plan: EvalPlan, run: RunDir) -> int:
    """Record the copies a resume finds missing (an owner's episode recorded, the kill before its copies were, or a
    run started with --no-share-t0); an error copy is replaced once its owner is ok. Returns how many it wrote."""
    if not plan.shared:
        return 0
    rows = {(r["task"], r["axis"], int(r["level"]), int(r["episode"])): r for r in run.rows()}
    owners = {(t, owner) for (t, _), owner in plan.shared.items()}
    new = []
    for (task, axis, level, _), row in rows.items():
        if level != 0 or (task, axis) not in owners or row.get("shared_from"):
            continue
        rec = EpisodeRecord(**row)
        for c in copies(plan, rec, set()):
            have = rows.get(c.key)
            if have is None or (have["status"] == "error" and rec.status != "error"):
                new.append(c)
    run.append(new)
    return len(new)


def taken_keys(plan: EvalPlan, run: RunDir) -> set:
    """Sharers' level-0 keys already ``ok`` in ``run`` (a copy must not overwrite them)."""
    return {k for k in run.done_keys() if k[2] == 0 and (k[0], k[1]) in plan.shared}


def record_sharing(run: RunDir, now: dict[str, Any]) -> None:
    """A resume under another sharing setting (or of a run made before it) records the setting it goes on with;
    the rows keep saying where each came from (``shared_from``)."""
    was = run.manifest.get("t0_sharing")
    if was != now:
        run.update_manifest(t0_sharing={**now, "earlier": was} if was else now)
