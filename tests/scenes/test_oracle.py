"""The privileged oracle solves T0 and the extreme default levels; certification files and videos."""

from __future__ import annotations

import json

import numpy as np
import pytest

import scenes
from indgen_vla.app.certify.certify_levels import run_oracle_episode
from indgen_vla.core.errors import ConfigError, PolicyError, RunDirError
from indgen_vla.core.protocol.axis_ref import AxisRef
from indgen_vla.core.protocol.interface import Observation, Policy
from scenes.axes import get_successor
from scenes.certificates import infeasible_levels, load_certification
from scenes.family import get_scene
from scenes.listing import builtin_scenes
from scenes.tabletop.oracle import OraclePolicy
from tests.fixtures.certify import run_certify
from tests.fixtures.levels import level_env

pytestmark = pytest.mark.filterwarnings("ignore::UserWarning")

# A representative subset runs by default; the full sweep of every axis extreme is marked slow.
FAST = [
    ("pick_place", "pick_y", 0, None),
    ("pick_place", "pick_y", -3, "bottle"),
    ("pick_place", "goal_y", 3, "lemon"),
    ("pick_place", "scale", 3, "can"),
    ("stack", "stack", 4, None),
    ("cabinet_pick", "clutter", 4, None),
]


def _spec(axis: str):
    """The shared table's spec of ``axis``."""
    return get_successor(AxisRef.parse(axis)).axis


FULL = [
    (s.name, a, k, t)
    for s in builtin_scenes()
    for a in s.axes
    for k in sorted({_spec(a).min_level, _spec(a).max_level})
    for t in s.tasks
]


def _solve(scene, axis, level, task, seed=11) -> tuple[bool, int]:
    env = level_env(scene, task=task, axis=axis, level=level, cameras=())
    try:
        return run_oracle_episode(env, OraclePolicy(), seed)
    finally:
        env.close()


@pytest.mark.parametrize(("scene", "axis", "level", "task"), FAST)
def test_oracle_solves_representative_levels(scene, axis, level, task):
    ok, steps = _solve(scene, axis, level, task)
    assert ok, f"oracle failed {scene}/{task} {axis}={level} after {steps} steps"


@pytest.mark.slow
@pytest.mark.parametrize(("scene", "axis", "level", "task"), FULL)
def test_oracle_solves_every_extreme_level_of_every_task(scene, axis, level, task):
    ok, steps = _solve(scene, axis, level, task)
    assert ok, f"oracle failed {scene}/{task} {axis}={level} after {steps} steps"


def test_oracle_protocol_and_errors():
    pol = OraclePolicy()
    assert isinstance(pol, Policy)
    assert pol.spec.name == "standin:oracle" and pol.spec.privileged and pol.spec.cameras == ()
    assert not pol.spec.batched and pol.spec.family == "standin"
    obs = Observation(images={}, state=np.zeros(8, np.float32), instruction="x")
    with pytest.raises(PolicyError, match="privileged"):
        pol.act([obs])
    with pytest.raises(PolicyError, match="not batched"):
        pol.act([obs, obs])


def test_oracle_is_deterministic_and_env_reset_does_not_leak_state():
    env = level_env("stack", axis="stack", level=1, cameras=())
    try:
        first = run_oracle_episode(env, OraclePolicy(), 3)
        q1 = env._rs.sim.data.qpos.copy()
        run_oracle_episode(env, OraclePolicy(), 4)
        again = run_oracle_episode(env, OraclePolicy(), 3)
        q2 = env._rs.sim.data.qpos.copy()
    finally:
        env.close()
    assert first == again and first[0]
    np.testing.assert_array_equal(q1, q2)


def test_certify_writes_rows_and_loads(tmp_path):
    from indgen_vla.app.cli import main

    assert (
        main(
            [
                "certify",
                "--scene",
                "stack",
                "--axis",
                "stack",
                "--levels",
                "0:1",
                "--episodes",
                "1",
                "--out",
                str(tmp_path),
            ]
        )
        == 0
    )
    cert = load_certification(tmp_path)
    assert cert["scene"] == "stack" and cert["axis"] == "stack" and cert["task"] == "orange_on_blue"
    assert [r["level"] for r in cert["levels"]] == [0, 1]
    assert cert["levels"][1]["param"] == pytest.approx(0.25)
    for r in cert["levels"]:
        assert {
            "level",
            "param",
            "n",
            "successes",
            "rate",
            "feasible",
            "lower_bound",
            "certified",
        } <= r.keys()
        assert r["n"] == 1 and r["rate"] == r["successes"] / r["n"]
        # one episode can never certify 95 %: a success leaves too little evidence, a failure fails the level
        assert not r["certified"] and r["status"] == ("insufficient" if r["successes"] else "failed")
    assert infeasible_levels(cert) == [k for k in (0, 1) if not cert["levels"][k]["successes"]]


def test_infeasible_levels_and_corrupt_files(tmp_path):
    cert = {
        "scene": "s",
        "axis": "a",
        "levels": [
            {"level": 0, "param": 0.0, "n": 20, "successes": 20, "rate": 1.0, "feasible": True},
            {"level": 1, "param": 1.0, "n": 20, "successes": 18, "rate": 0.9, "feasible": False},
        ],
    }
    p = tmp_path / "certify.json"
    p.write_text(json.dumps(cert))
    assert infeasible_levels(load_certification(p)) == [1]  # rows without a status: feasible False = failed
    p.write_text("{not json")
    with pytest.raises(RunDirError, match="not valid JSON"):
        load_certification(p)
    p.write_text(json.dumps({"scene": "s"}))
    with pytest.raises(RunDirError, match="not a certification"):
        load_certification(tmp_path)
    with pytest.raises(RunDirError, match="no certification"):
        load_certification(tmp_path / "missing")
    with pytest.raises(ConfigError, match="workers"):
        run_certify("stack", "stack", levels="0", episodes=1, workers=0)


def test_write_mp4(tmp_path):
    import imageio.v2 as imageio

    from indgen_vla.core.runs.video import write_mp4

    env = level_env("pick_place", cameras=(), max_steps=4)
    try:
        env.reset(seed=0)
        frames = [env.render_frame("agentview", (63, 80))]
        for _ in range(4):
            env.step(np.zeros(7))
            frames.append(env.render_frame("agentview", (63, 80)))
    finally:
        env.close()
    out = write_mp4(frames, tmp_path / "vid" / "pick_y_L0_ep0_success.mp4", fps=20)
    reader = imageio.get_reader(out)
    got = [f for f in reader]
    reader.close()
    assert len(got) == 5 and got[0].shape[2] == 3
    with pytest.raises(ConfigError, match="no frames"):
        write_mp4([], tmp_path / "x.mp4")
    with pytest.raises(ConfigError, match="uint8"):
        write_mp4([np.zeros((8, 8, 3), np.float32)], tmp_path / "x.mp4")


def test_find_certification_matches_scene_task_axis_and_step(tmp_path, monkeypatch):
    from scenes.certificates import find_certification

    d = tmp_path / "stack" / "orange_on_blue" / "stack"
    d.mkdir(parents=True)
    row = {"level": 0, "param": 0.0, "n": 1, "successes": 1, "rate": 1.0, "feasible": True}
    (d / "certify.json").write_text(
        json.dumps(
            {"scene": "stack", "task": "orange_on_blue", "axis": "stack", "step": 0.25, "levels": [row]}
        )
    )
    assert find_certification(get_scene("stack"), "orange_on_blue", "stack", root=tmp_path)["levels"] == [row]
    assert find_certification(get_scene("stack"), "orange_on_blue", "stack", step=0.5, root=tmp_path) is None
    assert find_certification(get_scene("stack"), "orange_on_blue", "pick_y", root=tmp_path) is None
    assert (
        find_certification(
            get_scene("stack"), list(scenes.get_scene("stack").tasks)[1], "stack", root=tmp_path
        )
        is None
    )
    monkeypatch.setenv("INDGEN_CERT_DIR", str(tmp_path))
    assert find_certification(get_scene("stack"), None, "stack") is not None
