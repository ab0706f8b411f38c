"""OpenStandMixerHead: the placeholder head (tree version 6) overhangs the mixer's front, so a finger can get under
it, and the oracle lifts it there along its arc (``oracle_lift.open_hinge``) until RoboCasa reads it open."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from scenes.family import get_scene
from tests.scenes.robocasa.test_robocasa import _box, _oracle_episodes, needs_venv


@needs_venv
def test_the_mixer_head_is_the_joint_robocasa_reads_and_overhangs_the_front(placeholders):
    """RoboCasa's ``StandMixer`` (robocasa/models/fixtures/stand_mixer.py, robocasa/robocasa be22d659, as installed)
    reads the head at ``f"{prefix}head_joint"``; ``OpenStandMixerHead._check_success`` (atomic/
    kitchen_stand_mixer.py) wants its normalised value over 0.99, which ``Fixture.get_joint_state`` takes as 0 at the
    range's low end for a range from 0: the head is shut at qpos 0 and opens upward. Its front edge overhangs the
    mixer's column and open bowl with nothing colliding under it (the version-5 head lay on the collider: nothing to
    lift)."""
    from scenes.robocasa.environment import venv_dir

    (src,) = venv_dir().glob("lib/python*/site-packages/robocasa/models/fixtures/stand_mixer.py")
    assert '"head": f"{prefix}head_joint"' in src.read_text()
    root = ET.parse(next((placeholders / "fixtures" / "stand_mixers").glob("*/model.xml"))).getroot()
    obj = next(b for b in root.iter("body") if b.get("name") == "object")
    head = next(b for b in obj.findall("body") if b.get("name") == "head")
    joint = head.find("joint")
    assert joint.get("name") == "head_joint" and float(joint.get("range").split()[0]) == 0.0
    hc, hh = _box(head.find("geom"))
    hc = hc + np.array(head.get("pos").split(), float)
    pivot = np.array(joint.get("pos").split(), float) + np.array(head.get("pos").split(), float)
    axis = np.array(joint.get("axis").split(), float)
    # opening by a small angle lifts the end away from the hinge (RoboCasa: 0 shut, the range's top open)
    front = hc - [0, hh[1], 0] - pivot
    assert np.cross(axis, front)[2] > 0
    colliders = [_box(g) for g in obj.findall("geom") if g.get("contype") != "0" and g.get("type") == "box"]
    # what rises to within 10 cm of the head's underside (the column; the open bowl's walls stay lower) lies well
    # behind its front edge, and nothing collides in the 10 cm under that edge: room for a finger under it
    under = hc[2] - hh[2]
    tall = [(c, h) for c, h in colliders if c[2] + h[2] > under - 0.10]
    overhang = min(c[1] - h[1] for c, h in tall) - (hc[1] - hh[1])
    assert overhang > 0.04  # a closed Panda finger is ~2 cm across
    below = hc - [0, hh[1] - 0.02, 0]  # 2 cm in from the front edge
    for z in np.linspace(under - 0.005, under - 0.10, 9):
        point = np.array([below[0], below[1], z])
        assert not any(np.all(np.abs(point - c) <= h) for c, h in colliders), z


def _raw(state: float = 0.0, eef=(0.25, 0.0, 1.29)) -> dict:
    """Worker facts of an OpenStandMixerHead episode as on level 0 (seed of episode 0): the base at the origin facing
    +x, the mixer turned so its front faces the base's left, the head hinged at (0.3, -0.165, 1.23), 0.33 m long."""
    angle = state * 0.8
    edge = [0.3, -0.165 + 0.33 * np.cos(angle), 1.23 + 0.33 * np.sin(angle)]
    return {
        "eef_pos": list(eef), "eef_mat": np.diag([1.0, -1.0, -1.0]), "gripper_qpos": [0.0, 0.0],
        "base_pos": [0.0, 0.0, 0.0], "base_yaw": 0.0, "fixture_pos": [0.3, 0.0, 1.08],
        "mixer_head_pos": [0.3, 0.0, 1.23], "mixer_hinge_pos": [0.3, -0.165, 1.23],
        "hinge_pos": [0.3, -0.165, 1.23], "hinge_edge": edge, "hinge_front": [0.0, 1.0, 0.0], "hinge_thick": 0.018,
        "hinge_state": state, "hinge_lift": "opens", "base_room": [0.06, 3.5, 0.68, 2.8], "success": state > 0.99,
    }  # fmt: skip


def test_the_oracle_drives_then_goes_under_the_heads_free_edge_and_lifts_it():
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import RoboCasaOracle
    from scenes.robocasa.oracle_lift import INSET, LIFT_TILT, under_edge

    s = privileged_state(_raw())
    assert s.facts.lift and s.goal is not None and s.target.floor_z is None
    o = RoboCasaOracle()
    a = o.action(s)
    # the point under the edge is 0.135 m to the left: the base drives left (base mode), the arm held
    assert o.phase == "drive" and o._tilt == LIFT_TILT and a[8] > 0.25 and a[11] == 1.0 and a[6] > 0
    # under the edge: INSET in from it, below the underside; lifted by an angle, it rises and moves back
    under = under_edge(np.array([0.3, -0.165, 1.23]), np.array([0.0, 1.0, 0.0]), 0.33, 0.018, 0.0, 0.0)
    assert np.allclose(under, [0.3, 0.165 - INSET, 1.212])
    up = under_edge(np.array([0.3, -0.165, 1.23]), np.array([0.0, 1.0, 0.0]), 0.33, 0.018, 0.3, 0.0)
    assert up[2] > under[2] + 0.05 and up[1] < under[1]
    o._next("lift")
    a = o.action(privileged_state(_raw(state=0.2, eef=tuple(under))))
    assert a[2] > 0 and a[1] < 0 and a[11] == -1.0  # up and back along the arc, arm mode
    o.action(privileged_state(_raw(state=1.0)))
    assert o.phase == "retreat"


def test_certify_scripts_opening_the_mixer_head():
    from scenes.oracles import oracle_scripts

    assert oracle_scripts(get_scene("robocasa"), "OpenStandMixerHead")


@needs_venv
@pytest.mark.slow  # 25 s: a cold worker and a ~90-step episode; the default tests above keep the script's steps
def test_the_oracle_opens_the_mixer_head(placeholders):
    assert _oracle_episodes("OpenStandMixerHead", "fixture_x", 0, (0,), None) == [True]


@needs_venv
@pytest.mark.slow  # 24 s; test_the_oracle_drives_then_goes_under_the_heads_free_edge_and_lifts_it keeps the drive
def test_the_oracle_opens_the_mixer_head_slid_away(placeholders):
    """fixture_x level 3 episode 0: the mixer slid 0.375 m along the counter; the base phase brings its edge back."""
    assert _oracle_episodes("OpenStandMixerHead", "fixture_x", 3, (0,), None) == [True]
