"""A miniature LIBERO asset tree: LIBERO's file names and layout with plain boxes, for LIBERO-Object and -Spatial.

Used by the tests (and for smoke-testing a machine without the Hub download): every LIBERO-Object and
LIBERO-Spatial task builds, steps, renders and loads its fixed initial states on it. Objects are 4 cm cubes
(any of LIBERO's quarter-turn placements leaves them upright) with a small box mesh as the visual; the basket keeps
LIBERO's wall layout; Spatial's fixtures are in ``miniature_spatial``.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

HOPE_OBJECTS = {  # LIBERO-Object's grocery items -> an RGB for their miniature
    "alphabet_soup": (0.85, 0.2, 0.15),
    "bbq_sauce": (0.45, 0.2, 0.1),
    "butter": (0.95, 0.85, 0.3),
    "chocolate_pudding": (0.4, 0.25, 0.15),
    "cream_cheese": (0.85, 0.9, 0.95),
    "ketchup": (0.8, 0.1, 0.1),
    "milk": (0.95, 0.95, 0.95),
    "orange_juice": (1.0, 0.6, 0.1),
    "salad_dressing": (0.5, 0.7, 0.3),
    "tomato_sauce": (0.75, 0.15, 0.2),
}
CUBE_HALF = 0.02
_GEOM = 'solimp="0.998 0.998 0.001" solref="0.001 1" density="100" friction="0.95 0.3 0.1"'
TEXTURES = (
    "light-gray-floor-tile.png",
    "light-gray-plaster.png",
    "tile_grigia_caldera_porcelain_floor.png",
    "smooth_light_gray_plaster.png",
    "martin_novak_wood_table.png",
)

ARENA = """<mujoco model="table_arena">
  <asset>
    <texture builtin="gradient" height="64" rgb1=".9 .9 1." rgb2=".2 .3 .4" type="skybox" width="64"/>
    <texture file="../textures/tile_grigia_caldera_porcelain_floor.png" type="2d" name="texplane"/>
    <material name="floorplane" reflectance="0.0" shininess="0.0" specular="0.0" texrepeat="3 3" texture="texplane"
      texuniform="true"/>
    <texture file="../textures/smooth_light_gray_plaster.png" type="2d" name="tex-wall"/>
    <material name="walls_mat" reflectance="0.0" shininess="0.1" specular="0.8" texrepeat="3 3" texture="tex-wall"
      texuniform="true"/>
  </asset>
  <worldbody>
    <body name="floor" pos="0 0 0">
      <geom condim="3" group="1" material="floorplane" name="floor" pos="0 0 0" size="3 3 .125" type="plane"/>
    </body>
    <geom pos="1.25 3 1.5" quat="0.7071 0.7071 0 0" size="1.75 1.5 0.01" type="box" conaffinity="0" contype="0"
      group="1" name="wall_left_visual" material="walls_mat"/>
    <geom pos="1.25 -3 1.5" quat="0.7071 -0.7071 0 0" size="1.75 1.5 0.01" type="box" conaffinity="0" contype="0"
      group="1" name="wall_right_visual" material="walls_mat"/>
    <geom pos="-2 0 1.5" quat="0.5 0.5 0.5 0.5" size="1.5 1.5 0.01" type="box" conaffinity="0" contype="0" group="1"
      name="wall_rear_visual" material="walls_mat"/>
    <light name="light1" diffuse=".8 .8 .8" dir="0 -.15 -1" directional="false" pos="1 1 4.0" specular="0.3 0.3 0.3"
      castshadow="false"/>
    <light name="light2" diffuse=".8 .8 .8" dir="0 -.15 -1" directional="false" pos="-3. -3. 4.0"
      specular="0.3 0.3 0.3" castshadow="false"/>
    <camera mode="fixed" name="frontview" pos="1.0 0 1.45" quat="0.56 0.43 0.43 0.56"/>
    <camera mode="fixed" name="birdview" pos="-0.2 0 3.0" quat="0.7071 0 0 0.7071"/>
    <camera mode="fixed" name="agentview" pos="0.5 0 1.35" quat="0.653 0.271 0.271 0.653"/>
  </worldbody>
</mujoco>
"""

OBJECT = """<mujoco model="textured">
  <asset>
    <texture file="texture_map.png" name="tex-textured" type="2d"/>
    <material name="textured" reflectance="0.5" texrepeat="1 1" texture="tex-textured" texuniform="false"/>
    <mesh file="textured.obj" name="textured_vis" scale="{h} {h} {h}"/>
  </asset>
  <worldbody>
    <body>
      <body name="object">
        <geom {g} type="mesh" mesh="textured_vis" conaffinity="0" contype="0" group="1" material="textured"/>
        <geom {g} type="box" pos="0 0 0" size="{h} {h} {h}" group="0" rgba="0.8 0.8 0.8 0.3"/>
      </body>
      <site rgba="0 0 0 0" size="0.005" pos="0 0 -{h}" name="bottom_site"/>
      <site rgba="0 0 0 0" size="0.005" pos="0 0 {h}" name="top_site"/>
      <site rgba="0 0 0 0" size="0.005" pos="{h} {h} 0" name="horizontal_radius_site"/>
    </body>
  </worldbody>
</mujoco>
"""

BASKET = """<mujoco model="basket">
  <asset>
    <texture file="texture.png" name="tex-basket" type="2d"/>
    <material name="basket" reflectance="0.5" texrepeat="1 1" texture="tex-basket" texuniform="false"/>
  </asset>
  <worldbody>
    <body>
      <body name="object">
        <site type="box" pos="0 0 0.07185" quat="1 0 0 0" size="0.06108 0.06108 0.06949" group="0" rgba="0.8 0 0 0"
          name="contain_region"/>
        <geom {g} type="box" pos="0 0 0.0045" size="0.0765 0.0724 0.0045" group="0" material="basket"/>
        <geom {g} type="box" pos="-0.0727 0 0.0766" size="0.0067 0.0724 0.0640" group="0" material="basket"/>
        <geom {g} type="box" pos="0.0756 0 0.0766" size="0.0067 0.0724 0.0640" group="0" material="basket"/>
        <geom {g} type="box" pos="0 -0.0686 0.0766" size="0.0765 0.0067 0.0640" group="0" material="basket"/>
        <geom {g} type="box" pos="0 0.0691 0.0766" size="0.0765 0.0067 0.0640" group="0" material="basket"/>
      </body>
      <site rgba="0 0 0 0" size="0.005" pos="0 0 -0.06" name="bottom_site"/>
      <site rgba="0 0 0 0" size="0.005" pos="0 0 0.04" name="top_site"/>
      <site rgba="0 0 0 0" size="0.005" pos="0.025 0.025 0" name="horizontal_radius_site"/>
    </body>
  </worldbody>
</mujoco>
"""

CUBE_OBJ = "".join(f"v {x} {y} {z}\n" for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)) + "".join(
    f"f {a} {b} {c}\n"
    for a, b, c in (
        (1, 3, 4),
        (1, 4, 2),
        (5, 6, 8),
        (5, 8, 7),
        (1, 2, 6),
        (1, 6, 5),
        (3, 7, 8),
        (3, 8, 4),
        (1, 5, 7),
        (1, 7, 3),
        (2, 4, 8),
        (2, 8, 6),
    )
)


def png(rgb: tuple[float, float, float], size: int = 8) -> bytes:
    """A tiny solid-colour RGB PNG (no imaging library needed)."""
    px = bytes(int(255 * c) for c in rgb)
    raw = b"".join(b"\x00" + px * size for _ in range(size))

    def chunk(tag: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)
        )

    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", struct.pack(">IIBBBBB", size, size, 8, 2, 0, 0, 0))
        + chunk(b"IDAT", zlib.compress(raw))
        + chunk(b"IEND", b"")
    )


def write_miniature_assets(root: str | Path) -> Path:
    """Write the miniature tree under ``root`` (idempotent) and return it; use it as $INDGEN_LIBERO_ASSETS."""
    root = Path(root)
    for sub in (
        "scenes",
        "textures",
        "stable_hope_objects",
        "stable_scanned_objects/basket",
        "turbosquid_objects",
        "articulated_objects",
    ):
        (root / sub).mkdir(parents=True, exist_ok=True)
    (root / "scenes" / "libero_floor_base_style.xml").write_text(ARENA)
    for i, name in enumerate(TEXTURES):
        (root / "textures" / name).write_bytes(png((0.55 + 0.08 * i, 0.55 + 0.05 * i, 0.55)))
    for name, rgb in HOPE_OBJECTS.items():
        d = root / "stable_hope_objects" / name
        d.mkdir(exist_ok=True)
        (d / f"{name}.xml").write_text(OBJECT.format(g=_GEOM, h=CUBE_HALF))
        (d / "textured.obj").write_text(CUBE_OBJ)
        (d / "texture_map.png").write_bytes(png(rgb))
    basket = root / "stable_scanned_objects" / "basket"
    (basket / "basket.xml").write_text(BASKET.format(g=_GEOM))
    (basket / "texture.png").write_bytes(png((0.6, 0.45, 0.25)))
    from scenes.libero.miniature_spatial import write_spatial_assets

    write_spatial_assets(root)
    return root
