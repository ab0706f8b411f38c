"""``evaluate --adaptive`` on the real pick_place scene: rounds, decisions, skipped levels, determinism, resume."""

import json
from pathlib import Path

import pandas as pd
import pytest

from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.sprt import SequentialRule
from tests.fixtures.kill import kill_midway
from tests.fixtures.resolved import evaluate

pytestmark = pytest.mark.filterwarnings("ignore")


def cfg(tmp_path, **kw):
    base = dict(policy="standin:random", scene="pick_place", axes=("pick_y",), levels="-2:2", episodes=50,
                workers=1, max_steps=6, adaptive="kstar", out=str(tmp_path / "run"))  # fmt: skip
    base.update(kw)
    return EvalConfig.from_flat(**base)


@pytest.mark.slow  # 9 s; the 4-task protocol test covers a kstar stop, 1 vs 2 workers and resume by default
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
    with pytest.raises(ConfigError, match="delta"):
        cfg(tmp_path, adaptive_delta=0.5)


class ClosablePolicy:
    """Acts until closed, then refuses: the adaptive loop must keep its policies open between rounds."""

    def __init__(self):
        from indgen_vla.core.protocol.interface import PolicySpec

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
    from indgen_vla.app.engine.adaptive import run_adaptive
    from indgen_vla.app.engine.local import LocalOptions, run_local
    from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
    from indgen_vla.core.runs.records import RunDir
    from tests.fixtures.resolved import build_plan

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
        run_local(
            batch,
            rc,
            lambda: policy,
            meta,
            lambda rec: run.append([rec]),
            LocalOptions(workers=1, replan_steps=4, close_policies=False),
        )

    run_adaptive(plan, run.episodes, run_jobs, c)
    df = run.episodes()
    assert (
        len(rounds) == 3 and (df["status"] == "ok").all() and not policy.closed
    )  # 3 rounds of 5 on one policy
    run_local(
        jobs[15:16], rc, lambda: policy, meta, lambda rec: None, LocalOptions(workers=1, replan_steps=4)
    )
    assert policy.closed  # by default run_local closes what it was given


def _ladder_frame(rows):
    return pd.DataFrame(rows, columns=["task", "axis", "level", "episode", "success", "status"])


def test_every_task_axis_ladder_is_decided_on_its_own_episodes(tmp_path):
    """Two tasks of stack side by side: the rule stops one task's ladder at a broken level 0 while the other
    task's intact level 0 moves it on to level 1; hand-computed from the rule's decisions."""
    from indgen_vla.app.engine.adaptive import ladder_plans, next_round
    from tests.fixtures.resolved import build_plan

    c = cfg(tmp_path, scene="stack", task="all", axes=("stack",), levels="0:2", episodes=20)
    plan = build_plan(c)
    a, b = plan.tasks[:2]
    rule = c.sequential_rule()
    broken, intact = rule.decide([False] * 20).episodes, rule.decide([True] * 20).episodes
    rows = [(a, "stack", 0, i, False, "ok") for i in range(broken)] + [
        (b, "stack", 0, i, True, "ok") for i in range(intact)
    ]
    plans = ladder_plans(plan, _ladder_frame(rows), c)
    assert plans[(a, "stack")].done and plans[(a, "stack")].decisions[0].verdict == "broken"
    assert plans[(b, "stack")].to_run == {1: list(range(rule.round_size))}
    untouched = [t for t in plan.tasks if t not in (a, b)]
    assert all(plans[(t, "stack")].to_run == {0: list(range(rule.round_size))} for t in untouched)
    todo = next_round(plan, _ladder_frame(rows), c)  # one round holds every open ladder's next episodes
    assert {(j.task, j.level) for j in todo} == {(b, 1)} | {(t, 0) for t in untouched}


@pytest.mark.slow  # ~15 s: a CLI run killed and resumed; test_adaptive_share resumes by default
def test_the_whole_protocol_runs_adaptively_in_one_invocation_and_resumes_after_kill(tmp_path):
    """--task all: every task's ladder decided in one run; a 1-worker run killed with SIGKILL mid-protocol and
    resumed gives the same episodes, outcomes and per-task decisions as a 2-worker run."""

    # delta 0.12: a level is decided broken after 2 rounds (10 episodes) instead of 3 (the default 0.1's 15), so
    # each of the 3 runs builds and rolls out a third less; still several rounds per ladder, killed mid-protocol
    flags = dict(scene="stack", task="all", axes=("stack",), levels="0:1", episodes=20, max_steps=2,
                 adaptive_delta=0.12)  # fmt: skip
    need = SequentialRule(delta=0.12, max_episodes=20).decide([False] * 20).episodes
    assert need == 2 * SequentialRule().round_size
    b = Path(evaluate(cfg(tmp_path / "w2", workers=2, **flags), quiet=True))
    df = pd.read_parquet(b / "episodes.parquet")
    s = json.loads((b / "summary.json").read_text())["axes"]["stack"]
    assert (
        set(df["level"]) == {0} and len(df) == 4 * need
    )  # each of the 4 ladders stops at its broken level 0
    assert {
        t: (e["kstar_status"]["pos"]["text"], e["break_level"]["pos"]) for t, e in s["tasks"].items()
    } == dict.fromkeys(s["tasks"], ("k* = 0, determined", 0))
    assert s["episodes"] == {"used": 4 * need, "fixed_design": 4 * 2 * 20}
    killed = tmp_path / "killed"
    argv = ["evaluate", "--policy", "standin:random", "--scene", "stack", "--task", "all", "--axis", "stack",
            "--levels", "0:1", "--episodes", "20", "--max-steps", "2", "--workers", "1", "--adaptive", "kstar",
            "--adaptive-delta", "0.12"]  # fmt: skip
    assert 0 < kill_midway(argv, killed, total=4 * need, at_least=3) < 4 * need
    evaluate(cfg(tmp_path, out=str(killed), **flags), quiet=True)
    cols, key = ["task", "level", "episode", "seed", "success", "steps"], ["task", "level", "episode"]
    got = pd.read_parquet(killed / "episodes.parquet")[cols].sort_values(key).reset_index(drop=True)
    pd.testing.assert_frame_equal(df[cols].sort_values(key).reset_index(drop=True), got)
    assert json.loads((killed / "summary.json").read_text())["axes"]["stack"]["tasks"] == s["tasks"]


def test_a_new_adaptive_run_prepares_its_first_rounds_scenes_not_the_plans_first_cells(tmp_path):
    """Workers started while the policy loads build the scenes of the rule's first round (level 0 of each
    ladder), not of the first cells of the whole plan, which may be levels the rule never reaches."""
    from indgen_vla.app.engine.run import _first_round
    from indgen_vla.app.engine.scheduler import cell_of, first_jobs
    from tests.fixtures.resolved import build_plan

    c = cfg(tmp_path, levels="-2:2", episodes=20)
    plan = build_plan(c)
    first = _first_round(c, plan)
    assert {cell_of(j) for j in first} == {(plan.tasks[0], "pick_y", 0)}
    assert len(first) == c.sequential_rule().round_size
    assert {cell_of(j)[2] for j in first_jobs(first, 2)} == {0}
    # a second worker would build level -1
    assert {cell_of(j)[2] for j in first_jobs(plan.jobs, 2)} == {0, -1}
    fixed = cfg(tmp_path, levels="-2:2", episodes=20, adaptive=None)
    assert _first_round(fixed, build_plan(fixed)) == build_plan(fixed).jobs


def test_until_failure_stops_both_directions_at_the_first_level_below_gamma(tmp_path):
    """The paper's real-robot design in simulation: a policy that never succeeds gets its 10 episodes at level 0
    (0/10 < γ) and nothing else; the summary names the design and calls the break observed."""
    from indgen_vla.app.engine.config import load_config_preset

    assert (
        load_config_preset("stack_real_robot_style")["adaptive"] == "until-failure"
    )  # the paper's protocol preset
    run = evaluate(cfg(tmp_path, policy="standin:noop", adaptive="until-failure", episodes=10), quiet=True)
    df = pd.read_parquet(Path(run) / "episodes.parquet")
    assert set(df["level"]) == {0} and sorted(df["episode"]) == list(range(10))
    manifest = json.loads((Path(run) / "manifest.json").read_text())
    assert manifest["plan"]["adaptive"] == {"mode": "until-failure", "gamma": 0.2}
    s = json.loads((Path(run) / "summary.json").read_text())["axes"]["pick_y"]
    assert s["break_level"] == {"pos": 0, "neg": 0} and "until failure" in s["design"]
    assert s["verdict"]["pos"].startswith("observed break at 0 (0 %, n = 10, 95 % CI [0, 28])")
    assert {r["level"]: r.get("not_run", False) for r in s["levels"]} == {
        -2: True,
        -1: True,
        0: False,
        1: True,
        2: True,
    }
