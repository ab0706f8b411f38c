"""A tiny random-init LeRobot policy with RoboCasa365's feature names, evaluated through ``lerobot:`` on placeholder
assets (``indgen evaluate ... --smoke``): the scene's EnvSpec picks lerobot's base-first layout, the run's manifest
records it. The mapping itself is covered by the fast tests/policy_wrappers/test_robocasa_layouts.py."""

from __future__ import annotations

import json

import pytest

from tests.fixtures.tiny_policies import build_tiny_checkpoint
from tests.scenes.robocasa.test_robocasa import needs_venv

CAMS = ("robot0_agentview_left", "robot0_agentview_right", "robot0_eye_in_hand")


@needs_venv
def test_a_tiny_lerobot_robocasa_policy_evaluates_on_placeholders(placeholders, tmp_path):
    """``indgen evaluate --policy lerobot:DIR --scene robocasa --task PickPlaceCounterToCabinet --axis base_y
    --levels 0:0 --episodes 1 --max-steps 3 --smoke``: refused without --smoke (placeholder assets), then runs and
    records lerobot's RoboCasa layout and 'not a measurement' in the manifest."""
    pytest.importorskip("lerobot")
    import pandas as pd

    from indgen_vla.app.cli import main

    ckpt = build_tiny_checkpoint("act", tmp_path / "ckpt", cameras=CAMS, size=16, state_dim=16, action_dim=12)
    out = tmp_path / "run"
    args = ["evaluate", "--policy", f"lerobot:{ckpt}", "--scene", "robocasa", "--task", "PickPlaceCounterToCabinet",
            "--axis", "base_y", "--levels", "0:0", "--episodes", "1", "--max-steps", "3", "--workers", "1",
            "--out", str(out)]  # fmt: skip
    assert (
        main(args) != 0 and not (out / "episodes.parquet").exists()
    )  # placeholders: an image policy needs --smoke
    code = main([*args, "--smoke"])
    df = pd.read_parquet(out / "episodes.parquet")
    assert code == 0 and list(df.status) == ["ok"] and list(df.steps) == [3], list(df.error)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["measurement"].startswith("not a measurement")
    policy = manifest["fingerprint"]["policy"]
    assert policy["family"] == "lerobot" and policy["layout"]["name"].startswith("lerobot-robocasa")
    assert "lerobot/envs/robocasa.py" in policy["layout"]["source"]
