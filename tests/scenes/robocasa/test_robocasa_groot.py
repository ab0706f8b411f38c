"""A GR00T N1.5 loopback server speaking RoboCasa365's fork's service drives a RoboCasa episode on placeholder assets.

The server reimplements robocasa-benchmark/Isaac-GR00T's N1.5 service (read from its copy XingxinHE/Isaac-GR00T at
9d7d7a9eb7ad30bd8ce30448d9ab53a918b45b10, ``gr00t/eval/service.py``: torch.save framing, ping / get_modality_config /
get_action; tests/policy_wrappers/test_groot.py ``GrootServer(wire="torch")``) and answers with the shapes its
``Gr00tPolicy.get_action`` returns for a batched request: ``action.<key>`` (B, 16, D) float32 under
PandaOmronDataConfig's action keys. The request formula itself is checked in test_groot_robocasa.py; here the keys,
dtypes and shapes the engine's episode sends, and that the scene stepped.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.scenes.robocasa.test_robocasa import needs_venv

sys.path.insert(0, str(Path(__file__).parents[2] / "policy_wrappers"))
from test_groot import GrootServer  # noqa: E402
from test_groot_robocasa import FORK_ACTION, FORK_LANGUAGE, FORK_STATE, FORK_VIDEO  # noqa: E402

STATE_DIMS = {"state.end_effector_position_relative": 3, "state.end_effector_rotation_relative": 4,
              "state.gripper_qpos": 2, "state.base_position": 3, "state.base_rotation": 4}  # fmt: skip


@needs_venv
@pytest.mark.slow  # ~80 s on a shared 2-core CPU: 20 steps rendering three 256 px cameras
@pytest.mark.timeout(300)
def test_a_groot_n15_server_drives_a_robocasa_episode(placeholders, tmp_path):
    """``indgen evaluate --policy groot:tcp://127.0.0.1:PORT?api=n1.5 --scene robocasa --task
    PickPlaceCounterToCabinet --axis base_y --levels 0:0 --episodes 1 --max-steps 20 --smoke``: 20 steps from two
    get_action calls (16 executed per query), each request the fork's flat batched keys."""
    pytest.importorskip("torch")
    import pandas as pd

    from indgen_vla.app.cli import main

    def reply(data):
        batch = len(data[FORK_LANGUAGE])
        return {k: np.full((batch, 16, n), 0.01, np.float32) for k, n in FORK_ACTION.items()}

    out = tmp_path / "run"
    with GrootServer(reply, wire="torch") as srv:
        code = main(["evaluate", "--policy", f"groot:tcp://127.0.0.1:{srv.port}?api=n1.5", "--scene", "robocasa",
                     "--task", "PickPlaceCounterToCabinet", "--axis", "base_y", "--levels", "0:0", "--episodes", "1",
                     "--max-steps", "20", "--workers", "1", "--smoke", "--out", str(out)])  # fmt: skip
    df = pd.read_parquet(out / "episodes.parquet")
    assert code == 0 and list(df.status) == ["ok"] and list(df.steps) == [20], list(df.error)
    actions = [r["data"] for r in srv.requests if r.get("endpoint") == "get_action"]
    assert len(actions) == 2
    for data in actions:
        assert set(data) == {*FORK_VIDEO, *FORK_STATE, FORK_LANGUAGE}
        for key in FORK_VIDEO:
            assert data[key].dtype == np.uint8 and data[key].shape == (1, 1, 256, 256, 3), key
        for key in FORK_STATE:
            assert data[key].dtype == np.float32 and data[key].shape == (1, 1, STATE_DIMS[key]), key
        assert isinstance(data[FORK_LANGUAGE], tuple) and all(isinstance(s, str) for s in data[FORK_LANGUAGE])
    # the robot moved between the two queries: the scene stepped the returned actions
    assert any(not np.array_equal(actions[0][k], actions[1][k]) for k in FORK_STATE)
    policy = json.loads((out / "manifest.json").read_text())["fingerprint"]["policy"]
    assert policy["family"] == "groot" and policy["layout"]["name"].startswith("groot-robocasa365")
