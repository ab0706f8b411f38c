"""``evaluate --adaptive`` on the real pick_place scene: rounds, decisions, skipped levels, determinism, resume."""

import json
from pathlib import Path

import pandas as pd
import pytest

from indgen_vla.engine.config import EvalConfig
from indgen_vla.engine.run import evaluate
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


class ClosablePolicy:
    """Acts until closed, then refuses: the adaptive loop must keep its policies open between rounds."""

    def __init__(self):
        from indgen_vla.interface import PolicySpec

        self.spec = PolicySpec("standin", "test:closable", chunk_size=4, replan_steps=4, cameras=())
        self.closed = False

    def reset(self, instruction, seed=None):
        if self.closed:
            raise RuntimeError("reset after close")

    def act(self, observations):
        import numpy as np

        if self.closed:
            raise RuntimeError("act after close")
        return np.zeros((len(observations), 4, 7), np.float32)

    def close(self):
        self.closed = True


def test_rounds_reuse_open_policies_and_the_caller_closes_them(tmp_path):
    from indgen_vla.engine.adaptive import run_adaptive
    from indgen_vla.engine.local import run_local
    from indgen_vla.engine.rollout import RunMeta, RunnerConfig
    from indgen_vla.engine.run import build_plan
    from indgen_vla.records import RunDir

    c = cfg(tmp_path, levels="0", episodes=20)
    plan = build_plan(c)
    jobs = plan.jobs
    run = RunDir.create_or_resume(tmp_path / "run", {"plan": c.plan_dict(["milk"], {"pick_y": [0]}, 6)})
    policy = ClosablePolicy()
    rc = RunnerConfig(levels=plan.builder, cameras=(), image_size=(64, 64), max_steps=6, privileged=False)
    meta = RunMeta("r", "test:closable", "", "pick_place")
    rounds = []

    def run_jobs(batch):
        rounds.append(len(batch))
        run_local(batch, rc, lambda: policy, meta, lambda rec: run.append([rec]), workers=1, replan_steps=4,
                  close_policies=False)  # fmt: skip

    run_adaptive(plan, run.episodes, run_jobs, c)
    df = run.episodes()
    assert (
        len(rounds) == 3 and (df["status"] == "ok").all() and not policy.closed
    )  # 3 rounds of 5 on one policy
    run_local(jobs[15:16], rc, lambda: policy, meta, lambda rec: None, workers=1, replan_steps=4)
    assert policy.closed  # by default run_local closes what it was given
