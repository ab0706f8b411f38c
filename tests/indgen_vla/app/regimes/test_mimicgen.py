"""MimicGen augmentation: SE(3) segment transforms on hand-computed poses, subtask splits, config errors,
and a generated dataset's round trip through lerobot's ``LeRobotDataset``."""

import json
import shutil

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from indgen_vla.app.regimes.mimicgen import MimicGenConfig, _new_seed
from indgen_vla.app.regimes.mimicgen_sources import load_sources, split_subtasks
from indgen_vla.app.regimes.se3 import (
    interpolate_poses,
    invert_pose,
    pose_from_pq,
    pose_from_state,
    pose_matrix,
    pose_to_action,
    target_poses,
    transform_segment,
)
from indgen_vla.core.errors import ConfigError

R_DOWN = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
RZ90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def _pose(pos, rot):
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = rot, pos
    return t


def test_pose_constructors_and_inverse():
    s = np.sqrt(0.5)
    assert np.allclose(
        pose_from_pq([0.2, 0.1, 0.8, s, 0, 0, s]), _pose([0.2, 0.1, 0.8], RZ90)
    )  # wxyz, 90° about z
    state = np.array([0.1, 0.2, 1.0, *Rotation.from_matrix(R_DOWN).as_rotvec(), 0.04, -0.04])
    assert np.allclose(pose_from_state(state), _pose([0.1, 0.2, 1.0], R_DOWN))
    t = _pose([1.0, 2.0, 3.0], RZ90)
    assert np.allclose(invert_pose(t), _pose([-2.0, 1.0, -3.0], RZ90.T))  # -R^T p = -(2, -1, 3)
    assert np.allclose(invert_pose(t) @ t, np.eye(4))


def test_segment_transform_translation_only():
    poses = np.stack([_pose([0.15, 0.0, 0.9], R_DOWN), _pose([0.1, -0.05, 0.85], R_DOWN)])
    out = transform_segment(poses, _pose([0.1, 0.0, 0.8], np.eye(3)), _pose([0.13, -0.02, 0.8], np.eye(3)))
    assert np.allclose(out[0], _pose([0.18, -0.02, 0.9], R_DOWN))
    assert np.allclose(out[1], _pose([0.13, -0.07, 0.85], R_DOWN))


def test_segment_transform_with_rotation_by_hand():
    # eef 5 cm in front of (+x) and 10 cm above the object; the object moves to (0.2, 0.1) and turns 90° about z:
    # the offset turns to +y, i.e. (0.2, 0.15, 0.9), and the gripper turns with it: RZ90 @ R_DOWN
    src_obj, new_obj = (
        _pose([0.1, 0.0, 0.8], np.eye(3)),
        pose_from_pq([0.2, 0.1, 0.8, np.sqrt(0.5), 0, 0, np.sqrt(0.5)]),
    )
    out = transform_segment(_pose([0.15, 0.0, 0.9], R_DOWN)[None], src_obj, new_obj)[0]
    assert np.allclose(out[:3, 3], [0.2, 0.15, 0.9])
    assert np.allclose(out[:3, :3], [[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]])
    # the eef stays fixed in the object's frame
    assert np.allclose(invert_pose(new_obj) @ out, invert_pose(src_obj) @ _pose([0.15, 0.0, 0.9], R_DOWN))


def test_interpolation_is_linear_and_slerp():
    start, end = np.eye(4), _pose([0.1, 0.0, -0.02], RZ90)
    path = interpolate_poses(start, end, 2)
    assert path.shape == (2, 4, 4) and np.allclose(path[-1], end)
    assert np.allclose(path[0][:3, 3], [0.05, 0.0, -0.01])
    assert np.allclose(path[0][:3, :3], Rotation.from_euler("z", 45, degrees=True).as_matrix())
    assert interpolate_poses(start, end, 0).shape == (0, 4, 4)


def test_action_to_target_and_back():
    # OSC_POSE: goal = p + 0.05 a[:3], Rot(0.5 a[3:6]) @ R (world frame)
    state = np.array([0.1, 0.2, 1.0, *Rotation.from_matrix(R_DOWN).as_rotvec(), 0.04, -0.04])
    action = np.array([0.2, -0.4, 1.0, 0.1, 0.0, -0.2, 1.0])
    target = target_poses(state[None], action[None])[0]
    assert np.allclose(target[:3, 3], [0.11, 0.18, 1.05])
    assert np.allclose(target[:3, :3], Rotation.from_rotvec([0.05, 0.0, -0.1]).as_matrix() @ R_DOWN)
    assert np.allclose(pose_to_action(target, pose_from_state(state), 1.0), action)
    # by hand: 1 cm along x and 0.1 rad about z from the identity -> (0.2, 0, 0, 0, 0, 0.2); 10 cm clips to 1
    cur = _pose([0.0, 0.0, 1.0], np.eye(3))
    tgt = pose_matrix([0.01, 0.0, 1.0], Rotation.from_rotvec([0.0, 0.0, 0.1]))
    assert np.allclose(pose_to_action(tgt, cur, -1.0), [0.2, 0, 0, 0, 0, 0.2, -1.0])
    assert pose_to_action(_pose([0.1, 0.0, 1.0], np.eye(3)), cur, -1.0)[0] == 1.0


def test_split_subtasks_at_the_lift():
    t = np.arange(20)
    states = np.zeros((20, 8))
    states[:, 2] = 0.9 + 0.01 * np.clip(t - 7, 0, 5)  # lifts 5 cm over steps 8..12
    actions = np.zeros((20, 7))
    actions[:, -1] = np.where((t >= 5) & (t < 15), 1.0, -1.0)  # closes at 5, releases at 15
    assert split_subtasks(states, actions, lift_frac=0.9) == [(0, 12), (12, 20)]  # 0.95 >= 0.9 + 0.9 * 0.05
    assert split_subtasks(states, actions, lift_frac=0.1)[0] == (0, 8)
    regrasp = actions.copy()
    regrasp[8, -1] = -1.0
    assert split_subtasks(states, regrasp) is None
    assert (
        split_subtasks(states, np.where(t[:, None] >= 5, 1.0, -1.0) * np.ones((20, 7))) is None
    )  # no release


def test_config_errors(tmp_path):
    with pytest.raises(ConfigError, match="not a LeRobotDataset"):
        MimicGenConfig(source=tmp_path / "nope", out=tmp_path / "out", n=3)
    (tmp_path / "src" / "meta").mkdir(parents=True)
    feats = {
        "observation.state": {"dtype": "float32", "shape": [8]},
        "action": {"dtype": "float32", "shape": [7]},
    }
    (tmp_path / "src" / "meta" / "info.json").write_text(json.dumps({"features": feats}))
    with pytest.raises(ConfigError, match="--n must be >= 1"):
        MimicGenConfig(source=tmp_path / "src", out=tmp_path / "out", n=0)
    with pytest.raises(ConfigError, match="--selection"):
        MimicGenConfig(source=tmp_path / "src", out=tmp_path / "out", n=1, selection="best")
    with pytest.raises(ConfigError, match="must differ from --source"):
        MimicGenConfig(source=tmp_path / "src", out=tmp_path / "src", n=1)
    with pytest.raises(ConfigError, match="indgen_episodes.jsonl"):
        load_sources(tmp_path / "src")


def test_new_seeds_are_deterministic_and_avoid_source_seeds():
    cfg = MimicGenConfig.__new__(MimicGenConfig)
    object.__setattr__(cfg, "seed", 7)
    a = [_new_seed(cfg, "pick_place", "lemon", i, set()) for i in range(5)]
    assert a == [_new_seed(cfg, "pick_place", "lemon", i, set()) for i in range(5)] and len(set(a)) == 5
    assert _new_seed(cfg, "pick_place", "lemon", 0, {a[0]}) != a[0]


@pytest.mark.slow  # ~30 s with images; test_train carries object poses through mimicgen by default
def test_mimicgen_round_trip_through_lerobot(tmp_path, one_demo):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from indgen_vla.app.api import mimicgen as generate
    from indgen_vla.app.regimes.demos import read_episode_sidecar

    (src, _), out = one_demo, tmp_path / "gen"
    rec = read_episode_sidecar(src)
    assert (
        len(rec) == 1
        and rec[0]["episode_index"] == 0
        and len(rec[0]["object_poses"]["pick"]) == rec[0]["frames"]
    )
    stats = generate(MimicGenConfig(source=src, out=out, n=1, seed=1, guarantee=True, max_attempts=3))
    assert stats["successes"] == 1 and 1 <= stats["attempts"] <= 3
    saved = json.loads((out / "mimicgen_stats.json").read_text())
    assert saved["successes"] == 1 and saved["source"] == str(src) and saved["seed"] == 1
    a, b = LeRobotDataset("local/indgen_demos", root=src), LeRobotDataset("local/indgen_mimicgen", root=out)
    assert b.num_episodes == 1 and len(b) == stats["frames"] and b.fps == a.fps
    assert a.features == b.features and list(a.meta.tasks.index) == list(b.meta.tasks.index)
    item = b[0]
    assert tuple(item["observation.images.wrist"].shape) == (3, 32, 32) and item["task"] == a[0]["task"]
    actions = np.stack([b[i]["action"].numpy() for i in range(len(b))])
    assert np.all(np.abs(actions) <= 1.0) and actions[:, -1].max() == 1.0 and actions[-1, -1] == -1.0
    gen = read_episode_sidecar(out)
    assert (
        gen[0]["regime"] == "mimicgen"
        and gen[0]["seed"] != rec[0]["seed"]
        and gen[0]["source_episodes"] == [0, 0]
    )


def test_mimicgen_generates_each_level_from_its_own_sources(level_demos, tmp_path):
    """A source recorded at pick_y levels 0 and 1: each level's episodes are generated at that level, from that
    level's sources, with the level columns and sidecar fields carried over and seeds evaluate never uses."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from indgen_vla.app.api import mimicgen as generate
    from indgen_vla.app.regimes.demos import LEVEL_FEATURES, read_episode_sidecar
    from indgen_vla.core.protocol.seeding import held_out_seeds

    src = level_demos[0]
    stats = generate(
        MimicGenConfig(source=src, out=tmp_path / "gen", n=1, seed=1, guarantee=True, max_attempts=3)
    )
    assert set(stats["tasks"]) == {"milk pick_y level 0", "milk pick_y level 1"} and stats["successes"] == 2
    sources = {r["episode_index"]: r for r in read_episode_sidecar(src)}
    gen = read_episode_sidecar(tmp_path / "gen")
    assert sorted((r["level"], r["axis"], r["param"]) for r in gen) == sorted(
        (r["level"], r["axis"], r["param"]) for r in sources.values()
    )
    for r in gen:
        assert {sources[i]["level"] for i in r["source_episodes"]} == {
            r["level"]
        }  # never another level's source
        assert r["seed"] not in held_out_seeds("pick_place", "milk", also=(1,))
        assert (
            abs(r["object_poses"]["pick"][0][1] - r["param"]) < 0.03
        )  # the pick object starts at its level's y
    ds = LeRobotDataset("local/indgen_mimicgen", root=tmp_path / "gen")
    assert set(LEVEL_FEATURES) <= set(ds.features)
    assert {int(ds[i]["level"]) for i in range(len(ds))} == {0, 1}


def _dataset(root) -> dict:
    """What a generated dataset holds, out-independent: every file's content (``dataset_digest``) but the two that
    record paths and seconds, the sidecar, and the stats without them."""
    from indgen_vla.app.regimes.demos import read_episode_sidecar
    from indgen_vla.app.regimes.mimicgen import RECORD, STATS_FILE
    from tests.fixtures.datasets import dataset_digest

    digest = dataset_digest(root)
    assert RECORD in digest and STATS_FILE in digest
    stats = json.loads((root / STATS_FILE).read_text())
    for key in ("out", "wall_s", "config"):
        stats.pop(key)
    return {"digest": {k: v for k, v in digest.items() if k not in (RECORD, STATS_FILE)},
            "sidecar": read_episode_sidecar(root), "stats": stats}  # fmt: skip


def _assert_same_dataset(a: dict, b: dict) -> None:
    assert not any(f.startswith(".indgen_journal") for f in b["digest"])
    assert a == b


RUN = {"n": 3, "seed": 1, "action_noise": 0.3}  # its attempts: kept, discarded, kept


@pytest.fixture(scope="module")
def generated(demos, tmp_path_factory):
    """Three uninterrupted attempts from the two T0 demos (two kept)."""
    from indgen_vla.app.api import mimicgen as generate

    out = tmp_path_factory.mktemp("mg") / "gen"
    generate(MimicGenConfig(source=demos, out=out, **RUN))
    return out


@pytest.mark.slow  # ~14 s: a generation interrupted and resumed
def test_interrupted_generation_resumes_to_the_same_dataset(generated, demos, tmp_path):
    """Stopped (Ctrl-C) after its first kept episode and a discarded attempt, with the next staging cut short as a
    kill leaves it, the rerun keeps that episode, runs the discarded attempt again and writes the same dataset,
    file by file, as an uninterrupted run."""
    from indgen_vla.app.api import mimicgen as generate
    from indgen_vla.app.regimes.journal import JOURNAL, read_episode_sidecar
    from indgen_vla.app.regimes.mimicgen import RECORD

    out, said = tmp_path / "gen", []

    def stop(label, ok, attempt, total):
        if attempt > ok > 0:  # after the discarded attempt that follows the first kept one
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        generate(MimicGenConfig(source=demos, out=out, **RUN), progress=stop)
    assert json.loads((out / RECORD).read_text())["complete"] is False and len(read_episode_sidecar(out)) == 1
    assert sorted(p.name for p in (out / JOURNAL).iterdir()) == ["checkpoint-000000", "ep-000000.pkl"]
    (out / JOURNAL / ".ep-000001.pkl.k1ll3d").write_bytes(b"torn")
    generate(MimicGenConfig(source=demos, out=out, **RUN), say=said.append)
    assert said[0] == f"mimicgen: resuming {out}: 1 episodes already saved"
    _assert_same_dataset(_dataset(generated), _dataset(out))


@pytest.mark.slow  # ~20 s with its generated dataset
def test_finished_generation_is_a_no_op_and_other_arguments_are_refused(generated, demos, tmp_path):
    from indgen_vla.app.api import mimicgen as generate

    stamp = {str(p): p.stat().st_mtime_ns for p in generated.rglob("*")}
    said = []
    stats = generate(MimicGenConfig(source=demos, out=generated, **RUN), say=said.append)
    assert said == [
        f"mimicgen: {generated} is already complete ({stats['successes']} episodes); nothing to do"
    ]
    assert {str(p): p.stat().st_mtime_ns for p in generated.rglob("*")} == stamp
    with pytest.raises(
        ConfigError, match="finished run made with --n 3, not --n 4; rerun with --n 3, or choose"
    ):
        generate(MimicGenConfig(source=demos, out=generated, **{**RUN, "n": 4}))
    with pytest.raises(ConfigError, match="made with no --guarantee, not --guarantee"):
        generate(MimicGenConfig(source=demos, out=generated, **{**RUN, "guarantee": True}))
    cut = tmp_path / "cut"  # killed between marking the dataset complete and writing its stats
    shutil.copytree(generated, cut)
    (cut / "mimicgen_stats.json").unlink()
    assert generate(MimicGenConfig(source=demos, out=cut, **RUN)) == stats
    assert (cut / "mimicgen_stats.json").read_text() == (generated / "mimicgen_stats.json").read_text()
    foreign = tmp_path / "notes"
    foreign.mkdir()
    (foreign / "todo.txt").write_text("keep me")
    with pytest.raises(ConfigError, match="already exists and is not empty"):
        generate(MimicGenConfig(source=demos, out=foreign, n=1))


def _staged_episodes(out) -> int:
    """Kept episodes a rerun keeps (fewer than 20: none checkpointed yet), as the journal stages them."""
    return len(list((out / ".indgen_journal").glob("ep-*.pkl")))


@pytest.mark.slow  # two interpreter start-ups with robosuite (~15 s each here)
def test_sigkilled_generation_resumes_to_the_same_dataset(generated, demos, tmp_path):
    import subprocess
    import sys

    from tests.fixtures.kill import kill_midway

    argv = ["mimicgen", "--source", str(demos), "--n", "3", "--action-noise", "0.3", "--seed", "1"]
    out = tmp_path / "killed"
    kept = json.loads((generated / "mimicgen_stats.json").read_text())["successes"]
    saved = kill_midway(argv, out, total=kept, count=_staged_episodes)
    assert 1 <= saved < kept
    run = subprocess.run([sys.executable, "-m", "indgen_vla.app.cli", *argv, "--out", str(out)], capture_output=True,
                         text=True)  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert f"{saved} episodes already saved" in " ".join(run.stderr.split())
    _assert_same_dataset(_dataset(generated), _dataset(out))
    bad = subprocess.run([sys.executable, "-m", "indgen_vla.app.cli", *argv[:-1], "2", "--out", str(out)],
                         capture_output=True, text=True)  # fmt: skip
    assert (
        bad.returncode == 2 and bad.stderr.strip().count("\n") == 0 and "--seed 1, not --seed 2" in bad.stderr
    )
