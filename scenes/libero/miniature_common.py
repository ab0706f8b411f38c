"""Shared pieces of the miniature LIBERO asset tree: arena and object XML skeletons, PNGs, file writers."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

GEOM = 'solimp="0.998 0.998 0.001" solref="0.001 1" density="100" friction="0.95 0.3 0.1"'
# The unit cube's 8 corners and its 12 triangles (1-based corner indices), as a Wavefront OBJ.
CUBE_OBJ = "".join(f"v {x} {y} {z}\n" for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)) + "".join(
    f"f {a} {b} {c}\n" for a, b, c in "134 142 568 587 126 165 378 384 157 173 248 286".split()
)
FLOOR = (
    '<geom condim="3" group="1" material="floorplane" name="floor" pos="0 0 0" size="3 3 .125" type="plane"/>'
)

# LIBERO's table arena; {assets}, {floor}, {table} and {cameras} are whole lines (an empty one is dropped).
_ARENA = """<mujoco model="table_arena">
  <asset>
    <texture builtin="gradient" height="64" rgb1=".9 .9 1." rgb2=".2 .3 .4" type="skybox" width="64"/>
    <texture file="../textures/tile_grigia_caldera_porcelain_floor.png" type="2d" name="texplane"/>
    <material name="floorplane" reflectance="0.0" shininess="0.0" specular="0.0" texrepeat="3 3" texture="texplane"
      texuniform="true"/>
    {assets}
    <texture file="../textures/smooth_light_gray_plaster.png" type="2d" name="tex-wall"/>
    <material name="walls_mat" reflectance="0.0" shininess="0.1" specular="0.8" texrepeat="3 3" texture="tex-wall"
      texuniform="true"/>
  </asset>
  <worldbody>
    {floor}
    <geom pos="1.25 3 1.5" quat="0.7071 0.7071 0 0" size="1.75 1.5 0.01" type="box" conaffinity="0" contype="0"
      group="1" name="wall_left_visual" material="walls_mat"/>
    <geom pos="1.25 -3 1.5" quat="0.7071 -0.7071 0 0" size="1.75 1.5 0.01" type="box" conaffinity="0" contype="0"
      group="1" name="wall_right_visual" material="walls_mat"/>
    <geom pos="-2 0 1.5" quat="0.5 0.5 0.5 0.5" size="1.5 1.5 0.01" type="box" conaffinity="0" contype="0" group="1"
      name="wall_rear_visual" material="walls_mat"/>
    {table}
    <light name="light1" diffuse=".8 .8 .8" dir="0 -.15 -1" directional="false" pos="1 1 4.0" specular="0.3 0.3 0.3"
      castshadow="false"/>
    <light name="light2" diffuse=".8 .8 .8" dir="0 -.15 -1" directional="false" pos="-3. -3. 4.0"
      specular="0.3 0.3 0.3" castshadow="false"/>
    <camera mode="fixed" name="frontview" pos="1.0 0 1.45" quat="0.56 0.43 0.43 0.56"/>
    <camera mode="fixed" name="birdview" pos="-0.2 0 3.0" quat="0.7071 0 0 0.7071"/>
    <camera mode="fixed" name="agentview" pos="0.5 0 1.35" quat="0.653 0.271 0.271 0.653"/>
    {cameras}
  </worldbody>
</mujoco>
"""

# A LIBERO object: its assets, the bodies under "object", and the bottom/top/horizontal-radius sites.
_OBJECT = """<mujoco model="{model}">
  <asset>
    {assets}
  </asset>
  <worldbody>
    <body>
      <body name="object">
        {body}
      </body>
      <site rgba="0 0 0 0" size="{s}" pos="0 0 -{b}" name="bottom_site"/>
      <site rgba="0 0 0 0" size="{s}" pos="0 0 {t}" name="top_site"/>
      <site rgba="0 0 0 0" size="{s}" pos="{r} {r} 0" name="horizontal_radius_site"/>
    </body>
  </worldbody>
</mujoco>
"""


def arena_xml(floor: str, assets: str = "", table: str = "", cameras: str = "") -> str:
    """LIBERO's table arena with the given floor and optional extra assets, table body and cameras."""
    text = _ARENA.format(assets=assets, floor=floor, table=table, cameras=cameras)
    return "".join(line + "\n" for line in text.splitlines() if line.strip())


def texture_asset(file: str, tex: str, material: str) -> str:
    """A 2D texture ``tex-<tex>`` from ``file`` and the material ``material`` that uses it."""
    return (
        f'<texture file="{file}" name="tex-{tex}" type="2d"/>\n    <material name="{material}" reflectance="0.5" '
        f'texrepeat="1 1" texture="tex-{tex}" texuniform="false"/>'
    )


def object_xml(
    model: str, assets: str, body: str, sites: tuple[float, float, float, float] = (0.005, 0.06, 0.04, 0.025)
) -> str:
    """An object file around ``assets`` and ``body``; ``sites``: (site size, bottom depth, top, radius)."""
    s, b, t, r = sites
    return _OBJECT.format(model=model, assets=assets, body=body, s=s, b=b, t=t, r=r)


def hope_object_xml(h: float) -> str:
    """A HOPE grocery item in LIBERO's layout: a textured box mesh over a cube collider of half-size ``h``."""
    return object_xml(
        "textured",
        texture_asset("texture_map.png", "textured", "textured")
        + f'\n    <mesh file="textured.obj" name="textured_vis" scale="{h} {h} {h}"/>',
        f'<geom {GEOM} type="mesh" mesh="textured_vis" conaffinity="0" contype="0" group="1" material="textured"/>\n'
        f'        <geom {GEOM} type="box" pos="0 0 0" size="{h} {h} {h}" group="0" rgba="0.8 0.8 0.8 0.3"/>',
        (0.005, h, h, h),
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


def write_hope_object(d: Path, h: float, rgb: tuple[float, float, float]) -> None:
    """Write a HOPE item's folder ``d``: ``<name>.xml``, its box mesh and its texture map."""
    d.mkdir(parents=True, exist_ok=True)
    (d / f"{d.name}.xml").write_text(hope_object_xml(h))
    (d / "textured.obj").write_text(CUBE_OBJ)
    (d / "texture_map.png").write_bytes(png(rgb))


def write_box_object(d: Path, xml: str, rgb: tuple[float, float, float]) -> None:
    """Write a scanned object's folder ``d``: ``<name>.xml`` and a solid ``texture.png``."""
    d.mkdir(parents=True, exist_ok=True)
    (d / f"{d.name}.xml").write_text(xml)
    (d / "texture.png").write_bytes(png(rgb))
