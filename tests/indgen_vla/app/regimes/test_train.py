"""A few-step lerobot training run on recorded demos: loss falls, the checkpoint loads through ``lerobot:``."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from indgen_vla.app.regimes.train import TrainConfig, TrainRecipe, train_policy
from indgen_vla.core.errors import ConfigError, PolicyError
from indgen_vla.core.protocol.interface import Observation
from indgen_vla.core.protocol.training_support import TrainedCell

pytest.importorskip("lerobot")
pytestmark = pytest.mark.timeout(180)

SHIPPED = Path(__file__).resolve().parents[4] / "checkpoints" / "act_pick_place_human"


@pytest.fixture(scope="module")
def trained(demos, tmp_path_factory) -> Path:
    """A 120-step state-only ACT trained on the demos (given twice: a two-dataset run)."""
    cfg = TrainRecipe(
        steps=120, batch_size=16, dim_model=32, n_heads=2, dim_feedforward=64, log_every=20, seed=1
    )
    return train_policy(
        TrainConfig(
            datasets=[demos, demos],
            out=tmp_path_factory.mktemp("ckpt") / "act",
            recipe=cfg,
            data_regime="test",
        )
    )


def _obs(state: np.ndarray) -> Observation:
    return Observation(images={}, state=state.astype(np.float32), instruction="pick up the milk carton")


def test_loss_decreases_and_checkpoint_is_saved(trained, demos):
    info = json.loads((trained / "train_info.json").read_text())
    losses = info["losses"]
    assert len(losses) == 6 and losses[-1] < 0.7 * info["first_loss"], (info["first_loss"], losses)
    assert info["episodes"] == 4 and info["data_regime"] == "test" and info["config"]["seed"] == 1
    # T0 demos recorded without --axis, given twice: level 0 of every axis, 4 episodes
    t0 = {"scene": "pick_place", "task": "milk", "level": 0, "axis": None, "param": None, "episodes": 4}
    assert info["levels"] == [t0]
    for name in ("config.json", "model.safetensors", "policy_preprocessor.json", "policy_postprocessor.json"):
        assert (trained / name).is_file(), name
    steps = json.loads((trained / "policy_preprocessor.json").read_text())["steps"]
    assert any(s.get("class", "").endswith("ProprioAsEnvStateStep") for s in steps)


def test_checkpoint_loads_through_lerobot_policy_path(trained, demos):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from policy_wrappers.specs import load_policy

    policy = load_policy(f"lerobot:{trained}")
    assert policy.spec.cameras == () and (policy.spec.chunk_size, policy.spec.replan_steps) == (20, 10)
    assert policy.spec.training == (TrainedCell("pick_place", "milk", 0, episodes=4),)  # from train_info.json
    item = LeRobotDataset("local/indgen_demos", root=demos)[0]
    policy.reset("pick up the milk carton", seed=0)
    chunk = policy.act([_obs(item["observation.state"].numpy())] * 2)
    assert chunk.shape == (2, 20, 7) and np.all(np.isfinite(chunk))
    assert np.allclose(chunk[0], chunk[1])
    # the trained model imitates the first demo action better than chance (gripper open, moving)
    assert chunk[0, 0, 6] < 0


def test_env_state_without_the_proprio_step_is_refused(trained, tmp_path):
    import shutil

    from policy_wrappers.specs import load_policy

    ckpt = tmp_path / "ckpt"
    shutil.copytree(trained, ckpt)
    pre = json.loads((ckpt / "policy_preprocessor.json").read_text())
    pre["steps"] = [s for s in pre["steps"] if "ProprioAsEnvStateStep" not in s.get("class", "")]
    (ckpt / "policy_preprocessor.json").write_text(json.dumps(pre))
    with pytest.raises(PolicyError, match="privileged"):
        load_policy(f"lerobot:{ckpt}")


def test_config_and_input_errors(demos, tmp_path):
    with pytest.raises(ConfigError, match="not trainable"):
        TrainRecipe(policy="pi0")
    with pytest.raises(ConfigError, match="exceeds chunk_size"):
        TrainRecipe(chunk_size=5, n_action_steps=10)
    with pytest.raises(ConfigError, match="unknown camera"):
        TrainRecipe(cameras=("front",))
    with pytest.raises(ConfigError, match="not a LeRobotDataset"):
        train_policy(TrainConfig(datasets=[tmp_path], out=tmp_path / "out", recipe=TrainRecipe(steps=1)))
    with pytest.raises(ConfigError, match="camera 'agentview' is missing"):
        train_policy(
            TrainConfig(
                datasets=[demos], out=tmp_path / "out", recipe=TrainRecipe(steps=1, cameras=("agentview",))
            )
        )


@pytest.mark.slow  # ~9 s: a training run and an evaluation
def test_object_policy_trains_loads_and_gets_object_poses_from_the_engine(demos, tmp_path):
    from indgen_vla.app.engine.config import EvalConfig
    from indgen_vla.core.protocol.interface import OBJECT_DIM
    from policy_wrappers.specs import load_policy
    from tests.fixtures.resolved import evaluate

    cfg = TrainRecipe(steps=40, batch_size=16, dim_model=32, n_heads=2, dim_feedforward=64, log_every=20,
                      objects=True)  # fmt: skip
    ckpt = train_policy(TrainConfig(datasets=[demos], out=tmp_path / "act_objects", recipe=cfg))
    steps = json.loads((ckpt / "policy_preprocessor.json").read_text())["steps"]
    assert any(s.get("class", "").endswith("ObjectPosesStep") for s in steps)
    assert not any(s.get("class", "").endswith("ProprioAsEnvStateStep") for s in steps)
    policy = load_policy(f"lerobot:{ckpt}")
    assert policy.spec.observes_objects and policy.spec.cameras == ()
    state = np.zeros(8, np.float32)
    with pytest.raises(PolicyError, match="object poses"):
        policy.act([_obs(state)])
    objects = np.zeros(OBJECT_DIM, np.float32)
    objects[6] = objects[13] = 1.0
    obs = Observation(images={}, state=state, instruction="pick up the milk carton", objects=objects)
    assert policy.act([obs]).shape == (1, 20, 7)
    policy.close()
    out = evaluate(EvalConfig.from_flat(policy=f"lerobot:{ckpt}", scene="pick_place", axes=("pick_y",), levels="0",
                              episodes=1, max_steps=10, out=str(tmp_path / "run")), quiet=True)  # fmt: skip
    import pandas as pd

    assert list(pd.read_parquet(out / "episodes.parquet")["status"]) == ["ok"]
    with pytest.raises(ConfigError, match="drop --cameras"):
        TrainRecipe(objects=True, cameras=("agentview",))


def test_object_poses_are_recorded_and_carried_through_mimicgen(demos, tmp_path):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from indgen_vla.app.api import mimicgen as generate
    from indgen_vla.app.regimes.demos import ENV_STATE, read_episode_sidecar
    from indgen_vla.app.regimes.mimicgen import MimicGenConfig

    gen = tmp_path / "gen"
    generate(MimicGenConfig(source=demos, out=gen, n=1, seed=1, guarantee=True, max_attempts=3))
    for root, repo in ((demos, "local/indgen_demos"), (gen, "local/indgen_mimicgen")):
        ds = LeRobotDataset(repo, root=root)
        pose = read_episode_sidecar(root)[0]["object_poses"]
        x, y, z, qw, qx, qy, qz = pose["pick"][0]  # frame 0 of episode 0, wxyz in the sidecar
        sign = 1.0 if qw >= 0 else -1.0
        want = [x, y, z, sign * qx, sign * qy, sign * qz, sign * qw]
        np.testing.assert_allclose(ds[0][ENV_STATE].numpy()[:7], want, atol=1e-5)
        gx, gy, gz = pose["goal"][0][:3]
        np.testing.assert_allclose(ds[0][ENV_STATE].numpy()[7:10], [gx, gy, gz], atol=1e-5)


def test_datasets_open_without_lerobots_torchcodec_warning(demos, caplog):
    """Where torchcodec cannot load (no FFmpeg libraries), lerobot's own probe logs a ~200-line traceback per
    dataset; train picks the same backend quietly."""
    from indgen_vla.app.regimes.train import _open_datasets, video_backend

    with caplog.at_level("WARNING"):
        (ds,) = _open_datasets([demos], "local/test")
    assert ds._video_backend == video_backend() in ("torchcodec", "pyav")
    assert not [r for r in caplog.records if "torchcodec" in r.getMessage()]


def test_objects_need_recorded_poses(tmp_path):
    from indgen_vla.app import api
    from indgen_vla.app.regimes.demos import DemosConfig

    api.demos(
        DemosConfig(scene="pick_place", out=tmp_path / "demos", n=1, seed=3, cameras=(), workers=1)
    )  # state only, without poses
    with pytest.raises(ConfigError, match="indgen demos --objects"):
        train_policy(
            TrainConfig(
                datasets=[tmp_path / "demos"], out=tmp_path / "out", recipe=TrainRecipe(steps=1, objects=True)
            )
        )


@pytest.mark.skipif(not SHIPPED.is_dir(), reason="shipped checkpoint not built yet")
def test_shipped_checkpoint_is_small_documented_and_loads():
    from policy_wrappers.specs import load_policy

    size = sum(f.stat().st_size for f in SHIPPED.iterdir() if f.is_file())
    assert size <= 20 * 1024 * 1024
    card = (SHIPPED / "README.md").read_text()
    for word in ("Data regime", "steps", "seed", "T0"):
        assert word in card
    policy = load_policy(f"lerobot:{SHIPPED}")
    assert policy.spec.cameras == ()
    state = np.array([-0.1, 0.0, 1.0, 2.2, 2.2, 0.0, 0.02, -0.02], dtype=np.float32)
    assert policy.act([_obs(state)]).shape[-1] == 7


@pytest.mark.slow  # ~12 s: a second training run and an evaluation
def test_training_levels_reach_the_checkpoint_the_manifest_and_the_report(level_demos, tmp_path):
    """Trained on pick_y levels 0 and 1: train_info.json and the policy's spec name them, evaluate records them in
    the manifest, and the report marks levels 0 and 1 (not 2) "trained"."""
    from indgen_vla.app.engine.config import EvalConfig
    from indgen_vla.core.protocol.training_support import cells_from_json
    from tests.fixtures.resolved import evaluate

    cfg = TrainRecipe(steps=5, batch_size=16, dim_model=32, n_heads=2, dim_feedforward=64, log_every=5)
    ckpt = train_policy(TrainConfig(datasets=[level_demos[0]], out=tmp_path / "act", recipe=cfg))
    cells = cells_from_json(json.loads((ckpt / "train_info.json").read_text())["levels"])
    assert sorted((c.axis, c.level, c.episodes) for c in cells) == [("pick_y", 0, 1), ("pick_y", 1, 1)]
    out = evaluate(EvalConfig.from_flat(policy=f"lerobot:{ckpt}", scene="pick_place", axes=("pick_y",), levels="0:2",
                              episodes=1, max_steps=5, workers=1, out=str(tmp_path / "run")), quiet=True)  # fmt: skip
    assert cells_from_json(json.loads((out / "manifest.json").read_text())["training_levels"]) == cells
    summary = json.loads((out / "summary.json").read_text())
    assert [e["level"] for e in summary["axes"]["pick_y"]["trained"]] == [0, 1]
    marked = [
        line.split(" | ")[0] for line in (out / "report.md").read_text().splitlines() if "· trained" in line
    ]
    assert marked == ["| 0", "| 1"]


TINY = TrainRecipe(
    steps=12, batch_size=16, dim_model=32, n_heads=2, dim_feedforward=64, log_every=5, save_every=4
)


def _same_checkpoint(a: Path, b: Path) -> None:
    """Every file of two checkpoints byte for byte, train_info.json but its training seconds."""
    files = sorted(p.name for p in a.iterdir())
    assert files == sorted(p.name for p in b.iterdir()) and "resume" not in files
    for name in files:
        if name != "train_info.json":
            assert (a / name).read_bytes() == (b / name).read_bytes(), name
    ia, ib = (json.loads((d / "train_info.json").read_text()) for d in (a, b))
    assert {k for k in ia if ia[k] != ib[k]} <= {"train_s"}


@pytest.fixture(scope="module")
def tiny(demos, tmp_path_factory) -> Path:
    """An uninterrupted 12-step run of TINY."""
    return train_policy(
        TrainConfig(datasets=[demos], out=tmp_path_factory.mktemp("tiny") / "act", recipe=TINY)
    )


def test_interrupted_training_resumes_to_the_same_checkpoint(tiny, demos, tmp_path):
    """Stopped at step 6 (state saved at step 4) and after a save a kill cut short, the rerun resumes from step 4
    and writes the uninterrupted run's checkpoint bit for bit: weights, optimiser path and loss log."""
    out, said = tmp_path / "act", []

    def stop(step, loss):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):  # the first logged loss is step 5: the state of step 4 is on disk
        train_policy(TrainConfig(datasets=[demos], out=out, recipe=TINY), progress=stop)
    assert sorted(p.name for p in (out / "resume").iterdir()) == ["last.json", "run.json", "step_000004"]
    half = out / "resume" / ".step_000008.x1y2"  # what a kill in the middle of the next save leaves
    half.mkdir()
    (half / "model.safetensors").write_bytes(b"torn")
    train_policy(TrainConfig(datasets=[demos], out=out, recipe=TINY), say=said.append)
    assert said == [f"train: resuming {out} from step 4 of 12"]
    _same_checkpoint(tiny, out)


def test_finished_rerun_is_a_no_op_and_other_arguments_are_refused(tiny, demos, tmp_path):
    stamp = {p.name: p.stat().st_mtime_ns for p in tiny.iterdir()}
    said = []
    assert train_policy(TrainConfig(datasets=[demos], out=tiny, recipe=TINY), say=said.append) == tiny
    assert said == [f"train: {tiny} is already complete (12 steps); nothing to do"]
    assert {p.name: p.stat().st_mtime_ns for p in tiny.iterdir()} == stamp
    assert (
        train_policy(TrainConfig(datasets=[demos], out=tiny, recipe=dataclasses.replace(TINY, save_every=3)))
        == tiny
    )  # how often it saves changes no checkpoint
    with pytest.raises(
        ConfigError, match=r"finished run made with --steps 12, not --steps 13; rerun with --steps 12"
    ):
        train_policy(TrainConfig(datasets=[demos], out=tiny, recipe=dataclasses.replace(TINY, steps=13)))
    with pytest.raises(ConfigError, match="made with --seed 0, not --seed 1"):
        train_policy(TrainConfig(datasets=[demos], out=tiny, recipe=dataclasses.replace(TINY, seed=1)))
    foreign = tmp_path / "notes"
    foreign.mkdir()
    (foreign / "todo.txt").write_text("keep me")
    with pytest.raises(ConfigError, match="already exists and is not empty"):
        train_policy(TrainConfig(datasets=[demos], out=foreign, recipe=TINY))
    assert (foreign / "todo.txt").read_text() == "keep me"


def _saved_step(out: Path) -> int:
    try:
        return int(json.loads((out / "resume" / "last.json").read_text())["state"].split("_")[1])
    except (OSError, ValueError, KeyError):
        return 0


@pytest.mark.slow  # three interpreter start-ups (~10 s each here) and a default-size ACT
def test_sigkilled_train_resumes_to_the_same_checkpoint(demos, tmp_path):
    import subprocess
    import sys

    from tests.fixtures.kill import kill_midway

    argv = ["train", str(demos), "--steps", "30", "--batch-size", "8", "--save-every", "5"]
    ref, out = tmp_path / "ref", tmp_path / "killed"
    subprocess.run([sys.executable, "-m", "indgen_vla.app.cli", *argv, "--out", str(ref)], check=True,
                   capture_output=True)  # fmt: skip
    saved = kill_midway(argv, out, total=30, at_least=5, count=_saved_step)
    assert 5 <= saved < 30
    run = subprocess.run([sys.executable, "-m", "indgen_vla.app.cli", *argv, "--out", str(out)], check=True,
                         capture_output=True, text=True)  # fmt: skip
    assert f"resuming {out} from step {saved} of 30" in run.stdout
    _same_checkpoint(ref, out)
    again = subprocess.run([sys.executable, "-m", "indgen_vla.app.cli", *argv, "--out", str(out)], capture_output=True,
                           text=True)  # fmt: skip
    assert again.returncode == 0 and "already complete" in again.stdout
    bad = subprocess.run([sys.executable, "-m", "indgen_vla.app.cli", *argv[:-1], "6", "--out", str(out)],
                         capture_output=True, text=True)  # fmt: skip
    assert bad.returncode == 0 and "already complete" in bad.stdout  # --save-every is not part of the run
    bad = subprocess.run([sys.executable, "-m", "indgen_vla.app.cli", *argv, "--seed", "2", "--out", str(out)],
                         capture_output=True, text=True)  # fmt: skip
    assert (
        bad.returncode == 2 and bad.stderr.strip().count("\n") == 0 and "--seed 0, not --seed 2" in bad.stderr
    )


def test_train_config_holds_the_recipe_and_the_evaluation_protocol(tmp_path):
    """``indgen train``'s flags parse into a ``TrainConfig`` whose ``TrainRecipe`` is what the checkpoint records;
    ``--eval-every`` and its protocol (an ``EvalConfig``) go together."""
    from indgen_vla.app.config_fields import from_flat
    from indgen_vla.app.engine.config import EvalConfig

    cfg = from_flat(TrainConfig, {"datasets": (tmp_path,), "out": tmp_path / "act", "cameras": "agentview",
                                  "steps": 7, "data_regime": "h"}, command="train")  # fmt: skip
    assert cfg.recipe == TrainRecipe(steps=7, cameras=("agentview",)) and cfg.datasets == (str(tmp_path),)
    assert cfg.eval_root == tmp_path / "act_evals"
    protocol = EvalConfig.from_flat(policy="object:x", scene="pick_place", axes=("pick_y",), out="_")
    assert TrainConfig(datasets=(tmp_path,), out="o", eval_every=5, evaluation=protocol).eval_every == 5
    with pytest.raises(ConfigError, match="--eval-every N and --eval 'FLAGS' go together"):
        TrainConfig(datasets=(tmp_path,), out="o", eval_every=5)
    with pytest.raises(ConfigError, match="--eval-every must be >= 1 update, got 0"):
        TrainConfig(datasets=(tmp_path,), out="o", eval_every=0, evaluation=protocol)
