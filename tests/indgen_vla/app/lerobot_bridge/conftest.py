"""One real lerobot-eval run of the shipped ACT through --env.type=indgen and the indgen evaluate run of the same
episodes, shared by this folder's tests (each costs tens of seconds on 2 cores: run once per session)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.fixtures.lerobot_runs import (
    AXIS,
    CHECKPOINT,
    EPISODES,
    LEVEL,
    SCENE,
    plugin_installed,
    run_lerobot_eval,
)


@pytest.fixture(scope="session")
def lerobot_eval_out(tmp_path_factory) -> Path:
    """A finished lerobot-eval output directory (eval_info.json) of EPISODES episodes at pick_y LEVEL."""
    if not plugin_installed():
        pytest.skip(
            "the lerobot_env_indgen distribution is not installed (pip install -e plugins/lerobot_env_indgen)"
        )
    return run_lerobot_eval(tmp_path_factory.mktemp("lerobot_eval") / "out")


@pytest.fixture(scope="session")
def indgen_run(tmp_path_factory) -> Path:
    """``indgen evaluate`` of the same policy, level and episodes."""
    import indgen_vla

    out = tmp_path_factory.mktemp("indgen_eval") / "run"
    indgen_vla.evaluate(policy=f"lerobot:{CHECKPOINT}", scene=SCENE, axis=AXIS, levels=f"{LEVEL}:{LEVEL}",
                        episodes=EPISODES, out=out, workers=1, quiet=True)  # fmt: skip
    return out
