"""TurnOnElectricKettle: the placeholder kettle's power lever (tree version 8) is RoboCasa's lever, low on the kettle's
+x side and pressed down at its free end, and the oracle presses it there with its hand tipped toward the kettle."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from scenes.family import get_scene
from tests.scenes.robocasa.test_robocasa import _box, _oracle_episodes, needs_venv


@needs_venv
def test_the_lever_is_the_joint_robocasa_reads_low_on_the_side_and_pressed_down_at_its_end(placeholders):
    """RoboCasa's ``ElectricKettle`` (robocasa/models/fixtures/electric_kettle.py, robocasa/robocasa be22d659, as
    installed) reads ``f"{joint_prefix}switch_joint"`` and turns on once it reads >= 0.95, which is all
    ``TurnOnElectricKettle._check_success`` reads (``environments/kitchen/atomic/kitchen_electric_kettle.py``,
    "Press down the lever"). RoboCasa's own kettles (their models in robocasa/robocasa 0e206dd1, the last commit
    holding them, ``models/assets/fixtures/electric_kettles/ElectricKettle011/model.xml``: ``Lever001_joint``, a
    hinge about ``0 1 0`` at x 0.063, z -0.121 of a model 0.308 tall, range 0..0.26, its plate out to x 0.108;
    ElectricKettle003 slides its lever 12 mm down) carry it at the foot of the handle on their +x side, a plate
    sticking out near the counter, pressed down at its free end: the placeholder's lever is so, hinged at its inner
    end, in the slab the kettle's collider leaves free on that side, under nothing of the kettle's own collider."""
    from scenes.robocasa.environment import venv_dir

    site = next(venv_dir().glob("lib/python*/site-packages/robocasa"))
    fixture = (site / "models/fixtures/electric_kettle.py").read_text()
    assert '"switch": f"{joint_prefix}switch_joint"' in fixture
    assert "self._switch >= 0.95 and not self._turned_on" in fixture
    task = (site / "environments/kitchen/atomic/kitchen_electric_kettle.py").read_text()
    assert 'return self.electric_kettle.get_state(self)["turned_on"]' in task
    assert "Press down the lever" in task
    root = ET.parse(next((placeholders / "fixtures" / "electric_kettles").glob("*/model.xml"))).getroot()
    obj = next(b for b in root.iter("body") if b.get("name") == "object")
    lever = next(b for b in obj.findall("body") if b.get("name") == "switch")
    j = lever.find("joint")
    lo, hi = (float(v) for v in j.get("range").split())
    assert j.get("type") == "hinge" and (lo, hi) == (0.0, 0.26) and lever.find("geom").get("contype") != "0"
    c, h = _box(lever.find("geom"))
    c = c + np.array(lever.get("pos").split(), float)
    pivot = c + np.array(j.get("pos").split(), float)
    free_end = 2 * c - pivot
    assert free_end[0] > pivot[0] > 0  # on the +x side, its free end outward
    # turning it on (positive angle) takes the free end down: the axis crossed with the lever points down
    assert np.cross(np.array(j.get("axis").split(), float), free_end - pivot)[2] < 0
    (body,) = [g for g in obj.findall("geom") if g.get("name") == "body"]
    bc, bh = _box(body)
    bottom = bc[2] - bh[2]
    assert c[2] - bottom < 0.06  # low: RoboCasa's levers stand 3-4 cm over the kettle's bottom
    # turned on, the free end still clears the counter
    assert c[2] - h[2] - 2 * h[0] * np.sin(0.95 * hi) > bottom
    assert c[0] - h[0] > bc[0] + bh[0]  # beside the collider: nothing of it over or under the lever
    footprint = next(g for g in obj.findall("geom") if g.get("name") == "reg_main")
    assert c[0] + h[0] <= _box(footprint)[1][0]  # inside the footprint RoboCasa places the kettle by


def _raw(on: bool = False, eef=(0.3, 0.0, 1.2), press=(0.4, 0.0, 0.96), heading=np.pi) -> dict:
    """Worker facts of a TurnOnElectricKettle episode: the base at the origin facing +x, the lever's press point at
    ``press``, the lever heading ``heading`` (rad; pi: its free end toward the base), room 0.5 m each way."""
    return {
        "eef_pos": list(eef), "eef_mat": np.diag([1.0, -1.0, -1.0]), "gripper_qpos": [0.0, 0.0],
        "base_pos": [0.0, 0.0, 0.0], "base_yaw": 0.0, "fixture_pos": [0.5, 0.0, 1.0], "button_pos": list(press),
        "button_quat": [np.cos(heading / 2), 0.0, 0.0, np.sin(heading / 2)], "button_touched": on,
        "base_room": [0.5, 0.5, 0.5, 0.5], "success": False,
    }  # fmt: skip


def test_the_hand_leans_its_fingertips_toward_the_kettle_its_long_side_along_it():
    """By hand: the lever pointing back at the base (heading pi), the hand tipped 0.5 rad is the press's hand tipped
    forward 0.5 rad (fingertips toward +x, the kettle; fingers' axis along y); pointing to the base's right (heading
    -pi/2), the fingertips lean left (toward the kettle), the fingers' axis along x (along the kettle's side)."""
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import RoboCasaOracle
    from scenes.robocasa.oracle_lever import lever_hand

    s = privileged_state(_raw())
    assert s.facts.lever and s.facts.button
    hand = lever_hand(s, 0.5)
    np.testing.assert_allclose(hand, RoboCasaOracle()._hand(s, 0.5), atol=1e-12)
    np.testing.assert_allclose(hand[:, 2], [np.sin(0.5), 0.0, -np.cos(0.5)], atol=1e-12)  # the approach axis
    right = lever_hand(privileged_state(_raw(heading=-np.pi / 2)), 0.5)
    np.testing.assert_allclose(right[:, 2], [0.0, np.sin(0.5), -np.cos(0.5)], atol=1e-12)
    np.testing.assert_allclose(np.abs(right[:, 0]), [1.0, 0.0, 0.0], atol=1e-12)


def test_the_oracle_drives_comes_in_beside_the_lever_presses_it_and_tips_further_when_stalled():
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import RoboCasaOracle
    from scenes.robocasa.oracle_lever import ABOVE, IN, LEVER_TILT

    o = RoboCasaOracle()
    a = o.action(privileged_state(_raw(press=(0.45, -0.2, 0.96))))
    assert o.phase == "drive" and a[8] < -0.25 and a[11] == 1.0  # 0.2 m to the right: the base drives right
    o = RoboCasaOracle()
    a = o.action(privileged_state(_raw()))
    assert o.phase == "approach" and a[11] == -1.0  # 0.40 m straight ahead already: no drive
    # in from up and back (the lever points at the base): along the hand's axis, IN from the press point
    way_in = np.array([0.4 - IN * np.sin(LEVER_TILT), 0.0, 0.96 + IN * np.cos(LEVER_TILT)])
    assert a[0] > 0 and a[2] < 0  # from (0.3, 0, 1.2) toward (0.33, 0, 1.09): ahead and down
    o.action(privileged_state(_raw(eef=tuple(way_in))))
    assert o.phase == "descend"
    over = np.array([0.4 - ABOVE * np.sin(LEVER_TILT), 0.0, 0.96 + ABOVE * np.cos(LEVER_TILT)])
    o.action(privileged_state(_raw(eef=tuple(over))))
    assert o.phase == "press"
    a = o.action(privileged_state(_raw(eef=(0.4, 0.0, 0.965))))
    assert a[2] < 0 and o.phase == "press"  # straight down onto it
    for _ in range(21):  # stalled 0.5 cm over it (the forearm on the kettle): tipped 0.2 rad more, in again
        o.action(privileged_state(_raw(eef=(0.4, 0.0, 0.965))))
    assert o.phase == "descend" and o._tilt == pytest.approx(LEVER_TILT + 0.2)
    o._next("press")
    o.action(privileged_state(_raw(on=True, eef=(0.4, 0.0, 0.955))))
    assert o.phase == "lift_off"  # RoboCasa reads the kettle on: back out the way it came


def test_certify_scripts_turning_the_kettle_on():
    from scenes.oracles import oracle_scripts

    assert oracle_scripts(get_scene("robocasa"), "TurnOnElectricKettle")


@needs_venv
@pytest.mark.slow  # ~30 s: a cold worker and a ~60-step episode; the default tests above keep the lever and the script
def test_the_oracle_turns_the_kettle_on(placeholders):
    assert _oracle_episodes("TurnOnElectricKettle", "fixture_x", 0, (0,), None) == [True]
