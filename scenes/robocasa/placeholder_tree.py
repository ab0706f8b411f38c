"""Write RoboCasa's placeholder asset tree; run with the RoboCasa venv's interpreter (``scenes.robocasa.placeholders``
starts it). Imports only the standard library, numpy, PyYAML and RoboCasa: it is not part of the ``scenes`` package.

The tree is the wheel's own ``models/assets`` (layouts, styles, fixture registry, procedural cabinet XML) plus, for
every file those reference that the wheel does not ship: a box ``model.xml`` per fixture carrying the joints, sites
and regions its fixture class looks up (the sink and the blender open at the top: a floor and four walls around
their basin / jar region); one box object per (registry, category); flat one-colour textures; a one-box mesh for
any mesh file. Pitfalls handled (issue 25): every joint has its own body (two joints on one body and axis make the
mass matrix singular); a door sits outside its body's collider (inside, MuJoCo resets mjData to qpos0
with only mjWARN_BADQACC set); the tree is written writable (objects write temporary XML into their folders).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import runpy
import shutil
import struct
import sys
import zlib
from pathlib import Path

MARKER = "INDGEN_PLACEHOLDER_TREE"  # a file at the root naming what wrote the tree
# 5: the sink and the blender are hollow; the blender has anchor_site, power_button_main; 6: the stand mixer's
# head overhangs its front (OpenStandMixerHead), the kettle's lid button collides and springs back, the fridge has
# its drawer and an open shelf, the stand mixer's bowl is open; 8: the kettle's switch is RoboCasa's lever, low on
# its side, hinged at its inner end and pressed down at its free end (7: the toaster oven, another branch)
VERSION = 8
SLAB = 0.05  # front and top slabs of a fixture's footprint kept free of its collider: where its moving parts live

# nominal full size (w, d, h) in metres of each fixture type's box (the registry's size/scale rescales it)
SIZES = {
    "sink": (0.8, 0.53, 0.2), "stove": (0.76, 0.66, 0.9), "stove_wide": (0.9, 0.66, 0.9), "stovetop": (0.76, 0.53, 0.05),
    "oven": (0.76, 0.66, 0.7), "microwave": (0.6, 0.4, 0.35), "hood": (0.76, 0.5, 0.4), "dishwasher": (0.6, 0.6, 0.85),
    "fridge_french_door": (0.9, 0.75, 1.8), "fridge_side_by_side": (0.9, 0.75, 1.8),
    "fridge_bottom_freezer": (0.76, 0.75, 1.8), "coffee_machine": (0.25, 0.35, 0.4), "toaster": (0.3, 0.2, 0.2),
    "toaster_oven": (0.45, 0.35, 0.28), "blender": (0.18, 0.18, 0.4), "blender_lid": (0.18, 0.18, 0.04),
    "stand_mixer": (0.22, 0.36, 0.36), "electric_kettle": (0.2, 0.16, 0.25), "stool": (0.4, 0.4, 0.65),
    "window": (1.0, 0.05, 1.0), "dish_rack": (0.45, 0.35, 0.15), "utensil_rack": (0.5, 0.05, 0.08),
    "wall_accessory": (0.08, 0.02, 0.12), "handle": (0.02, 0.03, 0.2), "panel": (0.5, 0.02, 0.7),
}  # fmt: skip
DEFAULT_SIZE = (0.12, 0.12, 0.2)  # counter-top accessories
# fixtures built of several colliders (open at the top: Model.hollow; the fridge, the mixer; the kettle, its lever
# slab free), not as one solid box
HOLLOW = ("sink", "blender", "fridge", "stand_mixer", "electric_kettle")


def fmt(*v: float) -> str:
    return " ".join(f"{x:.5g}" for x in v)


class Model:
    """One fixture's MJCF: a root body ``object`` with a collision box (or ``hollow``'s floor and walls) and
    children with one joint each."""

    def __init__(self, name: str, size: tuple[float, float, float], solid: bool = True):
        self.name, (w, d, h) = name, size
        self.hx, self.hy, self.hz = w / 2, d / 2, h / 2
        self.geoms: list[str] = []
        self.bodies: list[str] = []
        self.sites: list[str] = []
        self.outer_sites: list[str] = []  # children of the model's outer body (RoboCasa's ``./body/site``)
        # the collider leaves a front and a top slab of the footprint free: moving parts sit there, inside the
        # footprint RoboCasa's placement checks use, and never inside a collider (MuJoCo would reset to qpos0);
        # ``solid=False``: no collider box, the caller builds its own (``hollow``)
        s = min(SLAB, self.hy / 2, self.hz / 2)
        self.front, self.top = -self.hy + s / 2, self.hz - s / 2  # the slabs' mid-planes
        self.slab = s
        if solid:
            self.box("body", (0, s / 2, -s / 2), (self.hx, self.hy - s / 2, self.hz - s / 2))
        self.region("main", (0, 0, 0), (self.hx, self.hy, self.hz))

    def hollow(self, outer, inner, floor: float, rim: float, y0: float = 0.0) -> None:
        """A container open at the top (a sink's basin, a blender's jar): a floor box over the ``outer`` half
        footprint (x, y) from the model's bottom up to height ``floor`` and four walls from there up to ``rim``
        around the ``inner`` half footprint, both centred at y ``y0``; the interior is free space."""
        (ox, oy), hz = outer, self.hz
        self.box("floor", (0, y0, (floor - hz) / 2), (ox, oy, (floor + hz) / 2))
        self.walls(outer, inner, floor, rim, y0)

    def walls(self, outer, inner, floor: float, rim: float, y0: float = 0.0, name: str = "wall") -> None:
        """Four walls from height ``floor`` up to ``rim`` between the ``inner`` and ``outer`` half footprints (x, y),
        centred at y ``y0``: ``<name>_x{neg,pos}`` along y, ``<name>_y{neg,pos}`` along x."""
        (ox, oy), (ix, iy) = outer, inner
        h, zc = (rim - floor) / 2, (rim + floor) / 2
        for side, tag in ((-1, "neg"), (1, "pos")):
            self.box(f"{name}_x{tag}", (side * (ox + ix) / 2, y0, zc), ((ox - ix) / 2, oy, h))
            self.box(f"{name}_y{tag}", (0, y0 + side * (oy + iy) / 2, zc), (ix, (oy - iy) / 2, h))

    def box(self, name: str, pos, half, rgba="0.7 0.7 0.72 1", into: list | None = None) -> None:
        geoms = self.geoms if into is None else into  # ``into``: a child body's geoms (the fridge's drawer)
        geoms.append(
            f'<geom name="{name}" type="box" pos="{fmt(*pos)}" size="{fmt(*half)}" rgba="{rgba}" group="0" '
            'density="100"/>'
        )
        geoms.append(
            f'<geom name="{name}_visual" type="box" pos="{fmt(*pos)}" size="{fmt(*half)}" rgba="{rgba}" group="1" '
            'contype="0" conaffinity="0" density="0"/>'
        )

    def region(self, name: str, pos, half, into: list | None = None) -> None:
        (self.geoms if into is None else into).append(
            f'<geom name="reg_{name}" type="box" pos="{fmt(*pos)}" size="{fmt(*half)}" rgba="0 1 0 0" group="1" '
            'contype="0" conaffinity="0" density="0"/>'
        )

    def site(self, name: str, pos, size=0.01, outer: bool = False) -> None:
        """A site on the ``object`` body, or with ``outer`` on the outer body (where RoboCasa's ``MJCFObject.
        anchor_offset`` looks: ``./body/site``)."""
        (self.outer_sites if outer else self.sites).append(
            f'<site name="{name}" pos="{fmt(*pos)}" size="{size}" rgba="1 0 0 0"/>'
        )

    def part(self, name: str, joint: str | None, pos, half, kind="hinge", axis=(1, 0, 0), rng=(0.0, 1.57),
             sites=(), geom_names=(), children="", collide=True, pivot=(0, 0, 0), friction=0.2,
             spring: tuple[float, float] | None = None) -> None:  # fmt: skip
        """A child body at ``pos`` (in a free slab, never inside a collider) with one joint (at ``pivot`` in its
        frame) and a small box of its own; ``collide=False`` for parts no task touches (racks, knobs); ``spring``
        (stiffness, rest position) for a button that springs back."""
        k = "" if spring is None else f' stiffness="{spring[0]:g}" springref="{spring[1]:g}"'
        j = (
            f'<joint name="{joint}" type="{kind}" pos="{fmt(*pivot)}" axis="{fmt(*axis)}" range="{fmt(*rng)}" '
            f'limited="true" damping="2" armature="0.01" frictionloss="{friction:g}"{k}/>'
            if joint
            else ""
        )
        gname = geom_names[0] if geom_names else f"{name}_g"
        flags = "" if collide else ' contype="0" conaffinity="0"'
        g = (
            f'<geom name="{gname}" type="box" pos="0 0 0" size="{fmt(*half)}" rgba="0.5 0.5 0.55 1" group="0" '
            f'density="200"{flags}/>'
            f'<geom name="{gname}_visual" type="box" pos="0 0 0" size="{fmt(*half)}" rgba="0.5 0.5 0.55 1" group="1" '
            'contype="0" conaffinity="0" density="0"/>'
        )
        s = "".join(f'<site name="{n}" pos="{fmt(*p)}" size="0.01" rgba="1 0 0 0"/>' for n, p in sites)
        self.bodies.append(f'<body name="{name}" pos="{fmt(*pos)}">{j}{g}{s}{children}</body>')

    def xml(self) -> str:
        hx, hy, hz = self.hx, self.hy, self.hz
        inner = "\n        ".join(self.geoms + self.sites + self.bodies)
        outer = "".join("\n      " + x for x in self.outer_sites)
        return f"""<mujoco model="{self.name}">
  <compiler angle="radian"/>
  <asset>
    <texture name="tex" type="2d" file="tex.png"/>
    <material name="mat" texture="tex"/>
  </asset>
  <worldbody>
    <body>
      <body name="object">
        {inner}
      </body>
      <site rgba="0 0 0 0" size="0.005" pos="0 0 {-hz:.5g}" name="bottom_site"/>
      <site rgba="0 0 0 0" size="0.005" pos="0 0 {hz:.5g}" name="top_site"/>
      <site rgba="0 0 0 0" size="0.005" pos="{hx:.5g} {hy:.5g} 0" name="horizontal_radius_site"/>{outer}
    </body>
  </worldbody>
</mujoco>
"""


def fixture_model(kind: str, name: str) -> str:
    """The placeholder model.xml of one fixture of ``kind`` (the fixture registry file's name)."""
    w, d, h = SIZES.get(kind, DEFAULT_SIZE)
    if kind.startswith("fridge"):
        kind = "fridge"
    m = Model(name, (w, d, h), solid=kind not in HOLLOW)
    hx, hy, hz = m.hx, m.hy, m.hz
    front, top, t = m.front, m.top, m.slab / 2 - 0.005  # slab mid-planes; a part's half-thickness in its slab
    small = (0.015, t * 0.6, 0.015)
    if kind == "sink":
        # a basin open at the top: RoboCasa's checks want the object's centre inside reg_basin (obj_inside_of with
        # partial_check), which a solid box would hold only for objects under 6 cm tall; its floor is the region's
        # bottom (RoboCasa drops objects placed in the sink there), its rim the sink's top (the counter's top)
        m.hollow((hx, hy), (hx * 0.7, hy * 0.6), -hz * 0.4, hz)
        m.region("basin", (0, 0, hz * 0.2), (hx * 0.7, hy * 0.6, hz * 0.6))
        # the class finds ./body/body/body/joint[@name=handle_joint] and ./body/body/body/site[@name=water];
        # the spout stands above the basin's rear, inside the footprint (behind it is the wall)
        m.bodies.append(
            f'<body name="spout" pos="0 {hy * 0.6:.4g} {hz + 0.05:.4g}">'
            '<joint name="handle_joint" type="hinge" axis="1 0 0" range="0 0.8" limited="true" damping="2" '
            'armature="0.01"/><geom name="spout_g" type="box" size="0.02 0.02 0.02" group="0" density="200" '
            'contype="0" conaffinity="0"/>'
            f'<site name="water" pos="0 -0.12 -0.1" size="0.03 0.05" type="cylinder" rgba="0 0 1 0"/>'
            '<body name="spout2" pos="0 0 0.05"><joint name="spout_joint" type="hinge" axis="0 0 1" '
            'range="-1.57 1.57" limited="true" damping="2" armature="0.01"/>'
            '<geom name="spout2_g" type="box" size="0.01 0.01 0.01" group="0" density="200" contype="0" '
            'conaffinity="0"/><body name="handle_temp" pos="0 0 0.03"><joint name="handle_temp_joint" type="hinge" '
            'axis="0 1 0" range="-0.8 0.8" limited="true" damping="2" armature="0.01"/>'
            '<geom name="handle_temp_g" type="box" size="0.005 0.005 0.005" group="0" density="200" contype="0" '
            'conaffinity="0"/></body></body></body>'
        )
    elif kind == "stand_mixer":
        mixer_bowl(m)
        # the head lies in the top slab, hinged at its rear edge: opening (qpos up to 0.8) lifts its front; the
        # joint's friction holds it open against gravity (RoboCasa's head is closed at qpos 0). As a tilt-head
        # mixer's head, it reaches over the front (since version 6): its front edge overhangs the free front slab,
        # so a finger can get under it and lift it (OpenStandMixerHead); before, it lay on the collider's top
        m.part("head", "head_joint", (0, 0, top), (hx * 0.6, hy, t), axis=(-1, 0, 0), rng=(0.0, 0.8),
               pivot=(0, hy, 0), friction=1.0)  # fmt: skip
        m.part(
            "bowl_b",
            "bowl_joint",
            (0, front, -hz * 0.5),
            small,
            axis=(0, 0, 1),
            rng=(-3.2, 3.2),
            collide=False,
        )
        m.part("knob_speed", "knob_speed_joint", (hx * 0.6, front, 0), small, rng=(0.0, 1.57), collide=False)
        m.part("button_head_lock", "button_head_lock_joint", (-hx * 0.6, front, 0), small, kind="slide",
               axis=(0, 1, 0), rng=(-0.01, 0.0), collide=False)  # fmt: skip
    elif kind == "electric_kettle":
        m.part("lid", "lid_joint", (0, 0, top), (hx * 0.7, hy * 0.7, t), axis=(-1, 0, 0), rng=(0.0, 1.57),
               pivot=(0, hy * 0.7, 0), friction=0.5)  # fmt: skip
        kettle_switch(m)
        # the lid's release button (ElectricKettle.update_state opens the shut lid once it reads > 0.1 of its
        # range): since version 6 a collider on the top beside the lid (where a kettle's handle carries it), pushed
        # down 1 cm to its stop and sprung back up (its spring at rest 1 cm over the top stop), away from where
        # CloseElectricKettleLid's oracle sweeps and presses the lid; before, it collided with nothing. Its top
        # stands 4 mm over the lid's (a finger on both counts the press before it meets the lid) and its bottom,
        # pushed down, 4 mm over the collider
        xb, top_b, bottom_b = (hx + hx * 0.7) / 2, hz - 0.001, hz - m.slab + 0.014
        m.part("button_lid", "button_lid_joint", (xb, 0, (top_b + bottom_b) / 2),
               ((hx * 0.3) / 2 - 0.002, 0.015, (top_b - bottom_b) / 2), kind="slide", axis=(0, 0, 1),
               rng=(-0.01, 0.0), friction=0.02, spring=(20.0, 0.01))  # fmt: skip
    elif kind == "microwave":
        m.region("int", (0, 0, 0), (hx * 0.8, hy * 0.8, hz * 0.8))
        m.part("door", "microjoint", (0, front, 0), (hx * 0.9, t, hz * 0.8), axis=(0, 0, 1), rng=(-1.57, 0.0),
               pivot=(-hx * 0.9, 0, 0), geom_names=("door",))  # fmt: skip
        m.box("start_button", (hx * 0.9, front, hz * 0.3), (0.01, t * 0.5, 0.01))
        m.box("stop_button", (hx * 0.9, front, -hz * 0.3), (0.01, t * 0.5, 0.01))
    elif kind in ("oven", "toaster_oven", "dishwasher"):
        for i, z in enumerate((-0.3, 0.3)):  # racks and trays: inside the box, touched by no task here
            m.region(f"rack{i}", (0, 0, hz * z), (hx * 0.8, hy * 0.8, hz * 0.15))
            m.part(f"rack{i}", f"rack{i}_joint", (0, 0, hz * z), (hx * 0.5, 0.005, 0.005), kind="slide",
                   axis=(0, -1, 0), rng=(0.0, 0.3), collide=False)  # fmt: skip
        if kind == "toaster_oven":
            m.region("tray0", (0, 0, -hz * 0.6), (hx * 0.8, hy * 0.8, hz * 0.1))
            m.part("tray0", "tray0_joint", (0, 0, -hz * 0.6), (hx * 0.5, 0.005, 0.005), kind="slide",
                   axis=(0, -1, 0), rng=(0.0, 0.3), collide=False)  # fmt: skip
        m.part("door", "door_joint", (0, front, 0), (hx * 0.7, t, hz * 0.8), axis=(1, 0, 0), rng=(0.0, 1.57),
               pivot=(0, 0, -hz * 0.8))  # fmt: skip
        knobs = ("time", "temp") if kind == "oven" else ("doneness", "function", "temp", "time")
        for i, k in enumerate(knobs):
            m.part(f"knob_{k}", f"knob_{k}_joint", (hx * 0.85, front, hz * (0.6 - 0.3 * i)), small, axis=(0, 1, 0),
                   rng=(0.0, 3.14), collide=False)  # fmt: skip
    elif kind == "fridge":
        fridge(m, t)
    elif kind in ("stove", "stove_wide", "stovetop"):
        for i, loc in enumerate(("front_left", "front_right", "rear_left", "rear_right", "center")):
            x = (-0.5 if "left" in loc else 0.5 if "right" in loc else 0.0) * hx
            y = (-0.5 if "front" in loc else 0.5 if "rear" in loc else 0.0) * hy
            m.site(f"burner_on_{loc}", (x, y, hz))
            m.site(f"burner_{loc}_place_site", (x, y, hz))
            m.part(f"knob_{loc}", f"knob_{loc}_joint", (hx * (-0.8 + 0.4 * i), front, 0), small,
                   axis=(0, 1, 0), rng=(-6.3, 6.3), collide=False)  # fmt: skip
    elif kind == "coffee_machine":
        m.site("receptacle_place_site", (0, front, -hz * 0.8))
        m.box("start_button", (0, front, hz * 0.6), (0.01, t * 0.5, 0.01))
    elif kind == "blender":
        # a motor base (up to 0.4 of the height) under an open jar, behind the front slab; the jar's interior is
        # reg_int (objects go in; RoboCasa drops TurnOnBlender's fruit there), its rim the blender's top, where the
        # lid (an auxiliary fixture) is placed at anchor_site: its origin half its height above the rim (the lid's
        # nominal size matches the blender's footprint, so both scale alike); Blender.update_state counts a press
        # on the geom <blender>_power_button_main, a button standing out of the base's front into the slab
        depth, y0, base = hy - m.slab / 2, m.slab / 2, -hz * 0.4
        inner = (hx * 0.7, depth * 0.7)
        m.hollow((hx, depth), inner, base, hz, y0)
        m.region("int", (0, y0, hz * 0.2), (*inner, hz * 0.6))
        m.box("power_button_main", (0, front, (base - hz) / 2), (0.015, m.slab / 2, 0.012))
        m.site("anchor_site", (0, y0, hz + SIZES["blender_lid"][2] / 2), outer=True)
    elif kind == "toaster":
        for i, pair in enumerate(("0_0", "0_1")):
            m.part(f"knob_{pair}", f"knob_{pair}_joint", (hx * (0.3 + 0.3 * i), front, 0), small, axis=(0, 1, 0),
                   rng=(0.0, 3.14), collide=False)  # fmt: skip
            m.part(f"lever_{pair}", f"lever_{pair}_joint", (-hx * (0.3 + 0.3 * i), front, 0), small,
                   kind="slide", axis=(0, 0, 1), rng=(-0.05, 0.0), collide=False)  # fmt: skip
        m.box("button_cancel", (0, front, -hz * 0.5), (0.01, t * 0.5, 0.01))
    elif kind in ("dish_rack", "fruit_bowl", "tiered_basket", "utensil_set", "knife_block"):
        m.region("int", (0, 0, hz), (hx * 0.8, hy * 0.8, 0.02))
    return m.xml()


# the fridge (heights over its floor, m): a solid freezer under an open compartment whose crisper drawer (RoboCasa's
# reg_type "drawer", opened 0.8 of its travel by PickPlaceFridgeDrawerToShelf) slides out under a shelf set back
# from the front, so a hand over the opened drawer's object has the room above it
FREEZER_TOP, DRAWER_WALL, SHELF_Z, SHELF_BACK = 0.86, 0.1, 1.08, 0.13  # SHELF_BACK: behind the door slab
DRAWER_DEPTH, DRAWER_TRAVEL, WALL = 0.3, 0.25, 0.04


def fridge(m: Model, t: float) -> None:
    """RoboCasa's fridge fixture (``robocasa/models/fixtures/fridge.py``) reads its regions and joints by name:
    ``fridge``/``freezer`` in a region's name is its compartment, ``drawer`` in it a drawer (any other a shelf,
    which ``get_reset_regions`` keeps at 0.2 m tall or more with its floor 0.5-1.5 m up), and a joint named with
    ``drawer`` slides one out; ``update_state`` moves a drawer's region with its geom, so the region lies in the
    drawer's body (at the model's origin, as the XML ``pos`` RoboCasa reads is that body's)."""
    hx, hy, hz, s = m.hx, m.hy, m.hz, m.slab
    z = lambda h: h - hz  # noqa: E731  (a height over the floor in the model's frame)
    y0, y1, ix = -hy + s, hy - WALL, hx - WALL  # the compartment: behind the door slab, to the back wall
    m.box("freezer", (0, s / 2, (z(0) + z(FREEZER_TOP)) / 2), (hx, hy - s / 2, FREEZER_TOP / 2))
    zc, hc = (z(FREEZER_TOP) + hz) / 2, (hz - z(FREEZER_TOP)) / 2
    m.box("wall_back", (0, (y1 + hy) / 2, zc), (hx, WALL / 2, hc))
    for side, tag in ((-1, "neg"), (1, "pos")):
        m.box(f"wall_x{tag}", (side * (ix + hx) / 2, (y0 + y1) / 2, zc), (WALL / 2, (y1 - y0) / 2, hc))
    m.box("ceiling", (0, (y0 + y1) / 2, hz - WALL / 2), (ix, (y1 - y0) / 2, WALL / 2))
    ys, sz = y0 + SHELF_BACK, z(SHELF_Z)
    m.box("shelf", (0, (ys + y1) / 2, sz - 0.01), (ix, (y1 - ys) / 2, 0.01))
    m.region("fridge_shelf0", (0, (ys + y1) / 2, sz + 0.25), (ix - 0.01, (y1 - ys) / 2 - 0.01, 0.25))
    m.region("freezer_shelf0", (0, s / 2, z(FREEZER_TOP / 2)), (hx * 0.8, hy * 0.7, 0.18))
    # the drawer: a tray (floor and four walls) 5 mm over the freezer's top, its front just behind the door slab
    dx, d0, fz = ix - 0.01, y0 + 0.005, z(FREEZER_TOP) + 0.005
    d1, top = d0 + DRAWER_DEPTH, fz + 0.02 + DRAWER_WALL
    tray: list[str] = []
    m.box("drawer_floor", (0, (d0 + d1) / 2, fz + 0.01), (dx, DRAWER_DEPTH / 2, 0.01), into=tray)
    for y, tag in ((d0 + 0.005, "front"), (d1 - 0.005, "back")):
        m.box(f"drawer_{tag}", (0, y, (fz + 0.02 + top) / 2), (dx, 0.005, DRAWER_WALL / 2), into=tray)
    for side, tag in ((-1, "neg"), (1, "pos")):
        m.box(f"drawer_x{tag}", (side * (dx - 0.005), (d0 + d1) / 2, (fz + 0.02 + top) / 2),
              (0.005, DRAWER_DEPTH / 2 - 0.01, DRAWER_WALL / 2), into=tray)  # fmt: skip
    m.region("fridge_drawer0", (0, (d0 + d1) / 2, (fz + 0.02 + top) / 2),
             (dx - 0.01, DRAWER_DEPTH / 2 - 0.01, DRAWER_WALL / 2), into=tray)  # fmt: skip
    m.bodies.append(
        '<body name="fridge_drawer0" pos="0 0 0"><joint name="fridge_drawer0_joint" type="slide" axis="0 -1 0" '
        f'range="0 {DRAWER_TRAVEL:g}" limited="true" damping="2" armature="0.01" frictionloss="1"/>'
        + "".join(tray)
        + "</body>"
    )
    door = (hz - z(FREEZER_TOP)) / 2 - 0.005
    m.part("fridge_door", "fridge_door_joint", (0, m.front, hz - door - 0.005), (hx * 0.9, t, door),
           axis=(0, 0, 1), rng=(-1.57, 0.0), pivot=(-hx * 0.9, 0, 0))  # fmt: skip
    m.part("freezer_door", "freezer_door_joint", (0, m.front, z(FREEZER_TOP / 2)), (hx * 0.9, t, FREEZER_TOP / 2 - 0.01),
           axis=(0, 0, 1), rng=(-1.57, 0.0), pivot=(-hx * 0.9, 0, 0))  # fmt: skip


# m, the stand mixer's bowl at nominal size: its floor's height over the mixer's bottom, its walls' thickness, its
# depth (the rim over its floor) and the height of reg_bowl over its floor
BOWL_FLOOR, BOWL_WALL, BOWL_DEPTH, BOWL_REGION = 0.03, 0.01, 0.08, 0.2


def kettle_switch(m: Model) -> None:
    """The kettle's collider with a free slab on its +x side, and in it, low, the power lever (``switch_joint``):
    RoboCasa's kettles carry it at the foot of the handle, on their +x side under the lid button, a plate sticking
    out about 4 cm over the counter and pressed down at its free end (ElectricKettle003's ``Lever001_joint`` slides
    12 mm down; 011, 021 and 028 hinge it at its inner end about +y, 0.26-0.52 rad; robocasa/robocasa 0e206dd1), and
    ``ElectricKettle.update_state`` turns the kettle on once it reads >= 0.95. Here it is hinged at its inner end
    about +y (0..0.26 rad, its free end down), 4 cm up, the slab over it free up to the lid button (since version 8:
    before, a 3 cm plate on the kettle's front rocking about its own middle)."""
    hx, hy, hz, s = m.hx, m.hy, m.hz, m.slab
    m.box("body", (-s / 2, s / 2, -s / 2), (hx - s / 2, hy - s / 2, hz - s / 2))
    length = s - 0.006  # 3 mm off the collider's side and inside the footprint's edge
    m.part("switch", "switch_joint", (hx - s / 2, 0, -hz + 0.04), (length / 2, 0.0125, 0.003), axis=(0, 1, 0),
           rng=(0.0, 0.26), pivot=(-length / 2, 0, 0), friction=0.05)  # fmt: skip


def mixer_bowl(m: Model) -> None:
    """The stand mixer under its head (the top slab): a foot, a column at the back and, in front of it, an open bowl
    (floor and four walls, ``BOWL_DEPTH`` deep) holding ``reg_bowl``, the one region ``StandMixer`` reads
    (``get_reset_region_names``); ``check_item_in_bowl`` wants every corner of the object in that region's lower
    half, so the region runs ``BOWL_REGION`` up from the bowl's floor (a solid mixer held it inside its collider)."""
    hx, hy, hz, s = m.hx, m.hy, m.hz, m.slab
    floor, w = -hz + BOWL_FLOOR, BOWL_WALL
    y0, y1 = -hy + w, hy * 0.25  # the bowl's inside, from its front wall to the column
    ix, iy, yc = hx - 2 * w, (y1 - y0) / 2 - w, (y0 + y1) / 2
    m.box("foot", (0, 0, (floor - hz) / 2), (hx, hy, BOWL_FLOOR / 2))
    m.box("column", (0, (y1 + hy) / 2, (floor + hz - s) / 2), (hx, (hy - y1) / 2, (hz - s - floor) / 2))
    m.walls((ix + w, iy + w), (ix, iy), floor, floor + BOWL_DEPTH, yc, name="bowl")
    m.region("bowl", (0, yc, floor + BOWL_REGION / 2), (ix, iy, BOWL_REGION / 2))


def simple_model(name: str, size: tuple[float, float, float]) -> str:
    """A box with only ``reg_main`` (cabinet panels, handles, wall accessories, anything else)."""
    return Model(name, size).xml()


def object_model(name: str, half: tuple[float, float, float]) -> str:
    """One kitchen object: a free box with robosuite's bottom/top/horizontal-radius sites and a ``reg_bbox``."""
    hx, hy, hz = half
    return f"""<mujoco model="{name}">
  <asset/>
  <worldbody>
    <body>
      <body name="object">
        <geom name="col" type="box" pos="0 0 0" size="{fmt(hx, hy, hz)}" rgba="0.8 0.4 0.2 1" group="0" density="100"
              solimp="0.998 0.998 0.001" solref="0.001 1" friction="0.95 0.3 0.1" condim="4"/>
        <geom name="vis" type="box" pos="0 0 0" size="{fmt(hx, hy, hz)}" rgba="0.8 0.4 0.2 1" group="1" contype="0"
              conaffinity="0" density="0"/>
        <geom name="reg_bbox" type="box" pos="0 0 0" size="{fmt(hx, hy, hz)}" rgba="0 1 0 0" group="1" contype="0"
              conaffinity="0" density="0"/>
      </body>
      <site rgba="0 0 0 0" size="0.005" pos="0 0 {-hz:.5g}" name="bottom_site"/>
      <site rgba="0 0 0 0" size="0.005" pos="0 0 {hz:.5g}" name="top_site"/>
      <site rgba="0 0 0 0" size="0.005" pos="{hx:.5g} {hy:.5g} 0" name="horizontal_radius_site"/>
    </body>
  </worldbody>
</mujoco>
"""


def flat_png(rgb: tuple[int, int, int], n: int = 4) -> bytes:
    """An n x n single-colour PNG (stdlib only)."""
    raw = b"".join(b"\x00" + bytes(rgb) * n for _ in range(n))

    def chunk(tag: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)
        )

    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", n, n, 8, 2, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw))
        + chunk(b"IEND", b"")
    )


def colour(path: str) -> tuple[int, int, int]:
    """A stable muted colour per texture path (so surfaces are told apart in a render)."""
    h = hashlib.sha1(path.encode()).digest()
    return tuple(90 + b % 120 for b in h[:3])  # type: ignore[return-value]


BOX_OBJ = (
    "\n".join(
        [f"v {x:g} {y:g} {z:g}" for x in (-0.05, 0.05) for y in (-0.05, 0.05) for z in (-0.05, 0.05)]
        + ["f 1 3 4 2", "f 5 6 8 7", "f 1 2 6 5", "f 3 7 8 4", "f 1 5 7 3", "f 2 4 8 6"]
    )
    + "\n"
)


class Writer:
    """Writes each placeholder file once, never over an existing file nor for one the wheel ships; counts the
    placeholders it wrote and those already there (an earlier run's)."""

    def __init__(self, dst: Path, wheel: Path):
        self.dst, self.wheel = dst, wheel
        self.written = {"fixtures": 0, "objects": 0, "textures": 0, "meshes": 0, "other": 0}
        self.present = dict.fromkeys(self.written, 0)
        self._seen: set[str] = set()  # a file several entries reference is counted once

    def write(self, rel: str, data: str | bytes, kind: str) -> None:
        key = os.path.normpath(rel)
        if key in self._seen:
            return
        self._seen.add(key)
        if (self.wheel / key).exists():  # copied from the wheel: RoboCasa's own file, no placeholder
            return
        p = self.dst / key
        if p.exists():
            self.present[kind] += 1
            return
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(data if isinstance(data, bytes) else data.encode())
        self.written[kind] += 1

    def texture(self, rel: str) -> None:
        self.write(rel, flat_png(colour(rel)), "textures")


def _strings(value):
    """Every string in a nested YAML value."""
    if isinstance(value, str):
        yield value
    elif isinstance(value, dict):
        for v in value.values():
            yield from _strings(v)
    elif isinstance(value, list | tuple):
        for v in value:
            yield from _strings(v)


def registry_entries(assets: Path):
    import yaml

    for f in sorted((assets / "fixtures" / "fixture_registry").glob("*.yaml")):
        data = yaml.safe_load(f.read_text()) or {}
        for key, cfg in data.items():
            if isinstance(cfg, dict):
                yield f.stem, key, cfg


def referenced_in_sources(pkg: Path) -> set[str]:
    """Asset paths written as literals in RoboCasa's (and robosuite's kitchen-facing) Python sources."""
    pat = re.compile(r"""["']((?:fixtures|textures|objects|generative_textures|arenas)/[^"'\s{}]+)["']""")
    out: set[str] = set()
    for py in pkg.rglob("*.py"):
        if "scripts" in py.parts or "demos" in py.parts:
            continue
        out.update(pat.findall(py.read_text(errors="ignore")))
    return out


def object_categories() -> dict:
    """RoboCasa's raw OBJ_CATEGORIES (before its ObjCat conversion), read from its source file."""
    import robocasa.models.objects as objs

    ns = runpy.run_path(str(Path(objs.__file__).parent / "kitchen_objects.py"))
    return ns["OBJ_CATEGORIES"]


REGISTRY_FOLDERS = {"objaverse": "objaverse", "aigen": "aigen_objs", "lightwheel": "lightwheel"}


def write_tree(dst: Path) -> dict:
    """Write (or complete) the tree; returns the placeholder files per kind ``written`` now and already
    ``present``, the files copied from the wheel (``package``) and every file in the tree (``total``)."""
    import robocasa

    pkg = Path(robocasa.__file__).parent
    wheel_assets = pkg / "models" / "assets"
    marker = dst / MARKER
    if marker.is_file() and not marker.read_text().startswith(f"version {VERSION}\n"):
        shutil.rmtree(dst)  # a placeholder tree of an older generator: written again, never patched in place
    dst.mkdir(parents=True, exist_ok=True)
    shutil.copytree(wheel_assets, dst, dirs_exist_ok=True)
    w = Writer(dst, wheel_assets)
    for kind, key, cfg in registry_entries(wheel_assets):
        xml = cfg.get("xml")
        if isinstance(xml, str):
            rel = xml if xml.endswith(".xml") else f"{xml}/model.xml"
            body = (
                fixture_model(kind, key)
                if not xml.startswith("objects/")
                else object_model(key, (0.04, 0.04, 0.06))
            )
            w.write(rel, body, "fixtures")
            w.texture(str(Path(rel).parent / "tex.png"))
        for v in _strings(cfg):  # nested too: a handle style's handle_config.texture
            if v.endswith((".png", ".jpg")):
                w.texture(v)
    for rel in sorted(referenced_in_sources(pkg)):
        if rel.endswith((".png", ".jpg")):
            w.texture(rel)
        elif rel.endswith(".xml"):
            kind = "handle" if "/handles/" in rel else "panel" if "panel" in rel else "other"
            w.write(rel, simple_model(Path(rel).parent.name, SIZES.get(kind, DEFAULT_SIZE)), "fixtures")
            w.texture(str(Path(rel).parent / "tex.png"))
        elif rel.startswith("fixtures/") and not Path(rel).suffix:
            w.write(f"{rel}/model.xml", simple_model(Path(rel).name, DEFAULT_SIZE), "fixtures")
            w.texture(f"{rel}/tex.png")
    for cat, cfg in object_categories().items():
        for reg, folder in REGISTRY_FOLDERS.items():
            if reg not in cfg:
                continue
            # an auxiliary object (a lid) lives one folder deeper (kitchen_object_utils.ObjCat); the flag is per
            # registry: without the extra folder its category has no model and sampling draws NaN probabilities
            aux = bool(cfg.get("is_auxiliary_obj") or cfg[reg].get("is_auxiliary_obj"))
            folders = cfg[reg].get("model_folders") or [f"{folder}/{cat}"]
            for fold in folders:
                model = f"objects/{fold}/{cat}_ph" + ("/part" if aux else "") + "/model.xml"
                w.write(model, object_model(cat, (0.03, 0.03, 0.04)), "objects")
    # files the wheel's own XML points at (cabinet textures, meshes) that the wheel does not ship
    for xml in list(dst.rglob("*.xml")):
        text = xml.read_text(errors="ignore")
        for ref in re.findall(r'file="([^"]+)"', text):
            target = (xml.parent / ref).resolve()
            if not str(target).startswith(str(dst.resolve())):
                continue
            rel = str(target.relative_to(dst.resolve()))  # the writer skips the wheel's own files
            if ref.endswith((".png", ".jpg")):
                w.texture(rel)
            elif ref.endswith((".obj", ".stl", ".msh")):
                w.write(rel, BOX_OBJ, "meshes")
    (dst / MARKER).write_text(f"version {VERSION}\nrobocasa {getattr(robocasa, '__version__', '?')}\n")
    for root, dirs, files in os.walk(dst):  # writable: objects write temporary XML into their folders
        for n in dirs + files:
            p = os.path.join(root, n)
            os.chmod(p, os.stat(p).st_mode | 0o200)
    package = sum(len(files) for _, _, files in os.walk(wheel_assets))
    total = sum(len(files) for _, _, files in os.walk(dst))
    return {"written": w.written, "present": w.present, "package": package, "total": total}


if __name__ == "__main__":
    print(json.dumps(write_tree(Path(sys.argv[1]))))
