"""One placeholder fixture's MJCF (``Model``: a box collider, regions, sites and jointed parts) and the nominal
sizes of each fixture kind's box."""

from __future__ import annotations

from dataclasses import dataclass

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


def fmt(*v: float) -> str:
    return " ".join(f"{x:.5g}" for x in v)


@dataclass(frozen=True)
class Joint:
    """A part's one joint: its type, axis, range, ``pivot`` (in the part's frame), friction loss and ``spring``
    (stiffness, rest position) for a button that springs back."""

    name: str
    kind: str = "hinge"
    axis: tuple[float, float, float] = (1, 0, 0)
    rng: tuple[float, float] = (0.0, 1.57)
    pivot: tuple[float, float, float] = (0, 0, 0)
    friction: float = 0.2
    spring: tuple[float, float] | None = None

    def xml(self) -> str:
        k = "" if self.spring is None else f' stiffness="{self.spring[0]:g}" springref="{self.spring[1]:g}"'
        return (
            f'<joint name="{self.name}" type="{self.kind}" pos="{fmt(*self.pivot)}" axis="{fmt(*self.axis)}" '
            f'range="{fmt(*self.rng)}" limited="true" damping="2" armature="0.01" frictionloss="{self.friction:g}"{k}/>'
        )


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
        self.thin = s / 2 - 0.005  # a part's half thickness in its slab
        self.small = (0.015, self.thin * 0.6, 0.015)  # a knob's or a lever's half sizes
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

    def part(self, name: str, joint: Joint | None, pos, half, sites=(), geom_names=(), children="",
             collide=True) -> None:  # fmt: skip
        """A child body at ``pos`` (in a free slab, never inside a collider) with one ``joint`` (None: fixed) and a
        small box of its own; ``collide=False`` for parts no task touches (racks, knobs)."""
        j = joint.xml() if joint is not None else ""
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
