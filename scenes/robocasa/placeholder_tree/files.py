"""The tree's files besides fixtures: one box object model, flat one-colour PNG textures, a one-box mesh, and the
``Writer`` that writes each placeholder once, never over the wheel's own files."""

from __future__ import annotations

import hashlib
import os
import struct
import zlib
from pathlib import Path

from .model import fmt

OBJECT_HALF = (0.03, 0.03, 0.04)  # m: a category's box ({cat}_ph), half sides before RoboCasa's scale
ACCESSORY_HALF = (0.04, 0.04, 0.06)  # m: a model the fixture registry names under objects/ (a glass cup)
# m: the widest a graspable category's box may be once RoboCasa scales it: fully open, the Panda's finger meshes stand
# 7.7 cm apart (robosuite's panda_gripper.xml), and a box at its category's scale (up to 2.5) reached 9.6-15 cm
# across, which no grasp closes on (a third of the pick-place tasks' evaluation episodes under the pretrain split,
# whose first instances are the registry's 8 cm models); RoboCasa's graspable models fit the hand
GRASPABLE_WIDTH = 0.07


def object_half(cfg: dict | None, registry: str, half=OBJECT_HALF) -> tuple[float, float, float]:
    """The half sides of a box of a category in one registry (``cfg``: RoboCasa's raw category entry, None for no
    category): ``half``, shrunk alike on all three sides where the category is graspable and its scale would make
    it wider than ``GRASPABLE_WIDTH``."""
    if not cfg or registry not in cfg or not cfg.get("graspable"):
        return tuple(half)  # type: ignore[return-value]
    scale = cfg[registry].get("scale", 1.0)
    across = max(scale[:2]) if isinstance(scale, (list, tuple)) else float(scale)
    wide = 2 * max(half[:2]) * across
    k = GRASPABLE_WIDTH / wide if wide > GRASPABLE_WIDTH else 1.0
    return tuple(round(h * k, 5) for h in half)  # type: ignore[return-value]


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
