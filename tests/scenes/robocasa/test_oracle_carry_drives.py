"""The carry that drives the mobile base twice (``RoboCasaOracle._carry`` with ``carry_drives``): CheesyBread's cheese
and bread, PickPlaceCounterToStandMixer's object beside the mixer and its bowl.

Upstream (robocasa/robocasa be22d659, the pinned rlinf-robocasa365 1.0.1,
``robocasa/environments/kitchen/atomic/kitchen_pick_place.py``): ``CheesyBread._get_obj_cfgs`` names its pick object
``cheese`` (``init_robot_here``) and places ``bread`` on a cutting board (``bread_container``) up to 1 m along the
counter; ``_check_success`` wants the bread still in its container, the gripper far from the cheese and the cheese
in contact with the bread. ``PickPlaceCounterToStandMixer`` puts its object beside the mixer (``loc="left_right"``)
and opens the head over the bowl.
"""

from __future__ import annotations

import numpy as np
import pytest

from scenes.family import get_scene
from tests.scenes.robocasa.test_oracle_carry import _raw
from tests.scenes.robocasa.test_robocasa import _oracle_episodes, needs_venv


def _cheesy(**over) -> dict:
    """Worker facts of a CheesyBread episode: the base at the origin facing +x, the cheese 0.4 m to its left, the
    bread's top 0.6 m ahead under a wall cabinet 0.23 m over it (pick_x level 0 episode 2's numbers, rounded)."""
    return {**_raw(obj_z=0.954), "obj_pos": [0.25, 0.4, 0.954], "place_pos": [0.6, 0.0, 1.148],
            "place_ceiling": 1.38, "base_room": [0.03, 5.0, 0.56, 0.56], "carry_drives": True, **over}  # fmt: skip


def test_the_carry_drives_to_the_pick_object_then_with_it_to_the_place_point():
    """First the base drives sideways until the object is straight ahead (fingers open); after the lift, holding it,
    until the place point is (``drive_place``); a carry without ``carry_drives`` (the fridge's) drives once, to
    the place point."""
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import CLOSED, CRAMPED_REACH, HELD_DRIVE, OPEN, RoboCasaOracle
    from scenes.robocasa.oracle_base import BASE, MARGIN, MODE

    o = RoboCasaOracle()
    a = o.action(privileged_state(_cheesy()))
    # left, fingers open, until the cheese stands straight ahead, and back until it is CRAMPED_REACH[0] out (the
    # hand grasps tipped: 0.25 m out, its wrist came too near the base)
    assert o.phase == "drive" and a[MODE] == 1.0 and a[6] == OPEN and a[BASE][1] > 0 and a[BASE][0] < 0
    assert np.allclose(o._base_goal, [0.25 - CRAMPED_REACH[0], 0.4])
    plain = RoboCasaOracle()  # nothing low over the place point (the mixer's bowl): sideways only
    plain.action(privileged_state(_cheesy(place_ceiling=None)))
    assert np.allclose(plain._base_goal, [0.0, 0.4])
    # the lift done, held at the carry height: the base drives back until the bread is straight ahead
    o.phase, o._count, o._hold, o._offset = "lift", 30, np.array([0.25, 0.4, 0.97]), 0.05
    moved = privileged_state(
        {**_cheesy(), "base_pos": [0.0, 0.4, 0.0], "eef_pos": [0.25, 0.4, o._carry_z + 0.05]}
    )
    o._trail = [moved.eef_pos] * 10
    o.action(moved)
    assert o.phase == "drive_place" and o._base_trail == []  # a fresh stall check for the second drive
    a = o.action(moved)
    # right, back toward the bread, at HELD_DRIVE of full speed (the object held)
    assert a[MODE] == 1.0 and a[6] == CLOSED and a[BASE][1] == -HELD_DRIVE
    assert np.allclose(o._base_goal, [0.03 - MARGIN, 0.0], atol=1e-9)  # forward only as the room allows
    fridge = RoboCasaOracle()
    fridge.action(privileged_state({**_cheesy(), "carry_drives": False, "place_pos": [0.6, 0.1, 1.148]}))
    assert fridge.phase == "drive" and np.allclose(fridge._base_goal, [0.0, 0.1])  # toward the place point


def test_under_a_low_wall_cabinet_the_hand_grasps_tipped_with_the_fingers_across_the_heading():
    """The bread 0.23 m under a wall cabinet (< ``CRAMPED``), a carry that drives: the hand tips ``CRAMPED_TILT``
    from the approach on, untwisted (R_DOWN slides the fingers along the base's y), so a pitch keeps the fingers
    level and the cheese flat; the coffee machine's button (as low at some seeds) keeps the square grasp's twist
    and ``UNDER_TILT`` after the grasp only: its carry does not drive."""
    from scenes.oracles import R_DOWN
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import CRAMPED, CRAMPED_REACH, CRAMPED_TILT, HAND_ROOM, RoboCasaOracle

    assert 0.277 < CRAMPED < HAND_ROOM
    assert np.allclose(R_DOWN[:, 0], [0.0, 1.0, 0.0])  # the untwisted fingers slide along the base's y
    o = RoboCasaOracle()
    s = privileged_state({**_cheesy(), "obj_quat": [np.cos(0.3), 0, 0, np.sin(0.3)]})
    o.action(s)
    assert o.phase == "drive" and o._twist == 0.0
    fingers = o._hand(s, CRAMPED_TILT, o._twist)[:, 0]
    assert abs(fingers[2]) < 1e-9  # level while tipped
    # pick_x level 4 episode 6: a cabinet 0.277 m over the bread, pointing down the hand stalled 16 cm short of it
    higher = RoboCasaOracle()
    higher.action(privileged_state({**_cheesy(), "place_ceiling": 1.148 + 0.277}))
    assert higher._twist == 0.0 and np.allclose(higher._base_goal, [0.25 - CRAMPED_REACH[0], 0.4])
    # as low over the counter (0.235 m at some seeds), but a carry that does not drive
    coffee = RoboCasaOracle()
    c = privileged_state({**_cheesy(), "place_ceiling": 1.148 + 0.235, "obj_quat": s.pick.quat_wxyz,
                          "base_room": None, "carry_drives": False})  # fmt: skip
    coffee.action(c)
    assert coffee._twist != 0.0  # the square grasp's twist (the turned cheese), not the cramped one


def test_the_carry_takes_the_cheese_over_what_stands_between_it_and_the_bread():
    """pick_x level 0 episode 0 (boxes as the worker read them, rounded): the placeholder coffee machine (top 1.238
    m) stands between the cheese and the bread; carried 6 cm over the bread's top only, the cheese met the machine's
    front during the held drive and fell (both the tipped grasp and the back-off failed so). ``standing_top`` counts
    what stands in the rectangle the cheese crosses, not the wall cabinet over it (its bottom above the bread's
    top) nor what stands beside it; the carry clears that height by ``CLEARANCE``."""
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import CLEARANCE, RoboCasaOracle
    from scenes.robocasa.worker_facts import standing_top

    cheese, bread = np.array([0.514, -2.621]), np.array([0.392, -2.254, 1.148])
    machine = (np.array([0.326, -2.427, 1.08]), np.array([0.135, 0.113, 0.157]))  # top 1.237
    cabinet = (np.array([0.185, -2.188, 1.395]), np.array([0.185, 0.4, 0.015]))  # bottom 1.38, over the bread
    board = (np.array([0.39, -2.256, 0.974]), np.array([0.049, 0.049, 0.054]))
    aside = (np.array([0.326, -1.8, 1.2]), np.array([0.1, 0.1, 0.28]))  # 0.45 m past the bread: not crossed
    top = standing_top([machine, cabinet, board, aside], cheese, bread[:2], bread[2], 0.037)
    assert top == pytest.approx(1.237)
    assert standing_top([cabinet, board], cheese, bread[:2], bread[2], 0.037) == pytest.approx(1.028)
    assert standing_top([], cheese, bread[:2], bread[2], 0.037) == -np.inf
    o = RoboCasaOracle()
    o.action(privileged_state(_cheesy(place_clear=top)))
    assert o._carry_z == pytest.approx(top + CLEARANCE)  # the object's bottom over the machine, not the bread


def test_the_cramped_grasp_tips_sideways_away_from_a_bread_beside_it():
    """pick_x level 2 episode 0: the bread 6 cm nearer the base than the cheese and 9 cm to its left; tipped
    forward (or pointing down) the hand came down on the bread 14 cm over the cheese and pushed it away. The hand
    tips a quarter turn toward the left instead (its body to the right of the cheese, the fingers level), then,
    lifted, turns back to the heading a step at a time; a bread far ahead (level 0 episode 2's) keeps the forward
    tip, and one to the right turns the hand the other way."""
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import CRAMPED_TILT, RoboCasaOracle
    from scenes.robocasa.oracle_carry import side_turn

    beside = _cheesy(obj_pos=[0.37, 0.069, 0.954], place_pos=[0.314, 0.159, 1.148])
    assert side_turn(privileged_state(_cheesy())) == 0.0
    assert side_turn(privileged_state(beside)) == pytest.approx(np.pi / 2)
    mirrored = _cheesy(obj_pos=[0.37, -0.069, 0.954], place_pos=[0.314, -0.159, 1.148])
    assert side_turn(privileged_state(mirrored)) == pytest.approx(-np.pi / 2)
    o = RoboCasaOracle()
    s = privileged_state(beside)
    o.action(s)
    hand = o._hand(s, CRAMPED_TILT, o._twist, o._turn)
    assert o._turn == pytest.approx(np.pi / 2) and abs(hand[2, 0]) < 1e-9  # the fingers level
    assert hand[1, 2] > 0.8 and abs(hand[0, 2]) < 1e-9  # pointing down and to the left, not forward
    # lifted to the carry height: the turn phase, then back to lift, the hand tipped along the heading again
    o.phase, o._count, o._hold, o._offset = "lift", 20, np.array([0.37, 0.069, 0.97]), 0.04
    up = privileged_state({**beside, "eef_pos": [0.37, 0.069, o._carry_z + 0.04]})
    o._trail = [up.eef_pos] * 10
    o.action(up)
    assert o.phase == "turn"
    for _ in range(40):
        o.action(up)
    assert o.phase == "lift" and o._turn == 0.0


def test_pointing_down_the_fingers_close_along_the_line_to_a_bread_beside_the_cheese():
    """pick_x level 4 episode 2 (no wall cabinet: the hand points down): the bread 6 cm farther and 10 cm to the left
    of the cheese; the square grasp's smaller twist spread the fingers across the line to it and the hand stalled on
    the bread's top 15 cm over the cheese. ``clear_twist`` grasps the square cheese across its other sides, the
    fingers along that line; a bread far away keeps the square grasp's twist."""
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import RoboCasaOracle

    beside = _cheesy(obj_pos=[0.247, -0.236, 0.954], place_pos=[0.308, -0.138, 1.148], place_ceiling=None,
                     obj_quat=[0.155, 0, 0, 0.988], obj_half_extents=[0.026, 0.026, 0.034])  # fmt: skip
    o = RoboCasaOracle()
    s = privileged_state(beside)
    square = o._grasp_twist(s)
    o.action(s)
    fingers = o._hand(s, 0.0, o._twist)[:2, 0]
    assert abs(abs(o._twist - square) - np.pi / 2) < 1e-9 and abs(fingers[0]) > 0.9  # along the heading
    far = RoboCasaOracle()
    far.action(privileged_state({**beside, "place_pos": [0.6, 0.0, 1.148]}))
    assert far._twist == square


def test_a_carry_that_drives_sets_the_objects_centre_on_the_place_point():
    """pick_x level 3 episode 0: the tipped hand holds the cheese 2.5 cm past its centre; aiming the grip site at
    the bread's centre set the cheese 3 cm short, 4 mm inside the bread's near edge, and it fell off as the hand
    backed out. The carry that drives aims the object's centre there; one that does not aims the grip site."""
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import RoboCasaOracle

    held = {**_cheesy(), "eef_pos": [0.55, 0.0, 1.28], "obj_pos": [0.525, 0.0, 1.25], "obj_touching": True}
    for drives, aim in ((True, [0.625, 0.0]), (False, [0.6, 0.0])):
        o = RoboCasaOracle()
        o.phase, o._carry_z, o._offset, o._twist = "transport", 1.208, 0.06, 0.0
        a = o.action(privileged_state({**held, "carry_drives": drives}))
        assert np.allclose(a[:2], np.clip(o.gain * (np.array(aim) - [0.55, 0.0]), -0.6, 0.6))


def test_the_worker_names_cheesy_breads_pick_object_as_the_pick_x_regions_do():
    """``worker_facts.PICK_OBJECT`` (the worker reads the cheese's facts) agrees with ``PICK_REGIONS`` (the object
    config pick_x moves, read against RoboCasa's source in test_pick_steps)."""
    from scenes.robocasa import PICK_REGIONS
    from scenes.robocasa.worker_facts import PICK_OBJECT

    assert {t: r.cfg for t, r in PICK_REGIONS.items() if r.cfg != "obj"} == PICK_OBJECT


@needs_venv
@pytest.mark.slow  # ~45 s: one oracle episode; test_the_carry_drives_to_the_pick_object_then_with_it_to_the_place_point keeps the drives
def test_the_oracle_puts_the_cheese_on_the_bread(placeholders):
    """pick_x level 1 episode 0 (a success of the certification runs in docs/results, 303 steps): both drives, the
    bread under a wall cabinet."""
    assert _oracle_episodes("CheesyBread", "pick_x", 1, (0,), None) == [True]


@needs_venv
@pytest.mark.slow  # ~3 min: four oracle episodes; the default tests above keep each fix
def test_the_oracle_puts_the_cheese_on_the_bread_past_the_coffee_machine_and_beside_it(placeholders):
    """The certification episodes the 2026-11-28 run failed (docs/results): pick_x level 0 episode 0 (the coffee
    machine between the cheese and the bread), level 2 episode 0 (the bread beside the cheese: the sideways tip),
    level 3 episode 0 (the cheese's centre on the bread's), and level 0 episode 2 (the bread 0.6 m ahead under the
    wall cabinet), which the tipped grasp already solved."""
    assert _oracle_episodes("CheesyBread", "pick_x", 0, (0, 2), None) == [True, True]
    assert _oracle_episodes("CheesyBread", "pick_x", 2, (0,), None) == [True]
    assert _oracle_episodes("CheesyBread", "pick_x", 3, (0,), None) == [True]


def test_certify_scripts_the_cheese_and_not_the_mixer_bowl():
    """CheesyBread is listed since oracle v5 (25 of 28 episodes under ``certify --episodes 8``, each failure explained
    in docs/results); PickPlaceCounterToStandMixer fails its first levels, so they stay no_oracle, not failed."""
    from scenes.oracles import oracle_scripts
    from scenes.robocasa.oracle import RoboCasaOracle

    assert oracle_scripts(get_scene("robocasa"), "CheesyBread") and RoboCasaOracle.version >= 5
    assert not oracle_scripts(get_scene("robocasa"), "PickPlaceCounterToStandMixer")
