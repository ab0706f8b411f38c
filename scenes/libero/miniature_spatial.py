"""The LIBERO-Spatial part of the miniature asset tree: tabletop arena, bowls, plate, ramekin, cookie box and the
articulated wooden cabinet and flat stove, with LIBERO's file names, body/joint/site names and fixture dimensions.

The cabinet keeps LIBERO's three sliding drawers (joints ``top_level``/``middle_level``/``bottom_level`` and
sites ``top_region``/``middle_region``/``bottom_region``/``top_side``) and the stove its knob hinge (``button``)
and ``cook_region``/``burner`` sites, so the model has LIBERO's qpos layout and its fixed initial states load.
"""

from __future__ import annotations

from pathlib import Path

from scenes.libero.miniature import _GEOM, CUBE_OBJ, OBJECT, png

# category -> (folder under the asset root, box half-sizes (x, y, z) about the object's origin, RGB)
SPATIAL_OBJECTS = {
    "akita_black_bowl": ("stable_scanned_objects", (0.03, 0.03, 0.02), (0.08, 0.08, 0.08)),
    "plate": ("stable_scanned_objects", (0.06, 0.06, 0.006), (0.92, 0.92, 0.9)),
    "glazed_rim_porcelain_ramekin": ("stable_scanned_objects", (0.035, 0.035, 0.025), (0.9, 0.88, 0.8)),
    "cookies": ("stable_hope_objects", (0.03, 0.03, 0.03), (0.7, 0.45, 0.2)),
}

TABLETOP = """<mujoco model="table_arena">
  <asset>
    <texture builtin="gradient" height="64" rgb1=".9 .9 1." rgb2=".2 .3 .4" type="skybox" width="64"/>
    <texture file="../textures/tile_grigia_caldera_porcelain_floor.png" type="2d" name="texplane"/>
    <material name="floorplane" reflectance="0.0" shininess="0.0" specular="0.0" texrepeat="3 3" texture="texplane"
      texuniform="true"/>
    <texture file="../textures/martin_novak_wood_table.png" type="cube" name="tex-table"/>
    <material name="table_texture" reflectance="0.0" shininess="0.0" specular="0.2" texrepeat="1 1" texture="tex-table"/>
    <texture file="../textures/martin_novak_wood_table.png" type="cube" name="tex-table-legs"/>
    <material name="table_legs" reflectance="0.8" shininess="0.8" texrepeat="1 1" texture="tex-table-legs"/>
    <texture file="../textures/smooth_light_gray_plaster.png" type="2d" name="tex-wall"/>
    <material name="walls_mat" reflectance="0.0" shininess="0.1" specular="0.8" texrepeat="3 3" texture="tex-wall"
      texuniform="true"/>
  </asset>
  <worldbody>
    <geom condim="3" group="1" material="floorplane" name="floor" pos="0 0 0" size="3 3 .125" type="plane"/>
    <geom pos="1.25 3 1.5" quat="0.7071 0.7071 0 0" size="1.75 1.5 0.01" type="box" conaffinity="0" contype="0"
      group="1" name="wall_left_visual" material="walls_mat"/>
    <geom pos="1.25 -3 1.5" quat="0.7071 -0.7071 0 0" size="1.75 1.5 0.01" type="box" conaffinity="0" contype="0"
      group="1" name="wall_right_visual" material="walls_mat"/>
    <geom pos="-2 0 1.5" quat="0.5 0.5 0.5 0.5" size="1.5 1.5 0.01" type="box" conaffinity="0" contype="0" group="1"
      name="wall_rear_visual" material="walls_mat"/>
    <body name="table" pos="0 0 0.4">
      <geom pos="0 0 0" size="0.4 0.4 0.4" type="box" group="0" name="table_collision" friction="1 0.005 0.0001"/>
      <geom pos="0 0 0" size="0.4 0.4 0.4" type="box" conaffinity="0" contype="0" group="1" name="table_visual"
        material="table_texture"/>
      <site pos="0 0 0.4" name="table_top" size="0.001 0.001 0.001" rgba="0 0 0 0"/>
      <geom pos="0 0 0" size="0.05 0.1" type="cylinder" conaffinity="0" contype="0" group="1" name="table_leg1_visual"
        material="table_legs"/>
      <geom pos="0 0 0" size="0.05 0.1" type="cylinder" conaffinity="0" contype="0" group="1" name="table_leg2_visual"
        material="table_legs"/>
      <geom pos="0 0 0" size="0.05 0.1" type="cylinder" conaffinity="0" contype="0" group="1" name="table_leg3_visual"
        material="table_legs"/>
      <geom pos="0 0 0" size="0.05 0.1" type="cylinder" conaffinity="0" contype="0" group="1" name="table_leg4_visual"
        material="table_legs"/>
    </body>
    <light name="light1" diffuse=".8 .8 .8" dir="0 -.15 -1" directional="false" pos="1 1 4.0" specular="0.3 0.3 0.3"
      castshadow="false"/>
    <light name="light2" diffuse=".8 .8 .8" dir="0 -.15 -1" directional="false" pos="-3. -3. 4.0"
      specular="0.3 0.3 0.3" castshadow="false"/>
    <camera mode="fixed" name="frontview" pos="1.0 0 1.45" quat="0.56 0.43 0.43 0.56"/>
    <camera mode="fixed" name="birdview" pos="-0.2 0 3.0" quat="0.7071 0 0 0.7071"/>
    <camera mode="fixed" name="agentview" pos="0.5 0 1.35" quat="0.653 0.271 0.271 0.653"/>
    <camera mode="fixed" name="sideview" pos="-0.0565 1.2761 1.4880" quat="0.0099 0.0069 0.5912 0.8064"/>
  </worldbody>
</mujoco>
"""

BOX_OBJECT = """<mujoco model="{name}">
  <asset>
    <texture file="texture.png" name="tex-{name}" type="2d"/>
    <material name="{name}" reflectance="0.5" texrepeat="1 1" texture="tex-{name}" texuniform="false"/>
  </asset>
  <worldbody>
    <body>
      <body name="object">
        <geom {g} type="box" pos="0 0 0" size="{x} {y} {z}" group="0" material="{name}"/>
      </body>
      <site rgba="0 0 0 0" size="0.005" pos="0 0 -0.06" name="bottom_site"/>
      <site rgba="0 0 0 0" size="0.005" pos="0 0 0.04" name="top_site"/>
      <site rgba="0 0 0 0" size="0.005" pos="0.025 0.025 0" name="horizontal_radius_site"/>
    </body>
  </worldbody>
</mujoco>
"""

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

CABINET = """<mujoco model="wooden_cabinet">
  <asset>
    <texture file="wooden_cabinet/dark_fine_wood.png" name="tex-wooden_cabinet" type="2d"/>
    <material name="wooden_cabinet" reflectance="0.5" texrepeat="1 1" texture="tex-wooden_cabinet" texuniform="false"/>
  </asset>
  <worldbody>
    <body>
      <body name="object">
        <body name="base" pos="0 0 0">
          <site type="box" pos="0.00354 0.01567 0.22152" quat="1 0 0 0" size="0.12534 0.09438 0.00147" group="0"
            rgba="0.8 0.8 0 0" name="top_side"/>
          {shell}
          {drawers}
        </body>
      </body>
      <site rgba="0 0 0 0" size="0.05" pos="0 0 -0.045" name="bottom_site"/>
      <site rgba="0 0 0 0" size="0.05" pos="0 0 0.045" name="top_site"/>
      <site rgba="0 0 0 0" size="0.05" pos="0.045 0.045 0" name="horizontal_radius_site"/>
    </body>
  </worldbody>
</mujoco>
"""

DRAWER = """<body name="cabinet_{level}" pos="0 0 0">
            <inertial pos="0 0 0" mass="3" diaginertia="1 1 1"/>
            <joint name="{level}_level" type="slide" pos="0 0 0" axis="0 1 0" limited="true" range="-0.16 0.01"
              damping="50"/>
            <site type="box" pos="0.00328 0.01128 {site}" quat="0.70711 0 0.70711 0" size="0.02993 0.07561 0.10224"
              group="0" rgba="0.8 0.8 0.8 0" name="{level}_region"/>
            {walls}
          </body>"""

STOVE = """<mujoco model="flat_stove">
  <asset>
    <texture file="flat_stove/metal.png" name="tex-stove_metal" type="2d"/>
    <material name="stove_knob_metal" reflectance="0.5" texrepeat="1 1" texture="tex-stove_metal" texuniform="false"/>
  </asset>
  <worldbody>
    <body>
      <body name="object">
        <body name="base" pos="0 0 0">
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
            <geom {g} type="box" pos="0.0013 0.0046 0.0066" size="0.034 0.034 0.0062" group="0" rgba="0.1 0.1 0.1 1"/>
          </body>
        </body>
      </body>
      <site rgba="0 0 0 0" size="0.05" pos="0 0 -0.045" name="bottom_site"/>
      <site rgba="0 0 0 0" size="0.05" pos="0 0 0.045" name="top_site"/>
      <site rgba="0 0 0 0" size="0.05" pos="0.045 0.045 0" name="horizontal_radius_site"/>
    </body>
  </worldbody>
</mujoco>
"""


def cabinet_xml() -> str:
    """LIBERO's wooden cabinet as boxes: the shell, three sliding drawers with their joints and region sites."""
    shell = "\n          ".join(_BOX.format(g=_GEOM, p=p, s=s, m="wooden_cabinet") for p, s in _SHELL)
    drawers = []
    for level, floor, wall, site in _LEVELS:
        walls = "\n            ".join(
            _BOX.format(g=_GEOM, p=p.format(f=floor, w=wall), s=s, m="wooden_cabinet") for p, s in _DRAWER
        )
        drawers.append(DRAWER.format(level=level, site=site, walls=walls))
    return CABINET.format(shell=shell, drawers="\n          ".join(drawers))


def write_spatial_assets(root: Path) -> None:
    """Write the LIBERO-Spatial files under the miniature tree ``root`` (idempotent)."""
    (root / "scenes" / "libero_tabletop_base_style.xml").write_text(TABLETOP)
    for name, (folder, (x, y, z), rgb) in SPATIAL_OBJECTS.items():
        d = root / folder / name
        d.mkdir(parents=True, exist_ok=True)
        if folder == "stable_hope_objects":  # HOPE objects keep LIBERO-Object's textured-mesh layout
            (d / f"{name}.xml").write_text(OBJECT.format(g=_GEOM, h=z))
            (d / "textured.obj").write_text(CUBE_OBJ)
            (d / "texture_map.png").write_bytes(png(rgb))
        else:
            (d / f"{name}.xml").write_text(BOX_OBJECT.format(name=name, g=_GEOM, x=x, y=y, z=z))
            (d / "texture.png").write_bytes(png(rgb))
    art = root / "articulated_objects"
    for sub, tex, rgb in (
        ("wooden_cabinet", "dark_fine_wood.png", (0.35, 0.22, 0.12)),
        ("flat_stove", "metal.png", (0.6, 0.6, 0.62)),
    ):
        (art / sub).mkdir(parents=True, exist_ok=True)
        (art / sub / tex).write_bytes(png(rgb))
    (art / "wooden_cabinet.xml").write_text(cabinet_xml())
    (art / "flat_stove.xml").write_text(STOVE.format(g=_GEOM))
