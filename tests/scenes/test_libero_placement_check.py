"""LIBERO's placement check on a two-box MuJoCo scene whose overlap is known by construction (no LIBERO needed)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from indgen_vla.core.errors import EpisodeUnavailableError
from scenes.libero import placement_check as placement

XML = """<mujoco><worldbody>
  <body name="a" pos="0 0 0.5"><freejoint/><geom name="a" type="box" size="0.05 0.05 0.05"/></body>
  <body name="b" pos="{bx} 0 0.5"><freejoint/><geom name="b" type="box" size="0.05 0.05 0.05"/></body>
</worldbody></mujoco>"""


def _scene(gap: float):
    """Two 10 cm cubes side by side in x; ``gap`` < 0 puts them that far inside each other."""
    m = mujoco.MjModel.from_xml_string(XML.format(bx=0.1 + gap))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    body = placement.body("a", {"a": 0, "b": 0}, lambda n: m.body(n).id, lambda n: np.array([m.geom(n).id]))
    return m, d, body


def test_overlap_is_the_contact_depth_with_the_neighbours_name():
    _, d, a = _scene(-0.008)
    depth, who = placement.overlap(d, a)
    assert who == "b" and depth == pytest.approx(0.008, abs=1e-6)
    _, d, a = _scene(0.01)  # 1 cm apart: no contact
    assert placement.overlap(d, a) == (0.0, "")


def test_verdict_refuses_an_overlap_over_5_mm_or_a_move_over_1_cm():
    assert placement.verdict(0.004, "b", 0.009, "a") is None
    assert "8.0 mm inside the b (over 5 mm)" in placement.verdict(0.008, "b", 0.0, "a")
    assert "moved the a 2.5 cm (over 1 cm): it was thrown" in placement.verdict(0.002, "b", 0.025, "a")


def test_check_reads_the_move_from_the_level_pose_and_says_where():
    """A 2 mm overlap passes until the settle leaves the box 3 cm from its pose; the line names the state."""
    m, d, a = _scene(-0.002)
    state = np.zeros(1 + m.nq + m.nv)
    state[1 : 1 + m.nq] = d.qpos
    overlaps = [placement.overlap(d, a)]
    placement.check([a], {"a": 0}, d, state, overlaps, "here")  # at its pose: holds
    d.qpos[0] += 0.03  # as if the settle had pushed it 3 cm
    mujoco.mj_forward(m, d)
    with pytest.raises(
        EpisodeUnavailableError, match=r"^here: the settling steps moved the a 3\.0 cm .*\(placement check\)$"
    ):
        placement.check([a], {"a": 0}, d, state, overlaps, "here")
