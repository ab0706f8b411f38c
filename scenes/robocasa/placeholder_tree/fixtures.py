"""Which builder makes the placeholder ``model.xml`` of each fixture kind (the fixture registry file's name)."""

from __future__ import annotations

from . import built_in, countertop
from .model import DEFAULT_SIZE, SIZES, Model

# fixtures built of several colliders (open at the top: Model.hollow; the fridge, the mixer; the kettle, its lever
# slab free), not as one solid box
HOLLOW = ("sink", "blender", "fridge", "stand_mixer", "electric_kettle")

BUILDERS = {
    "sink": built_in.sink, "microwave": built_in.microwave, "oven": built_in.oven,
    "dishwasher": built_in.dishwasher, "fridge": built_in.fridge, "stove": built_in.stove,
    "stove_wide": built_in.stove, "stovetop": built_in.stove, "stand_mixer": countertop.stand_mixer,
    "electric_kettle": countertop.electric_kettle, "coffee_machine": countertop.coffee_machine,
    "blender": countertop.blender, "toaster": countertop.toaster, "toaster_oven": countertop.toaster_oven,
    **dict.fromkeys(("dish_rack", "fruit_bowl", "tiered_basket", "utensil_set", "knife_block"), countertop.open_top),
}  # fmt: skip


def fixture_model(kind: str, name: str) -> str:
    """The placeholder model.xml of one fixture of ``kind`` (any other kind: a box with only ``reg_main``)."""
    w, d, h = SIZES.get(kind, DEFAULT_SIZE)
    if kind.startswith("fridge"):
        kind = "fridge"
    m = Model(name, (w, d, h), solid=kind not in HOLLOW)
    if kind in BUILDERS:
        BUILDERS[kind](m)
    return m.xml()


def simple_model(name: str, size: tuple[float, float, float]) -> str:
    """A box with only ``reg_main`` (cabinet panels, handles, wall accessories, anything else)."""
    return Model(name, size).xml()
