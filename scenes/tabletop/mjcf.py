"""MJCF object factories: scaled pick objects, the basket, the cabinet, blocks, risers and distractors.

Scale is built into the MJCF (primitive sizes or mesh ``scale`` attributes), never applied to sim
state after reset, so a scaled object has consistent geometry, inertia and contacts.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import robosuite
from robosuite.models.objects import BoxObject, CompositeObject, CylinderObject, MujocoXMLObject

from indgen_vla.core.errors import SceneError
from scenes.spec import BLOCK_COLOURS, INCH

_ASSETS = Path(robosuite.__file__).resolve().parent / "models" / "assets" / "objects"
MESH_OBJECTS = {
    "milk": "milk.xml",
    "bread": "bread.xml",
    "can": "can.xml",
    "lemon": "lemon.xml",
    "bottle": "bottle.xml",
    "cereal": "cereal.xml",
}
_PRIMITIVE_COLOURS = {"cube": BLOCK_COLOURS["red"], "cylinder": BLOCK_COLOURS["green"]}
CUBE_HALF = 0.021
CYL_RADIUS, CYL_HALF_HEIGHT = 0.022, 0.04
BLOCK_HALF = 0.02
TARGET_HALF = 0.025
RISER_HALF_XY = 0.035
RISER_HALF_Z = 0.25 * INCH / 2


def _cache_dir() -> Path:
    d = Path(os.environ.get("INDGEN_SCENE_CACHE", Path(tempfile.gettempdir()) / "indgen_scene_assets"))
    d.mkdir(parents=True, exist_ok=True)
    return d


def _scaled_xml(fname: str, scale: float) -> str:
    """Write a copy of a robosuite object XML with its mesh and sites scaled and asset paths made absolute."""
    src = _ASSETS / fname
    tree = ET.parse(src)
    for el in tree.iter():
        if el.tag in ("mesh", "texture") and "file" in el.attrib:
            el.set("file", str((src.parent / el.get("file")).resolve()))
        if el.tag == "mesh":
            base = [float(v) for v in el.get("scale", "1 1 1").split()]
            el.set("scale", " ".join(f"{v * scale:.6g}" for v in base))
        if el.tag in ("site", "geom") and "pos" in el.attrib:
            pos = [float(v) for v in el.get("pos").split()]
            el.set("pos", " ".join(f"{v * scale:.6g}" for v in pos))
    text = ET.tostring(tree.getroot(), encoding="unicode")
    digest = hashlib.sha1(text.encode()).hexdigest()[:16]
    out = _cache_dir() / f"{Path(fname).stem}_{digest}.xml"
    if not out.exists():  # content-addressed: concurrent writers produce identical files
        tmp = out.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(text)
        os.replace(tmp, out)
    return str(out)


def make_object(kind: str, name: str, scale: float = 1.0, *, visual: bool = False):
    """A catalog object (mesh or primitive) at ``scale``; ``visual=True`` gives a static, non-colliding copy."""
    obj = _make_object(kind, name, scale, joints=None if visual else "default")
    if (
        visual
    ):  # keep every geom visible but out of collision (robosuite's "visual" type drops group-0 meshes)
        for geom in obj.get_obj().iter("geom"):
            geom.set("contype", "0")
            geom.set("conaffinity", "0")
    return obj


def _make_object(kind: str, name: str, scale: float, joints):
    obj_type = "all"
    if kind in MESH_OBJECTS:
        return MujocoXMLObject(
            _scaled_xml(MESH_OBJECTS[kind], scale),
            name=name,
            joints=joints,
            obj_type=obj_type,
            duplicate_collision_geoms=True,
        )
    if kind == "cube":
        s = CUBE_HALF * scale
        return BoxObject(
            name=name,
            size=[s, s, s],
            rgba=_PRIMITIVE_COLOURS["cube"],
            density=300,
            friction=[1.0, 0.005, 0.0001],
            joints=joints,
            obj_type=obj_type,
        )
    if kind == "cylinder":
        return CylinderObject(
            name=name,
            size=[CYL_RADIUS * scale, CYL_HALF_HEIGHT * scale],
            rgba=_PRIMITIVE_COLOURS["cylinder"],
            density=300,
            friction=[1.0, 0.005, 0.0001],
            joints=joints,
            obj_type=obj_type,
        )
    if kind.startswith("block_"):
        colour = kind.removeprefix("block_")
        if colour not in BLOCK_COLOURS:
            raise SceneError(f"unknown block colour {colour!r}; known: {', '.join(BLOCK_COLOURS)}")
        s = BLOCK_HALF * scale
        return BoxObject(
            name=name,
            size=[s, s, s],
            rgba=BLOCK_COLOURS[colour],
            density=300,
            friction=[1.0, 0.005, 0.0001],
            joints=joints,
            obj_type=obj_type,
        )
    raise SceneError(f"no MJCF builder for object kind {kind!r}")


def target_block(colour: str, name: str) -> BoxObject:
    """The block the pick block goes on (slightly larger than the pick block, heavy so it stays put)."""
    return BoxObject(
        name=name,
        size=[TARGET_HALF] * 3,
        rgba=BLOCK_COLOURS[colour],
        density=2000,
        friction=[1.0, 0.005, 0.0001],
    )


def riser_stack(n_plates: int, name: str) -> CompositeObject:
    """``n_plates`` 0.25 in plates fused into one heavy free body: the target stack's extra height."""
    if n_plates < 1:
        raise SceneError("a riser stack needs at least one plate")
    hz = RISER_HALF_Z
    shades = [(0.55, 0.45, 0.35, 1.0), (0.45, 0.36, 0.28, 1.0)]
    plates = [
        ([RISER_HALF_XY, RISER_HALF_XY, hz], [0.0, 0.0, (2 * i + 1) * hz - hz * n_plates])
        for i in range(n_plates)
    ]
    rgbas = [shades[i % 2] for i in range(n_plates)]
    return _boxes(name, [RISER_HALF_XY, RISER_HALF_XY, hz * n_plates], plates, rgbas, density=3000.0)


def _boxes(name: str, total_size: list, boxes: list, rgbas: list, density: float, **kw) -> CompositeObject:
    """One rigid body of ``boxes`` (half sizes, centre relative to the bounding box centre ``total_size``)."""
    return CompositeObject(
        name=name,
        total_size=total_size,
        geom_types=["box"] * len(boxes),
        geom_sizes=[b[0] for b in boxes],
        geom_locations=[b[1] for b in boxes],
        geom_rgbas=rgbas,
        geom_frictions=[[1.0, 0.005, 0.0001]] * len(boxes),
        density=density,
        locations_relative_to_center=True,
        **kw,
    )


BASKET_INNER = (0.075, 0.075)  # interior half-extents (x, y)
BASKET_WALL_H = 0.035  # half-height of the walls
BASKET_T = 0.006  # half-thickness of floor and walls


def basket(name: str) -> CompositeObject:
    """An open-top basket from five boxes, heavy enough that a dropped object does not shove it."""
    ix, iy = BASKET_INNER
    t, h = BASKET_T, BASKET_WALL_H
    geoms = [
        ([ix + 2 * t, iy + 2 * t, t], [0, 0, -h + t]),  # floor; the body frame is the basket's centre
        ([t, iy + 2 * t, h], [ix + t, 0, 0]),
        ([t, iy + 2 * t, h], [-ix - t, 0, 0]),
        ([ix, t, h], [0, iy + t, 0]),
        ([ix, t, h], [0, -iy - t, 0]),
    ]
    brown = (0.55, 0.38, 0.2, 1.0)
    return _boxes(name, [ix + 2 * t, iy + 2 * t, h], geoms, [brown] * 5, density=1500.0)


# Cabinet compartment (fixed body): interior half-extents and heights, relative to its base centre.
CAB_INNER = (0.085, 0.15)  # interior half depth (x), half width (y)
CAB_FLOOR = 0.06  # height of the compartment floor above the table
CAB_WALL = 0.11  # wall height above the compartment floor
CAB_T = 0.008  # wall half-thickness
CAB_LIP = 0.012  # front lip height above the floor
CAB_BACK = 0.04  # back wall height above the floor (low, so the agentview camera sees into the compartment)


def cabinet(name: str) -> CompositeObject:
    """An open-top cabinet compartment on a plinth: back and side walls, a low front lip, no door."""
    ix, iy = CAB_INNER
    t = CAB_T
    half_h = (CAB_FLOOR + CAB_WALL) / 2
    zc = -half_h  # body frame is the bounding-box centre; z=zc is the table
    geoms = [
        ([ix + 2 * t, iy + 2 * t, CAB_FLOOR / 2], [0, 0, zc + CAB_FLOOR / 2]),  # plinth
        (
            [t, iy + 2 * t, CAB_BACK / 2],
            [ix + t, 0, zc + CAB_FLOOR + CAB_BACK / 2],
        ),  # back (low: camera sees in)
        ([ix, t, CAB_WALL / 2], [0, iy + t, zc + CAB_FLOOR + CAB_WALL / 2]),  # left
        ([ix, t, CAB_WALL / 2], [0, -iy - t, zc + CAB_FLOOR + CAB_WALL / 2]),  # right
        ([t, iy + 2 * t, CAB_LIP / 2], [-ix - t, 0, zc + CAB_FLOOR + CAB_LIP / 2]),  # front lip
    ]
    wood = (0.78, 0.7, 0.58, 1.0)
    rgbas = [wood, wood, wood, wood, (0.6, 0.5, 0.4, 1.0)]
    return _boxes(name, [ix + 2 * t, iy + 2 * t, half_h], geoms, rgbas, density=1000.0, joints=None)


CLUTTER_KINDS = ("clutter_box_blue", "clutter_cyl_yellow", "clutter_box_orange", "clutter_cyl_red")


def clutter_object(i: int, name: str):
    """The i-th clutter object (a fixed sequence, so level k's clutter is level k-1's plus one)."""
    kind = CLUTTER_KINDS[i % len(CLUTTER_KINDS)]
    colour = BLOCK_COLOURS[kind.rsplit("_", 1)[1]]
    if "_box_" in kind:
        return BoxObject(
            name=name, size=[0.018, 0.018, 0.035], rgba=colour, density=400, friction=[1.0, 0.005, 0.0001]
        )
    return CylinderObject(
        name=name, size=[0.018, 0.035], rgba=colour, density=400, friction=[1.0, 0.005, 0.0001]
    )


DISTRACTOR_KINDS = ("milk", "cereal", "bottle", "can", "bread", "lemon")
