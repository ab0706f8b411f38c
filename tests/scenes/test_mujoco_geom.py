"""``scenes.mujoco_geom`` on a two-body MJCF model: collision geoms, world boxes, contacts, the grasp height."""

from __future__ import annotations

import numpy as np
import pytest

from scenes import mujoco_geom as geom

mujoco = pytest.importorskip("mujoco")

XML = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="box" pos="0.1 0.2 0.05">
      <freejoint/>
      <geom name="box_col" type="box" size="0.02 0.03 0.05"/>
      <geom name="box_vis" type="sphere" size="0.2" contype="0" conaffinity="0"/>
      <body name="handle" pos="0 0 0.05">
        <geom name="handle_col" type="box" size="0.01 0.01 0.01"/>
      </body>
    </body>
    <body name="far" pos="0.5 0 0.3">
      <freejoint/>
      <geom name="far_col" type="box" size="0.01 0.01 0.01"/>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def sim():
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return m, d


def test_body_geoms_and_world_aabb(sim):
    m, d = sim
    box = m.body("box").id
    geoms = geom.body_geoms(m, box)
    # the child body's geom belongs to the tree; the non-colliding visual sphere does not
    assert list(geoms) == [m.geom("box_col").id, m.geom("handle_col").id]
    lo, hi = geom.world_aabb(m, d, geoms)
    np.testing.assert_allclose(lo, [0.08, 0.17, 0.0], atol=1e-12)
    np.testing.assert_allclose(hi, [0.12, 0.23, 0.11], atol=1e-12)
    assert geom.geom_corners(m, d, geoms).shape == (16, 3)


def test_touching_reads_the_current_contacts(sim):
    m, d = sim
    floor = geom.geom_mask(m, geom.named_geoms(m, ["floor"]))
    box = geom.geom_mask(m, geom.body_geoms(m, m.body("box").id))
    far = geom.geom_mask(m, geom.named_geoms(m, ["far_col"]))
    assert d.ncon > 0  # the box rests on the floor
    assert geom.touching(d, floor, box) and geom.touching(d, box, floor)
    assert not geom.touching(d, floor, far) and not geom.touching(d, box, far)


def test_grasp_height_keeps_the_hand_clear():
    assert geom.grasp_height(0.0, 0.1, 0.5) == pytest.approx(0.08)  # top - 0.02 wins over the middle
    assert geom.grasp_height(0.0, 0.03, 0.5) == pytest.approx(0.015)  # a short object: at its middle
    assert geom.grasp_height(0.0, 0.03, 0.9) == pytest.approx(0.018)  # the hand stays 1.2 cm above its top
    assert geom.grasp_height(0.0, 0.015, 0.5) == pytest.approx(0.01)  # never below bottom + 1 cm
