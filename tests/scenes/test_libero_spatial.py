"""The LIBERO-Spatial adapter on the miniature asset tree: registry and axes, every task at level 0, fidelity to
lerobot's LiberoEnv, the scale (bowl resting on another object) and distractor levels, and the oracle."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("libero")

import scenes  # noqa: E402
from indgen_vla.core.errors import UnknownNameError  # noqa: E402
from scenes.family import get_scene  # noqa: E402
from tests.fixtures.levels import level_env  # noqa: E402
from tests.scenes.conftest import assert_steps_match  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")
SCENE = "libero_spatial"
DRAWER = "in_the_top_drawer_of_the_wooden_cabinet"


def _env(axis="scale", level=0, **kw):
    kw.setdefault("cameras", ())
    return level_env(SCENE, axis=axis, level=level, **kw)


def test_registry_axes_and_tasks():
    tasks = list(scenes.get_scene(SCENE).tasks)
    assert len(tasks) == 10 and tasks[0] == "between_the_plate_and_the_ramekin" and DRAWER in tasks
    assert list(scenes.get_scene(SCENE).axes) == ["scale", "distractor"]
    for task in tasks:
        t = get_scene(SCENE).task_info(task)
        assert (t.pick, t.goal, t.goal_region) == ("akita_black_bowl_1", "plate_1", "plate_region")
        assert t.language.startswith("pick up the black bowl") and t.language.endswith(
            "place it on the plate"
        )
    assert (
        not get_scene(SCENE).task_info("on_the_cookie_box").pick_on_table
        and get_scene(SCENE).task_info("on_the_cookie_box").pick_region == "box_region"
    )
    assert (
        not get_scene(SCENE).task_info(DRAWER).pick_on_table
        and get_scene(SCENE).task_info("next_to_the_plate").pick_on_table
    )
    assert dict(get_scene(SCENE).task_info(DRAWER).objects)["akita_black_bowl_2"] == "akita_black_bowl"


@pytest.mark.parametrize("axis", ["pick_y", "goal_y", "pick_y+distractor"])
def test_moving_axes_are_refused_with_the_supported_ones(axis):
    with pytest.raises(UnknownNameError) as e:
        level_env(SCENE, axis=axis)
    msg = str(e.value)
    assert "\n" not in msg and f"axis of scene {SCENE}" in msg and "known: distractor, scale" in msg


@pytest.mark.slow  # 10 s: all ten tasks; level 0 of one task is checked pixel for pixel by default
def test_every_task_builds_and_steps_at_level_0(mini):
    for task in list(scenes.get_scene(SCENE).tasks):
        env = _env(task=task, max_steps=2)
        try:
            assert env.bddl_file == get_scene(SCENE).task_info(task).bddl_path and env._states.shape == (
                50,
                92,
            )
            obs, info = env.reset(seed=0, options={"episode": 1})
            assert info["init_state"] == 1 and obs.state.shape == (8,)
            for _ in range(2):
                obs, r, term, trunc, info = env.step(np.zeros(7, dtype=np.float32))
            assert trunc and not term, task
        finally:
            env.close()


@pytest.mark.slow  # ~8 s: test_libero's LIBERO-Object twin stays in the default suite
def test_level0_matches_lerobot_libero_env(mini):
    """Level 0 of the drawer task is LIBERO's own as lerobot runs it: same images and state, same joint layout."""
    from scenes.libero.assets import import_libero

    import_libero()
    from lerobot.envs.libero import LiberoEnv, _get_suite

    env = _env(task=DRAWER, cameras=("agentview", "wrist"), image_size=(32, 32))
    task_id = get_scene(SCENE).task_info(DRAWER).task_id
    ref = LiberoEnv(
        _get_suite(SCENE),
        task_id,
        SCENE,
        obs_type="pixels_agent_pos",
        observation_width=32,
        observation_height=32,
        episode_index=4,
    )
    try:
        assert env.max_steps == ref._max_episode_steps and env.instruction == ref.task_description
        obs, _ = env.reset(seed=5, options={"episode": 4})
        robs, _ = ref.reset(seed=5)
        np.testing.assert_array_equal(obs.images["agentview"], robs["pixels"]["image"])
        np.testing.assert_array_equal(obs.images["wrist"], robs["pixels"]["image2"])
        np.testing.assert_allclose(obs.state[:3], robs["robot_state"]["eef"]["pos"], atol=1e-6)
        sim = env._env.sim
        assert (
            sim.data.qpos[sim.model.get_joint_qpos_addr("wooden_cabinet_1_top_level")] < -0.14
        )  # drawer open
        assert_steps_match(env, ref, [0.2, 0.1, -0.1, 0.0, 0.0, 0.0, 1.0])
    finally:
        env.close()
        ref.close()


@pytest.mark.parametrize(
    ("axis", "level", "task"),
    [
        ("scale", 3, "on_the_cookie_box"),
        ("scale", -3, DRAWER),
        ("distractor", 4, "on_the_stove"),
        ("scale+distractor", 2, "on_the_ramekin"),
    ],
)
def test_levels_build_and_change_one_thing(mini, axis, level, task):
    from indgen_vla.core.protocol.axis_ref import AxisRef
    from indgen_vla.core.protocol.progression import check_single_axis
    from scenes.axes import get_successor, shifts

    env, base = _env(axis, level, task=task, max_steps=2), _env(axis, 0, task=task)
    try:
        fields = [p.axis.field for p in shifts(get_successor(AxisRef.parse(axis)))]
        check_single_axis(base.spec, env.spec, fields, axis)
        assert env.success_predicate is base.success_predicate
        env.reset(seed=1, options={"episode": 5})
        base.reset(seed=1, options={"episode": 5})
        s, s0 = env.privileged_state(), base.privileged_state()
        if "scale" in axis:
            want = env.spec.pick.scale
            assert s.pick.bottom == pytest.approx(s0.pick.bottom, abs=3e-3)  # re-seated where it rested
            ratio = (s.pick.top - s.pick.bottom) / (s0.pick.top - s0.pick.bottom)
            sizes = env._env.sim.model.geom_size[env._pick_geoms]
            assert ratio == pytest.approx(want, abs=0.01)
            np.testing.assert_allclose(
                sizes, base._env.sim.model.geom_size[base._pick_geoms] * want, rtol=1e-4
            )
            assert np.allclose(s.goal.pos, s0.goal.pos, atol=2e-3)
        if "distractor" in axis:
            names = [n for n in env._env.sim.model.body_names if n.startswith("indgen_distractor_")]
            assert len({n.split("_main")[0] for n in names}) == level
        if axis == "distractor":
            assert np.allclose(s.pick.pos, s0.pick.pos, atol=2e-3)
        for _ in range(2):
            obs, r, term, trunc, info = env.step(np.zeros(7))
        assert trunc and obs.state.shape == (8,)
    finally:
        env.close()
        base.close()


# from the table; from inside the open top drawer (must clear the cabinet top); from on top of the cabinet
@pytest.mark.parametrize("task", ["from_table_center", DRAWER, "on_the_wooden_cabinet"])
def test_oracle_solves_level_0(mini, task):
    from tests.fixtures.certify import run_certify

    cert = run_certify(SCENE, "scale", task=task, levels=[0], episodes=1)
    assert cert["levels"][0]["successes"] == cert["levels"][0]["n"], cert
