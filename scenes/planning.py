"""Resolve what an evaluation asks of the scene layer, once: the scene side of ``indgen_vla.core.protocol.plan``.

``resolve_scene_plan`` is the one call the engine makes into ``scenes`` for a run. It checks the scene, tasks,
axes, levels and condition 2 with the registry's one-line errors, computes every level's axis parameter, looks up
the certificate behind every level, and returns a frozen ``ScenePlan`` whose ``SceneLevels`` builder later builds
each level's env in the worker processes (so nothing downstream looks a scene up by name again). Each axis name
is parsed here once (``indgen_vla.core.protocol.axis_ref.AxisRef``); the family's methods take the parsed axis.
Everything that builds an environment (evaluate, certify, demos, mimicgen, the scripts) builds it through a
``SceneLevels``: the plan's, or ``scene_levels``'s where no plan is needed.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from indgen_vla.core.protocol.axis_ref import AxisRef
from indgen_vla.core.protocol.plan import CERTIFIED, FAILED, UNCERTIFIED, Cell, ScenePlan
from indgen_vla.core.protocol.progression import parse_levels
from indgen_vla.core.reporting.certification_view import NO_ORACLE
from scenes.axes import axis_param, load_preset, spec_at_level, successor_steps
from scenes.certificates import (
    certified_levels,
    current_oracle_version,
    find_certification,
    infeasible_levels,
    level_verdict,
)
from scenes.heldout import EXHAUSTIVE, basis, covers_every_state
from scenes.oracles import oracle_scripts
from scenes.render_info import gl_renderer

if TYPE_CHECKING:
    from scenes.axes import Successor
    from scenes.base_env import BaseSceneEnv
    from scenes.family import Scene


@dataclass(frozen=True)
class SceneLevels:
    """Builds the planned levels of one scene family: its successors resolved once, picklable for workers.

    Implements ``indgen_vla.core.protocol.plan.LevelBuilder``.
    """

    # the family as the command configured it (RoboCasa365's split, registries): pickled, the workers build with it
    family: Scene
    successors: Mapping[str, Successor] = field(default_factory=dict)
    # axis -> task -> successor, for an axis whose family resolves its step per task (RoboCasa365's pick_x)
    task_successors: Mapping[str, Mapping[str, Successor]] = field(default_factory=dict)

    @property
    def scene(self) -> str:
        """The family's registered name (what records and the manifest name)."""
        return self.family.name

    @property
    def options(self) -> tuple[tuple[str, str], ...]:
        """The family's options as the command resolved them (``Scene.options``), sorted."""
        return tuple(sorted(self.family.options().items()))

    @property
    def preload(self) -> tuple[str, ...]:
        return tuple(self.family.preload)

    @property
    def env_spec(self):
        """The family's observation/action contract (``indgen_vla.core.protocol.interface.EnvSpec``): cameras, state, action."""
        return self.family.env_spec

    @property
    def placeholder_assets(self) -> bool:
        """The family simulates placeholder assets (boxes): an image policy's rate there is not a measurement."""
        return bool(self.family.environment.placeholder_assets())

    @property
    def action_dim(self) -> int:
        """The family's action size (``EnvSpec.action_dim``: 7 on the tabletop families, 12 on RoboCasa365)."""
        return int(self.family.env_spec.action_dim)

    def check_ready(self) -> None:
        """Raise the family's one-line missing-install or missing-assets ``SceneError`` (e.g. LIBERO's asset tree)
        before any environment is built; resolving names, axes and levels never needs it."""
        self.family.environment.check_ready()

    def make_env(
        self, task: str, axis: str, level: int, *, cameras: Sequence[str], image_size: tuple[int, int],
        max_steps: int | None,
    ) -> BaseSceneEnv:  # fmt: skip
        return self.family.environment.make_env(task, self.successor(task, axis), level, cameras=cameras,
                                                  image_size=image_size, max_steps=max_steps)  # fmt: skip

    def successor(self, task: str, axis: str) -> Successor:
        """The successor ``axis`` moves ``task`` along (the task's own where the family's steps differ by task)."""
        return self.task_successors.get(axis, {}).get(task, self.successors[axis])

    def describe(self) -> dict[str, Any]:
        sc = self.family
        return {
            "scene": self.scene,
            "family": f"{type(sc).__module__}.{type(sc).__qualname__}",
            "preload": list(self.preload),
            "env_spec": {"name": sc.env_spec.name, "state_dim": sc.env_spec.state_dim,
                         "action_dim": sc.env_spec.action_dim, "layout": sc.env_spec.layout},
            "environment": sc.environment.environment_versions(),  # the worker venv's versions when the family runs in its own
            "protocol": sc.environment.protocol_facts(),
            "successors": {a: self._successor_entry(a, s) for a, s in self.successors.items()},
        }  # fmt: skip

    def _successor_entry(self, axis: str, successor: Successor) -> dict[str, Any]:
        """The axis's successor type and steps; each task's steps where the family resolves them per task."""
        per_task = self.task_successors.get(axis)
        if per_task:
            return {"type": type(successor).__name__, "task_steps": task_steps(per_task)}
        return {"type": type(successor).__name__, "steps": successor_steps(successor)}

    def worker_environment(self) -> dict[str, str]:
        """The plan's choices as the environment variables the family reads (``SceneEnvironment.worker_environment``), for
        simulator actors on nodes whose own environment says otherwise."""
        return self.family.environment.worker_environment()

    def render_backend(self) -> str:
        """The OpenGL vendor and renderer this machine's ``MUJOCO_GL`` backend renders with (pixels differ by it)."""
        return gl_renderer()


def env_key(identity: Any) -> str:
    """A short hash of a level's ``Scene.level_identity`` (dataclasses as dicts, floats exact); "" for None."""
    if identity is None:
        return ""

    def plain(obj: Any) -> Any:
        if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
            return dataclasses.asdict(obj)
        return repr(obj)

    text = json.dumps(identity, sort_keys=True, default=plain)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def task_steps(per_task: Mapping[str, Successor]) -> dict[str, dict[str, float]]:
    """Each task's component steps (``successor_steps``), in the run's task order."""
    return {t: successor_steps(s) for t, s in per_task.items()}


def scene_levels(
    scene: Scene, axes: Sequence[str | AxisRef], step: float | None = None, preset: str | None = None,
    tasks: Sequence[str] = (),
) -> SceneLevels:  # fmt: skip
    """A builder for ``axes`` of ``scene`` without a full plan (T0 builds, benchmarks, tests that drive workers
    directly); with ``tasks``, each task's own successor where the family's steps differ by task; ``scene`` as the
    command configured it (``Scene.configured``), else with the options the environment gives."""
    sc = scene.configured({})
    overrides = load_preset(preset) if preset else None
    return _levels(sc, [AxisRef.parse(a) for a in axes], tasks, step, overrides)


def _levels(
    sc: Scene, refs: Sequence[AxisRef], tasks: Sequence[str], step: float | None, overrides: Mapping | None
) -> SceneLevels:
    """Each axis's successor (the family's own steps/ranges under the preset's), per task where they differ."""
    successors, per_task = {}, {}
    for ref in refs:
        shared = sc.successor(ref, step, overrides)
        if not tasks:
            successors[ref.name] = shared
            continue
        by_task = {t: sc.successor(ref, step, overrides, t) for t in tasks}
        successors[ref.name] = by_task[tasks[0]]
        if any(s != shared for s in by_task.values()):
            per_task[ref.name] = by_task
    return SceneLevels(sc, successors, per_task)


def resolve_scene_plan(
    scene: Scene,
    task: str | None,
    axes: Sequence[str | AxisRef],
    levels: str | Sequence[int] | None = None,
    step: float | None = None,
    preset: str | None = None,
    certificates: bool = True,
    options: Mapping[str, Any] | None = None,
) -> ScenePlan:
    """Resolve a run's scene side once (one-line errors for unknown names, bad levels, condition 2).

    Args:
        scene: a scene family (``scenes.family.get_scene``), configured or not.
        task: a task name, ``"all"``, or None for the scene's default task.
        axes: axis names or compositions (or their parsed ``AxisRef``), in the run's order.
        levels: the ``--levels`` text (``-3:3``, ``0,2``) or list, None for each axis's default range.
        step: ``--step``, overriding a single axis's step.
        preset: ``--axes-preset``, a configs/axes name or YAML path (steps and ranges).
        certificates: look up each level's certificate; False for ``indgen certify``, which makes them (every
            level then uncertified, and an unreadable certify.json is certify's to replace, not an error).
        options: the family's options (``Scene.scene_options``: RoboCasa365's ``split``, ``obj_registries``; None
            or absent: the family's default), resolved here once; the certificates looked up and the builder's
            workers use the same.
    """
    sc = scene.configured(
        dict(options or {})
    )  # a new value: the certificates and the workers read one choice
    return _resolve(sc, task, axes, levels, step, preset, certificates)


def _resolve(
    sc: Scene, task: str | None, axes: Sequence[str | AxisRef], levels: str | Sequence[int] | None,
    step: float | None, preset: str | None, certificates: bool,
) -> ScenePlan:  # fmt: skip
    """``resolve_scene_plan``'s work, with the family configured."""
    # names, axes and levels only: no assets needed (building an env does: SceneLevels.check_ready)
    refs = list({r.name: r for r in map(AxisRef.parse, axes)}.values())  # malformed: one line, before lookups
    for ref in refs:  # every component one of the scene's axes, before select_tasks reads the axes
        sc.check_axis(ref)
    tasks = sc.select_tasks(task, refs)  # on RoboCasa365 "all" is the axes' own task list (appendix B)
    overrides = load_preset(preset) if preset else None
    overridden = step is not None or preset is not None
    builder = _levels(sc, refs, tasks, step, overrides)
    specs, planned = {}, {}
    for ref in refs:
        name = ref.name
        specs[name] = builder.successors[name].axis
        planned[name] = tuple(parse_levels(levels, specs[name]))
        for t in tasks:  # condition 2 (strictly harder), before any episode runs; one line if violated
            sc.check_progression(t, builder.successor(t, name), overridden)
    cells, oracle_version = [], current_oracle_version(sc)
    for ref in refs:
        for t in tasks:
            successor = builder.successor(t, ref.name)
            cert = find_certification(sc, t, ref, step, preset=preset) if certificates else None
            scripted = cert is not None or oracle_scripts(sc, t)
            failed = set(infeasible_levels(cert)) if cert else set()
            certified = set(certified_levels(cert)) if cert else set()
            rows = {int(r["level"]): r for r in cert["levels"]} if cert else {}
            base = sc.base(t)
            for k in planned[ref.name]:
                status = FAILED if k in failed else CERTIFIED if k in certified else UNCERTIFIED
                row = rows.get(k)
                verdict = level_verdict(row, cert, oracle_version) if row else ""
                evidence = f"{row['successes']}/{row['n']} ({verdict})" if row else ""
                if row and row.get("infeasible"):  # too few initial states hold the level (a placement check)
                    evidence = (
                        f"{row['successes']}/{row['n']} ({verdict}: {row['unavailable']} seeds unavailable)"
                    )
                evidence = evidence if scripted else NO_ORACLE  # certify refuses such a task: say so
                param = axis_param(spec_at_level(base, successor, k), successor, k)
                key = env_key(sc.level_identity(t, successor, k)) if k == 0 else ""
                made = basis(row) if status == CERTIFIED else ""
                if made and sc.fixed_state_count and covers_every_state(row, sc.fixed_state_count):
                    made = EXHAUSTIVE  # LIBERO: a row that played all its fixed states, ledger or not
                cells.append(Cell(t, ref.name, k, param, status, evidence, key, made))
    steps = {a: task_steps(by_task) for a, by_task in builder.task_successors.items()}
    return ScenePlan(sc.name, tuple(tasks), specs, planned, tuple(cells), builder, task_steps=steps,
                     refs={r.name: r for r in refs})  # fmt: skip
