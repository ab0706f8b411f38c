"""CloseElectricKettleLid: the worker's hinge facts become the lid's hinge (goal) and free edge (target), and the
oracle sweeps the standing lid shut from behind its top edge, then presses it down."""

from __future__ import annotations

import numpy as np
import pytest

from scenes.family import get_scene
from tests.scenes.robocasa.test_robocasa import _oracle_episodes, needs_venv


def _raw(state: float = 1.0, eef=(0.3, 0.0, 1.3)) -> dict:
    """Worker facts of a CloseElectricKettleLid episode: the base at the origin facing +x, the kettle facing it
    (-x), the lid hinged at (0.45, 0, 1.14), 0.1 m long, standing up (``state`` 1) or lying shut toward the base."""
    angle = state * np.pi / 2
    edge = [0.45 - 0.1 * np.cos(angle), 0.0, 1.14 + 0.1 * np.sin(angle)]
    return {
        "eef_pos": list(eef), "eef_mat": np.diag([1.0, -1.0, -1.0]), "gripper_qpos": [0.0, 0.0],
        "base_pos": [0.0, 0.0, 0.0], "base_yaw": 0.0, "fixture_pos": [0.4, 0.0, 1.04],
        "hinge_pos": [0.45, 0.0, 1.14], "hinge_edge": edge, "hinge_front": [-1.0, 0.0, 0.0], "hinge_thick": 0.015,
        "hinge_state": state, "success": state <= 0.01,
    }  # fmt: skip


def test_the_lid_facts_become_its_hinge_and_free_edge():
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle_fixtures import hinge_frame

    s = privileged_state(_raw())
    assert np.allclose(s.goal.pos, [0.45, 0.0, 1.14]) and s.goal.top == 0.015
    assert np.allclose(s.pick.pos, [0.45, 0.0, 1.24]) and s.target.floor_z is None  # a push, no put-down
    hinge, front, length, thick, angle = hinge_frame(s)
    assert np.allclose(front, [-1.0, 0.0, 0.0]) and length == pytest.approx(0.1)
    assert thick == 0.015 and angle == pytest.approx(np.pi / 2)
    assert hinge_frame(privileged_state(_raw(state=0.0)))[4] == pytest.approx(
        0.0, abs=1e-9
    )  # shut, toward the base


def test_the_oracle_goes_behind_the_lid_then_sweeps_it_toward_the_front():
    from scenes.robocasa import privileged_state
    from scenes.robocasa.oracle import RoboCasaOracle
    from scenes.robocasa.oracle_fixtures import LID_TILT

    o = RoboCasaOracle()
    # no room reported: no drive; the hinge 0.45 m ahead: a tipped hand, beyond the lid, fingers shut
    a = o.action(privileged_state(_raw()))
    assert o.phase == "approach" and o._tilt == LID_TILT and a[0] > 0 and a[6] > 0
    o = RoboCasaOracle()
    o.action(privileged_state({**_raw(), "hinge_pos": [0.6, 0.0, 1.14], "hinge_edge": [0.6, 0.0, 1.24]}))
    assert o._tilt == 0.0  # 0.6 m ahead: the hand points down
    o.phase = "sweep"
    a = o.action(privileged_state(_raw(eef=(0.49, 0.0, 1.21))))  # behind the lid's top edge
    assert a[0] < 0 and a[2] < 0  # toward the base (the kettle's front) and down
    o.action(privileged_state(_raw(state=0.2, eef=(0.40, 0.0, 1.17))))
    assert o.phase == "press"  # nearly shut: pressed down the rest of the way


def test_certify_scripts_the_kettle_lid_and_lever():
    """Both kettle parts have scripts (the lid's sweep, the lever's press: docs/results)."""
    from scenes.oracles import oracle_scripts

    assert oracle_scripts(get_scene("robocasa"), "CloseElectricKettleLid")
    assert oracle_scripts(get_scene("robocasa"), "TurnOnElectricKettle")


@needs_venv
@pytest.mark.slow  # 32 s on the shared 2-core machine: a cold worker and a 141-step episode
def test_the_oracle_closes_the_kettle_lid(placeholders):
    assert _oracle_episodes("CloseElectricKettleLid", "fixture_x", 0, (0,), None) == [True]
