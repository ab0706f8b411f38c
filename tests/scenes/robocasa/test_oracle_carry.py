"""RoboCasa's carry script (``RoboCasaOracle._carry``): a put-down task's ``place_pos`` becomes a target the oracle
carries the object onto; sink to counter and counter to drawer succeed in simulation at level 0 and at a shifted
level."""

from __future__ import annotations

import numpy as np
import pytest

from scenes.family import get_scene
from tests.scenes.robocasa.test_robocasa import _oracle_episodes, needs_venv


def _raw(obj_z: float = 0.91, eef=(0.0, 0.0, 1.2)) -> dict:
    """Worker facts of a sink-to-counter episode: object in the sink at (0.4, 0), container top 1.03 m at
    (0.4, -0.5), the base at the origin facing +x."""
    return {
        "eef_pos": list(eef), "eef_mat": np.diag([1.0, -1.0, -1.0]), "gripper_qpos": [0.02, -0.02],
        "base_pos": [0.0, 0.0, 0.0], "base_yaw": 0.0, "obj_pos": [0.4, 0.0, obj_z], "obj_quat": [1.0, 0, 0, 0],
        "obj_linvel": [0.0, 0, 0], "obj_bottom": obj_z - 0.04, "obj_top": obj_z + 0.04, "obj_half_width": 0.04,
        "obj_touching": False, "obj_half_extents": [0.03, 0.03, 0.04], "place_pos": [0.4, -0.5, 1.03],
        "success": False,
    }  # fmt: skip


def test_place_pos_is_the_carry_target():
    from scenes.robocasa import privileged_state

    s = privileged_state(_raw())
    assert s.goal is None and s.facts.fixture_centre is None
    assert np.allclose(s.target.place_xy, [0.4, -0.5])
    assert (s.target.place_bottom, s.target.floor_z) == (1.03, 1.03)
    assert s.target.clear_z == 1.03  # the higher of the container's top and the object's bottom (0.87)
    covered = privileged_state(
        {**_raw(), "place_ceiling": 1.2}
    )  # the coffee machine's button over its pour site
    assert covered.goal.top == 1.2 and np.allclose(covered.goal.pos, [0.4, -0.5, 1.03])


def test_a_container_rim_raises_the_carry_height():
    """Counter to blender: the jar's floor is the place point and its rim (``place_clear``) the height to clear."""
    from scenes.robocasa import privileged_state

    s = privileged_state({**_raw(), "place_pos": [0.4, -0.5, 1.04], "place_clear": 1.34})
    assert s.target.place_bottom == 1.04 and s.target.clear_z == 1.34


def test_the_carry_height_is_fixed_before_the_object_rises():
    """The carry height is the higher surface plus CLEARANCE, fixed at the first action: the object's bottom
    (one of the two surfaces) rises with it once grasped, and a height read live rose without end."""
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import CLEARANCE, RoboCasaOracle

    o = RoboCasaOracle()
    a = o.action(privileged_state(_raw()))
    assert o.phase == "approach" and a[0] > 0 and a[6] < 0  # toward the object, fingers open
    o.phase, o._offset, o._hold = "lift", 0.05, np.array([0.4, 0.0, 0.92])
    a = o.action(privileged_state(_raw(obj_z=1.3, eef=(0.4, 0.0, 1.0))))  # held up high: bottom 1.26
    assert o._carry_z == pytest.approx(1.03 + CLEARANCE)
    assert a[2] > 0 and a[6] > 0  # up toward 1.03 + CLEARANCE + 0.05 = 1.14, still closed


def test_certify_scripts_the_carry_tasks():
    from scenes.oracles import oracle_scripts

    for task in (
        "PickPlaceSinkToCounter",
        "PickPlaceCounterToDrawer",
        "PickPlaceCounterToSink",
        "PickPlaceCounterToBlender",
    ):
        assert oracle_scripts(get_scene("robocasa"), task), task
    # solved half the time on placeholders until the square grasp (oracle v3): 8/8 at pick_x levels since
    assert oracle_scripts(get_scene("robocasa"), "CoffeeSetupMug")


@needs_venv  # ~15 s: the carry script's episode of the smoke group (251 steps)
@pytest.mark.slow  # ~13 s: one simulated episode (the unit tests above cover the script's targets)
def test_the_carry_script_puts_an_object_on_the_container(placeholders):
    assert _oracle_episodes("PickPlaceSinkToCounter", "pick_x", 0, (4,), 300) == [True]


@needs_venv
@pytest.mark.slow  # ~1.5 min: four certification episodes
def test_the_oracle_puts_the_object_from_the_sink_on_the_container(placeholders):
    """Certification episodes of sink to counter: level 0, and pick_x level 3 (the object 3 steps along the sink)."""
    assert _oracle_episodes("PickPlaceSinkToCounter", "pick_x", 0, (0, 2), 400) == [
        True,
        True,
    ]
    assert _oracle_episodes("PickPlaceSinkToCounter", "pick_x", 3, (0, 2), 400) == [
        True,
        True,
    ]


@needs_venv
@pytest.mark.slow  # ~2 min: four certification episodes
def test_the_oracle_puts_the_object_in_the_open_drawer(placeholders):
    """Counter to drawer: into the part of the open drawer no counter top covers (horizon levels 0 and 2).
    Episode 1 of level 0 is an island, whose top overhangs the drawer by 15 cm: the middle of the whole opening
    (the script's first target) lay under it."""
    assert _oracle_episodes("PickPlaceCounterToDrawer", "horizon", 0, (1, 2), 400) == [True, True]
    assert _oracle_episodes("PickPlaceCounterToDrawer", "horizon", 2, (0, 1), 500) == [True, True]


@needs_venv
@pytest.mark.slow  # ~35 s: two certification episodes
def test_the_oracle_puts_the_object_in_the_sink_basin(placeholders):
    """Counter to sink (placeholder tree v5: the basin is open): RoboCasa wants the object's centre in reg_basin."""
    assert _oracle_episodes("PickPlaceCounterToSink", "horizon", 0, (0, 1), 400) == [True, True]


@needs_venv
@pytest.mark.slow  # ~20 s: one certification episode
def test_the_oracle_drops_the_object_into_the_blender_jar(placeholders):
    """Counter to blender: carried over the jar's rim (place_clear), let go where the hand stalls, inside reg_int."""
    assert _oracle_episodes("PickPlaceCounterToBlender", "horizon", 1, (0,), 500) == [True]
