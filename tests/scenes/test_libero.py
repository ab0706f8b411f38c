"""The LIBERO-Object adapter on a miniature asset tree: registry, BDDL edits, level-0 fidelity to lerobot's
LiberoEnv, the axes, the oracle, certify/evaluate and the missing-assets error."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("libero")

import scenes  # noqa: E402
from indgen_vla.core.errors import SceneError  # noqa: E402
from indgen_vla.core.protocol.axis_ref import AxisRef  # noqa: E402
from scenes.family import get_scene  # noqa: E402
from scenes.libero.bddl import add_fixtures, parse_regions, shift_region  # noqa: E402
from tests.fixtures.levels import level_env, level_param  # noqa: E402
from tests.scenes.conftest import assert_steps_match  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")
SCENE = "libero_object"


def _evaluate(policy, args, env, timeout):
    """Run ``indgen_vla.app.cli evaluate`` with ``policy`` and ``args`` on this scene; return the process."""
    cmd = [
        sys.executable,
        "-m",
        "indgen_vla.app.cli",
        "evaluate",
        "--policy",
        policy,
        "--scene",
        SCENE,
        *args,
    ]
    return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)


def _env(axis="pick_y", level=0, **kw):
    kw.setdefault("cameras", ())
    return level_env(SCENE, axis=axis, level=level, **kw)


def test_registry_without_simulator():
    assert SCENE in scenes.scene_names()
    tasks = list(scenes.get_scene(SCENE).tasks)
    # lerobot task_id order
    assert len(tasks) == 10 and tasks[0] == "alphabet_soup" and tasks[-1] == "orange_juice"
    assert set(list(scenes.get_scene(SCENE).axes)) == {"pick_y", "goal_y", "scale", "distractor"}
    assert level_param(SCENE, None, "pick_y", 2) == pytest.approx(-0.24 + 0.05)
    assert level_param(SCENE, "milk", "goal_y", -3) == pytest.approx(0.26 - 3 * 0.0367)
    assert level_param(SCENE, None, "scale", 3) == pytest.approx(1.2001)
    t = get_scene(SCENE).task_info("alphabet_soup")
    assert (t.pick, t.goal, t.pick_region, t.goal_region) == (
        "alphabet_soup_1",
        "basket_1",
        "target_object_region",
        "bin_region",
    )
    assert t.language == "pick up the alphabet soup and place it in the basket"


def test_bddl_edits_touch_only_their_region():
    text = get_scene(SCENE).task_info("ketchup").bddl_path.read_text()
    moved = shift_region(text, "bin_region", 0.0, 0.0367)
    a, b = parse_regions(text), parse_regions(moved)
    assert {k for k in a if a[k] != b[k]} == {"bin_region"}
    assert b["bin_region"][1][1] == pytest.approx(a["bin_region"][1][1] + 0.0367)
    assert "indgen_distractor_1 - milk" in add_fixtures(text, [("indgen_distractor_1", "milk")])


def test_missing_assets_is_one_line(tmp_path, monkeypatch):
    monkeypatch.setenv("INDGEN_LIBERO_ASSETS", str(tmp_path))
    with pytest.raises(SceneError, match="INDGEN_LIBERO_ASSETS") as e:
        scenes.get_scene(SCENE).environment.check_ready()
    msg = str(e.value)  # the project's own one-step fix first, then the alternatives
    assert "\n" not in msg and msg.index("run 'indgen setup libero'") < msg.index(
        "hf download lerobot/libero-assets"
    )
    env = {**os.environ, "INDGEN_LIBERO_ASSETS": str(tmp_path)}
    r = _evaluate("standin:noop", ["--axis", "pick_y", "--out", str(tmp_path / "run")], env=env, timeout=120)
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("error:")]
    assert r.returncode != 0 and len(lines) == 1 and "LIBERO's assets" in lines[0], r.stderr[-2000:]


def test_no_tree_at_all_is_the_error_alone(tmp_path, monkeypatch, capsys):
    """An empty home and no variables: evaluate prints the missing-assets error only, not also a note that the
    shipped certificates' tree differs from "yours (none, None)"."""
    from indgen_vla.app.cli import main
    from scenes import certificates

    for var in ("INDGEN_LIBERO_ASSETS", "LIBERO_ASSETS"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    if scenes.get_scene(SCENE).certificates.asset_tree() is not None:
        pytest.skip("hf-libero's package ships an assets/ folder here")
    certificates._SAID.discard(SCENE)
    args = ["evaluate", "--policy", "standin:oracle", "--scene", SCENE, "--axis", "scale", "--levels", "0"]
    assert main([*args, "--episodes", "1", "--out", str(tmp_path / "run")]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("error: LIBERO's assets are missing"), err


def test_names_axes_and_levels_need_no_assets(tmp_path, monkeypatch):
    """On a machine without LIBERO's tree (an empty home, no variables), a plan resolves and bad names, axes and
    levels get their own one-line errors; only a command that builds an env asks for the assets."""
    from indgen_vla.core.errors import ConfigError, UnknownNameError
    from scenes.libero.assets import find_assets
    from scenes.planning import resolve_scene_plan

    for var in ("INDGEN_LIBERO_ASSETS", "LIBERO_ASSETS"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    if find_assets(required=False) is not None:
        pytest.skip("hf-libero's package holds an asset tree here")
    plan = resolve_scene_plan(get_scene(SCENE), "milk", ["pick_y"], "-1:1")
    assert [c.level for c in plan.cells] == [-1, 0, 1]
    for task, axis, levels, error, text in [
        ("nosuch", "pick_y", "0", UnknownNameError, "unknown task of scene libero_object 'nosuch'"),
        ("milk", "clutter", "0", UnknownNameError, "unknown axis of scene libero_object 'clutter'"),
        ("milk", "pick_y", "1:x", ConfigError, "--levels '1:x' is not a range"),
    ]:
        with pytest.raises(error, match=re.escape(text)):
            resolve_scene_plan(get_scene(SCENE), task, [axis], levels)
    with pytest.raises(SceneError, match="run 'indgen setup libero'"):
        plan.builder.check_ready()


def test_level0_matches_lerobot_libero_env(mini):
    """Level 0 is LIBERO's own task as lerobot runs it: same BDDL, init state, settle steps, images and state."""
    from scenes.libero.assets import import_libero
    from scenes.libero.env import LiberoSceneEnv

    import_libero()  # writes LIBERO's config.yaml first: lerobot's module imports libero (which would prompt)
    from lerobot.envs.libero import LiberoEnv, _get_suite

    env = _env(cameras=("agentview", "wrist"), image_size=(32, 32))
    ref = LiberoEnv(
        _get_suite(SCENE),
        0,
        SCENE,
        obs_type="pixels_agent_pos",
        observation_width=32,
        observation_height=32,
        episode_index=3,
    )
    try:
        assert (
            isinstance(env, LiberoSceneEnv)
            and env.bddl_file == get_scene(SCENE).task_info("alphabet_soup").bddl_path
        )
        assert env.max_steps == ref._max_episode_steps == 280 and env.instruction == ref.task_description
        obs, info = env.reset(seed=11, options={"episode": 3})
        robs, _ = ref.reset(seed=11)
        assert info["init_state"] == 3
        np.testing.assert_array_equal(obs.images["agentview"], robs["pixels"]["image"])
        np.testing.assert_array_equal(obs.images["wrist"], robs["pixels"]["image2"])
        from robosuite.utils.transform_utils import quat2axisangle

        eef, grip = robs["robot_state"]["eef"], robs["robot_state"]["gripper"]["qpos"]
        want = np.concatenate([eef["pos"], quat2axisangle(eef["quat"]), grip]).astype(np.float32)
        np.testing.assert_allclose(obs.state, want, atol=1e-6)
        assert_steps_match(env, ref, [0.3, -0.2, 0.1, 0.0, 0.0, 0.1, 1.0])
        # steps nobody observes skip the renders; the next observed frame is still lerobot's, pixel for pixel
        cam = env._env.env._observables["agentview_image"]
        renders, real = [], cam._sensor

        def counted(cache):
            renders.append(1)
            return real(cache)

        counted.__modality__ = real.__modality__
        cam._sensor = counted
        a = np.array([-0.2, 0.3, 0.0, 0.1, 0.0, 0.0, -1.0], np.float32)
        for _ in range(3):
            obs, *_ = env.step(a, observe=False)
            robs, *_ = ref.step(a)
            assert obs.images == {} and not renders
        obs, *_ = env.step(a)
        robs, *_ = ref.step(a)
        assert len(renders) == 1
        np.testing.assert_array_equal(obs.images["agentview"], robs["pixels"]["image"])
        np.testing.assert_array_equal(obs.images["wrist"], robs["pixels"]["image2"])
    finally:
        env.close()
        ref.close()


@pytest.mark.parametrize(
    ("axis", "level"),
    [("pick_y", 3), ("goal_y", -3), ("scale", 3), ("distractor", 4), ("pick_y+distractor", -3)],
)
def test_axes_build_step_and_change_one_thing(mini, axis, level):
    from indgen_vla.core.protocol.progression import check_single_axis
    from scenes.axes import get_successor, shifts

    env, base = _env(axis, level, max_steps=2), _env(axis, 0)
    try:
        fields = [p.axis.field for p in shifts(get_successor(AxisRef.parse(axis)))]
        check_single_axis(base.spec, env.spec, fields, axis)
        assert env.success_predicate is base.success_predicate
        env.reset(seed=1, options={"episode": 5})
        base.reset(seed=1, options={"episode": 5})
        s, s0 = env.privileged_state(), base.privileged_state()
        diff = np.flatnonzero(env._level_state(5) != base._level_state(5))
        dpick, dgoal = env.shift
        if axis.startswith("pick_y"):
            assert s.pick.pos[1] - s0.pick.pos[1] == pytest.approx(dpick, abs=2e-3)
            assert dpick == pytest.approx(0.025 * level)
            assert list(diff) == [1 + env._qpos[env.info.pick] + 1]
        if axis == "goal_y":
            assert s.goal.pos[1] - s0.goal.pos[1] == pytest.approx(dgoal, abs=2e-3)
            assert list(diff) == [1 + env._qpos[env.info.goal] + 1]
        if axis == "scale":
            assert s.pick.bottom == pytest.approx(s0.pick.bottom, abs=2e-3)
            assert (s.pick.top - s.pick.bottom) / (s0.pick.top - s0.pick.bottom) == pytest.approx(
                1.2, abs=0.01
            )
        if "distractor" in axis:
            names = [n for n in env._env.sim.model.body_names if n.startswith("indgen_distractor_")]
            assert len({n.split("_main")[0] for n in names}) == abs(level)
        for _ in range(2):
            obs, r, term, trunc, info = env.step(np.zeros(7))
        assert trunc and not term and obs.state.shape == (8,)
        with pytest.raises(SceneError, match="reset"):
            env.step(np.zeros(7))
    finally:
        env.close()
        base.close()


def test_episode_index_fixes_the_initial_state(mini):
    env = _env("goal_y", 1)
    try:
        env.reset(seed=1, options={"episode": 7})
        a = env.privileged_state().goal.pos
        env.reset(seed=99, options={"episode": 7})
        b = env.privileged_state().goal.pos
        env.reset(seed=1, options={"episode": 8})
        c = env.privileged_state().goal.pos
        np.testing.assert_allclose(a, b, atol=1e-9)
        assert np.abs(a - c).max() > 1e-4
        lo, hi = env.support.goal_y
        assert lo - 1e-9 <= env._level_state(7)[1 + env._qpos[env.info.goal] + 1] <= hi + 1e-9
        for _ in range(5):  # the LIBERO backend feeds the failure trace too: an idle arm touches nothing
            env.step(np.array([0, 0, 0, 0, 0, 0, -1.0]))
        assert env.failure_mode(False) == "no_contact" and env.failure_mode(True) == "none"
    finally:
        env.close()


@pytest.mark.slow  # ~15 s: oracle episodes at the extreme levels
def test_oracle_certifies_extreme_levels(mini):
    from tests.fixtures.certify import run_certify

    cert = run_certify(SCENE, "pick_y", levels=[-3, 0, 3], episodes=1)
    assert [r["successes"] == r["n"] for r in cert["levels"]] == [True, True, True], cert  # no failure
    cert = run_certify(SCENE, "goal_y+distractor", levels=[3], episodes=1)
    assert cert["levels"][0]["successes"] == cert["levels"][0]["n"], cert


# the one default test of evaluate on LIBERO end to end (test_libero_adaptive is slow)
def test_evaluate_cli_with_oracle(mini, tmp_path):
    out = tmp_path / "run"
    # one level: the extremes' feasibility is test_oracle_certifies_extreme_levels; this is the evaluate pipeline
    args = ["--axis", "scale", "--levels", "3", "--episodes", "1", "--out", str(out)]
    from indgen_vla.app.cli import main

    # in-process: no interpreter start-up
    assert main(["evaluate", "--policy", "standin:oracle", "--scene", SCENE, *args]) == 0
    import pandas as pd

    eps = pd.read_parquet(out / "episodes.parquet")
    assert list(eps["success"]) == [True] and set(eps["status"]) == {"ok"}
    assert set(eps["failure"]) == {"none"}
    # the miniature tree is boxes and flat textures: the manifest records it and report.md says so before any rate
    assert json.loads((out / "manifest.json").read_text())["placeholder_assets"] is True
    first = (out / "report.md").read_text().split("\n")[2]
    assert first.startswith("**Placeholder assets** (") and "not the benchmark's own" in first


@pytest.mark.slow  # 6 s (two LIBERO builds); pick_place's shared T0 is checked against rollouts by default
def test_level_0_of_axes_with_one_key_is_one_environment(mini):
    """What a shared T0 (``evaluate``'s share_t0) relies on: axes whose level-0 ``env_key`` is equal build envs that
    start and step alike (images, state, privileged poses) from the same seed and episode."""
    from scenes.planning import resolve_scene_plan

    sp = resolve_scene_plan(get_scene(SCENE), "alphabet_soup", ["pick_y", "scale+distractor"], "0")
    keys = {sp.cell("alphabet_soup", a, 0).env_key for a in sp.axes}
    assert len(keys) == 1 and "" not in keys
    envs = [_env(a, 0, cameras=("agentview",), image_size=(32, 32)) for a in sp.axes]
    try:
        obs = [e.reset(seed=5, options={"episode": 4})[0] for e in envs]
        for _ in range(3):
            obs = [e.step(np.array([0.3, -0.2, 0.1, 0, 0, 0, 1.0]))[0] for e in envs]
        np.testing.assert_array_equal(obs[0].images["agentview"], obs[1].images["agentview"])
        np.testing.assert_array_equal(obs[0].state, obs[1].state)
        np.testing.assert_array_equal(*(e.privileged_state().pick.pos for e in envs))
    finally:
        for e in envs:
            e.close()


@pytest.mark.slow  # ~8 s: a whole LIBERO episode, then a reset
def test_reset_after_an_episode_that_ended_on_a_lazy_step_sees_fresh_frames(mini):
    """An episode that ends on a step nobody observed (``observe=False``) must not leave the next reset's cameras
    held: the first observation of episode i is the same whatever ran on the env before (seen: stale frames,
    pixel differences up to 101, before the fix)."""
    kw = dict(cameras=("agentview",), image_size=(64, 64))
    fresh, used = _env(**kw), _env(**kw)
    try:
        want, _ = fresh.reset(seed=3, options={"episode": 2})
        used.reset(seed=5, options={"episode": 4})
        for _ in range(3):
            used.step(np.array([0.3, 0, 0, 0, 0, 0, -1.0]), observe=False)
        got, _ = used.reset(seed=3, options={"episode": 2})
        np.testing.assert_allclose(got.state, want.state, atol=1e-7)
        np.testing.assert_array_equal(got.images["agentview"], want.images["agentview"])
    finally:
        fresh.close()
        used.close()


@pytest.mark.slow  # ~12 s: two LIBERO envs rendered
def test_envs_sharing_a_process_render_their_own_frames(mini):
    """robosuite renders LIBERO's cameras, and frees a hard reset's old render context, in whatever GL context is
    current; another env in the process (a pipelined lane's) and video frames (``mujoco.Renderer``) make their own
    current. Interleaved with both, an env's frames are those it renders alone (seen before the fix: the other
    scene's pixels, and after the other env's hard reset, deleted textures)."""
    kw = dict(cameras=("agentview", "wrist"), image_size=(32, 32))
    a, b = _env(**kw), _env(task="cream_cheese", **kw)
    act = np.array([0.3, -0.2, 0.1, 0, 0, 0, -1.0])

    def frames(obs):
        return [obs.images[c].copy() for c in kw["cameras"]]

    def episode(between=lambda k: None):
        obs, _ = a.reset(seed=3, options={"episode": 2})
        seen = [frames(obs)]
        for k in range(4):
            between(k)
            obs, *_ = a.step(act)
            seen.append(frames(obs))
        return seen

    def interfere(k):
        if k == 0:
            b.reset(seed=5, options={"episode": 4})
        elif k == 1:
            a.render_frame("agentview", (32, 32))
        elif k == 2:
            b.reset(seed=6, options={"episode": 1})  # frees b's previous render context
        else:
            b.close()

    try:
        want = episode()
        got = episode(interfere)
        for k, (w, g) in enumerate(zip(want, got, strict=True)):
            for c, wi, gi in zip(kw["cameras"], w, g, strict=True):
                np.testing.assert_array_equal(gi, wi, err_msg=f"{c} after step {k}")
    finally:
        a.close()
        b.close()


def test_a_held_axis_starts_its_ladder_at_the_held_level(mini):
    """distractor@pick_y=-1 at level 1: the pick object one step in -y (LIBERO's fixed states moved, condition 2
    checked against them) and one distractor; its level 0 is pick_y's level -1, and A@B=0 is A's T0."""
    sc = scenes.get_scene(SCENE)
    task = sc.tasks[0]

    def successor(name: str):
        return sc.successor(AxisRef.parse(name))

    held = successor("distractor@pick_y=-1")
    assert sc.level_identity(task, held, 0) == sc.level_identity(task, successor("pick_y"), -1)
    zero = sc.level_identity(task, successor("pick_y@distractor=0"), 0)
    assert zero == sc.level_identity(task, successor("pick_y"), 0)
    env = _env("distractor@pick_y=-1", 1, max_steps=2)
    try:
        assert (
            env.shift == (pytest.approx(-0.025), 0.0) and env.spec.distractors == 1 and env.axis_param == 1.0
        )
        names = [n for n in env._env.sim.model.body_names if n.startswith("indgen_distractor_")]
        assert len({n.split("_main")[0] for n in names}) == 1
    finally:
        env.close()


def test_an_image_policy_on_the_miniature_tree_is_no_measurement(mini, tmp_path, capsys, monkeypatch):
    """The miniature tree is boxes and flat textures: like RoboCasa's placeholders, an image policy is refused there
    unless --smoke (whose manifest says "not a measurement"); the oracle, which reads no image, runs as before. The
    policy's preview already says it will be refused, so no early worker builds a scene meanwhile (the refusal
    waited ~6 s for that build)."""
    pytest.importorskip("lerobot")
    import indgen_vla.app.engine.local as local
    from indgen_vla.app.cli import main
    from scenes.family import get_scene
    from tests.fixtures.tiny_policies import build_tiny_checkpoint

    def no_early_workers(*a, **k):
        raise AssertionError("early workers started for a policy the preview shows will be refused")

    monkeypatch.setattr(local, "EarlyWorkers", no_early_workers)
    assert get_scene("libero_object").environment.placeholder_assets()
    ckpt = build_tiny_checkpoint("act", tmp_path / "act")
    args = ["evaluate", "--policy", f"lerobot:{ckpt}", "--scene", "libero_object", "--task", "alphabet_soup",
            "--axis", "scale", "--levels", "0", "--episodes", "1", "--max-steps", "2", "--workers", "1"]  # fmt: skip
    assert main([*args, "--out", str(tmp_path / "refused")]) == 2
    assert "runs on placeholder assets" in capsys.readouterr().err  # --smoke runs it: tests/scenes/robocasa
