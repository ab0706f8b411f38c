"""T0 run once per task under ``evaluate --adaptive`` (engine/share.py, engine/adaptive.py): the ladders of a task
that share level 0 ask for the same level-0 episodes, so a round runs the owner's and records the copies; decisions
and rates equal a run with ``--no-share-t0``."""

import json
import zlib
from pathlib import Path

import pandas as pd
import pytest

from indgen_vla.app.engine.adaptive import ladder_plans, next_round, run_adaptive
from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.app.engine.share import copies
from indgen_vla.core.runs.records import EpisodeRecord, RunDir, episodes_frame
from tests.fixtures.kill import kill_midway
from tests.fixtures.resolved import build_plan, evaluate

pytestmark = pytest.mark.filterwarnings("ignore")

AXES = ("pick_y", "scale")
OUTCOME = ["seed", "success", "steps", "status", "failure", "progress", "param"]


def cfg(out, **kw):
    base = dict(policy="standin:random", scene="pick_place", axes=AXES, levels="0:1", episodes=2, workers=1,
                max_steps=8, adaptive="until-failure", out=str(out))  # fmt: skip
    return EvalConfig.from_flat(**{**base, **kw})


def test_a_round_runs_a_shared_level_0_once_for_its_owner(tmp_path):
    c = cfg(tmp_path, episodes=3)
    plan = build_plan(c)
    assert plan.shared == {("milk", "scale"): "pick_y"}
    first = next_round(plan, episodes_frame([]), c)
    # scale's ladder wants the same three episodes: they run once, for pick_y
    assert [j.key for j in first] == [("milk", "pick_y", 0, i) for i in range(3)]
    unshared = build_plan(cfg(tmp_path, episodes=3, share_t0=False))
    assert {j.axis for j in next_round(unshared, episodes_frame([]), c)} == set(AXES)


def _outcome(job) -> bool:
    """A deterministic simulator stand-in: level 0 the same for every axis (its seed, not its axis), other levels
    per axis, success falling with |level|."""
    salt = f"{job.seed}/{job.level}/{job.axis if job.level else ''}"
    return zlib.crc32(salt.encode()) % 100 < (90, 55, 25, 5)[abs(job.level)]


def _run(tmp_path, name, c):
    """``run_adaptive`` as ``evaluate`` drives it, each rollout recorded with its copies (a round in one append)."""
    plan = build_plan(c)
    run = RunDir.create_or_resume(tmp_path / name, {"plan": {}})
    rolled = []

    def run_jobs(batch):
        recs = []
        for j in batch:
            rolled.append(j.key)
            rec = EpisodeRecord("r", c.policy.spec, "", c.plan.scene, j.task, j.axis, j.level, j.param, j.episode, j.seed,
                                _outcome(j), 10)  # fmt: skip
            recs += [rec, *copies(plan, rec, set())]
        run.append(recs)

    run_adaptive(plan, run.episodes, run_jobs, c)
    return plan, run.episodes(), rolled


@pytest.mark.parametrize("mode", ["until-failure", "kstar", "curve"])
def test_shared_ladders_decide_as_unshared_ones(tmp_path, mode):
    """Every mode: the same episodes, per-level rates and decisions with T0 shared as without, fewer rollouts."""
    flags = dict(adaptive=mode, levels="-3:3", episodes=20 if mode != "until-failure" else 10, round_size=5)
    (plan, shared, rolled), (_, own, rolled_own) = (
        _run(tmp_path, n, cfg(tmp_path, share_t0=s, **flags)) for n, s in (("s", True), ("o", False))
    )
    key = ["task", "axis", "level", "episode"]
    a, b = (df.sort_values(key).reset_index(drop=True) for df in (shared, own))
    pd.testing.assert_frame_equal(a[[*key, "success", "status"]], b[[*key, "success", "status"]])
    copied = a[a["shared_from"] != ""]
    assert set(copied["axis"]) == {"scale"} and set(copied["level"]) == {0}
    assert (copied["shared_from"] == "pick_y").all()
    assert len(rolled) == len(rolled_own) - len(copied) and len(set(rolled)) == len(rolled)
    assert not any(k[1] == "scale" and k[2] == 0 for k in rolled)
    assert {k[2] for k in rolled} != {0}  # the ladders went past level 0, each on its own levels
    c = cfg(tmp_path, **flags)
    p_shared, p_own = ladder_plans(plan, shared, c), ladder_plans(plan, own, c)
    assert {k: (p.decisions, p.kstar) for k, p in p_shared.items()} == {
        k: (p.decisions, p.kstar) for k, p in p_own.items()
    }


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """One until-failure run with T0 shared (the default, 2 workers) and one with --no-share-t0 (1), by ``evaluate``."""
    root = tmp_path_factory.mktemp("adaptive_share")
    shared = evaluate(cfg(root / "shared", workers=2), quiet=True)
    return shared, evaluate(cfg(root / "own", share_t0=False), quiet=True)


def _episodes(run) -> pd.DataFrame:
    return RunDir(run).episodes().set_index(["task", "axis", "level", "episode"]).sort_index()


def test_until_failure_runs_t0_once_and_reports_as_unshared(runs):
    shared, own = (_episodes(r) for r in runs)
    assert shared[OUTCOME].equals(own[OUTCOME])  # the random stand-in never succeeds: both ladders stop at 0
    assert list(shared.index) == [("milk", a, 0, i) for a in sorted(AXES) for i in range(2)]
    assert (shared.loc[("milk", "scale")]["shared_from"] == "pick_y").all()
    assert (own["shared_from"] == "").all()
    s = [json.loads((Path(r) / "summary.json").read_text())["axes"] for r in runs]
    assert s[0] == s[1]
    manifest = json.loads((Path(runs[0]) / "manifest.json").read_text())["t0_sharing"]
    assert manifest == {"enabled": True, "groups": {"milk": [["pick_y", "scale"]]}, "rollouts": 6, "saved": 2}


def test_a_resume_of_a_half_done_shared_t0_finishes_it_like_an_unkilled_run(runs, tmp_path):
    """Killed with the owner's first level-0 episode recorded and its copy not (an older journal), the rest not
    run: the resume (1 worker) writes the copy and runs the owner's second episode once, for both ladders, ending
    where the 2-worker run did."""
    full = RunDir(runs[0])
    killed = RunDir.create_or_resume(tmp_path / "killed", full.manifest)
    first = next(r for r in full.rows() if r["axis"] == "pick_y" and r["episode"] == 0)
    killed.append([EpisodeRecord(**first)])
    evaluate(cfg(tmp_path / "killed"), quiet=True)
    cols = [*OUTCOME, "shared_from"]
    assert _episodes(tmp_path / "killed")[cols].equals(_episodes(runs[0])[cols])


@pytest.mark.slow  # 7 s; the half-done resume above covers the state a kill leaves by default
def test_sigkill_mid_shared_t0_then_resume(tmp_path):
    """A real kill while level 0's shared episodes are being recorded: the resume ends where an unkilled run does."""
    flags = ["--policy", "standin:random", "--scene", "pick_place", "--axis", ",".join(AXES), "--levels", "0:1",
             "--episodes", "6", "--workers", "1", "--max-steps", "8", "--adaptive", "until-failure"]  # fmt: skip
    killed = tmp_path / "killed"
    assert 0 < kill_midway(["evaluate", *flags], killed, total=12, at_least=3) < 12
    evaluate(cfg(killed, episodes=6), quiet=True)
    whole = evaluate(cfg(tmp_path / "whole", episodes=6), quiet=True)
    cols = [*OUTCOME, "shared_from"]
    got = _episodes(killed)
    assert got[cols].equals(_episodes(whole)[cols])
    assert (got.loc[("milk", "scale")]["shared_from"] == "pick_y").all()
