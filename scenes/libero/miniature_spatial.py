"""The LIBERO-Spatial part of the miniature asset tree: tabletop arena, bowls, plate, ramekin, cookie box and the
articulated wooden cabinet and flat stove, with LIBERO's file names, body/joint/site names and fixture dimensions.

The cabinet keeps LIBERO's three sliding drawers (joints ``top_level``/``middle_level``/``bottom_level`` and
sites ``top_region``/``middle_region``/``bottom_region``/``top_side``) and the stove its knob hinge (``button``)
and ``cook_region``/``burner`` sites, so the model has LIBERO's qpos layout and its fixed initial states load.
"""

from __future__ import annotations

from pathlib import Path

from scenes.libero.miniature_common import (
    FLOOR,
    GEOM,
    arena_xml,
    object_xml,
    png,
    texture_asset,
    write_box_object,
    write_hope_object,
)

# category -> (folder under the asset root, box half-sizes (x, y, z) about the object's origin, RGB)
SPATIAL_OBJECTS = {
    "akita_black_bowl": ("stable_scanned_objects", (0.03, 0.03, 0.02), (0.08, 0.08, 0.08)),
    "plate": ("stable_scanned_objects", (0.06, 0.06, 0.006), (0.92, 0.92, 0.9)),
    "glazed_rim_porcelain_ramekin": ("stable_scanned_objects", (0.035, 0.035, 0.025), (0.9, 0.88, 0.8)),
    "cookies": ("stable_hope_objects", (0.03, 0.03, 0.03), (0.7, 0.45, 0.2)),
}

_TABLE_ASSETS = """<texture file="../textures/martin_novak_wood_table.png" type="cube" name="tex-table"/>
    <material name="table_texture" reflectance="0.0" shininess="0.0" specular="0.2" texrepeat="1 1" texture="tex-table"/>
    <texture file="../textures/martin_novak_wood_table.png" type="cube" name="tex-table-legs"/>
    <material name="table_legs" reflectance="0.8" shininess="0.8" texrepeat="1 1" texture="tex-table-legs"/>"""
_TABLE = """<body name="table" pos="0 0 0.4">
      <geom pos="0 0 0" size="0.4 0.4 0.4" type="box" group="0" name="table_collision" friction="1 0.005 0.0001"/>
      <geom pos="0 0 0" size="0.4 0.4 0.4" type="box" conaffinity="0" contype="0" group="1" name="table_visual"
        material="table_texture"/>
      <site pos="0 0 0.4" name="table_top" size="0.001 0.001 0.001" rgba="0 0 0 0"/>{legs}
    </body>"""
_LEG = """
      <geom pos="0 0 0" size="0.05 0.1" type="cylinder" conaffinity="0" contype="0" group="1" name="table_leg{i}_visual"
        material="table_legs"/>"""
TABLETOP = arena_xml(
    FLOOR,
    assets=_TABLE_ASSETS,
    table=_TABLE.format(legs="".join(_LEG.format(i=i) for i in range(1, 5))),
    cameras='<camera mode="fixed" name="sideview" pos="-0.0565 1.2761 1.4880" quat="0.0099 0.0069 0.5912 0.8064"/>',
)

_BOX = '<geom {g} type="box" pos="{p}" size="{s}" group="0" material="{m}"/>'
# The cabinet shell (body "base") and one drawer's walls, as (pos, half-size) in the cabinet's frame (LIBERO's).
_SHELL = (
    ("0.004 0.016 0.007", "0.123 0.09 0.002"),
    ("0.004 0.1095 0.1135", "0.119 0.002 0.111"),
    ("-0.112 0.016 0.114", "0.005 0.095 0.106"),
    ("0.119 0.016 0.114", "0.005 0.095 0.106"),
    ("0.004 0.016 0.2216", "0.127 0.094 0.0014"),
    ("0.004 0.0187 0.1494", "0.112 0.089 0.0009"),
    ("0.004 0.0187 0.0793", "0.112 0.089 0.0009"),
)
_DRAWER = (
    ("0.0035 0.0105 {f}", "0.107 0.081 0.004"),
    ("0.0033 -0.0752 {w}", "0.109 0.0027 0.034"),
    ("0.0033 0.0908 {w}", "0.107 0.0036 0.032"),
    ("-0.1019 0.011 {w}", "0.0024 0.081 0.032"),
    ("0.1089 0.011 {w}", "0.0024 0.081 0.032"),
    ("-0.0028 -0.1016 {w}", "0.044 0.008 0.008"),
)
# drawer -> (joint, region site, drawer floor z, wall centre z, region site z)
_LEVELS = (
    ("top", 0.15514, 0.18358, 0.18563),
    ("middle", 0.08543, 0.11387, 0.1169),
    ("bottom", 0.01682, 0.04525, 0.04701),
)
_FIXTURE_SITES = (0.05, 0.045, 0.045, 0.045)  # the cabinet's and the stove's bottom/top/radius sites

CABINET_BASE = """<body name="base" pos="0 0 0">
          <site type="box" pos="0.00354 0.01567 0.22152" quat="1 0 0 0" size="0.12534 0.09438 0.00147" group="0"
            rgba="0.8 0.8 0 0" name="top_side"/>
          {shell}
          {drawers}
        </body>"""

DRAWER = """<body name="cabinet_{level}" pos="0 0 0">
            <inertial pos="0 0 0" mass="3" diaginertia="1 1 1"/>
            <joint name="{level}_level" type="slide" pos="0 0 0" axis="0 1 0" limited="true" range="-0.16 0.01"
              damping="50"/>
            <site type="box" pos="0.00328 0.01128 {site}" quat="0.70711 0 0.70711 0" size="0.02993 0.07561 0.10224"
              group="0" rgba="0.8 0.8 0.8 0" name="{level}_region"/>
            {walls}
          </body>"""

STOVE_BASE = f"""<body name="base" pos="0 0 0">
          <body name="burner" pos="0.15 0 0">
            <site type="box" pos="0 0 0" quat="1 0 0 0" size="0.075 0.075 0.0025" group="0" rgba="0.8 0.8 0 0"
              name="cook_region"/>
            <geom size="0.095 0.095 0.02" pos="0 0 0" type="box" material="stove_knob_metal" group="0" name="base"/>
            <geom size="0.095 0.095 0.0005" pos="0 0 0.025" type="box" rgba="0 0 0 0" group="0"
              name="collision_burner"/>
            <site name="burner" pos="0 0 0.022" size="0.0625 0.0005" rgba="0.9 0.05 0.05 1" type="cylinder"/>
          </body>
          <body name="button" pos="0 0 0" quat="0.7071068 0 0 0.7071068">
            <inertial pos="0 0 0" mass="3" diaginertia="1 1 1"/>
            <joint name="button" type="hinge" pos="0 0 0" axis="0 0 1" limited="true" range="-0.005 2.1" damping="1"/>
            <geom {GEOM} type="box" pos="0.0013 0.0046 0.0066" size="0.034 0.034 0.0062" group="0" rgba="0.1 0.1 0.1 1"/>
          </body>
        </body>"""
STOVE = object_xml(
    "flat_stove",
    texture_asset("flat_stove/metal.png", "stove_metal", "stove_knob_metal"),
    STOVE_BASE,
    _FIXTURE_SITES,
)


def box_object_xml(name: str, x: float, y: float, z: float) -> str:
    """A scanned object as one textured box of half-sizes ``x``, ``y``, ``z``."""
    body = _BOX.format(g=GEOM, p="0 0 0", s=f"{x} {y} {z}", m=name)
    return object_xml(name, texture_asset("texture.png", name, name), body)


def cabinet_xml() -> str:
    """LIBERO's wooden cabinet as boxes: the shell, three sliding drawers with their joints and region sites."""
    shell = "\n          ".join(_BOX.format(g=GEOM, p=p, s=s, m="wooden_cabinet") for p, s in _SHELL)
    drawers = []
    for level, floor, wall, site in _LEVELS:
        walls = "\n            ".join(
            _BOX.format(g=GEOM, p=p.format(f=floor, w=wall), s=s, m="wooden_cabinet") for p, s in _DRAWER
        )
        drawers.append(DRAWER.format(level=level, site=site, walls=walls))
    base = CABINET_BASE.format(shell=shell, drawers="\n          ".join(drawers))
    assets = texture_asset("wooden_cabinet/dark_fine_wood.png", "wooden_cabinet", "wooden_cabinet")
    return object_xml("wooden_cabinet", assets, base, _FIXTURE_SITES)


def write_spatial_assets(root: Path) -> None:
    """Write the LIBERO-Spatial files under the miniature tree ``root`` (idempotent)."""
    (root / "scenes" / "libero_tabletop_base_style.xml").write_text(TABLETOP)
    for name, (folder, (x, y, z), rgb) in SPATIAL_OBJECTS.items():
        if folder == "stable_hope_objects":  # HOPE objects keep LIBERO-Object's textured-mesh layout
            write_hope_object(root / folder / name, z, rgb)
        else:
            write_box_object(root / folder / name, box_object_xml(name, x, y, z), rgb)
    art = root / "articulated_objects"
    for sub, tex, rgb in (
        ("wooden_cabinet", "dark_fine_wood.png", (0.35, 0.22, 0.12)),
        ("flat_stove", "metal.png", (0.6, 0.6, 0.62)),
    ):
        (art / sub).mkdir(parents=True, exist_ok=True)
        (art / sub / tex).write_bytes(png(rgb))
    (art / "wooden_cabinet.xml").write_text(cabinet_xml())
    (art / "flat_stove.xml").write_text(STOVE)
