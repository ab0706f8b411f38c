"""LIBERO scene adapter: LIBERO-Object's tasks (hf-libero env classes, BDDL problems, fixed initial states)
moved along the paper's axes.

Level 0 is LIBERO's own task exactly as lerobot's ``LiberoEnv`` runs it. A level k edits LIBERO's own inputs
only: the BDDL init region of the pick object (``pick_y``) or of the basket (``goal_y``), the pick object's XML
scale (``scale``), visual-only distractor fixtures (``distractor``); episode i starts from LIBERO's fixed initial
state i with the moved object translated by the same amount as its region. Importing this is cheap.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from indgen_vla.errors import ConfigError, SceneError
from scenes.spec import Item

AXES = ("pick_y", "goal_y", "scale", "distractor")
NUM_STEPS_WAIT = 10  # lerobot's LiberoEnv settles the scene with this many no-op steps after each reset
# Distractor spots on LIBERO-Object's floor, clear of its object regions and of the moved pick/basket.
DISTRACTOR_SLOTS = ((0.20, 0.22), (-0.22, 0.24), (0.22, -0.34), (0.26, -0.06))


@dataclass(frozen=True)
class LiberoSpec:
    """One LIBERO task at one level: nominal pick/basket spots (BDDL region centres), pick scale, distractors."""

    scene: str
    task: str
    pick: Item
    goal: Item
    distractors: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.distractors, int) or not 0 <= self.distractors <= len(DISTRACTOR_SLOTS):
            raise ConfigError(f"scene {self.scene}: distractors must be 0..{len(DISTRACTOR_SLOTS)}, "
                              f"got {self.distractors!r}")


def available() -> bool:
    """Is hf-libero installed (the scenes are registered only then)?"""
    try:
        from scenes.libero.assets import libero_root

        libero_root()
        return True
    except SceneError:
        return False


@cache
def scene_defs() -> dict:
    """``{scene name: SceneDef}`` of the LIBERO suites this adapter supports (empty without hf-libero)."""
    if not available():
        return {}
    from scenes.catalog import SceneDef
    from scenes.libero.bddl import SUITES, short_name, suite_task_names

    out = {}
    for suite, (_, max_steps) in SUITES.items():
        tasks = tuple(short_name(suite, f) for f in suite_task_names(suite))
        out[suite] = SceneDef(
            name=suite,
            description=f"{suite} (hf-libero): LIBERO's own tasks and fixed initial states, moved along the axes",
            tasks=tasks, axes=AXES, max_steps=max_steps, builder="scenes.libero.env:LiberoSceneEnv",
            base=lambda t, s=suite: base_spec(s, t),
            instruction=lambda t, s=suite: task_info(s, t).language,
        )
    return out


def task_info(suite: str, task: str):
    from scenes.libero.bddl import load_task

    return load_task(suite, task)


def base_spec(suite: str, task: str) -> LiberoSpec:
    """T0: the pick object and basket at their BDDL init-region centres, unscaled, no distractors."""
    t = task_info(suite, task)
    px, py = t.centre(t.pick_region)
    gx, gy = t.centre(t.goal_region)
    return LiberoSpec(scene=suite, task=task, pick=Item(t.category(t.pick), px, py),
                      goal=Item(t.category(t.goal), gx, gy))


def check_ready(scene: str) -> None:
    """Raise the one-line missing-assets ``SceneError`` before any episode runs."""
    from scenes.libero.assets import find_assets

    if scene in scene_defs():
        find_assets()
