"""RoboCasa365 (the paper's second benchmark): RoboCasa's own kitchen tasks moved along the paper's axes, simulated in
RoboCasa's own venv (robosuite 1.5, mujoco 3.3.1) that ``scenes.external`` drives over a pipe.

Level 0 is RoboCasa's task as RoboCasa samples it from the episode's seed (layout, style, objects); level k resets
from T0's episode metadata with one field moved (``scenes/robocasa/backend.py``). Importing this is cheap.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import EnvSpec
from indgen_vla.core.protocol.progression import ProgressionError
from indgen_vla.core.reporting.levels import BLACK_BOX  # appendix B: T0 is empirical here
from scenes.axes import axis_param, get_successor, merge_overrides, resolve_alias, shifts, spec_at_level
from scenes.external import ExternalSceneEnv
from scenes.family import Scene, SceneCertificates, SceneEnvironment, register_scene
from scenes.libero.assets import tree_identity
from scenes.robocasa import splits
from scenes.robocasa.departures import DEVIATIONS, PICK_T0, SPAWN_JITTER
from scenes.robocasa.environment import find_assets, find_python, is_placeholder, venv_dir
from scenes.robocasa.horizons import REGISTRY, TASK_HORIZONS, task_horizon
from scenes.robocasa.oracle_state import privileged_state
from scenes.robocasa.split_option import SplitOption
from scenes.robocasa.splits import REGISTRIES_ENV, SPLIT_ENV, SPLIT_WORDS, in_split
from scenes.runtime import ExternalRuntime

if TYPE_CHECKING:
    from collections.abc import Sequence

    from indgen_vla.core.protocol.axis_ref import AxisRef
    from scenes.axes import Successor


@dataclass(frozen=True)
class PickRegion:
    """Where RoboCasa samples a pick_x task's pick object: the object config and its region's x size."""

    cfg: str  # the object config's name in the task's _get_obj_cfgs ("obj"; CheesyBread's "cheese")
    width: float  # its placement's size[0] (m): the valid sampling region appendix B divides into the levels
    # where RoboCasa 1.0.1 sets it, under robocasa/environments/kitchen/atomic/ (FILE:LINE; tests read that line)
    source: str


# Appendix B's pick_x tasks, in its order, with the region RoboCasa 1.0.1 (rlinf-robocasa365 1.0.1) samples each
# one's pick object in: upstream constants, read from the pinned install (tests/scenes/robocasa check each line).
# RoboCasa clips a region to the fixture's own top where that is narrower (utils/env_utils.py
# _get_placement_initializer: inner_size = min(outer_size - margin, size)), which a plan cannot know: the worker
# divides the range RoboCasa samples in each episode's kitchen (scenes/robocasa/pick_window.py).
PICK_REGIONS: dict[str, PickRegion] = {
    "CheesyBread": PickRegion("cheese", 1.0, "kitchen_pick_place.py:1757"),
    "CoffeeSetupMug": PickRegion("obj", 0.30, "kitchen_coffee.py:67"),  # PickPlaceCoffee, counter_to_machine
    "PickPlaceCabinetToCounter": PickRegion("obj", 0.50, "kitchen_pick_place.py:204"),
    "PickPlaceCounterToBlender": PickRegion("obj", 0.50, "kitchen_pick_place.py:1660"),
    "PickPlaceCounterToCabinet": PickRegion("obj", 0.60, "kitchen_pick_place.py:89"),
    "PickPlaceCounterToDrawer": PickRegion("obj", 0.60, "kitchen_pick_place.py:1503"),
    "PickPlaceCounterToSink": PickRegion("obj", 0.30, "kitchen_pick_place.py:314"),
    "PickPlaceCounterToStandMixer": PickRegion("obj", 0.30, "kitchen_pick_place.py:1281"),
    "PickPlaceSinkToCounter": PickRegion("obj", 0.25, "kitchen_pick_place.py:422"),
}
# The paper's task lists per axis (appendix B; issue 25). ``horizon`` is RoboCasa365's ``base_y`` (an alias).
AXIS_TASKS: dict[str, tuple[str, ...]] = {
    "pick_x": tuple(PICK_REGIONS),
    "fixture_x": (
        "CloseStandMixerHead", "OpenStandMixerHead", "TurnOnElectricKettle", "OpenElectricKettleLid",
        "CloseElectricKettleLid", "TurnOnBlender",
    ),
    "horizon": (
        "PickPlaceFridgeDrawerToShelf", "CloseToasterOvenDoor", "PickPlaceCounterToDrawer", "PickPlaceCounterToSink",
        "PickPlaceCounterToCabinet", "PickPlaceCounterToBlender",
    ),
    "clutter": ("PickPlaceCabinetToCounter",),
}  # fmt: skip
# Appendix B's "number of progressions along the axis (e.g. 5)": pick_x's levels 0..4 tile each task's region.
PICK_PROGRESSIONS = 5
# RoboCasa365's own steps and ranges of the shared axes (appendix B): base_y runs 0..3 (12.5 cm a step); pick_x
# runs 0..4, its step each task's own: the task's region (PICK_REGIONS) / PICK_PROGRESSIONS (``pick_step``), unless
# --step or an axes preset sets one, which a plan refuses in one line where a level leaves a task's region (a
# preset's max_level narrows the range and keeps the step, as on every axis).
AXIS_OVERRIDES = {"horizon": {"max_level": 3}, "pick_x": {"max_level": PICK_PROGRESSIONS - 1}}
# RoboCasa's own canonical kitchens (robocasa/utils/env_utils.py KITCHEN_SCENES_5X5 and _5X1: the (layout, style)
# pairs its evaluation uses), the black-box regime's canonical configurations (appendix B, Definition 3): the task
# ``PickPlaceCounterToCabinet@11-34`` runs in layout 11, style 34; ``Task@5x5`` / ``Task@5x1`` name every kitchen
# of a set (``all@5x5``: every task of the axis in each). A plain task draws its kitchen from the episode's seed.
KITCHEN_SETS: dict[str, tuple[tuple[int, int], ...]] = {
    "5x5": tuple((layout, style) for layout in (11, 15, 18, 40, 50) for style in (14, 28, 34, 46, 58)),
    "5x1": tuple((layout, 34) for layout in (11, 15, 18, 40, 50)),
}
# the canonical layouts an appendix-B task's class excludes (its EXCLUDE_LAYOUTS; no EXCLUDE_STYLES meets the sets)
EXCLUDED_KITCHENS: dict[str, frozenset[int]] = {"PickPlaceFridgeDrawerToShelf": frozenset({18})}
PICK_JITTER = 0.02  # T0's pick window on pick_x: +-2 cm in x (pick_window.PICK_JITTER): condition 2 sees it

PANDA_OMRON = EnvSpec(
    name="robocasa_panda_omron",
    cameras=("robot0_agentview_left", "robot0_agentview_right", "robot0_eye_in_hand"),
    state_dim=16,
    action_dim=12,
    layout=(
        "state: base-to-eef pos 3 + base-to-eef quat 4 + base pos 3 + base quat 4 + gripper qpos 2; action: eef pos 3 "
        "+ eef rot 3 + gripper 1 + base motion 4 + control mode 1 (RoboCasa's convert_action order); images upright"
    ),
    # RoboCasa's own names (robocasa/wrappers/gym_wrapper.py PandaOmronKeyConverter: state.*, action.*), which
    # every policy family's RoboCasa convention (policy_wrappers/layouts.py) orders in its own way
    state_parts=(
        ("end_effector_position_relative", 3), ("end_effector_rotation_relative", 4), ("base_position", 3),
        ("base_rotation", 4), ("gripper_qpos", 2),
    ),
    action_parts=(
        ("end_effector_position", 3), ("end_effector_rotation", 3), ("gripper_close", 1), ("base_motion", 4),
        ("control_mode", 1),
    ),
)  # fmt: skip


@dataclass(frozen=True)
class RoboCasaPick:
    """The pick object's offset (metres, the placement's fixture frame) from T0's sampled placement: the plan's; an
    episode whose kitchen clips the region moves 1/5 of its own range a level (``pick_window``, its param)."""

    x: float = 0.0


@dataclass(frozen=True)
class RoboCasaSpec:
    """One RoboCasa task at one level: the offsets each axis moves away from T0 (all zero at level 0)."""

    task: str
    pick: RoboCasaPick = RoboCasaPick()
    fixture_x: float = 0.0
    robot_back: float = 0.0
    clutter: int = 0
    jitter: float = PICK_JITTER  # T0's spread of pick.x (the window RoboCasa draws the object's x in)


@dataclass(frozen=True)
class RoboCasaSuccess:
    """RoboCasa's own ``_check_success`` of the task, read from the worker (one predicate for every level)."""

    def __call__(self, state) -> bool:
        return bool(state.bddl_success)


def split_task(task: str) -> tuple[str, tuple[int, int] | None]:
    """``"Task@L-S"`` -> ("Task", (L, S)); a plain task -> (task, None). One line when the kitchen is not one of
    RoboCasa's canonical kitchens (``KITCHEN_SETS["5x5"]``)."""
    name, sep, kitchen = task.partition("@")
    if not sep:
        return task, None
    try:
        pair = tuple(int(v) for v in kitchen.split("-"))
    except ValueError:
        pair = ()
    if pair not in KITCHEN_SETS["5x5"]:
        layouts = sorted({lay for lay, _ in KITCHEN_SETS["5x5"]})
        styles = sorted({sty for _, sty in KITCHEN_SETS["5x5"]})
        raise ConfigError(
            f"task {task}: '@{kitchen}' is not one of RoboCasa's canonical kitchens (KITCHEN_SCENES_5X5: layouts "
            f"{', '.join(map(str, layouts))} x styles {', '.join(map(str, styles))}); write {name}@LAYOUT-STYLE "
            f"from those, or {name}@5x5 / {name}@5x1 for a whole set"
        )
    return name, pair  # type: ignore[return-value]


def pick_step(task: str) -> float:
    """Appendix B's pick_x step of ``task``: its valid sampling region / the number of progressions, so levels
    0..4 tile the region (0.60 m / 5 = 12 cm on PickPlaceCounterToCabinet, 0.25 m / 5 = 5 cm on -SinkToCounter)."""
    return round(PICK_REGIONS[split_task(task)[0]].width / PICK_PROGRESSIONS, 9)


def pick_part(successor: Successor):
    """The pick_x component of ``successor`` (itself when it is pick_x), or None."""
    parts = getattr(successor, "parts", (successor,))
    return next((p for p in parts if p.axis.name == "pick_x"), None)


def check_pick_region(task: str, successor: Successor) -> None:
    """Every level of the axis's range (as condition 2, whatever --levels runs) keeps its pick window (2 x
    ``PICK_JITTER`` wide, T0's at the region's low-x end) inside the task's declared region: one line naming the
    fix. A kitchen that clips the region is the worker's to judge, per episode (``pick_window.level_offset``)."""
    part = pick_part(successor)
    if part is None:
        return
    name, top = split_task(task)[0], successor.axis.max_level
    region, room = PICK_REGIONS[name], PICK_REGIONS[name].width - 2 * PICK_JITTER
    at = top * part.axis.step
    if at > room + 1e-9:
        raise ProgressionError(
            f"scene robocasa: pick_x levels 0..{top} at {part.axis.step:g} m a level put {name}'s level-{top} pick "
            f"window at {at:.3f}..{at + 2 * PICK_JITTER:.3f} m, past the end of its {region.width:.2f} m region "
            f"(RoboCasa's {region.source}); drop --step and any preset pick_x step (each task's own is its region "
            f"/ {PICK_PROGRESSIONS}), give one <= {room / top:.4f} m for this task, or a smaller max_level in "
            "--axes-preset"
        )


def pick_config(task: str, successor: Successor, level: int) -> dict:
    """What the worker's pick_x window needs (``pick_window.level_offset``): the task's object config and declared
    region, the level and the axis's last level (a kitchen hosts all of 0..top or none), and the step: None where it
    is the task's own (``pick_step``: 1/5 of the range RoboCasa samples in each kitchen), else the user's metres.
    ``report``: the episode's offset is its axis parameter (pick_x alone; a composition records its level)."""
    part = pick_part(successor)
    name = split_task(task)[0]
    own = abs(part.axis.step - pick_step(name)) <= 1e-12  # a --step equal to the task's own is the task's own
    return {
        "cfg": PICK_REGIONS[name].cfg, "declared": PICK_REGIONS[name].width, "level": int(level),
        "top": int(successor.axis.max_level), "step": None if own else float(part.axis.step),
        "progressions": PICK_PROGRESSIONS, "report": part is successor,
    }  # fmt: skip


def _python() -> Path:
    return find_python()


def _worker_env() -> dict[str, str]:
    return {"ROBOCASA_ASSETS_PATH": str(find_assets()), "MUJOCO_GL": "egl"}


# what backend.py passes robosuite.make: create_env's composite config, whose base part Kitchen makes
# JOINT_VELOCITY_LEGACY (base_motion in the base's current frame), as RoboCasa's own evaluators drive it
BASE_CONTROLLER = "RoboCasa's create_env config (base JOINT_VELOCITY_LEGACY)"


class RoboCasaEnvironment(SceneEnvironment):
    """RoboCasa365's environment: ``ExternalSceneEnv`` driving RoboCasa's own venv, under the command's split."""

    def env_class(self) -> type[ExternalSceneEnv]:
        return ExternalSceneEnv

    def environment_versions(self) -> dict[str, str]:
        """The worker venv's versions, and the base controller it builds with (``backend.py``): RoboCasa's
        ``create_env`` config since issue 41, robosuite's default before, which turns base commands once the base has
        turned, so runs under the two are neither pooled nor resumed as each other."""
        return {**super().environment_versions(), "base_controller": BASE_CONTROLLER}

    def placeholder_assets(self) -> bool:
        assets = find_assets(required=False)
        return assets is not None and is_placeholder(assets)

    def privileged_from(self, raw: dict):
        return privileged_state(raw)

    def check_ready(self) -> None:
        """The venv, the asset tree, and a split and registries (``splits.choice``) that tree can serve."""
        find_python()
        assets = find_assets()
        problem = splits.tree_problem(
            assets, *self.family.split_choice(), placeholders=is_placeholder(assets)
        )
        if problem:
            raise ConfigError(problem)

    def protocol_facts(self) -> dict:
        """RoboCasa's own reset as initial states, the kitchen asset tree's identity (real or placeholders), and
        the black-box regime (appendix B): T0 is empirical, condition 2 validated post hoc (``indgen reference``
        and the report's monotone test)."""
        assets = find_assets()
        split, registries = self.family.split_choice()
        # the split's kitchens and instances are where T0 comes from; the choice the worker made before the option
        # (splits.LEGACY) keeps the words runs had then, so they resume and pool with runs under it
        drawn = "" if (split, registries) == splits.LEGACY else f"; {splits.describe(split, registries)}"
        return {
            **super().protocol_facts(),
            "initial_states": "RoboCasa's own reset from each episode's seed (layout, style, objects); levels "
            f"replay T0's ep_meta with one field moved; {PICK_T0}{drawn}",
            "split": {
                "split": split,
                "obj_registries": list(registries),
                "kitchens": splits.SPLIT_WORDS[split],
            },
            "assets": {
                "root": str(assets),
                "placeholders": is_placeholder(assets),
                "listing_sha256": tree_identity(assets),
            },  # fmt: skip
            "regime": BLACK_BOX,
            # each task's episode length, RoboCasa's own (the fingerprint's horizon unless --max-steps replaces it)
            "max_steps": dict(TASK_HORIZONS),
            "horizon_source": REGISTRY,
            "spawn_jitter": SPAWN_JITTER,
            "deviations": list(DEVIATIONS),  # from RoboCasa's own protocol (docs/robocasa.md)
        }

    def worker_environment(self) -> dict[str, str]:
        """The split and registries this command resolved (``split_choice``), for the run's simulators everywhere."""
        split, registries = self.family.split_choice()
        return {SPLIT_ENV: split, REGISTRIES_ENV: ",".join(registries)}


class RoboCasaCertificates(SceneCertificates):
    """RoboCasa365's certificates depend on the kitchen asset tree and the command's split."""

    def asset_tree(self):
        return find_assets(required=False)

    def scope(self) -> str:
        """The split and registries, unless they are the worker's choice before the option (``splits.LEGACY``),
        whose certificates keep their folder."""
        split, registries = self.family.split_choice()
        return (
            ""
            if (split, registries) == splits.LEGACY
            else f"split={split};obj_registries={','.join(registries)}"
        )


@register_scene
class RoboCasa(SplitOption, Scene):
    """RoboCasa365 (rlinf-robocasa365 1.0.1 = upstream RoboCasa v1.0.1), PandaOmron in RoboCasa's kitchens.

    **Task Description:**
    RoboCasa's atomic kitchen tasks the paper moves (appendix B): pick-and-place between counter, cabinet, sink,
    drawer, blender and stand mixer; the stand-mixer head, the electric kettle and the toaster-oven door.

    **Randomizations:**
    - episode i: RoboCasa's own sampling from the episode's seed (kitchen layout, style, objects and their poses);
      ``Task@L-S`` pins one of RoboCasa's canonical kitchens (``KITCHEN_SETS``: the black-box regime's configurations)
    - along the axes: the pick object's placement window moved in x (``pick_x``), the robot base moved back from
      T0's pose (``horizon``, alias ``base_y``), the task's appliance slid along the counter (its own axis across
      the robot's heading) with the robot base kept at T0's pose (``fixture_x``), one more object in the cabinet
      (``clutter``); everything else stays at T0's

    **Success Conditions:**
    - RoboCasa's own ``_check_success`` of the task (e.g. ``obj_inside_of(obj, cab) and gripper_obj_far``)
    """

    name = "robocasa"
    description = "RoboCasa365 kitchens (own venv: indgen setup robocasa), PandaOmron, 12-d action"
    tasks = tuple(dict.fromkeys(t for ts in AXIS_TASKS.values() for t in ts))
    axes = ("pick_x", "fixture_x", "horizon", "clutter")
    # each episode's length is its task's own (``task_max_steps``: RoboCasa's get_task_horizon, 300..900 steps);
    # this class-wide bound is only what ``indgen scenes`` shows beside them
    max_steps = max(TASK_HORIZONS.values())
    distractor_slots = ()
    success_predicate = RoboCasaSuccess()
    committed_certificates = False
    env_spec: ClassVar[EnvSpec] = PANDA_OMRON
    runtime: ClassVar[ExternalRuntime] = ExternalRuntime(
        name="robocasa", python=_python, backend=Path(__file__).with_name("backend.py"), env=_worker_env
    )
    preload: ClassVar[tuple[str, ...]] = ()
    axis_overrides: ClassVar[dict] = AXIS_OVERRIDES
    oracle: ClassVar[str] = "scenes.robocasa.oracle:RoboCasaOracle"  # PandaOmron: arm, some tasks base
    Environment = RoboCasaEnvironment
    Certificates = RoboCasaCertificates

    def successor(self, axis: AxisRef, step=None, overrides=None, task: str | None = None):
        """pick_x's step is ``task``'s own (``pick_step``: its region / 5, appendix B) unless --step (a single axis)
        or the axes preset sets one; every other step is the family's (``axis_overrides``) or the preset's."""
        import dataclasses

        merged = merge_overrides(self.axis_overrides, overrides)
        pick = merged.get("pick_x", {})
        parts = [resolve_alias(p) for p in axis.components]
        explicit = "step" in pick or (step is not None and len(parts) == 1)
        if task is None or "pick_x" not in parts or explicit:
            return super().successor(axis, step, overrides)
        name = self.resolve_task(task)
        self._check_task_lists(name, ("pick_x",))
        merged["pick_x"] = {**pick, "step": pick_step(name)}
        successor = get_successor(axis, step, merged)
        if len(parts) > 1:
            return successor
        base, region = split_task(name)[0], PICK_REGIONS[split_task(name)[0]]
        what = (f"translate the pick object along x by 1/{PICK_PROGRESSIONS} of the range RoboCasa samples it in, "
                f"in the episode's kitchen ({base}'s {region.width:.2f} m region, RoboCasa's {region.source}, where "
                "the kitchen holds it)")  # fmt: skip
        return dataclasses.replace(successor, axis=dataclasses.replace(successor.axis, description=what))

    def check_progression(self, task: str, successor: Successor, overridden: bool) -> None:
        """Condition 2, and pick_x's levels inside the task's pick region (``check_pick_region``)."""
        super().check_progression(task, successor, overridden)
        check_pick_region(task, successor)

    def resolve_task(self, task: str | None) -> str:
        """A task name, or ``Task@L-S``: that task in one of RoboCasa's canonical kitchens (``KITCHEN_SETS``)."""
        if task is None or "@" not in task:
            return super().resolve_task(task)
        name, _ = split_task(task)
        super().resolve_task(name)
        return task

    def task_max_steps(self, task: str) -> int:
        """RoboCasa's registered limit of ``task`` (``horizons.TASK_HORIZONS``), as lerobot and openpi take it."""
        return task_horizon(self.resolve_task(task))

    def row(self) -> dict:
        return {**super().row(), "max_steps": f"{min(TASK_HORIZONS.values())}..{self.max_steps} (per task)"}

    def base(self, task: str) -> RoboCasaSpec:
        return RoboCasaSpec(task=self.resolve_task(task))

    def instruction(self, task: str) -> str:
        return task  # replaced by RoboCasa's own ep_meta["lang"] at every reset

    def needs(self) -> str:
        py = find_python(required=False)
        assets = find_assets(required=False)
        venv = (
            f"RoboCasa venv ready ({py})"
            if py
            else f"RoboCasa venv missing ({venv_dir()}: indgen setup robocasa)"
        )
        if assets is None:
            return f"{venv}; kitchen assets missing (INDGEN_ROBOCASA_ASSETS)"
        kind = "placeholders, smoke runs only" if is_placeholder(assets) else "found"
        split, registries = self.split_choice()
        return f"{venv}; kitchen assets {kind} ({assets}); split {split}, object registries {'+'.join(registries)}"

    def select_tasks(self, task: str | None, axes: Sequence[AxisRef] = ()) -> list[str]:
        """``all``: the tasks on every axis of the run (appendix B's lists, ``AXIS_TASKS``), None their first; a
        named task must be on each axis's list (one line naming the list)."""
        if task and "@" in task:  # canonical kitchens: each task (or the axes' list for all@) in each kitchen
            name, _, kitchen = task.partition("@")
            names = self.select_tasks(name, axes)
            if kitchen in KITCHEN_SETS:
                return [f"{n}@{lay}-{sty}" for n in names for lay, sty in KITCHEN_SETS[kitchen]
                        if lay not in EXCLUDED_KITCHENS.get(n, ())]  # fmt: skip
            lay = split_task(task)[1][0]  # one line when it is not a canonical kitchen
            for n in names:
                if lay in EXCLUDED_KITCHENS.get(n, ()):
                    raise ConfigError(
                        f"task {n}@{kitchen}: RoboCasa's {n} excludes layout {lay}; pick another kitchen"
                    )
            return [f"{n}@{kitchen}" for n in names]
        lists = [AXIS_TASKS[p] for a in axes for p in map(resolve_alias, a.components) if p in AXIS_TASKS]
        if task not in (None, "", "all") or not lists:
            tasks = super().select_tasks(task)
            for a in axes:
                self.check_axis_task(tasks[0], a)
            return tasks
        shared = [t for t in lists[0] if all(t in ts for ts in lists[1:])]
        if not shared:
            raise ConfigError(
                f"scene robocasa: axes {', '.join(map(str, axes))} share no task (appendix B gives each its own list); run "
                "them one at a time (--config robocasa_pick, robocasa_fixture, robocasa_horizon, robocasa_clutter)"
            )
        return shared if task == "all" else shared[:1]

    def check_axis_task(self, task: str, axis: AxisRef) -> None:
        """Every component of ``axis`` must list ``task`` (appendix B gives each axis its own tasks)."""
        self._check_task_lists(task, axis.components)

    def _check_task_lists(self, task: str, parts: Sequence[str]) -> None:
        """One line naming the list of the first of the single axes ``parts`` whose task list lacks ``task``."""
        task = split_task(task)[0]
        for part in map(resolve_alias, parts):
            if task not in AXIS_TASKS.get(part, ()):
                raise ConfigError(
                    f"scene robocasa: task {task} is not on axis {part}'s task list (appendix B); its tasks are "
                    f"{', '.join(AXIS_TASKS.get(part, ()))}"
                )

    def level_identity(self, task: str, successor: Successor, level: int) -> dict:
        """What the worker builds for (task, level): ``level_config`` without the cameras (the run's, every axis
        alike) and the axis's reading of the level (``axis_param``); pick_x's window, even at level 0, stays in."""
        config = self.level_config(task, successor, level, (), (0, 0))
        return {k: v for k, v in config.items() if k not in ("cameras", "image_size", "axis_param")}

    def level_config(self, task: str, successor: Successor, level: int, cameras, image_size) -> dict:
        """What the worker builds for (task, level): RoboCasa's task, cameras, and the level's ep_meta edits."""
        names = [p.axis.name for p in shifts(successor)]
        self._check_task_lists(task, names)
        spec = spec_at_level(self.base(task), successor, level)
        parts = set(names)
        name, kitchen = split_task(task)
        split, registries = self.split_choice()
        if kitchen is not None and not in_split(split, *kitchen):
            raise ConfigError(
                f"task {task}: kitchen {kitchen[0]}-{kitchen[1]} is not in RoboCasa365's {split} split "
                f"({SPLIT_WORDS[split]}); run {name} without '@', or pass --split pretrain or all"
            )
        return {
            "task": name,
            # RoboCasa365's split and RoboCasa's object registries (scenes/robocasa/splits.py, the user's choice)
            "split": split,
            "obj_registries": list(registries),
            # a canonical kitchen (KITCHEN_SETS): RoboCasa's layout_ids / style_ids; None: drawn from the seed
            "layout_ids": None if kitchen is None else [kitchen[0]],
            "style_ids": None if kitchen is None else [kitchen[1]],
            "cameras": list(cameras),
            "image_size": tuple(image_size),
            "edits": {
                "pick_x": spec.pick.x,
                "base_back": spec.robot_back,
                "fixture_x": spec.fixture_x,
                "clutter": spec.clutter,
            },  # fmt: skip
            # pick_x: the window on RoboCasa's range in the episode's kitchen (backend: pick_window.py)
            "pick": pick_config(task, successor, level) if "pick_x" in parts else None,
            "axis_param": axis_param(spec, successor, level),
            "spec": spec,
        }
