"""``--env.type=indgen``: lerobot-eval builds indgen's own levels and episodes (the episode-seed mapping, the plugin's
discovery) and its per-episode successes equal indgen evaluate's, episode by episode."""

from __future__ import annotations

import pandas as pd
import pytest

from indgen_vla.app.api import family_of
from indgen_vla.app.engine.config import config_from_values
from indgen_vla.app.lerobot_bridge.level_env import (
    FIRST_SEED,
    LevelRequest,
    group_name,
    parse_group,
    resolve_levels,
)
from indgen_vla.core.errors import ConfigError
from tests.fixtures.lerobot_runs import AXIS, EPISODES, LEVEL, SCENE, needs_plugin, successes
from tests.fixtures.resolved import build_plan


def test_reset_seed_is_indgen_episode_and_seed():
    """Reset seed first_seed + i is episode i with the seed indgen evaluate plans for it (plan_jobs)."""
    for run_seed in (0, 7):
        (setup,), _ = resolve_levels(
            LevelRequest(scene=SCENE, axis=AXIS, level=2, run_seed=run_seed), family_of
        )
        cfg = config_from_values({"policy": "standin:oracle", "out": "x", "scene": SCENE, "axis": AXIS,
                                  "levels": "2:2", "episodes": 4, "seed": run_seed}, strict=True)  # fmt: skip
        planned = [(j.episode, j.seed, j.param) for j in build_plan(cfg).jobs]
        ours = [(setup.job(setup.episode_of(FIRST_SEED + i)).episode, setup.job(i).seed, setup.job(i).param)
                for i in range(4)]  # fmt: skip
        assert ours == planned
    with pytest.raises(ConfigError, match="below --env.first_seed=1000"):
        setup.episode_of(FIRST_SEED - 1)


def test_group_names_the_level():
    g = group_name("pick_place", "milk", "pick_y", -2, -0.18, 3, 1000)
    assert parse_group(g) == {"scene": "pick_place", "task": "milk", "axis": "pick_y", "level": -2, "param": -0.18,
                              "run_seed": 3, "first_seed": 1000}  # fmt: skip
    assert parse_group("libero_object") is None
    assert parse_group("indgen@a@b") is None


def test_bad_options_are_one_line():
    with pytest.raises(ConfigError, match="cameras"):
        resolve_levels(LevelRequest(scene=SCENE, axis=AXIS, level=0, cameras=("top",)), family_of)
    with pytest.raises(ConfigError, match="first_seed"):
        LevelRequest(scene=SCENE, axis=AXIS, level=0, first_seed=-1)


def test_plugin_registers_env_type():
    """The distribution lerobot's register_third_party_plugins() imports registers --env.type=indgen."""
    pytest.importorskip("lerobot_env_indgen", reason="the lerobot_env_indgen distribution is not installed")
    from lerobot.envs.configs import EnvConfig
    from lerobot.utils.import_utils import register_third_party_plugins

    register_third_party_plugins()
    cfg = EnvConfig.get_choice_class("indgen")(scene=SCENE, axis=AXIS, level=1)
    assert cfg.type == "indgen" and cfg.features_map["agent_pos"] == "observation.state"
    assert [s.group for s in cfg.levels] == [
        group_name(SCENE, "milk", AXIS, 1, cfg.levels[0].param, 0, FIRST_SEED)
    ]


@needs_plugin
def test_lerobot_eval_equals_indgen_evaluate_episode_by_episode(lerobot_eval_out, indgen_run):
    """The shipped ACT through lerobot-eval --env.type=indgen and through indgen evaluate: the same episode succeeds
    or fails in both (lerobot-eval's episode i, reset seed 1000 + i, is indgen's episode i)."""
    ours = pd.read_parquet(indgen_run / "episodes.parquet").sort_values("episode")
    assert list(ours["episode"]) == list(range(EPISODES)) and set(ours["level"]) == {LEVEL}
    theirs = successes(lerobot_eval_out)
    assert theirs == [bool(s) for s in ours["success"]]
    assert 0 < sum(theirs) < EPISODES  # successes and failures both: equality is not two constant vectors
