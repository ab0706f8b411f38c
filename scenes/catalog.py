"""The registered scenes (pure data, no simulator import) and the ``indgen scenes`` / ``indgen axes`` listings."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass

from indgen_vla.errors import ConfigError, UnknownNameError
from scenes.axes import base_axis_names, get_successor
from scenes.spec import BLOCK_COLOURS, PICK_OBJECTS, Item, SceneSpec

SHORT_DRESSING = ("lemon", "bread", "can", "cube", "cylinder")


@dataclass(frozen=True)
class SceneDef:
    """A scene family: its tasks, the axes it supports, its episode length and where its builder lives."""

    name: str
    description: str
    tasks: tuple[str, ...]
    axes: tuple[str, ...]
    max_steps: int
    builder: str  # "module:function" turning a SceneSpec into a robosuite Layout
    base: Callable[[str], SceneSpec]
    instruction: Callable[[str], str]

    def __post_init__(self) -> None:
        if not self.tasks or self.max_steps < 1:
            raise ConfigError(f"scene {self.name}: needs tasks and a positive max_steps")
        unknown = [a for a in self.axes if a not in base_axis_names()]
        if unknown:
            raise ConfigError(f"scene {self.name}: unknown axes {unknown}")


def _pick_place_base(task: str) -> SceneSpec:
    dressing = tuple(k for k in SHORT_DRESSING if k != task)[:2]
    return SceneSpec(
        scene="pick_place",
        task=task,
        pick=Item(task, x=-0.06, y=-0.13),
        goal=Item("basket", x=-0.04, y=0.16),
        dressing=(Item(dressing[0], x=0.14, y=-0.32), Item(dressing[1], x=0.2, y=0.37)),
    )


def _stack_pair(task: str) -> tuple[str, str]:
    top, _, bottom = task.partition("_on_")
    return top, bottom


def _stack_base(task: str) -> SceneSpec:
    top, bottom = _stack_pair(task)
    return SceneSpec(
        scene="stack",
        task=task,
        pick=Item(f"block_{top}", x=-0.1, y=-0.12),
        goal=Item(f"block_{bottom}", x=-0.07, y=0.10),
    )


def _cabinet_base(task: str) -> SceneSpec:
    # pick.x/pick.y are relative to the compartment centre; goal is the table spot in front of the cabinet
    return SceneSpec(
        scene="cabinet_pick",
        task=task,
        pick=Item(task, x=0.0, y=0.0),
        goal=Item("table", x=-0.16, y=0.0),
        jitter=0.008,
    )


STACK_TASKS = ("orange_on_blue", "red_on_green", "yellow_on_red", "blue_on_yellow")
for _t in STACK_TASKS:
    assert all(c in BLOCK_COLOURS for c in _stack_pair(_t)), _t

SCENES: dict[str, SceneDef] = {
    "pick_place": SceneDef(
        name="pick_place",
        description="LIBERO-Object style: pick one object and place it in the basket",
        tasks=tuple(PICK_OBJECTS),
        axes=("pick_y", "goal_y", "scale", "pick_x", "horizon", "distractor"),
        max_steps=280,
        builder="scenes.layouts:pick_place_layout",
        base=_pick_place_base,
        instruction=lambda t: f"pick up the {PICK_OBJECTS[t][0]} and place it in the basket",
    ),
    "stack": SceneDef(
        name="stack",
        description="real-robot Stack: place one block on another that sits on a riser stack",
        tasks=STACK_TASKS,
        axes=("stack", "pick_y", "goal_y", "scale", "horizon", "distractor"),
        max_steps=240,
        builder="scenes.layouts:stack_layout",
        base=_stack_base,
        instruction=lambda t: "place the {} block on the {} block".format(*_stack_pair(t)),
    ),
    "cabinet_pick": SceneDef(
        name="cabinet_pick",
        description="RoboCasa style: take an object out of a cabinet compartment and put it on the table",
        tasks=("can", "cube", "lemon", "cylinder", "bread"),
        axes=("clutter", "fixture_x", "distractor"),
        max_steps=300,
        builder="scenes.layouts:cabinet_layout",
        base=_cabinet_base,
        instruction=lambda t: f"take the {PICK_OBJECTS[t][0]} out of the cabinet and put it on the table",
    ),
}


def all_scenes() -> dict[str, SceneDef]:
    """Built-in scenes plus the LIBERO suites (registered when hf-libero is installed)."""
    from scenes.libero import scene_defs

    return {**SCENES, **scene_defs()}


def get_scene(name: str) -> SceneDef:
    scenes = SCENES if name in SCENES else all_scenes()
    try:
        return scenes[name]
    except KeyError:
        raise UnknownNameError("scene", name, list(scenes)) from None


def resolve_task(scene: SceneDef, task: str | None) -> str:
    if task is None:
        return scene.tasks[0]
    if task not in scene.tasks:
        raise UnknownNameError(f"task of scene {scene.name}", task, list(scene.tasks))
    return task


def check_axis_supported(scene: SceneDef, axis: str) -> None:
    """Every component of ``axis`` must be one of the scene's axes."""
    for part in axis.split("+"):
        if part not in scene.axes:
            if part not in base_axis_names():
                raise UnknownNameError("axis", part, base_axis_names())
            raise UnknownNameError(f"axis of scene {scene.name}", part, list(scene.axes))


def scene_rows() -> list[dict]:
    """One row per scene for ``indgen scenes``: the built-ins, then the LIBERO suites (assets not required)."""
    from scenes.libero import listing

    rows = [
        {
            "name": s.name,
            "description": s.description,
            "tasks": list(s.tasks),
            "axes": list(s.axes),
            "max_steps": s.max_steps,
            "needs": None,
        }
        for s in SCENES.values()
    ]
    return rows + listing()


def _axis_rows() -> list[dict]:
    scenes = scene_rows()
    rows = []
    for name in base_axis_names() + ["pick_y+distractor"]:
        ax = get_successor(name).axis
        rows.append(
            {
                "name": ax.name,
                "step": ax.step,
                "unit": ax.unit,
                "levels": f"{ax.min_level}..{ax.max_level}",
                "signed": ax.signed,
                "field": ax.field,
                "description": ax.description,
                "scenes": [s["name"] for s in scenes if all(p in s["axes"] for p in name.split("+"))],
            }
        )
    return rows


def scenes_main(args) -> int:
    """``indgen scenes``: every scene with its tasks, axes, episode length and what it needs beyond the venv."""
    rows = scene_rows()
    if getattr(args, "json", False):
        print(json.dumps(rows, indent=2))
        return 0
    from rich.console import Console
    from rich.table import Table

    table = Table(title="scenes")
    for col in ("scene", "tasks", "axes", "max steps", "description"):
        table.add_column(col)
    for r in rows:
        desc = r["description"] + (f"; needs {r['needs']}" if r["needs"] else "")
        table.add_row(
            r["name"], ", ".join(r["tasks"]) or "-", ", ".join(r["axes"]), str(r["max_steps"]), desc
        )
    Console().print(table)
    return 0


def axes_main(args) -> int:
    """``indgen axes``: every axis with its step, level range, description and supporting scenes."""
    rows = _axis_rows()
    if getattr(args, "json", False):
        print(json.dumps(rows, indent=2))
        return 0
    from rich.console import Console
    from rich.table import Table

    table = Table(title="axes (compose any supported pair with '+', e.g. pick_y+distractor)")
    for col in ("axis", "step", "levels", "scenes", "description"):
        table.add_column(col)
    for r in rows:
        table.add_row(
            r["name"], f"{r['step']:g} {r['unit']}", r["levels"], ", ".join(r["scenes"]), r["description"]
        )
    Console().print(table)
    return 0
