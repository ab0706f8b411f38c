"""TurnOnBlender: the oracle presses the placeholder blender's power button (``<blender>_power_button_main``,
which ``Blender.update_state`` counts at the release of a touch) and leaves it straight up; the task resets on the
placeholders now that the blender has the ``anchor_site`` RoboCasa puts its lid at."""

from __future__ import annotations

import numpy as np
import pytest

from tests.scenes.robocasa.test_robocasa import _oracle_episodes, needs_venv


def _raw(touched: bool = False, eef=(0.3, 0.0, 1.2)) -> dict:
    """Worker facts of a TurnOnBlender episode: the fruit in the jar, the button's top at (0.3, 0, 1.0), the base
    at the origin facing +x."""
    return {
        "eef_pos": list(eef), "eef_mat": np.diag([1.0, -1.0, -1.0]), "gripper_qpos": [0.0, 0.0],
        "base_pos": [0.0, 0.0, 0.0], "base_yaw": 0.0, "obj_pos": [0.4, 0.0, 1.1], "obj_quat": [1.0, 0, 0, 0],
        "obj_linvel": [0.0, 0, 0], "obj_bottom": 1.07, "obj_top": 1.13, "obj_half_width": 0.03,
        "obj_touching": False, "fixture_pos": [0.4, 0.0, 1.15], "button_pos": [0.3, 0.0, 1.0],
        "button_touched": touched, "success": False,
    }  # fmt: skip


def test_the_button_not_the_fruit_is_what_the_oracle_presses():
    from scenes.robocasa import privileged_state

    s = privileged_state(_raw(touched=True))
    assert np.allclose(s.pick.pos, [0.3, 0.0, 1.0]) and s.pick.touching_gripper
    assert np.allclose(s.target.place_xy, [0.3, 0.0]) and s.target.floor_z is None  # a press, no put-down
    assert s.facts.button
    mixer = privileged_state({k: v for k, v in _raw().items() if not k.startswith(("button", "obj"))})
    assert not mixer.facts.button  # the stand mixer's head is pushed until closed, not touched and left


def test_the_press_leaves_the_button_straight_up_at_the_first_touch():
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import BUTTON_TILT, RoboCasaOracle

    o = RoboCasaOracle()
    o.action(privileged_state(_raw()))
    assert o._tilt == BUTTON_TILT
    o.phase = "press"
    a = o.action(privileged_state(_raw(eef=(0.3, 0.0, 1.05))))
    assert o.phase == "press" and a[2] < 0  # down onto it
    o.action(privileged_state(_raw(touched=True, eef=(0.3, 0.0, 1.01))))
    assert o.phase == "lift_off"
    a = o.action(privileged_state(_raw(touched=True, eef=(0.3, 0.0, 1.01))))
    assert a[2] > 0 and abs(a[0]) < 1e-6 and abs(a[1]) < 1e-6  # straight up: a second touch would count again


@needs_venv  # ~10 s: a cold worker and a 31-step episode (the reset raised TypeError before the lid's anchor)
@pytest.mark.slow  # ~14 s: a whole oracle episode
def test_the_oracle_turns_the_blender_on(placeholders):
    assert _oracle_episodes("TurnOnBlender", "fixture_x", 0, (0,), None) == [
        True
    ]  # RoboCasa's 300-step horizon


@needs_venv
@pytest.mark.slow  # ~1 min: three certification episodes, one on a shifted blender
def test_the_oracle_turns_the_blender_on_after_it_slides_away(placeholders):
    assert _oracle_episodes("TurnOnBlender", "fixture_x", 0, (1, 2), 150) == [True, True]
    assert _oracle_episodes("TurnOnBlender", "fixture_x", 1, (0,), 150) == [True]


def test_fixture_x_moves_the_blenders_lid_with_it():
    """The lid is an auxiliary fixture placed at the blender's anchor_site: left at T0's pose by fixture_x, it was
    off the blender, and RoboCasa keeps a blender without its lid off (0/4 at fixture_x level 1 before)."""
    from types import SimpleNamespace

    from scenes.robocasa.backend import auxiliaries

    env = SimpleNamespace(fxtr_placements=dict.fromkeys(
        ["blender_left_group", "blender_left_group_auxiliary_left_group", "blender_left_group_2", "counter_main"]))  # fmt: skip
    assert auxiliaries(env, "blender_left_group") == ["blender_left_group_auxiliary_left_group"]
    assert auxiliaries(env, "counter_main") == []
