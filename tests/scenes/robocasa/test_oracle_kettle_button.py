"""OpenElectricKettleLid: the placeholder kettle's lid button (tree version 6) collides and springs back, and the
oracle presses it down from above (the blender's press) until RoboCasa counts the press, then leaves it."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from scenes.family import get_scene
from tests.scenes.robocasa.test_robocasa import _box, _oracle_episodes, needs_venv


@needs_venv
def test_the_lid_button_is_the_joint_robocasa_reads_and_a_push_down_presses_it(placeholders):
    """RoboCasa's ``ElectricKettle`` (robocasa/models/fixtures/electric_kettle.py, robocasa/robocasa be22d659, as
    installed) reads ``f"{joint_prefix}button_lid_joint"`` and opens the shut lid once it reads > 0.1; for a range
    below 0 ``Fixture.get_joint_state`` reads ``1 - (q - lo) / (hi - lo)``: 0 at the top stop, 1 pushed 1 cm down.
    The button collides (version 5's did not), stands beside the lid on the top, higher than the lid by more than
    the 1 mm that counts, over nothing of the kettle's own collider even pushed down, and its spring holds it at its top stop against its weight and frictionloss."""
    from scenes.robocasa.environment import venv_dir

    (src,) = venv_dir().glob("lib/python*/site-packages/robocasa/models/fixtures/electric_kettle.py")
    text = src.read_text()
    assert '"lid_button": f"{joint_prefix}button_lid_joint"' in text
    assert "self._lid_button > 0.1 and self._lid <= 0.01" in text
    root = ET.parse(next((placeholders / "fixtures" / "electric_kettles").glob("*/model.xml"))).getroot()
    obj = next(b for b in root.iter("body") if b.get("name") == "object")
    parts = {b.get("name"): b for b in obj.findall("body")}
    button, lid = parts["button_lid"], parts["lid"]
    j = button.find("joint")
    lo, hi = (float(v) for v in j.get("range").split())
    assert j.get("type") == "slide" and j.get("axis") == "0 0 1" and (lo, hi) == (-0.01, 0.0)
    geom = button.find("geom")
    assert geom.get("contype") != "0"
    c, h = _box(geom)
    c = c + np.array(button.get("pos").split(), float)
    lc, lh = _box(lid.find("geom"))
    lc = lc + np.array(lid.get("pos").split(), float)
    assert c[0] - h[0] > lc[0] + lh[0]  # beside the lid, not under or over it
    assert c[2] + h[2] - (lc[2] + lh[2]) > 0.1 * (hi - lo)  # a finger on both counts the press before the lid
    colliders = [_box(g) for g in obj.findall("geom") if g.get("contype") != "0" and g.get("type") == "box"]
    pushed_bottom = c[2] - h[2] + lo
    assert all(
        pushed_bottom > bc[2] + bh[2] or np.any(np.abs(c[:2] - bc[:2]) >= h[:2] + bh[:2])
        for bc, bh in colliders
    )
    spring = float(j.get("stiffness")) * (float(j.get("springref")) - hi)  # N up at the top stop
    weight = 200 * 8 * np.prod(h) * 9.81  # the part's density 200
    assert spring > weight + float(j.get("frictionloss"))


def _raw(pressed: bool = False, eef=(0.3, 0.0, 1.3), button=(0.4, 0.0, 1.12)) -> dict:
    """Worker facts of an OpenElectricKettleLid episode: the base at the origin facing +x, the button's top at
    ``button``, the base free to drive 0.5 m each way."""
    return {
        "eef_pos": list(eef), "eef_mat": np.diag([1.0, -1.0, -1.0]), "gripper_qpos": [0.0, 0.0],
        "base_pos": [0.0, 0.0, 0.0], "base_yaw": 0.0, "fixture_pos": [0.45, 0.0, 1.0], "button_pos": list(button),
        "button_touched": pressed, "base_room": [0.5, 0.5, 0.5, 0.5], "success": False,
    }  # fmt: skip


def test_the_oracle_drives_to_the_button_presses_it_and_leaves_it_once_counted():
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import RoboCasaOracle

    s = privileged_state(_raw())
    assert s.facts.button and s.facts.base_room == (0.5, 0.5, 0.5, 0.5)
    o = RoboCasaOracle()
    a = o.action(s)
    assert o.phase == "approach" and a[11] == -1.0  # straight ahead already: no drive
    o = RoboCasaOracle()
    a = o.action(privileged_state(_raw(button=(0.4, -0.2, 1.12))))
    assert o.phase == "drive" and a[8] < -0.25 and a[11] == 1.0  # 0.2 m to the right: the base drives right
    o = RoboCasaOracle()
    o.action(s)
    o._next("press")
    a = o.action(privileged_state(_raw(eef=(0.4, 0.0, 1.13))))
    assert a[2] < 0 and o.phase == "press"  # down onto it
    o.action(privileged_state(_raw(pressed=True, eef=(0.4, 0.0, 1.115))))
    assert o.phase == "lift_off"  # RoboCasa counted the press: up, the lid opens by itself


def test_certify_scripts_opening_the_kettle_lid():
    from scenes.oracles import oracle_scripts

    assert oracle_scripts(get_scene("robocasa"), "OpenElectricKettleLid")


@needs_venv
@pytest.mark.slow  # 8 s: a cold worker and a ~40-step episode; the default tests above keep the script's steps
def test_the_oracle_opens_the_kettle_lid(placeholders):
    assert _oracle_episodes("OpenElectricKettleLid", "fixture_x", 0, (0,), None) == [True]
