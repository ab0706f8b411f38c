"""The tabletop family: pick_place, stack and cabinet_pick on this package's robosuite scene (pure data here, no
simulator import). Each is one registered ``TabletopScene``; ``builders`` turns a level's spec into its simulator
``Layout`` (with ``mjcf``'s objects), ``env`` builds the level, ``oracle`` scripts it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from indgen_vla.core.errors import ConfigError
from scenes.family import TABLETOP_ORACLE, Scene, SceneEnvironment, register_scene
from scenes.predicates import InReceptacle, OnTableOutside, OnTarget
from scenes.spec import BLOCK_COLOURS, PICK_OBJECTS, Item, SceneSpec

if TYPE_CHECKING:
    from scenes.sim import Layout
    from scenes.tabletop.env import SceneEnv

SHORT_DRESSING = ("lemon", "bread", "can", "cube", "cylinder")
STACK_TASKS = ("orange_on_blue", "red_on_green", "yellow_on_red", "blue_on_yellow")


class TabletopEnvironment(SceneEnvironment):
    """The tabletop families' environment: this package's robosuite ``SceneEnv``."""

    def env_class(self) -> type[SceneEnv]:
        from scenes.tabletop.env import SceneEnv  # lazy: optional robosuite (the listings never build)

        return SceneEnv


class TabletopScene(Scene):
    """A family built by this package's robosuite backend (``scenes.tabletop.env.SceneEnv``) from a ``SceneSpec``:
    the base a tabletop family of your own subclasses (docs/extending.md).

    ``builder`` names the ``scenes.tabletop.builders`` function turning a level's spec (and the family's distractor
    slots) into the simulator ``Layout``.
    """

    tasks: ClassVar[tuple[str, ...]]
    builder: ClassVar[str]
    env_from_spec = True  # SceneEnv builds scene.layout(spec_at_level(...)); the successor adds nothing else
    oracle = TABLETOP_ORACLE
    preload = (*Scene.preload, "scenes.tabletop.env", "scenes.tabletop.builders")
    Environment = TabletopEnvironment

    def layout(self, spec: SceneSpec) -> Layout:
        """The simulator layout of one level (imports robosuite)."""
        import scenes.tabletop.builders as builders  # lazy: optional robosuite (the listings never build)

        return getattr(builders, self.builder)(spec, self.distractor_slots)

    @classmethod
    def validate(cls) -> None:
        super().validate()
        if not getattr(cls, "tasks", ()) or not isinstance(cls.tasks, tuple):
            raise ConfigError(f"scene {cls.name}: set tasks to a non-empty tuple of task names")
        if not isinstance(getattr(cls, "builder", None), str):
            raise ConfigError(
                f"scene {cls.name}: set builder to the name of a scenes.tabletop.builders function"
            )


@register_scene
class PickPlace(TabletopScene):
    """LIBERO-Object style pick and place into a basket.

    **Task Description:**
    Pick up the task's object (milk carton, bread, soda can, lemon, bottle, red cube or green cylinder) and place
    it in the basket; two other objects dress the table.

    **Randomizations:**
    - per episode seed, the pick object's and the basket's x/y each move by a uniform offset in +-1 cm (T0 jitter)
    - along the axes: the pick object's y (``pick_y``), x (``pick_x``) and size (``scale``), the basket's y
      (``goal_y``), the robot base's distance (``horizon``), visual-only distractors (``distractor``)

    **Success Conditions:**
    - the object rests inside the basket (within its walls, below its rim), released by the gripper and still
    """

    name = "pick_place"
    description = "LIBERO-Object style: pick one object and place it in the basket"
    tasks = tuple(PICK_OBJECTS)
    axes = ("pick_y", "goal_y", "scale", "pick_x", "horizon", "distractor")
    max_steps = 280
    distractor_slots = ((0.22, 0.02), (-0.16, 0.32), (0.26, -0.18), (-0.2, -0.34))
    success_predicate = InReceptacle()
    certified_compositions = ("pick_y+distractor",)
    builder = "pick_place_layout"

    def base(self, task: str) -> SceneSpec:
        dressing = tuple(k for k in SHORT_DRESSING if k != task)[:2]
        return SceneSpec(
            scene=self.name,
            task=task,
            pick=Item(task, x=-0.06, y=-0.13),
            goal=Item("basket", x=-0.04, y=0.16),
            dressing=(Item(dressing[0], x=0.14, y=-0.32), Item(dressing[1], x=0.2, y=0.37)),
        )

    def instruction(self, task: str) -> str:
        return f"pick up the {PICK_OBJECTS[task][0]} and place it in the basket"


def _stack_pair(task: str) -> tuple[str, str]:
    top, _, bottom = task.partition("_on_")
    return top, bottom


@register_scene
class Stack(TabletopScene):
    """The paper's real-robot Stack task in simulation.

    **Task Description:**
    Place one coloured block (the task's first colour) on another (its second) that sits on a stack of
    0.25 in riser plates.

    **Randomizations:**
    - per episode seed, the pick block's and the target's x/y each move by a uniform offset in +-1 cm (T0 jitter;
      the risers move with the target)
    - along the axes: the riser stack's height (``stack``), the pick block's y (``pick_y``) and size (``scale``),
      the target's y (``goal_y``), the robot base's distance (``horizon``), visual-only distractors
      (``distractor``)

    **Success Conditions:**
    - the pick block rests on top of the target block (within 2 cm in x/y, within 1 cm of its top), released
      and still
    """

    name = "stack"
    description = "real-robot Stack: place one block on another that sits on a riser stack"
    tasks = STACK_TASKS
    axes = ("stack", "pick_y", "goal_y", "scale", "horizon", "distractor")
    max_steps = 240
    distractor_slots = ((0.2, -0.02), (-0.16, 0.3), (0.24, -0.22), (0.22, 0.26))
    success_predicate = OnTarget()
    builder = "stack_layout"

    @classmethod
    def validate(cls) -> None:
        super().validate()
        bad = [t for t in cls.tasks if not all(c in BLOCK_COLOURS for c in _stack_pair(t))]
        if bad:
            raise ConfigError(
                f"scene {cls.name}: tasks {bad} are not '<colour>_on_<colour>' of {list(BLOCK_COLOURS)}"
            )

    def base(self, task: str) -> SceneSpec:
        top, bottom = _stack_pair(task)
        return SceneSpec(
            scene=self.name,
            task=task,
            pick=Item(f"block_{top}", x=-0.1, y=-0.12),
            goal=Item(f"block_{bottom}", x=-0.07, y=0.10),
        )

    def instruction(self, task: str) -> str:
        return "place the {} block on the {} block".format(*_stack_pair(task))


@register_scene
class CabinetPick(TabletopScene):
    """RoboCasa style: take an object out of a cabinet compartment.

    **Task Description:**
    Take the task's object out of the open cabinet's compartment and put it on the table in front of the cabinet.

    **Randomizations:**
    - per episode seed, the object's x/y in the compartment moves by a uniform offset in +-0.8 cm (T0 jitter)
    - along the axes: clutter objects beside it in the compartment (``clutter``), the cabinet's position along
      the counter (``fixture_x``), visual-only distractors on the table (``distractor``)

    **Success Conditions:**
    - the object rests on the table top outside the cabinet's footprint, released and still
    """

    name = "cabinet_pick"
    description = "RoboCasa style: take an object out of a cabinet compartment and put it on the table"
    tasks = ("can", "cube", "lemon", "cylinder", "bread")
    axes = ("clutter", "fixture_x", "distractor")
    max_steps = 300
    distractor_slots = ((-0.2, 0.3), (-0.2, -0.34), (0.32, 0.38), (0.32, -0.4))
    success_predicate = OnTableOutside()
    builder = "cabinet_layout"

    def base(self, task: str) -> SceneSpec:
        # pick.x/pick.y are relative to the compartment centre; goal is the table spot in front of the cabinet
        return SceneSpec(
            scene=self.name,
            task=task,
            pick=Item(task, x=0.0, y=0.0),
            goal=Item("table", x=-0.16, y=0.0),
            jitter=0.008,
        )

    def instruction(self, task: str) -> str:
        return f"take the {PICK_OBJECTS[task][0]} out of the cabinet and put it on the table"
