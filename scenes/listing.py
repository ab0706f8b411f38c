"""What ``indgen scenes`` and ``indgen axes`` list: one row per registered family, one per axis (pure data, no
simulator import), and which families this package builds itself."""

from __future__ import annotations

from indgen_vla.core.protocol.axis_ref import AxisRef
from scenes.axes import axis_components, base_axis_names, get_successor
from scenes.family import registered_scenes
from scenes.tabletop import TabletopScene


def builtin_scenes() -> list[TabletopScene]:
    """The registered families this package builds itself (no external assets)."""
    return [s for s in registered_scenes() if isinstance(s, TabletopScene)]


def scene_rows() -> list[dict]:
    """One row per registered scene for ``indgen scenes``: the built-ins, then the LIBERO suites (assets not
    required)."""
    return [s.row() for s in registered_scenes()]


def axis_rows() -> list[dict]:
    """Every base axis and two examples of compositions: step, unit, levels, field, description, scenes."""
    scenes = scene_rows()
    rows = []
    for ref in map(AxisRef.parse, base_axis_names() + ["pick_y+distractor", "pick_y@distractor=2"]):
        ax = get_successor(ref).axis
        rows.append(
            {
                "name": ax.name,
                "step": ax.step,
                "unit": ax.unit,
                "levels": f"{ax.min_level}..{ax.max_level}",
                "signed": ax.signed,
                "field": ax.field,
                "description": ax.description,
                "scenes": [s["name"] for s in scenes if all(p in s["axes"] for p in axis_components(ref))],
            }
        )
    return rows
