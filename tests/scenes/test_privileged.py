"""``scenes.privileged``: shapes are checked when a state is built, and only a real state reaches an oracle."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from indgen_vla.core.errors import PolicyError, SceneError
from indgen_vla.core.protocol.interface import Observation
from scenes.privileged import (
    PRIVILEGED_KEY,
    GoalState,
    PickState,
    PrivilegedState,
    Targets,
    privileged_of,
)


def _pick(**kw) -> PickState:
    args = dict(pos=np.zeros(3), quat_wxyz=np.array([1.0, 0, 0, 0]), linvel=np.zeros(3), bottom=0.8, top=0.85,
                half_width=0.02, touching_gripper=False)  # fmt: skip
    return PickState(**{**args, **kw})


def _state(**kw) -> PrivilegedState:
    args = dict(eef_pos=np.zeros(3), eef_mat=np.eye(3), gripper_qpos=np.zeros(2), pick=_pick(), goal=None,
                target=Targets(place_xy=np.zeros(2), place_bottom=0.8, clear_z=0.9, grasp_z=0.82))  # fmt: skip
    return PrivilegedState(**{**args, **kw})


@pytest.mark.parametrize(
    ("build", "what"),
    [
        (lambda: _state(eef_mat=np.eye(4)), "eef_mat"),
        (lambda: _state(eef_pos=np.zeros(2)), "eef_pos"),
        (lambda: _pick(quat_wxyz=np.zeros(3)), "pick.quat_wxyz"),
        (lambda: GoalState(pos=np.zeros(2), quat_wxyz=np.zeros(4), top=0.9), "goal.pos"),
        (
            lambda: Targets(place_xy=np.zeros(3), place_bottom=0.8, clear_z=0.9, grasp_z=0.82),
            "target.place_xy",
        ),
    ],
)
def test_bad_shapes_are_one_line_scene_errors(build, what):
    with pytest.raises(SceneError) as e:
        build()
    assert what in str(e.value) and "\n" not in str(e.value)


def test_state_is_frozen_and_travels_in_extras():
    s = _state()
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.eef_pos = np.ones(3)

    obs = Observation(images={}, state=np.zeros(8, np.float32), instruction="x", extras={"step": 3})
    got = dataclasses.replace(obs, extras={**obs.extras, PRIVILEGED_KEY: s})  # as with_privileged(obs, env)
    assert privileged_of(got, "me") is s
    bad = dataclasses.replace(obs, extras={PRIVILEGED_KEY: {"eef_pos": np.zeros(3)}})  # the old dict form
    with pytest.raises(PolicyError, match="^me needs the env's privileged state"):
        privileged_of(bad, "me")
