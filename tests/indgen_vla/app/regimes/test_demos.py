"""Noisy-oracle T0 demonstrations round-trip through lerobot's own LeRobotDataset."""

from pathlib import Path

import numpy as np
import pytest

from indgen_vla.app import api
from indgen_vla.app.regimes.demos import DemosConfig, HumanNoise
from indgen_vla.core.errors import ConfigError
from tests.fixtures.levels import level_env, level_param


@pytest.mark.slow  # ~30 s (32-px rendering + dataset write); test_train covers the state-only round trip by default
def test_demos_round_trip_through_lerobot(one_demo):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    out, stats = one_demo
    assert stats["episodes"] == 1 and stats["frames"] > 50
    ds = LeRobotDataset("local/indgen_demos", root=out)
    assert ds.num_episodes == 1 and len(ds) == stats["frames"]
    item = ds[0]
    assert tuple(item["observation.images.agentview"].shape) == (3, 32, 32)
    assert tuple(item["observation.state"].shape) == (8,) and tuple(item["action"].shape) == (7,)
    assert item["task"].startswith("pick up the") and item["task"].endswith("in the basket")
    actions = np.stack([ds[i]["action"].numpy() for i in range(len(ds))])
    assert np.all(np.abs(actions) <= 1.0) and set(np.unique(np.sign(actions[:, -1]))) <= {-1.0, 1.0}
    assert actions[:, -1].max() == 1.0  # the gripper closed at some point: a grasp happened
    with pytest.raises(ConfigError, match="made with --seed 3, not --seed 0"):
        api.demos(DemosConfig(scene="pick_place", out=out, n=1, workers=1))


def test_noise_validation():
    with pytest.raises(ConfigError):
        HumanNoise(sigma=-1)
    with pytest.raises(ConfigError):
        HumanNoise(pause_steps=(3, 1))


def _run(code: str) -> str:
    """stdout + stderr of ``code`` in a fresh interpreter (robosuite not imported yet: its warning would show)."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout + out.stderr


def test_demos_build_t0_and_levels_through_the_plans_builder():
    """T0 is level 0 of the family's first axis, each task's own; --axis cells use the plan's builder."""
    from indgen_vla.app.regimes.demos import LevelRequest, plan_cells
    from scenes import get_scene
    from scenes.planning import resolve_scene_plan, scene_levels

    cells, maker = plan_cells(get_scene("pick_place"), "all", LevelRequest(), (), 64)
    assert maker.t0_axis == "pick_y" and {c.axis for c in cells} == {None}
    assert maker.builder == scene_levels(get_scene("pick_place"), ["pick_y"], tasks=[c.task for c in cells])
    at = LevelRequest(axes=("pick_y+distractor",), levels="0:1")
    cells, maker = plan_cells(get_scene("pick_place"), "milk", at, (), 64)
    assert (
        maker.builder
        == resolve_scene_plan(get_scene("pick_place"), "milk", ["pick_y+distractor"], "0:1").builder
    )
    assert [(c.axis, c.level) for c in cells] == [("pick_y+distractor", 0), ("pick_y+distractor", 1)]


@pytest.mark.slow  # ~12 s: fresh interpreters
def test_demos_and_mimicgen_build_their_scenes_without_robosuites_macro_warning():
    """Both commands build scenes in their own process through the plan's builder, whose layouts import robosuite by
    scenes.tabletop.mjcf, not scenes.sim: its three-line macro-file warning must not reach the terminal there either
    (the fork server's preload: tests/scenes/test_planning.py::test_the_fork_servers_preload_is_quiet)."""
    code = ("import indgen_vla.app.regimes.mimicgen\n"
            "from indgen_vla.app.regimes.demos import LevelRequest, plan_cells\n"
            "from scenes import get_scene\n"
            "cells, maker = plan_cells(get_scene('pick_place'), None, LevelRequest(), (), 64)\n"
            "env = maker(cells[0])\nenv.reset(seed=0)\nenv.close()")  # fmt: skip
    assert "macro" not in _run(code)


@pytest.mark.slow  # ~25 s: both commands end to end, one state-only episode each
def test_the_demos_and_mimicgen_commands_print_no_macro_warning(tmp_path):
    src, dst = tmp_path / "demos", tmp_path / "mg"
    out = _run(f"from indgen_vla.app.cli import main\nassert main(['demos', '--scene', 'pick_place', '--n', '1', "
               f"'--cameras', '', '--out', {str(src)!r}]) == 0\n"
               f"assert main(['mimicgen', '--source', {str(src)!r}, '--n', '1', '--out', {str(dst)!r}]) == 0")  # fmt: skip
    assert "recorded 1 episodes" in out and "macro" not in out


# ---- levels (--axis/--levels), the default path, and seeds evaluate never shares -------------------------------
SIDECAR_KEYS = ["episode_index", "regime", "scene", "task", "seed", "level", "frames", "object_poses"]


@pytest.mark.parametrize(
    "flags, message",
    [
        (["--levels", "0:2"], "--levels, --step and --axes-preset need --axis"),
        (["--axis", "pick_y"], "--axis pick_y needs --levels"),
        (["--axis", "pick_y,scale", "--levels", "0:1"], "one axis per dataset"),
        (["--axis", "pick_yy", "--levels", "0:1"], "unknown axis 'pick_yy'; did you mean 'pick_y'"),
        (
            ["--axis", "pick_y", "--levels", "-4:-2"],
            "level -4 is outside axis pick_y's range -3..3",
        ),  # a range, not a flag
        (["--axis", "scale", "--levels", "2:0"], "write it as 0:2"),
        (
            ["--axis", "scale", "--levels", "0:1", "--task", "milkk"],
            "unknown task of scene pick_place 'milkk'",
        ),
        (["--scene", "libero_object", "--axis", "scale", "--levels", "0:1"], "fixed initial states"),
        (["--workers", "0"], "--workers must be >= 1, got 0"),
    ],
)
def test_bad_level_arguments_are_one_line_exit_2_and_write_nothing(tmp_path, capsys, flags, message):
    from indgen_vla.app.cli import main

    out = tmp_path / "demos"
    assert main(["demos", "--scene", "pick_place", "--n", "1", "--out", str(out), *flags]) == 2
    err = capsys.readouterr().err
    assert message in err and err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()


def test_default_demos_keep_the_features_sidecar_and_seeds_they_always_had(demos):
    """Without --axis nothing changed: no level columns, the sidecar's keys in their order, T0's seed formula."""
    import json

    from indgen_vla.app.regimes.demos import LEVEL_FEATURES, features, read_episode_sidecar

    info = json.loads((demos / "meta" / "info.json").read_text())
    assert not set(LEVEL_FEATURES) & set(info["features"])
    assert set(features((), (96, 96), False, objects=True)) <= set(info["features"])
    records = read_episode_sidecar(demos)
    assert [list(r) for r in records] == [SIDECAR_KEYS] * 2 and {r["level"] for r in records} == {0}
    assert [r["seed"] for r in records] == [
        2370510695,
        1920048413,
    ]  # episode_seed(5, "demos", "pick_place", "milk", i)


def _demo_seeds(seed: int, task: str, n: int, key: tuple = ()) -> list[int]:
    from indgen_vla.core.protocol.seeding import episode_seed

    return [
        episode_seed(seed, "demos", "pick_place", task, *key, a) for a in range(3 * n)
    ]  # every attempt allowed


def test_default_demo_and_mimicgen_seeds_are_disjoint_from_evaluations():
    """Every seed demos (3 n attempts, n = 200) and mimicgen (5 n) may take with default arguments, at T0 and at pick_y
    levels, lies outside the held-out evaluation seeds (evaluate --seed 0..9, 1000 episodes), so the guard never
    bumps one: default datasets keep their seeds, and none starts where an evaluation episode does."""
    import scenes
    from indgen_vla.core.protocol.seeding import episode_seed, evaluation_seed, fresh_seed, held_out_seeds

    for task in list(scenes.get_scene("pick_place").tasks):
        held = held_out_seeds("pick_place", task)
        evaluate_default = {evaluation_seed(0, "pick_place", task, e) for e in range(50)}
        assert evaluate_default <= held
        seeds = _demo_seeds(0, task, 200)
        for k in (-3, -1, 1, 3):
            seeds += _demo_seeds(0, task, 200, ("pick_y", k))
        seeds += [episode_seed(0, "mimicgen", "pick_place", task, a, 0) for a in range(1000)]
        assert not set(seeds) & held
        assert fresh_seed(0, "demos", "pick_place", task, 0, avoid=held) == seeds[0]


def test_level_demos_record_each_level_with_its_axis_parameter(level_demos, demos):
    """Per frame (lerobot reads the columns back) and in the sidecar; level 0 is the default recording's episode."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from indgen_vla.app.regimes.demos import read_episode_sidecar

    out, stats = level_demos
    assert stats["episodes"] == 2 and stats["axis"] == "pick_y" and stats["levels"] == [0, 1]
    records = read_episode_sidecar(out)
    want = {k: level_param("pick_place", "milk", "pick_y", k) for k in (0, 1)}
    assert [(r["level"], r["axis"], r["param"]) for r in records] == [(k, "pick_y", want[k]) for k in (0, 1)]
    data = LeRobotDataset("local/indgen_demos", root=out).hf_dataset.with_format("numpy")
    cols = {k: np.asarray(data[k]) for k in ("episode_index", "level", "axis", "axis_param")}
    for r in records:
        rows = np.flatnonzero(cols["episode_index"] == r["episode_index"])
        assert len(rows) == r["frames"] and set(cols["level"][rows]) == {r["level"]}
        assert set(cols["axis"][rows]) == {"pick_y"}
        np.testing.assert_allclose(cols["axis_param"][rows], want[r["level"]])
    t0 = read_episode_sidecar(demos)[0]
    assert records[0]["seed"] == t0["seed"] and records[0]["object_poses"] == t0["object_poses"]
    # level 1 moved the pick object one pick_y step (25 mm) from T0's, up to T0's placement jitter
    y0, y1 = (r["object_poses"]["pick"][0][1] for r in records)
    assert abs((y1 - want[1]) - (y0 - want[0])) < 0.03 and records[1]["seed"] != records[0]["seed"]


def test_demos_start_from_other_initial_states_than_evaluation_episodes(level_demos):
    from indgen_vla.app.regimes.demos import read_episode_sidecar
    from indgen_vla.core.protocol.seeding import evaluation_seed
    from scenes.poses import object_poses
    from scenes.privileged import privileged_of, with_privileged

    env = level_env("pick_place", task="milk", cameras=())
    try:
        starts = []
        for e in range(5):
            obs, _ = env.reset(seed=evaluation_seed(0, "pick_place", "milk", e))
            starts.append(object_poses(privileged_of(with_privileged(obs, env), "test"))["pick"][:2])
    finally:
        env.close()
    demo = read_episode_sidecar(level_demos[0])[0]["object_poses"]["pick"][0][:2]
    assert min(np.hypot(*(np.asarray(demo) - s)) for s in starts) > 1e-4


# ---- resuming, workers, and reruns into an existing dataset ------------------------------------------------------
# the `demos` fixture's arguments as `indgen demos` flags
DEMOS_FLAGS = ["--scene", "pick_place", "--n", "2", "--seed", "5", "--cameras", "", "--objects"]


def _sidecar_lines(out) -> int:
    path = out / "meta" / "indgen_episodes.jsonl"
    return len(path.read_text().splitlines()) if path.is_file() else 0


@pytest.mark.slow  # ~25 s: a 2-worker recording interrupted and resumed
def test_an_interrupted_two_worker_recording_resumes_into_the_uninterrupted_dataset(demos, tmp_path):
    """Ctrl-C after the first kept episode of a 2-worker run, resumed with 1 worker: the files of the `demos`
    fixture (one uninterrupted in-process run), the first episode saved again from the journal."""
    from tests.fixtures.datasets import dataset_digest

    out = tmp_path / "demos"

    def interrupt(label, kept, attempt):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        api.demos(
            DemosConfig(scene="pick_place", out=out, n=2, seed=5, cameras=(), objects=True, workers=2),
            progress=interrupt,
        )
    assert _sidecar_lines(out) == 1 and not json_of(out)["complete"]
    said = []
    stats = api.demos(
        DemosConfig(scene="pick_place", out=out, n=2, seed=5, cameras=(), objects=True, workers=1),
        notice=said.append,
    )
    assert said == [f"resuming {out}: 1 of 2 episodes already recorded"]
    assert stats["episodes"] == 2 and json_of(out)["stats"] == stats
    assert dataset_digest(out) == dataset_digest(demos)


def json_of(out) -> dict:
    import json

    return json.loads((out / "meta" / "indgen_demos.json").read_text())


def test_a_complete_dataset_rerun_says_so_and_changes_nothing(demos, capsys):
    from indgen_vla.app.cli import main
    from tests.fixtures.datasets import dataset_digest

    before = dataset_digest(demos)
    assert main(["demos", *DEMOS_FLAGS, "--workers", "2", "--out", str(demos)]) == 0
    err = capsys.readouterr().err
    assert f"{demos} is already complete: 2 episodes" in err and "nothing to do" in err
    assert dataset_digest(demos) == before


@pytest.mark.parametrize(
    "change, message",
    [
        (
            ["--n", "3"],
            "holds a finished run made with --n 2, not --n 3; rerun with --n 2, or choose a new --out",
        ),
        (["--noise", "0.2"], "made with --noise 0.1, not --noise 0.2"),
        (["--cameras", "agentview"], "made with no --cameras, not --cameras agentview"),
        (["--task", "milk"], "made with no --task, not --task milk"),
    ],
)
def test_a_rerun_with_other_arguments_is_refused_naming_the_option(demos, capsys, change, message):
    from indgen_vla.app.cli import main
    from tests.fixtures.datasets import dataset_digest

    before = dataset_digest(demos)
    flags = DEMOS_FLAGS.copy()
    for flag, value in zip(change[::2], change[1::2], strict=True):
        if flag in flags:
            flags[flags.index(flag) + 1] = value
        else:
            flags += [flag, value]
    assert main(["demos", *flags, "--out", str(demos)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.startswith("error: ") and err.count("\n") == 1
    assert dataset_digest(demos) == before


def test_a_directory_that_is_no_demos_dataset_is_refused(tmp_path, capsys):
    from indgen_vla.app.cli import main

    out = tmp_path / "other"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert main(["demos", *DEMOS_FLAGS, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "already exists and is not an indgen demos dataset" in err and err.count("\n") == 1
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


def _processes_with(marker: str) -> list[int]:
    """Live processes whose environment holds ``marker`` (a killed run's fork server and workers inherit it)."""
    pids = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit() and marker.encode() in (proc / "environ").read_bytes():
                pids.append(int(proc.name))
        except OSError:  # gone, or a zombie
            continue
    return pids


@pytest.mark.slow  # ~40 s: two CLI runs (a fork server and 2 workers each), killed and resumed
def test_a_killed_demos_command_resumes_into_the_uninterrupted_dataset(demos, tmp_path, monkeypatch):
    """SIGKILL after the first saved episode: the workers and the fork server exit too (a pool worker would
    otherwise wait for work forever), and the rerun ends with the uninterrupted dataset."""
    import time

    from indgen_vla.app.cli import main
    from tests.fixtures.datasets import dataset_digest
    from tests.fixtures.kill import kill_midway

    marker = f"INDGEN_TEST_RUN={tmp_path.name}"
    monkeypatch.setenv("INDGEN_TEST_RUN", tmp_path.name)
    out = tmp_path / "demos"
    argv = ["demos", *DEMOS_FLAGS, "--workers", "2"]
    assert kill_midway(argv, out, total=2, at_least=1, timeout_s=300, count=_sidecar_lines) == 1
    deadline = time.time() + 15
    while _processes_with(marker) and time.time() < deadline:
        time.sleep(0.2)
    assert _processes_with(marker) == []
    assert main([*argv, "--out", str(out)]) == 0
    assert dataset_digest(out) == dataset_digest(demos)


@pytest.mark.slow  # ~2-4 min: 4 rendered episodes (16 px, both cameras)
def test_rendered_demos_are_the_same_for_one_and_two_workers(tmp_path):
    from tests.fixtures.datasets import dataset_digest

    one, two = tmp_path / "one", tmp_path / "two"
    api.demos(DemosConfig(scene="pick_place", out=one, n=2, seed=7, image_size=16, workers=1))
    api.demos(DemosConfig(scene="pick_place", out=two, n=2, seed=7, image_size=16, workers=2))
    assert dataset_digest(one) == dataset_digest(two)


def test_demos_config_names_ideas_as_evaluate_does_and_refuses_in_one_line(tmp_path):
    """``indgen demos``' flags parse into a ``DemosConfig`` (the level section named as evaluate names it); a bad
    value is one line naming the flag."""
    from indgen_vla.app.config_fields import from_flat
    from indgen_vla.app.regimes.demos import LevelRequest

    flat = {"scene": "pick_place", "n": 2, "out": tmp_path, "axes": "pick_y", "levels": "0:1", "cameras": "",
            "noise": 0.2, "workers": 1}  # fmt: skip
    cfg = from_flat(DemosConfig, flat, command="demos")
    assert cfg.at == LevelRequest(axes=("pick_y",), levels="0:1") and cfg.at.axis == "pick_y"
    assert cfg.cameras == () and cfg.noise == HumanNoise(sigma=0.2) and cfg.out == tmp_path
    for values, says in (
        ({"n": 0}, "--n must be >= 1, got 0"),
        ({"workers": 0}, "--workers must be >= 1, got 0"),
    ):
        with pytest.raises(ConfigError, match=says):
            DemosConfig(**{"scene": "pick_place", "n": 1, "out": tmp_path, **values})
    with pytest.raises(ConfigError, match="indgen demos records one axis per dataset"):
        LevelRequest(axes="pick_y,scale", levels="0:1")
    with pytest.raises(ConfigError, match="--axis pick_y needs --levels"):
        LevelRequest(axes=("pick_y",))
