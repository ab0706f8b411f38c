"""``evaluate --adaptive`` on the real pick_place scene: rounds, decisions, skipped levels, determinism, resume."""

import json
from pathlib import Path

import pandas as pd
import pytest

from indgen_vla.engine.cli import evaluate
from indgen_vla.engine.config import EvalConfig
from indgen_vla.errors import ConfigError
from indgen_vla.sequential import SequentialRule

pytestmark = pytest.mark.filterwarnings("ignore")


def cfg(tmp_path, **kw):
    base = dict(policy="standin:random", scene="pick_place", axes=("pick_y",), levels="-2:2", episodes=50,
                workers=1, max_steps=6, adaptive="kstar", out=str(tmp_path / "run"))  # fmt: skip
    base.update(kw)
    return EvalConfig(**base)


def test_kstar_mode_stops_at_a_decided_break_and_records_decisions(tmp_path):
    rule = SequentialRule(max_episodes=50)
    need = rule.decide([False] * 50).episodes  # a policy that never succeeds: decided broken after this many
    assert need < 50 and need % rule.round_size == 0
    a = evaluate(cfg(tmp_path / "w1"), quiet=True)
    df = pd.read_parquet(Path(a) / "episodes.parquet")
    # level 0 breaks, which ends both directions: no other level runs
    assert set(df["level"]) == {0} and len(df) == need and not df["success"].any()
    s = json.loads((Path(a) / "summary.json").read_text())["axes"]["pick_y"]
    lv = {r["level"]: r for r in s["levels"]}
    assert lv[0]["decision"] == "broken" and lv[0]["sequential"]["episodes_used"] == need
    assert lv[2]["n"] == 0 and s["break_level"]["pos"] == 0
    manifest = json.loads((Path(a) / "manifest.json").read_text())
    assert manifest["plan"]["adaptive"]["mode"] == "kstar" and manifest["plan"]["adaptive"]["round_size"] == 5
    # two workers: the same episodes and outcomes
    b = evaluate(cfg(tmp_path / "w2", workers=2), quiet=True)
    cols = ["level", "episode", "seed", "success", "steps"]
    key = ["level", "episode"]
    pd.testing.assert_frame_equal(
        df[cols].sort_values(key).reset_index(drop=True),
        pd.read_parquet(Path(b) / "episodes.parquet")[cols].sort_values(key).reset_index(drop=True),
    )
    # re-running the finished run adds nothing
    evaluate(cfg(tmp_path / "w1"), quiet=True)
    assert len(pd.read_parquet(Path(a) / "episodes.parquet")) == need


def test_adaptive_config_errors(tmp_path):
    with pytest.raises(ConfigError, match="--adaptive must be one of"):
        cfg(tmp_path, adaptive="fast")
    with pytest.raises(ConfigError, match="one --task at a time"):
        cfg(tmp_path, task="all")
    with pytest.raises(ConfigError, match="delta"):
        cfg(tmp_path, adaptive_delta=0.5)
