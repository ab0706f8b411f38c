"""``lerobot-train ... --env.type=indgen --env_eval_freq N``: LeRobot's training loop evaluates an indgen level while it
trains (slow: a real training run of a tiny ACT on two recorded demonstrations)."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from tests.fixtures.lerobot_runs import AXIS, ROOT, SCENE, lerobot_env, needs_plugin

pytestmark = [pytest.mark.slow, needs_plugin]


def test_lerobot_train_evaluates_an_indgen_level(tmp_path):
    from indgen_vla.app import api
    from indgen_vla.app.regimes.demos import DemosConfig

    data = tmp_path / "demos"
    api.demos(
        DemosConfig(scene=SCENE, out=data, n=2, cameras=(), objects=True, workers=1)
    )  # state + object poses, no images
    out = tmp_path / "train"
    cmd = [sys.executable, "-m", "lerobot.scripts.lerobot_train", "--dataset.repo_id=local/indgen_demos",
           f"--dataset.root={data}", "--policy.type=act", "--policy.device=cpu", "--policy.push_to_hub=false",
           "--policy.dim_model=32", "--policy.n_heads=2", "--policy.dim_feedforward=64", "--policy.chunk_size=10",
           "--policy.n_action_steps=10", "--steps=2", "--env_eval_freq=2", "--batch_size=4", "--num_workers=0",
           "--save_checkpoint=false", "--log_freq=1", "--env.type=indgen", f"--env.scene={SCENE}",
           f"--env.axis={AXIS}", "--env.level=1", "--env.object_poses=true", "--env.max_steps=30",
           "--env.video_size=64", "--eval.n_episodes=2", "--eval.batch_size=2", "--eval.use_async_envs=false",
           f"--output_dir={out}"]  # fmt: skip
    proc = subprocess.run(cmd, env=lerobot_env(), cwd=ROOT, capture_output=True, text=True, timeout=1200)
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log[-3000:]
    assert "Eval policy at step 2" in log
    group = f"indgen@{SCENE}@milk@{AXIS}@1@p-0.105@seed0@first1000"
    m = re.search(rf"Suite per_group aggregated: \{{'{re.escape(group)}': \{{[^}}]*'n_episodes': (\d+)", log)
    assert m and int(m.group(1)) == 2, log[-3000:]
