"""T0 run once for the axes that share it (engine/share.py) on the real pick_place scene with CPU stand-ins."""

import json
from pathlib import Path

import pandas as pd
import pytest

from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.app.engine.share import fill_copies, sharing_entry, with_sharing
from indgen_vla.core.protocol.plan import SHARING_OFF
from indgen_vla.core.runs.records import EpisodeRecord, RunDir
from tests.fixtures.kill import kill_midway
from tests.fixtures.resolved import build_plan, evaluate

pytestmark = pytest.mark.filterwarnings("ignore")

AXES = ("pick_y", "scale")
OUTCOME = ["seed", "success", "steps", "status", "failure", "progress"]


def cfg(out, **kw):
    base = dict(policy="standin:random", scene="pick_place", axes=AXES, levels="0:1", episodes=2, workers=1,
                max_steps=8, out=str(out))  # fmt: skip
    return EvalConfig.from_flat(**{**base, **kw})


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The same seeded run with T0 shared (the default) and with --no-share-t0."""
    root = tmp_path_factory.mktemp("share")
    return evaluate(cfg(root / "shared"), quiet=True), evaluate(cfg(root / "own", share_t0=False), quiet=True)


def episodes(run) -> pd.DataFrame:
    return (
        pd.read_parquet(Path(run) / "episodes.parquet")
        .set_index(["task", "axis", "level", "episode"])
        .sort_index()
    )


def test_t0_runs_once_and_both_axes_report_it(runs):
    shared, own = (episodes(r) for r in runs)
    assert len(shared) == len(own) == 8  # one row per (task, axis, level, episode), as without sharing
    assert (own["shared_from"] == "").all()
    copies = shared[shared["shared_from"] != ""]
    # rollouts: 6 rows are rolled out for their own axis; scale's level 0 is pick_y's rollouts, recorded again
    assert len(shared) - len(copies) == 6 and list(copies.index) == [
        ("milk", "scale", 0, 0),
        ("milk", "scale", 0, 1),
    ]
    assert (copies["shared_from"] == "pick_y").all() and (copies["wall_s"] == 0).all()
    t0 = shared.loc[("milk", "pick_y", 0)]
    assert copies.loc[("milk", "scale", 0)][OUTCOME].equals(t0[OUTCOME])
    assert (copies["param"] == 1.0).all()  # scale's own level-0 parameter, not pick_y's position
    manifest = json.loads((Path(runs[0]) / "manifest.json").read_text())
    assert manifest["t0_sharing"] == {"enabled": True, "groups": {"milk": [["pick_y", "scale"]]}, "rollouts": 6,
                                      "saved": 2}  # fmt: skip
    off = json.loads((Path(runs[1]) / "manifest.json").read_text())["t0_sharing"]
    assert off["enabled"] is False and off["reason"] == "off (--no-share-t0)" and off["saved"] == 0


def test_report_and_contrasts_equal_an_unshared_run(runs):
    shared, own = (episodes(r) for r in runs)
    assert shared[OUTCOME + ["param"]].equals(own[OUTCOME + ["param"]])  # the stand-in is seeded per episode
    summaries = [json.loads((Path(r) / "summary.json").read_text()) for r in runs]
    assert summaries[0]["axes"] == summaries[1]["axes"]  # levels, n, CIs, k*, vs_t0 alike


@pytest.mark.slow  # ~5 s: two runs compared
def test_compare_axes_says_shared_t0_pairs_check_nothing(runs, tmp_path):
    from indgen_vla.app.cli import main

    for run, name in zip(runs, ("shared", "own"), strict=True):
        assert main(["compare", str(run), "--axes", "pick_y:scale", "--out", str(tmp_path / name)]) == 0
    got = {
        n: json.loads((tmp_path / n / "compare.json").read_text())["axes"]["pick_y vs scale"]
        for n in ("shared", "own")
    }
    t0 = {n: next(r for r in a["levels"] if r["level"] == 0) for n, a in got.items()}
    assert t0["shared"]["same_rollout"] == 2 and t0["shared"]["p_value"] != t0["shared"]["p_value"]  # NaN
    assert "same_rollout" not in t0["own"] and t0["own"]["p_value"] == 1.0
    assert "one rollout recorded for both axes" in got["shared"]["pairing"]
    assert "one rollout" not in got["own"]["pairing"]


def test_no_share_t0_shares_nothing_and_says_why(tmp_path):
    off = cfg(tmp_path, share_t0=False, adaptive="kstar")
    plan = with_sharing(off, build_plan(cfg(tmp_path, share_t0=False)))
    record = sharing_entry(off, plan)
    assert (
        plan.shared == {}
        and record["reason"] == SHARING_OFF
        and not record["enabled"]
        and record["saved"] == 0
    )
    on = cfg(tmp_path, adaptive="kstar")  # adaptive runs share too (test_adaptive_share.py)
    assert with_sharing(on, plan).shared == {("milk", "scale"): "pick_y"}


def test_a_resume_writes_the_copies_a_kill_cut_off(tmp_path, runs):
    plan = build_plan(cfg(tmp_path))
    run = RunDir.create_or_resume(tmp_path / "r", {"plan": {}})
    full = RunDir(runs[0]).rows()
    run.append([EpisodeRecord(**r) for r in full if not r["shared_from"]])  # killed before the copies
    assert fill_copies(plan, run) == 2 and fill_copies(plan, run) == 0
    got = {(r["axis"], r["level"], r["episode"]): (r["success"], r["shared_from"]) for r in run.rows()}
    assert got == {(r["axis"], r["level"], r["episode"]): (r["success"], r["shared_from"]) for r in full}


@pytest.mark.slow  # ~8 s: a CLI run killed and resumed; test_adaptive_share resumes shared rows by default
def test_resume_after_sigkill_with_shared_rows(tmp_path, runs, capsys):
    """The killed run is a real process; the resume (cli.main in this process) reads only what it left on disk."""
    from indgen_vla.app.cli import main

    args = ["evaluate", "--policy", "standin:random", "--scene", "pick_place", "--axis", ",".join(AXES), "--levels",
            "0:1", "--episodes", "2", "--workers", "1", "--max-steps", "8"]  # fmt: skip
    killed = tmp_path / "killed"
    kept = kill_midway(
        args, killed, total=8, at_least=3
    )  # pick_y's T0 first: its rows come with scale's copies
    assert 3 <= kept < 8
    capsys.readouterr()
    assert main([*args, "--out", str(killed)]) == 0
    cols = [*OUTCOME, "param", "shared_from"]
    assert episodes(killed)[cols].equals(episodes(runs[0])[cols])
    assert "planned episodes already recorded" in " ".join(capsys.readouterr().err.split())


def test_an_error_copy_gives_way_to_its_owners_retry(tmp_path, runs):
    plan = build_plan(cfg(tmp_path))
    run = RunDir.create_or_resume(tmp_path / "r", {"plan": {}})
    owner = next(r for r in RunDir(runs[0]).rows() if r["axis"] == "pick_y" and r["level"] == 0)
    run.append(
        [EpisodeRecord(**{**owner, "status": "error", "error": "attempt 3: boom", "failure": "error"})]
    )
    assert fill_copies(plan, run) == 1 and run.rows()[-1]["status"] == "error"  # scale's level 0 errs with it
    run.append([EpisodeRecord(**owner)])  # the retry on resume
    assert fill_copies(plan, run) == 1
    assert {(r["axis"], r["status"]) for r in run.rows()} == {("pick_y", "ok"), ("scale", "ok")}
