"""LIBERO scene adapter: LIBERO-Object's and LIBERO-Spatial's tasks (hf-libero env classes, BDDL problems, fixed
initial states) moved along the paper's axes.

Level 0 is LIBERO's own task exactly as lerobot's ``LiberoEnv`` runs it. A level k edits LIBERO's own inputs
only: the BDDL init region of the pick object (``pick_y``) or of the basket (``goal_y``), the pick object's XML
scale (``scale``), visual-only distractor fixtures (``distractor``); episode i starts from LIBERO's fixed initial
state i with the moved object translated by the same amount as its region. LIBERO-Spatial gets ``scale`` and
``distractor`` only: its instructions pick one of two identical bowls by where it is, so moving the bowl or the
plate (``pick_y``/``goal_y``) could change which bowl is meant. Importing this is cheap.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

from indgen_vla.errors import ConfigError, SceneError
from scenes.spec import Item

AXES = ("pick_y", "goal_y", "scale", "distractor")
# Axes that keep every task's meaning, per suite (Spatial's instructions locate the bowl relative to landmarks).
SUITE_AXES = {"libero_object": AXES, "libero_spatial": ("scale", "distractor")}
NUM_STEPS_WAIT = 10  # lerobot's LiberoEnv settles the scene with this many no-op steps after each reset
# Distractor spots on LIBERO-Object's floor, clear of its object regions and of the moved pick/basket.
DISTRACTOR_SLOTS = ((0.20, 0.22), (-0.22, 0.24), (0.22, -0.34), (0.26, -0.06))
# Spots on LIBERO-Spatial's table, clear of its regions, the cabinet (and its open drawer) and the stove.
SUITE_SLOTS = {"libero_spatial": ((0.30, 0.30), (0.32, -0.18), (-0.12, 0.46), (0.24, 0.50))}


def distractor_slots(suite: str) -> tuple[tuple[float, float], ...]:
    """Where the suite's distractors go, in order (table/floor coordinates of LIBERO's regions)."""
    return SUITE_SLOTS.get(suite, DISTRACTOR_SLOTS)


@dataclass(frozen=True)
class LiberoSpec:
    """One LIBERO task at one level: nominal pick/basket spots (BDDL region centres), pick scale, distractors."""

    scene: str
    task: str
    pick: Item
    goal: Item
    distractors: int = 0

    def __post_init__(self) -> None:
        n = len(distractor_slots(self.scene))
        if not isinstance(self.distractors, int) or not 0 <= self.distractors <= n:
            raise ConfigError(f"scene {self.scene}: distractors must be 0..{n}, got {self.distractors!r}")


def available() -> bool:
    """Is hf-libero installed (the scenes are registered only then)?"""
    try:
        from scenes.libero.assets import libero_root

        libero_root()
        return True
    except SceneError:
        return False


def description(suite: str) -> str:
    """One line saying what the suite's scene is, e.g. for ``libero_object``."""
    name = "LIBERO-" + suite.removeprefix("libero_").capitalize()
    return f"{name} (hf-libero): LIBERO's own tasks and fixed initial states"


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
            description=description(suite),
            tasks=tasks,
            axes=SUITE_AXES[suite],
            max_steps=max_steps,
            builder="scenes.libero.env:LiberoSceneEnv",
            base=lambda t, s=suite: base_spec(s, t),
            instruction=lambda t, s=suite: task_info(s, t).language,
        )
    return out


def listing() -> list[dict]:
    """``indgen scenes`` rows for the LIBERO suites: tasks, axes and what they need (no ``libero`` import)."""
    from scenes.libero.assets import HUB_REPO, find_assets
    from scenes.libero.bddl import SUITES

    defs = scene_defs()
    assets = find_assets(required=False) if defs else None
    if not defs:
        needs = "hf-libero (pip install 'lerobot[libero]') and LIBERO's assets"
    elif assets is None:
        needs = f"LIBERO's assets (missing: hf download {HUB_REPO} --repo-type dataset, or set INDGEN_LIBERO_ASSETS)"
    else:
        needs = f"LIBERO's assets (found: {assets})"
    return [
        {
            "name": suite,
            "description": description(suite),
            "tasks": list(defs[suite].tasks) if suite in defs else [],
            "axes": list(SUITE_AXES[suite]),
            "max_steps": max_steps,
            "needs": needs,
        }
        for suite, (_, max_steps) in SUITES.items()
    ]


def task_info(suite: str, task: str):
    from scenes.libero.bddl import load_task

    return load_task(suite, task)


def base_spec(suite: str, task: str) -> LiberoSpec:
    """T0: the pick object and receptacle at their BDDL init-region centres, unscaled, no distractors."""
    t = task_info(suite, task)
    px, py = t.centre(t.pick_region)
    gx, gy = t.centre(t.goal_region)
    return LiberoSpec(
        scene=suite, task=task, pick=Item(t.category(t.pick), px, py), goal=Item(t.category(t.goal), gx, gy)
    )


def check_ready(scene: str) -> None:
    """Raise the one-line missing-assets ``SceneError`` before any episode runs."""
    from scenes.libero.assets import find_assets

    if scene in scene_defs():
        find_assets()
