"""RoboCasa365 on placeholder assets, through the worker in RoboCasa's own venv (skipped, with the reason, when the
venv is missing: ``make robocasa`` / ``indgen setup robocasa`` creates it; ``make test`` does so first)."""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from indgen_vla.errors import ConfigError, SceneError


def _python():
    from scenes.robocasa.environment import find_python

    return find_python(required=False)


needs_venv = pytest.mark.skipif(
    _python() is None, reason="RoboCasa venv missing: run 'make robocasa' (indgen setup robocasa, ~1 min)"
)


@pytest.fixture(scope="module")
def placeholders(tmp_path_factory):
    """A fresh placeholder tree, pointed at by INDGEN_ROBOCASA_ASSETS for the module."""
    from scenes.robocasa.placeholders import write_placeholders

    root = tmp_path_factory.mktemp("robocasa_assets")
    write_placeholders(root)
    saved = os.environ.get("INDGEN_ROBOCASA_ASSETS")
    os.environ["INDGEN_ROBOCASA_ASSETS"] = str(root)
    yield root
    if saved is None:
        os.environ.pop("INDGEN_ROBOCASA_ASSETS", None)
    else:
        os.environ["INDGEN_ROBOCASA_ASSETS"] = saved


def test_base_y_is_the_horizon_axis_and_task_lists_are_checked():
    import scenes
    from scenes.registry import get_scene

    assert scenes.get_axis("base_y").name == "horizon"
    sc = get_scene("robocasa")
    sc.check_axis("base_y")
    with pytest.raises(ConfigError, match="not on axis horizon's task list"):
        sc.check_axis_task("CloseStandMixerHead", "base_y")


def test_env_spec_follows_lerobot():
    """lerobot's src/lerobot/envs/robocasa.py: OBS_STATE_DIM = 16, ACTION_DIM = 12, DEFAULT_CAMERAS =
    robot0_agentview_left, robot0_eye_in_hand, robot0_agentview_right (raw RoboCasa names)."""
    from scenes.registry import get_scene

    spec = get_scene("robocasa").env_spec
    assert (spec.state_dim, spec.action_dim) == (16, 12)
    assert set(spec.cameras) == {"robot0_agentview_left", "robot0_eye_in_hand", "robot0_agentview_right"}


@needs_venv
def test_placeholder_tree_is_writable_with_one_joint_per_body(placeholders):
    from scenes.robocasa.environment import find_assets, is_placeholder

    assert find_assets() == placeholders.resolve() and is_placeholder(placeholders)
    mixers = sorted((placeholders / "fixtures").glob("stand_mixers/*/model.xml"))
    assert mixers
    names = set()
    for body in ET.parse(mixers[0]).iter("body"):
        joints = body.findall("joint")
        assert len(joints) <= 1, f"body {body.get('name')} has {len(joints)} joints (singular mass matrix)"
        names.update(j.get("name") for j in joints)
    assert {"head_joint", "knob_speed_joint", "button_head_lock_joint"} <= names
    assert os.access(mixers[0].parent, os.W_OK)


def _normalized_meta(meta: dict) -> dict:
    """ep_meta with numpy scalars as plain values and RoboCasa's replay bookkeeping dropped (on a replay it
    rewrites each object's ``info.groups`` to the model file it chose, which pins the same model)."""
    out = {}
    for k, v in meta.items():
        if k == "object_cfgs":
            v = [{**c, "info": {i: str(x) for i, x in c.get("info", {}).items() if i != "groups"}} for c in v]
        out[k] = repr(v) if not isinstance(v, (list, tuple)) else repr([str(x) for x in v])
    return out


@needs_venv
def test_base_y_successor_edits_only_the_robot_base_and_steps(placeholders):
    import scenes

    metas, states = {}, {}
    for level in (0, 1):
        env = scenes.make_env(
            "robocasa", task="PickPlaceCounterToCabinet", axis="base_y", level=level, cameras=()
        )
        try:
            obs, _ = env.reset(seed=3)
            assert obs.state.shape == (16,) and obs.images == {}
            obs, reward, term, trunc, info = env.step(np.zeros(12))
            assert obs.state.shape == (16,) and not info["success"] and env.action_space.shape == (12,)
            metas[level] = env.call("ep_meta")
            states[level] = env.privileged_state()
        finally:
            env.close()
    a, b = _normalized_meta(metas[0]), _normalized_meta(metas[1])
    assert {k for k in a.keys() | b.keys() if a.get(k) != b.get(k)} == {"init_robot_base_pos"}
    moved = np.subtract(metas[1]["init_robot_base_pos"], metas[0]["init_robot_base_pos"])
    assert np.linalg.norm(moved) == pytest.approx(0.125, abs=1e-6)
    base = [np.asarray(s["base_pos"][:2]) for s in (states[0], states[1])]
    assert np.linalg.norm(base[1] - base[0]) == pytest.approx(0.125, abs=0.02)


@needs_venv
@pytest.mark.xfail(strict=True, reason="open (issue 25): a replay of T0's ep_meta re-samples the objects' poses "
                   "when the robot base moved; pin T0's object placements next")  # fmt: skip
def test_base_y_keeps_the_objects_pose(placeholders):
    import scenes

    poses = []
    for level in (0, 1):
        env = scenes.make_env(
            "robocasa", task="PickPlaceCounterToCabinet", axis="base_y", level=level, cameras=()
        )
        try:
            env.reset(seed=3)
            poses.append(env.privileged_state()["obj_pos"])
        finally:
            env.close()
    np.testing.assert_allclose(poses[0], poses[1], atol=1e-6)


@needs_venv
def test_a_worker_that_dies_mid_episode_is_an_episode_error_then_restarts(placeholders):
    import scenes
    from scenes.runtime import WorkerDied

    env = scenes.make_env("robocasa", task="PickPlaceCounterToCabinet", axis="base_y", level=0, cameras=())
    try:
        env.reset(seed=3)
        env.step(np.zeros(12))
        env.kill_worker()
        with pytest.raises(
            WorkerDied, match=r"robocasa/PickPlaceCounterToCabinet axis horizon level 0: .*died"
        ):
            env.step(np.zeros(12))
        obs, _ = env.reset(seed=3)  # the engine's retry: a fresh worker, rebuilt, the same episode
        assert obs.state.shape == (16,)
        assert "obj_pos" in env.privileged_state()
    finally:
        env.close()


@needs_venv
def test_unwired_successor_is_refused_in_one_line(placeholders):
    import scenes

    with pytest.raises(SceneError, match="fixture_x successor is not wired"):
        scenes.make_env("robocasa", task="CloseStandMixerHead", axis="fixture_x", level=1, cameras=())
