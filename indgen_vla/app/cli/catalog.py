"""``indgen scenes``, ``indgen axes`` and ``indgen policies``: what is registered (``scenes.listing.scene_rows``,
``axis_rows``; ``policy_wrappers.specs.catalog``), as tables or ``--json``."""

from __future__ import annotations

import argparse
import json

from policy_wrappers.specs import catalog


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The three listing subcommands, each with ``--json``."""
    for name, help_ in (
        ("scenes", "list registered scenes and their tasks"),
        ("axes", "list registered axes with step, level range and description"),
        ("policies", "list policy spec families and stand-ins"),
    ):
        p = sp.add_parser(name, help=help_)
        p.add_argument("--json", action="store_true", help="machine-readable output")
        if name == "axes":
            p.add_argument("--scene", default=None,
                           help="show this scene family's own steps and ranges, per task (e.g. robocasa)")  # fmt: skip


def main(args: argparse.Namespace) -> int:
    """Print the listing ``args.command`` names (``axes --scene``: that family's own steps and ranges)."""
    if args.command == "axes" and args.scene:
        return scene_axes_table(args.scene, args.json)
    return {"scenes": scenes_table, "axes": axes_table, "policies": policies_text}[args.command](args.json)


def scenes_table(as_json: bool) -> int:
    """Every scene with its tasks, axes, episode length and what it needs beyond the venv."""
    from scenes.listing import scene_rows  # lazy: start-up (scenes: numpy)

    rows = scene_rows()
    if as_json:
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


def axes_table(as_json: bool) -> int:
    """Every axis with its step, level range, description and supporting scenes."""
    from scenes.listing import axis_rows  # lazy: start-up (scenes: numpy)

    title = ("axes (compose any supported pair with '+', e.g. pick_y+distractor: both step per level; hold one at a "
             "level with '@', e.g. --axis pick_y@distractor=0:3: a 2-D grid, one pick_y ladder per distractor level)")  # fmt: skip
    return _axis_listing(axis_rows(), as_json, title, "scenes")


def scene_axes_table(scene: str, as_json: bool) -> int:
    """One scene family's own steps and level ranges, per task where they differ (``scenes.scene_axes``)."""
    from scenes.family import get_scene  # lazy: start-up (scenes: numpy)
    from scenes.scene_axes import scene_axis_rows  # lazy: start-up (scenes: numpy)

    title = f"axes of scene {scene}: its own steps and level ranges, per task where they differ"
    return _axis_listing(scene_axis_rows(get_scene(scene)), as_json, title, "tasks")


def _axis_listing(rows: list[dict], as_json: bool, title: str, where: str) -> int:
    """Axis rows as JSON or one rich table (axis, step, levels, ``where``: the scenes or tasks it holds for)."""
    if as_json:
        print(json.dumps(rows, indent=2))
        return 0
    from rich.console import Console
    from rich.table import Table

    table = Table(title=title)
    for col in ("axis", "step", "levels", where, "description"):
        table.add_column(col)
    for r in rows:
        table.add_row(
            r["name"], f"{r['step']:g} {r['unit']}", r["levels"], ", ".join(r[where]), r["description"]
        )
    Console().print(table)
    return 0


def policies_text(as_json: bool) -> int:
    """Spec families and stand-ins."""
    data = catalog()
    if as_json:
        print(json.dumps(data, indent=2))
        return 0
    print("Policy spec families (--policy FAMILY:TARGET[?key=value&...]):")
    for row in data["families"]:
        print(f"  {row['name'] + ':':<13} {row['description']}")
        print(f"  {'':<13} e.g. {row['example']}")
    print("Stand-ins:")
    for row in data["standins"]:
        print(f"  {row['name']:<16} {row['description']}")
    return 0
