"""The scene registry: one ``Scene`` subclass per scene family, registered once with ``@register_scene``.

A family's ``Scene`` is its catalogue: its tasks, the axes it supports (the first is the default), its episode
length, the T0 spec and instruction of each task, its one success predicate, where its distractors go. Two small
frozen parts hold the rest: ``scene.environment`` (a ``SceneEnvironment``: how to build an env) and
``scene.certificates`` (a ``SceneCertificates``: what a per-machine certificate depends on). Like ManiSkill's
``@register_env`` tasks, each registered class's docstring has three sections: **Task Description**,
**Randomizations** and **Success Conditions**.

Importing this is cheap (no simulator); ``make_env`` imports the simulator backend when it builds.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from indgen_vla.core.errors import ConfigError, UnknownNameError
from indgen_vla.core.protocol.interface import TABLETOP, EnvSpec
from scenes.axes import (
    axis_components,
    base_axis_names,
    check_progression,
    get_successor,
    merge_overrides,
    spec_at_level,
)
from scenes.runtime import worker_versions

if TYPE_CHECKING:
    from collections.abc import Sequence

    import gymnasium as gym

    from indgen_vla.core.protocol.axis_ref import AxisRef
    from scenes.axes import Successor

TABLETOP_ORACLE = "scenes.tabletop.oracle:OraclePolicy"  # standin:oracle without a scene, and the default

DOC_SECTIONS = ("Task Description", "Randomizations", "Success Conditions")

_SCENES: dict[str, Scene] = {}


@dataclass(frozen=True)
class SceneEnvironment:
    """A family's environment builder: how and where its levels are built (``scene.environment``); a family whose
    simulator or assets differ subclasses it and names the subclass in its ``Environment`` class attribute."""

    family: Scene

    def env_class(self) -> type[gym.Env]:
        """The ``scenes.base_env.BaseSceneEnv`` subclass that builds this family's levels, imported only in this
        method (it loads the simulator); typed ``gym.Env`` here because ``scenes.base_env`` imports this module."""
        raise NotImplementedError

    def make_env(
        self, task: str, successor: Successor, level: int, *, cameras: Sequence[str], image_size: tuple[int, int],
        max_steps: int | None,
    ) -> gym.Env:  # fmt: skip
        """Build one level of one (resolved) task along ``successor``."""
        return self.env_class()(
            self.family, task, successor, level, cameras=cameras, image_size=image_size, max_steps=max_steps
        )

    def check_ready(self) -> None:
        """Fail fast, in one line, when external assets are missing (nothing to check by default)."""

    def placeholder_assets(self) -> bool:
        """True when the assets found are placeholders (boxes): images are then no measurement."""
        return False

    def privileged_from(self, raw: Any):
        """A ``PrivilegedState`` from what a family in its own runtime sends (``ExternalSceneEnv``); others return
        one directly."""
        return raw

    def environment_versions(self) -> dict[str, str]:
        """Package versions of the environment the simulator runs in, when it is not ours (for the manifest)."""
        if self.family.runtime is None:
            return {}

        return worker_versions(self.family.runtime)

    def protocol_facts(self) -> dict[str, Any]:
        """What besides the code fixes an episode's outcome, for the run's protocol fingerprint: the horizon, the
        settling steps after reset, where initial states come from, and the identity of the asset tree."""
        return {
            "max_steps": self.family.max_steps,
            "settle_steps": 0,
            "initial_states": "sampled from each episode's seed (T0 jitter)",
            "assets": "shipped with the simulator packages (their versions identify them)",
        }

    def worker_environment(self) -> dict[str, str]:
        """The driver's resolved values of the environment variables that change what a worker builds (RoboCasa365's
        split): a Ray actor on another node gets these, not its node's own ({}: none)."""
        return {}


@dataclass(frozen=True)
class SceneCertificates:
    """A family's certificate store hooks (``scene.certificates``): what a per-machine certificate depends on
    (``committed_certificates = False``); ``scenes.certificates`` reads them."""

    family: Scene

    def asset_tree(self):
        """The asset tree a per-machine certificate depends on, or None."""
        return None

    def scope(self) -> str:
        """A user's choice besides the asset tree that changes which initial states a level draws (RoboCasa365's
        split): per-machine certificates made under another live in another folder ("": none)."""
        return ""


class Scene:
    """A scene family's catalogue (tasks, axes, T0, successors, listing) and options, holding its two parts; subclass
    it, fill the class attributes and methods, and decorate it with ``register_scene``.

    Class attributes:
        name: the registry name (``--scene``).
        description: one line for ``indgen scenes``.
        tasks: the task names (the first is the default); a property where they are read from external files.
        axes: the single axes the family supports (any '+'-composition of them works too); the first is the
            ``default_axis`` (T0 is built as its level 0).
        max_steps: the episode length (steps at 20 Hz) unless the caller overrides it.
        distractor_slots: (x, y) table spots of the ``distractor`` axis's visual-only objects, in order.
        success_predicate: the one frozen predicate that judges every level of every axis.
        committed_certificates: True when its oracle certificates ship with the package (``certification_dir``);
            False when they are made per machine (e.g. per LIBERO asset tree).
        certified_compositions: compositions certified beside the single axes by ``certify_all``
            (``indgen_vla.app.certify.suite``).
        env_spec: the family's observation/action contract (``indgen_vla.core.protocol.interface.EnvSpec``; tabletop: 8-d state,
            7-d action, cameras agentview/wrist).
        runtime: None when the simulator runs in our venv; else a ``scenes.runtime.ExternalRuntime`` naming the
            family's own interpreter and worker backend (``ExternalSceneEnv`` drives it over a pipe).
        preload: modules a worker process imports before its first env (the local backend's forkserver); a
            family whose simulator runs in another environment names none of that simulator's modules.
            ``scenes`` (the package) drops robosuite's macro-file warning before any of its modules imports it;
            the robosuite families fill MuJoCo's asset cache with the run's first task (``scenes.asset_cache``).
        oracle: ``"module:Class"`` of the family's privileged oracle (``standin:oracle``, ``indgen certify``).
        axis_overrides: the family's own steps and level ranges of shared axes, in an axes preset's form
            (``{"horizon": {"max_level": 3}}``); ``--axes-preset`` and ``--step`` still override them. A family
            whose step depends on the task (RoboCasa365's pick_x: the task's region / 5) resolves it in
            ``successor`` when given the task.
        fixed_initial_states: a description of the finite set of initial states episodes start from, whichever
            the seed (LIBERO: its 50 fixed states, episode % 50), "" when the seed draws each episode's own.
            ``evaluate`` runs through that set, so ``indgen demos`` refuses such a family (its demonstrations, and
            mimicgen's from them, would start from the evaluation's initial states).
        env_from_spec: True when the env a level builds depends on its successor only through the level's
            ``SceneSpec`` (``level_identity`` is then that spec: axes with one level-0 spec share their T0 runs).
        scene_options: the options a command may set for the family (RoboCasa365: ``split``, ``obj_registries``,
            flags ``--split``, ``--obj-registries``); ``configured`` applies them, a plan's builder carries them.
        Environment: its ``SceneEnvironment`` subclass (``env_class`` at least), reached as ``scene.environment``.
        Certificates: its ``SceneCertificates`` subclass (per-machine certificates), reached as ``scene.certificates``.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    tasks: tuple[str, ...]
    axes: ClassVar[tuple[str, ...]]
    max_steps: ClassVar[int]
    distractor_slots: ClassVar[tuple[tuple[float, float], ...]]
    success_predicate: ClassVar[Callable[[Any], bool]]
    committed_certificates: ClassVar[bool] = True
    certified_compositions: ClassVar[tuple[str, ...]] = ()
    env_spec: ClassVar[EnvSpec] = TABLETOP
    runtime: ClassVar[Any] = None
    preload: ClassVar[tuple[str, ...]] = (
        "scenes.base_env", "scenes.sim", "mujoco", "scenes.robosuite_kernels", "scenes.asset_cache"
    )  # fmt: skip
    oracle: ClassVar[str] = TABLETOP_ORACLE  # the privileged oracle ("module:attr") standin:oracle runs
    axis_overrides: ClassVar[Mapping[str, Mapping[str, float]]] = {}
    fixed_initial_states: ClassVar[str] = ""
    fixed_state_count: ClassVar[int] = 0  # how many (LIBERO: 50); certificates over them are exhaustive
    env_from_spec: ClassVar[bool] = False
    scene_options: ClassVar[tuple[str, ...]] = ()
    Environment: ClassVar[type[SceneEnvironment]] = SceneEnvironment
    Certificates: ClassVar[type[SceneCertificates]] = SceneCertificates

    def __repr__(self) -> str:
        return f"<scene {self.name} ({type(self).__name__})>"

    def __eq__(self, other: object) -> bool:
        """A family is a value: the same class under the same options (two plans' builders compare equal)."""
        return type(other) is type(self) and other.options() == self.options()  # type: ignore[attr-defined]

    def __hash__(self) -> int:
        return hash((type(self), tuple(sorted(self.options().items()))))

    @property
    def environment(self) -> SceneEnvironment:
        """The family's environment builder (its ``Environment`` over this configured family)."""
        return self.Environment(self)

    @property
    def certificates(self) -> SceneCertificates:
        """The family's certificate store hooks (its ``Certificates`` over this configured family)."""
        return self.Certificates(self)

    # ---- the catalogue: what the family offers (tasks, axes, T0, instruction, successors, listing) ---------
    @property
    def default_axis(self) -> str:
        """The family's first axis: T0 builds (``indgen demos`` without --axis, the asset cache) are its level 0."""
        return self.axes[0]

    def base(self, task: str):
        """T0: the frozen spec of ``task`` at level 0 (what the axes' successors edit)."""
        raise NotImplementedError

    def instruction(self, task: str) -> str:
        """The language instruction of ``task`` (the same at every level)."""
        raise NotImplementedError

    def successor(
        self, axis: AxisRef, step: float | None = None, overrides: Mapping[str, Mapping] | None = None,
        task: str | None = None,
    ):  # fmt: skip
        """The successor of ``axis`` on this family: its own ``axis_overrides`` under a preset's and ``--step``;
        ``task`` matters only to a family whose steps differ by task (None: the family's task-free successor)."""
        return get_successor(axis, step, merge_overrides(self.axis_overrides, overrides))

    def task_max_steps(self, task: str) -> int:
        """``task``'s episode length when no ``--max-steps`` is given: the family's own (RoboCasa365: per task)."""
        return self.max_steps

    def check_progression(self, task: str, successor: Successor, overridden: bool) -> None:
        """Condition 2 (strictly harder levels) before any episode runs, from the frozen specs; ``overridden``
        says --step / --axes-preset changed a step (a family that needs a built env checks only then)."""
        check_progression(self.base(task), successor)

    def level_identity(self, task: str, successor: Successor, level: int) -> Any:
        """What ``make_env`` builds for (task, level) along ``successor``, as plain data without the axis's name:
        two axes whose level-0 identities are equal build one environment, so ``evaluate`` runs that T0 once
        (``indgen_vla.core.protocol.plan.shared_t0``). None: the family cannot tell, and nothing is shared. A family whose env
        reads the successor only through the level's spec says so with ``env_from_spec``."""
        if not self.env_from_spec:
            return None

        return {"scene": self.name, "task": task, "spec": spec_at_level(self.base(task), successor, level)}

    def resolve_task(self, task: str | None) -> str:
        """``task``, or the default (first) task when None; a one-line error suggesting the right name."""
        if task is None:
            return self.tasks[0]
        if task not in self.tasks:
            raise UnknownNameError(f"task of scene {self.name}", task, list(self.tasks))
        return task

    def select_tasks(self, task: str | None, axes: Sequence[AxisRef] = ()) -> list[str]:
        """The tasks a run along ``axes`` covers: the default for None/"", every task for "all", else the one
        named (a family whose axes run on their own task lists narrows "all" to them: RoboCasa365)."""
        tasks = list(self.tasks)
        if task in (None, ""):
            return tasks[:1]
        if task == "all":
            return tasks
        if task not in tasks:
            raise UnknownNameError(f"task of scene {self.name}", task, tasks + ["all"])
        return [task]

    def check_axis(self, axis: AxisRef) -> None:
        """Every component of ``axis`` must be one of the family's axes (one line naming the right ones); a held axis
        (``A@B=j``) only on a family that resolves successors as ``Scene.successor`` does (the held level is a level
        of B's default ladder, which a family with its own per-task successors does not promise)."""
        if axis.held is not None and type(self).successor is not Scene.successor:
            raise ConfigError(
                f"scene {self.name} resolves its axes its own way (per-task steps and task lists), so held axes "
                f"(A@B=j) do not run there; evaluate {axis.ladder} and {axis.held} as separate axes on it"
            )
        for part in axis_components(axis):
            if part not in self.axes:
                if part not in base_axis_names():
                    raise UnknownNameError("axis", part, base_axis_names())
                where = ", ".join(sc.name for sc in registered_scenes() if part in sc.axes)
                raise UnknownNameError(f"axis of scene {self.name}", part, list(self.axes),
                                       f"{part!r} runs on {where or 'no registered scene'}")  # fmt: skip

    def row(self) -> dict:
        """The family's ``indgen scenes`` row (listing tasks never needs the simulator or the assets)."""
        return {
            "name": self.name,
            "description": self.description,
            "tasks": list(self.listed_tasks()),
            "axes": list(self.axes),
            "max_steps": self.max_steps,
            "needs": self.needs(),
        }

    def listed_tasks(self) -> tuple[str, ...]:
        """The tasks ``indgen scenes`` shows (a family whose task list needs an install shows none without it)."""
        return tuple(self.tasks)

    def needs(self) -> str | None:
        """What the family needs beyond the venv, for ``indgen scenes`` (None: nothing)."""
        return None

    # ---- the options: what a command chose (part of the family's value; both parts read them) -----------
    def check_options(self, given: Mapping[str, Any]) -> None:
        """One line for an option given (not None) that the family has not (``scene_options``) or a value it
        refuses; ``get_scene`` calls it at a command's edge (CLI, API), before anything runs."""
        extra = [k for k, v in given.items() if v is not None and k not in self.scene_options]
        if extra:
            flag = "--" + extra[0].replace("_", "-")
            takers = [s.name for s in _SCENES.values() if extra[0] in s.scene_options]
            raise ConfigError(
                f"scene {self.name} takes no {flag} (only {', '.join(takers) or 'no scene'} does); leave it out"
            )

    def configured(self, given: Mapping[str, Any]) -> Scene:
        """The family under the options ``given`` (None: not given, the family's default) as a new value, resolved
        once: what a command's plan holds and its builder carries to workers."""
        self.check_options(given)
        return self

    def options(self) -> dict[str, str]:
        """The family's options as this instance resolved them ({}: none), for a builder to carry."""
        return {}

    # ---- registration --------------------------------------------------------------------------------------
    @classmethod
    def validate(cls) -> None:
        """Check the class attributes when the class is registered (one line naming the problem)."""
        where = f"scene class {cls.__name__}"
        name = getattr(cls, "name", None)
        if not isinstance(name, str) or not name:
            raise ConfigError(f"{where}: set a class attribute name = '<scene name>'")
        for attr in ("description", "axes", "max_steps", "distractor_slots", "success_predicate"):
            if not hasattr(cls, attr):
                raise ConfigError(f"scene {name}: set the class attribute {attr!r}")
        if not isinstance(cls.max_steps, int) or cls.max_steps < 1:
            raise ConfigError(f"scene {name}: max_steps must be a positive integer, got {cls.max_steps!r}")
        if not cls.axes:
            raise ConfigError(f"scene {name}: needs at least one axis")
        unknown = [a for a in cls.axes if a not in base_axis_names()]
        if unknown:
            raise ConfigError(f"scene {name}: unknown axes {unknown}; axes are {base_axis_names()}")
        for attr, base in (("Environment", SceneEnvironment), ("Certificates", SceneCertificates)):
            if not (isinstance(getattr(cls, attr), type) and issubclass(getattr(cls, attr), base)):
                raise ConfigError(f"scene {name}: {attr} must be a {base.__name__} subclass")
        if any(len(s) != 2 for s in cls.distractor_slots):
            raise ConfigError(f"scene {name}: distractor_slots must be (x, y) pairs")
        doc = cls.__dict__.get("__doc__") or ""
        missing = [s for s in DOC_SECTIONS if s not in doc]
        if missing:
            raise ConfigError(f"scene {name}: its class docstring lacks the section(s) {missing}")


def register_scene[T: type[Scene]](cls: T) -> T:
    """Class decorator: validate a ``Scene`` subclass and register one instance of it under ``cls.name``."""
    if not (isinstance(cls, type) and issubclass(cls, Scene)):
        raise ConfigError(f"register_scene decorates Scene subclasses, got {cls!r}")
    cls.validate()
    old = _SCENES.get(cls.name)
    if old is not None and type(old).__qualname__ != cls.__qualname__:
        raise ConfigError(f"scene {cls.name!r} is already registered by {type(old).__qualname__}")
    _SCENES[cls.name] = cls()
    return cls


def get_scene(name: str, options: Mapping[str, Any] | None = None) -> Scene:
    """The registered scene ``name``, configured with a command's ``options`` when given (``Scene.configured``: a
    new value, RoboCasa365's split); an unknown name is one line suggesting the closest ones. Called at the edges
    only (the CLI, the API, a worker's entry): everything inside takes the object."""
    try:
        sc = _SCENES[name]
    except (KeyError, TypeError):
        raise UnknownNameError("scene", str(name), list(_SCENES)) from None
    return sc if options is None else sc.configured(dict(options))


def registered_scenes() -> list[Scene]:
    """Every registered scene in registration order (built-ins first, then the LIBERO suites)."""
    return list(_SCENES.values())
