"""LIBERO scene adapter: LIBERO-Object's and LIBERO-Spatial's tasks (hf-libero env classes, BDDL problems, fixed
initial states) moved along the paper's axes; each suite is one registered ``LiberoSuite`` subclass.

Level 0 is LIBERO's own task exactly as lerobot's ``LiberoEnv`` runs it. A level k edits LIBERO's own inputs
only: the BDDL init region of the pick object (``pick_y``) or of the basket (``goal_y``), the pick object's XML
scale (``scale``), visual-only distractor fixtures (``distractor``); episode i starts from LIBERO's fixed initial
state i with the moved object translated by the same amount as its region. LIBERO-Spatial gets ``scale`` and
``distractor`` only: its instructions pick one of two identical bowls by where it is, so moving the bowl or the
plate (``pick_y``/``goal_y``) could change which bowl is meant. Importing this is cheap.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

from indgen_vla.core.errors import ConfigError, SceneError
from scenes.axes import shifts
from scenes.family import Scene, SceneCertificates, SceneEnvironment, register_scene
from scenes.libero import placement_check as placement
from scenes.libero.assets import find_assets, is_placeholder_tree, libero_root, tree_identity
from scenes.libero.bddl import load_task, short_name, suite_task_names
from scenes.predicates import BddlGoal
from scenes.spec import Item

if TYPE_CHECKING:
    from scenes.axes import Successor
    from scenes.libero.env import LiberoSceneEnv


_SLOT_COUNT: dict[
    str, int
] = {}  # each suite's number of distractor slots (``LiberoSuite.__init_subclass__``)


@dataclass(frozen=True)
class LiberoSpec:
    """One LIBERO task at one level: nominal pick/basket spots (BDDL region centres), pick scale, distractors."""

    scene: str
    task: str
    pick: Item
    goal: Item
    distractors: int = 0

    def __post_init__(self) -> None:
        n = _SLOT_COUNT[self.scene]
        if not isinstance(self.distractors, int) or not 0 <= self.distractors <= n:
            raise ConfigError(f"scene {self.scene}: distractors must be 0..{n}, got {self.distractors!r}")


def available() -> bool:
    """Is hf-libero installed (the suites' tasks can be read only then)?"""
    try:
        libero_root()
        return True
    except SceneError:
        return False


class LiberoEnvironment(SceneEnvironment):
    """A LIBERO suite's environment: ``LiberoSceneEnv`` over the user's LIBERO asset tree."""

    def env_class(self) -> type[LiberoSceneEnv]:
        from scenes.libero.env import LiberoSceneEnv  # lazy: optional robosuite (the listings never build)

        return LiberoSceneEnv

    def placeholder_assets(self) -> bool:
        """The asset tree in use is the miniature or a gap-filled overlay (``assets.PLACEHOLDER_MARK``)."""
        tree = find_assets(required=False)
        return tree is not None and is_placeholder_tree(tree)

    def check_ready(self) -> None:
        """Raise the one-line missing-install or missing-assets ``SceneError`` before any episode runs."""
        libero_root()
        find_assets()

    def protocol_facts(self) -> dict:
        from scenes.libero.env import NUM_STEPS_WAIT  # lazy: optional robosuite (the listings never build)

        assets = find_assets()
        return {
            **super().protocol_facts(),
            "settle_steps": NUM_STEPS_WAIT,
            # with the placement check: a moved level's state that does not hold its object is an unavailable
            # episode, not a policy failure (a run made before the check does not resume or pool under it)
            "initial_states": f"LIBERO's fixed initial states of hf-libero's init files, episode % 50; {placement.RULE}",
            "assets": {"root": str(assets), "listing_sha256": tree_identity(assets)},
        }


class LiberoCertificates(SceneCertificates):
    """A suite's certificates depend on the user's LIBERO asset tree."""

    def asset_tree(self):
        return find_assets(required=False)


class LiberoSuite(Scene):
    """A LIBERO suite: its tasks are LIBERO's own (read from hf-libero's BDDL files), built by ``LiberoSceneEnv``.

    A subclass sets ``name`` (LIBERO's suite name), ``task_pattern`` (a regex whose group 1 turns a task file
    name into its short task name), ``axes``, ``distractor_slots`` and ``max_steps`` (lerobot's LiberoEnv's).
    """

    task_pattern: ClassVar[str]
    max_steps = 280

    def __init_subclass__(cls, **kwargs) -> None:
        """A suite's spec checks its distractors against the suite's slots (a spec carries the suite's name)."""
        super().__init_subclass__(**kwargs)
        _SLOT_COUNT[cls.name] = len(cls.distractor_slots)

    success_predicate = BddlGoal()  # the one predicate at every level: LIBERO's own BDDL goal
    committed_certificates = False  # certificates depend on the user's LIBERO asset tree
    fixed_initial_states = "LIBERO's 50 fixed initial states (episode % 50)"
    fixed_state_count = 50  # a certificate of 59 episodes plays every one: exhaustive (scenes.heldout)
    oracle = (
        "scenes.libero.oracle:LiberoOracle"  # grasps clear of neighbours, stops waiting at the arm's reach
    )
    # LiberoSceneEnv's BDDL and placement read the level's spec (its successor only checks condition 2)
    env_from_spec = True
    Environment = LiberoEnvironment
    Certificates = LiberoCertificates

    @property
    def tasks(self) -> tuple[str, ...]:
        """LIBERO's tasks of the suite in benchmark order, by short name (needs hf-libero, not its assets)."""
        return tuple(short_name(self.task_pattern, f) for f in suite_task_names(self.name))

    def listed_tasks(self) -> tuple[str, ...]:
        return self.tasks if available() else ()

    def task_info(self, task: str):
        """The parsed BDDL problem of ``task`` (``scenes.libero.bddl.LiberoTask``)."""
        return load_task(self.name, self.task_pattern, task)

    def base(self, task: str) -> LiberoSpec:
        """T0: the pick object and receptacle at their BDDL init-region centres, unscaled, no distractors."""
        t = self.task_info(task)
        px, py = t.centre(t.pick_region)
        gx, gy = t.centre(t.goal_region)
        return LiberoSpec(
            scene=self.name,
            task=task,
            pick=Item(t.category(t.pick), px, py),
            goal=Item(t.category(t.goal), gx, gy),
        )

    def instruction(self, task: str) -> str:
        return self.task_info(task).language

    def needs(self) -> str:
        if not available():
            return "hf-libero (pip install 'lerobot[libero]') and LIBERO's assets"
        assets = find_assets(required=False)
        if assets is None:
            return "LIBERO's assets (missing: indgen setup libero, or set INDGEN_LIBERO_ASSETS)"
        return f"LIBERO's assets (found: {assets})"

    def check_progression(self, task: str, successor: Successor, overridden: bool) -> None:
        """Condition 2 is checked against LIBERO's fixed initial states, which needs level 0 built (physics only,
        ~10 s): up front only when --step / --axes-preset changed a pick_y/goal_y step; the env repeats the check
        when it is built."""
        if overridden and any(p.axis.name in ("pick_y", "goal_y") for p in shifts(successor)):
            self.environment.make_env(
                task, successor, 0, cameras=(), image_size=(128, 128), max_steps=None
            ).close()


@register_scene
class LiberoObject(LiberoSuite):
    """LIBERO-Object (hf-libero), LIBERO's own ten pick-and-place tasks.

    **Task Description:**
    Pick up the named grocery item (alphabet soup, cream cheese, ketchup, ...) among others on the floor and
    place it in the basket, as LIBERO's BDDL problem states.

    **Randomizations:**
    - episode i starts from LIBERO's fixed initial state i % 50 (lerobot's LiberoEnv), then 10 no-op steps
    - along the axes: the pick object's BDDL init region and start pose in y (``pick_y``), the basket's
      (``goal_y``), the pick object's XML scale (``scale``), visual-only distractor objects (``distractor``)

    **Success Conditions:**
    - LIBERO's own BDDL goal, ``(In pick basket_contain_region)``, via ``env.check_success()``
    """

    name = "libero_object"
    description = "LIBERO-Object (hf-libero): LIBERO's own tasks and fixed initial states"
    task_pattern = r"pick_up_the_(.+)_and_place_it_in_the_basket"
    axes = ("pick_y", "goal_y", "scale", "distractor")
    # distractor spots on LIBERO-Object's floor, clear of its object regions and of the moved pick/basket
    distractor_slots = ((0.20, 0.22), (-0.22, 0.24), (0.22, -0.34), (0.26, -0.06))


@register_scene
class LiberoSpatial(LiberoSuite):
    """LIBERO-Spatial (hf-libero), LIBERO's own ten tasks that name a black bowl by where it is.

    **Task Description:**
    Pick up the black bowl the instruction locates (between the plate and the ramekin, on the cookie box, in the
    top drawer, ...) and place it on the plate, as LIBERO's BDDL problem states.

    **Randomizations:**
    - episode i starts from LIBERO's fixed initial state i % 50 (lerobot's LiberoEnv), then 10 no-op steps
    - along the axes: the bowl's XML scale (``scale``) and visual-only distractor objects (``distractor``) only;
      moving the bowl or the plate could change which of the two identical bowls the instruction means

    **Success Conditions:**
    - LIBERO's own BDDL goal, ``(On bowl plate)``, via ``env.check_success()``
    """

    name = "libero_spatial"
    description = "LIBERO-Spatial (hf-libero): LIBERO's own tasks and fixed initial states"
    task_pattern = r"pick_up_the_black_bowl_(.+)_and_place_it_on_the_plate"
    axes = ("scale", "distractor")
    # spots on LIBERO-Spatial's table, clear of its regions, the cabinet (and its open drawer) and the stove
    distractor_slots = ((0.30, 0.30), (0.32, -0.18), (-0.12, 0.46), (0.24, 0.50))
