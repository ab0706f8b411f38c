"""``indgen axes --scene NAME``: the axes a family runs with its own steps and ranges, per task where they differ
(RoboCasa365's pick_x step is each task's region / 5; its fixture_x and base_y run 0..3 at 0.125 m), not the shared
table of ``indgen axes``. Importing this is cheap."""

from __future__ import annotations

from typing import TYPE_CHECKING

from indgen_vla.core.protocol.axis_ref import AxisRef
from scenes.axes import resolve_alias

if TYPE_CHECKING:
    from scenes.family import Scene


def scene_axis_rows(sc: Scene) -> list[dict]:
    """One row per (axis, group of tasks that share its step and range) of ``scene``, in the family's axis order."""
    rows: list[dict] = []
    for axis in map(AxisRef.parse, sc.axes):
        try:
            tasks = sc.select_tasks("all", (axis,))
        except Exception:  # a family whose "all" needs its install: its default task only
            tasks = [sc.resolve_task(None)]
        groups: dict[tuple, list[str]] = {}
        for t in tasks:
            ax = sc.successor(axis, None, None, t).axis
            low = -ax.max_level if ax.signed else 0
            key = (resolve_alias(axis.name), ax.step, ax.unit, f"{low}..{ax.max_level}", ax.description)
            groups.setdefault(key, []).append(t)
        for (name, step, unit, levels, description), ts in groups.items():
            rows.append({"name": name, "step": step, "unit": unit, "levels": levels, "tasks": ts,
                         "description": description})  # fmt: skip
    return rows
