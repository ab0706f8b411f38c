"""The resolved evaluation plan: the seam between the application and the scene layer.

``indgen evaluate`` asks the scene layer once (``scenes.planning.resolve_scene_plan``) what its config means:
the scene family and the environment it runs in, the tasks, each axis's successor and level parameters, and
the certificate behind every level. The engine then adds the episode jobs with their seeds and from there on
reads only this frozen object: the backends build environments through its ``builder``, the adaptive scheduler
and resume read its levels and jobs, and the manifest records it (``EvalPlan.record``). Core code: it imports
neither ``scenes`` nor ``policy_wrappers``.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from indgen_vla.core.protocol.axis_ref import AxisRef
from indgen_vla.core.protocol.progression import AxisSpec
from indgen_vla.core.protocol.seeding import evaluation_seed

CERTIFIED, FAILED, UNCERTIFIED = "certified", "failed", "uncertified"
# set while the local backend starts its workers' fork server: JSON {"scene", "task"} of the first task its workers
# build, which a family's preload may use to warm its caches (``scenes.asset_cache``)
WARM_CELL_ENV = "INDGEN_WARM_CELL"


class LevelBuilder(Protocol):
    """Builds one level's environment in whichever process runs it; frozen and picklable (it travels to
    worker processes and Ray actors). The scene layer provides it; the engine only calls it."""

    scene: str

    @property
    def preload(self) -> tuple[str, ...]:
        """Modules a worker process may import ahead of its first env (a forkserver's preload list)."""
        ...

    def check_ready(self) -> None:
        """Raise one line naming what building an env here lacks (an asset tree, a venv) and its set-up command."""
        ...

    def make_env(
        self, task: str, axis: str, level: int, *, cameras: Sequence[str], image_size: tuple[int, int],
        max_steps: int | None,
    ) -> Any:  # fmt: skip
        """One level of one task along one planned axis."""
        ...

    def describe(self) -> dict[str, Any]:
        """The family, its environment and each axis's successor, as JSON for the manifest."""
        ...

    def render_backend(self) -> str:
        """The GL vendor/renderer the family's envs render with on this machine (the protocol fingerprint)."""
        ...

    # also read by the engine, where a builder has them: ``env_spec`` (the family's ``EnvSpec``: a policy whose
    # cameras or action size it lacks is refused before any episode), ``placeholder_assets`` (bool: an image
    # policy runs there only with --smoke), ``action_dim`` and ``worker_environment`` (the plan's choices as the
    # environment variables a Ray simulator actor gets: RoboCasa365's split)


@dataclass(frozen=True)
class Cell:
    """One (task, axis, level) of the plan: its axis parameter and the certificate it relies on."""

    task: str
    axis: str
    level: int
    param: float
    certificate: str  # CERTIFIED | FAILED | UNCERTIFIED (no certificate, or not enough evidence)
    evidence: str = ""  # the oracle's successes/n behind the certificate, "" when there is none
    # level 0 only: a hash of what the scene layer builds for it (``Scene.level_identity``), the axis's name left out;
    # equal keys of one task's axes mean one environment, so evaluate runs that T0 once. "" = unknown: never shared
    env_key: str = ""
    # a certified level's basis (scenes.heldout): "held-out" (a fresh seed block, its share of the error) or
    # "in-sample (tuned)" (seeds an earlier attempt, sweep or tuning had used, or an unknown history); else ""
    basis: str = ""


@dataclass(frozen=True)
class PlannedAxis:
    """One axis of a plan, resolved: what its name means, its spec and its planned levels."""

    ref: AxisRef
    spec: AxisSpec
    levels: tuple[int, ...]


@dataclass(frozen=True)
class ScenePlan:
    """What the scene layer resolves from a config: everything scene-side an evaluation needs."""

    scene: str
    tasks: tuple[str, ...]
    axes: Mapping[str, AxisSpec]  # in the config's order
    levels: Mapping[str, tuple[int, ...]]
    cells: tuple[Cell, ...]
    builder: LevelBuilder
    # axis -> task -> component steps, for an axis whose family resolves its step per task (RoboCasa365's pick_x:
    # the task's region / 5); empty when every task of an axis shares ``axes[axis].step``
    task_steps: Mapping[str, Mapping[str, Mapping[str, float]]] = dataclasses.field(default_factory=dict)
    # axis -> the parsed name (its components, held axis and level), in the config's order
    refs: Mapping[str, AxisRef] = dataclasses.field(default_factory=dict)

    def axis(self, name: str) -> PlannedAxis:
        """The resolved axis ``name``: its parsed name, its spec (step, range) and the levels the run covers."""
        return PlannedAxis(self.refs.get(name) or AxisRef.parse(name), self.axes[name], self.levels[name])

    def cell(self, task: str, axis: str, level: int) -> Cell:
        return self._by_key[(task, axis, level)]

    @functools.cached_property
    def _by_key(self) -> dict[tuple[str, str, int], Cell]:
        return {(c.task, c.axis, c.level): c for c in self.cells}

    def params(self) -> dict[tuple[str, str, int], float]:
        """The axis parameter of every (task, axis, level)."""
        return {k: c.param for k, c in self._by_key.items()}


@dataclass(frozen=True)
class EpisodeJob:
    """One planned episode; its seed depends only on the plan, never on workers or order."""

    task: str
    axis: str
    level: int
    episode: int
    seed: int
    param: float
    video: bool = False

    @property
    def key(self) -> tuple[str, str, int, int]:
        return (self.task, self.axis, self.level, self.episode)


@dataclass(frozen=True)
class EvalPlan:
    """A resolved config: the scene plan plus every planned episode, in a fixed order.

    ``shared`` maps (task, axis) to the earlier axis whose level-0 episodes it reports as its own (``share_t0``): the
    jobs keep one episode per (task, axis, level, episode), but only ``rollouts()`` are run, and each level-0 record
    of an owner axis is recorded again for the axes that share it (``engine/share.py``).
    """

    scene_plan: ScenePlan
    jobs: tuple[EpisodeJob, ...]
    shared: Mapping[tuple[str, str], str] = dataclasses.field(default_factory=dict)

    @property
    def scene(self) -> str:
        return self.scene_plan.scene

    @property
    def tasks(self) -> tuple[str, ...]:
        return self.scene_plan.tasks

    @property
    def axes(self) -> Mapping[str, AxisSpec]:
        return self.scene_plan.axes

    @property
    def levels(self) -> Mapping[str, tuple[int, ...]]:
        return self.scene_plan.levels

    @property
    def builder(self) -> LevelBuilder:
        return self.scene_plan.builder

    def rollouts(self) -> tuple[EpisodeJob, ...]:
        """The jobs that are run: all but the level-0 episodes another axis's rollouts stand for."""
        return rollouts(self.jobs, self.shared)

    def job(self, key: tuple[str, str, int, int]) -> EpisodeJob:
        """The planned episode of ``key`` (task, axis, level, episode)."""
        return self._jobs_by_key[key]

    @functools.cached_property
    def _jobs_by_key(self) -> dict[tuple[str, str, int, int], EpisodeJob]:
        return {j.key: j for j in self.jobs}

    def sharers(self, task: str, axis: str) -> tuple[str, ...]:
        """The axes that report ``axis``'s level-0 episodes of ``task`` as their own (in the config's order)."""
        return tuple(b for (t, b), owner in self.shared.items() if t == task and owner == axis)

    def jobs_hash(self) -> str:
        """SHA-256 of every planned episode (``jobs_sha256``): equal plans, equal hashes."""
        return jobs_sha256(self.jobs)

    def record(self) -> dict[str, Any]:
        """The manifest's ``resolved`` entry: the environment, every cell with its certificate, the jobs' hash."""
        return {
            "environment": self.builder.describe(),
            "cells": [dataclasses.asdict(c) for c in self.scene_plan.cells],
            "episodes": len(self.jobs),
            "jobs_sha256": self.jobs_hash(),
        }


def jobs_sha256(jobs: Sequence[EpisodeJob]) -> str:
    """SHA-256 of planned episodes in order (key, seed, parameter, video flag): the manifest's ``jobs_sha256``, also
    of a plan no single ``EvalPlan`` made (``indgen merge``'s union of shards)."""
    rows = [[j.task, j.axis, j.level, j.episode, j.seed, repr(j.param), j.video] for j in jobs]
    return hashlib.sha256(json.dumps(rows).encode()).hexdigest()


def plan_jobs(
    scene: str,
    tasks: Sequence[str],
    levels: Mapping[str, Sequence[int]],
    params: Mapping[tuple[str, str, int], float],
    episodes: int,
    seed: int,
    video: bool = False,
    video_per_level: int = 1,
) -> tuple[EpisodeJob, ...]:
    """Every episode of the run in a fixed order (axis in ``levels``' order, task, level by |k|, episode).

    The seed depends on (run seed, scene, task, episode) but not on the axis or level: episode i sees
    the same random draws at every level, so levels differ only in the axis parameter (common random
    numbers, a paired design that also makes level 0 identical across axes).
    """
    jobs = []
    for axis, axis_levels in levels.items():
        for task in tasks:
            for level in sorted(axis_levels, key=lambda k: (abs(k), k)):
                for ep in range(episodes):
                    s = evaluation_seed(seed, scene, task, ep)
                    jobs.append(
                        EpisodeJob(
                            task,
                            axis,
                            level,
                            ep,
                            s,
                            params[(task, axis, level)],
                            video and ep < video_per_level,
                        )
                    )
    return tuple(jobs)


def rollouts(jobs: Sequence[EpisodeJob], shared: Mapping[tuple[str, str], str]) -> tuple[EpisodeJob, ...]:
    """``jobs`` but the level-0 episodes of the (task, axis) pairs in ``shared`` (another axis's rollouts)."""
    return tuple(j for j in jobs if not (j.level == 0 and (j.task, j.axis) in shared))


def shared_t0(sp: ScenePlan) -> dict[tuple[str, str], str]:
    """(task, axis) -> the first axis (config order) of ``task`` whose level 0 is the same environment: equal,
    non-empty ``Cell.env_key`` (the scene layer's description of the level, never the axis's name); axes whose level 0
    differs (RoboCasa's ``pick_x`` window) or is unknown map to nothing."""
    return shared_t0_of(
        sp.tasks, list(sp.axes), {(c.task, c.axis): c.env_key for c in sp.cells if c.level == 0}
    )


def shared_t0_of(
    tasks: Sequence[str], axes: Sequence[str], keys: Mapping[tuple[str, str], str]
) -> dict[tuple[str, str], str]:
    """``shared_t0`` from the level-0 cells' ``env_key`` by (task, axis) alone (a merge has its shards' cells)."""
    out: dict[tuple[str, str], str] = {}
    for task in tasks:
        owners: dict[str, str] = {}
        for axis in axes:
            key = keys.get((task, axis), "")
            if not key:
                continue
            owner = owners.setdefault(key, axis)
            if owner != axis:
                out[(task, axis)] = owner
    return out


SHARING_OFF = "off (--no-share-t0)"  # t0_sharing's reason when a run does not share


def sharing_record(plan: EvalPlan, enabled: bool, reason: str = "") -> dict[str, Any]:
    """The manifest's ``t0_sharing`` of ``plan`` (whose ``shared`` is empty when sharing is off)."""
    return sharing_summary(plan.tasks, list(plan.axes), plan.shared, plan.jobs, enabled, reason)


def sharing_summary(
    tasks: Sequence[str], axes: Sequence[str], shared: Mapping[tuple[str, str], str], jobs: Sequence[EpisodeJob],
    enabled: bool, reason: str = "",
) -> dict[str, Any]:  # fmt: skip
    """The manifest's ``t0_sharing``: whether it was on (``reason`` when off), per task the groups of axes that
    share one T0 (owner first), and how many of the planned ``jobs`` are rolled out and how many that saves."""
    groups: dict[str, list[list[str]]] = {}
    for task in tasks:
        for owner in axes:
            b = [a for (t, a), o in shared.items() if t == task and o == owner]
            if (task, owner) not in shared and b:
                groups.setdefault(task, []).append([owner, *b])
    out: dict[str, Any] = {"enabled": enabled}
    if reason:
        out["reason"] = reason
    run = len(rollouts(jobs, shared))
    return out | {"groups": groups, "rollouts": run, "saved": len(jobs) - run}
