"""Certification shows where results are read: summary.json, report.md's caveats and evaluate's warning say which
levels of which task are certified, uncertified, without any oracle, or failed (issue 41)."""

from __future__ import annotations

import pytest

from scenes.family import get_scene


@pytest.fixture
def unscripted_toaster(monkeypatch):
    """CloseToasterOvenDoor (a base_y task) taken off the RoboCasa oracle's list: every base_y task has a script
    since oracle v4, and these tests need one without (the path a task RoboCasa adds later would take)."""
    from scenes.robocasa.oracle import RoboCasaOracle

    kept = tuple(t for t in RoboCasaOracle.tasks if t != "CloseToasterOvenDoor")
    monkeypatch.setattr(RoboCasaOracle, "tasks", kept)


def test_a_task_without_an_oracle_is_marked_in_the_plan_and_summary(placeholders, unscripted_toaster):
    """CloseToasterOvenDoor without an oracle script: its cells say so, summary.json's certification files its levels
    under ``no_oracle`` and report.md's caveat says certify cannot help; a scripted task's are ``uncertified``."""
    import dataclasses

    import pandas as pd

    from indgen_vla.core.reporting.caveats import report_caveats
    from indgen_vla.core.reporting.certification_view import NO_ORACLE
    from indgen_vla.core.reporting.summary import summarize
    from scenes.planning import resolve_scene_plan

    plan = resolve_scene_plan(get_scene("robocasa"), "all", ("base_y",), "0:1", None, None)
    by_task = {c.task: c for c in plan.cells if c.level == 1}
    assert (
        by_task["CloseToasterOvenDoor"].evidence == NO_ORACLE
        and by_task["PickPlaceCounterToSink"].evidence != NO_ORACLE
    )
    manifest = {"plan": {"tasks": list(plan.tasks), "levels": {"base_y": [0, 1]}, "episodes": 1},
                "resolved": {"cells": [dataclasses.asdict(c) for c in plan.cells]}}  # fmt: skip
    empty = pd.DataFrame(columns=["task", "axis", "level", "episode", "seed", "param", "success", "status",
                                  "steps"])  # fmt: skip
    summary = summarize(empty, manifest)
    cert = summary["axes"]["base_y"]["certification"]
    assert cert["CloseToasterOvenDoor"] == {"no_oracle": [0, 1]} and cert["PickPlaceCounterToSink"] == {
        "uncertified": [0, 1]
    }
    lines = report_caveats([("run", summary)])
    (none,) = [x for x in lines if "no oracle" in x]
    assert (
        "CloseToasterOvenDoor: 0, +1" in none
        and "PickPlaceCounterToSink" not in none
        and "cannot help" in none
    )
    (short,) = [x for x in lines if "**uncertified**" in x]
    assert "PickPlaceCounterToSink: 0, +1" in short and "CloseToasterOvenDoor" not in short


def test_evaluate_does_not_advise_certify_for_a_task_without_an_oracle(
    placeholders, unscripted_toaster, tmp_path
):
    """The warning names the unscripted task's levels and stops advising ``indgen certify`` (which refuses it)."""
    from indgen_vla.app.engine.config import EvalConfig
    from indgen_vla.app.engine.run import check_feasible
    from tests.fixtures.resolved import build_plan

    cfg = EvalConfig.from_flat(policy="standin:noop", scene="robocasa", task="all", axes=("base_y",), levels="0:1",
                     episodes=1, out=str(tmp_path / "run"))  # fmt: skip
    lines = check_feasible(cfg, build_plan(cfg))
    (none,) = [x for x in lines if "no script" in x]
    assert "CloseToasterOvenDoor: levels 0, +1" in none and "indgen certify refuses" in none
    assert "PickPlaceCounterToSink" not in none and "'indgen certify" not in none
    (short,) = [x for x in lines if "'indgen certify" in x]
    assert "PickPlaceCounterToSink" in short and "CloseToasterOvenDoor" not in short


def test_summary_files_failed_and_certified_levels_per_task():
    from indgen_vla.core.reporting.certification_view import certification_caveats, certification_entry

    cells = [{"task": "T", "axis": "a", "level": k, "certificate": c, "evidence": ""}
             for k, c in ((0, "certified"), (1, "certified"), (2, "failed"))]  # fmt: skip
    entry = certification_entry({"resolved": {"cells": [*cells, {**cells[0], "axis": "b"}]}}, "a")
    assert entry == {"T": {"certified": [0, 1], "failed": [2]}}
    (line,) = certification_caveats("run", "a", entry)
    assert "**failed**" in line and "T: +2" in line
    assert certification_caveats("run", "a", {"T": {"certified": [0, 1]}}) == []  # all certified: no caveat
    assert certification_entry({}, "a") == {}  # a manifest from before the cells were recorded


def test_infeasible_episodes_are_counted_per_level_and_named_in_the_report():
    """An episode whose kitchen cannot hold the level (the worker's ``unavailable``: the placement check, the pick
    window) is an error row excluded from n; summary.json counts it per task and level and report.md says so."""
    import pandas as pd

    from indgen_vla.core.reporting.caveats import report_caveats
    from indgen_vla.core.reporting.summary import summarize

    err = ("EpisodeUnavailableError: PickPlaceCounterToCabinet seed 5 (layout 1, style 2): base_y moved the robot "
           "base mobilebase0_pedestal_feet_col 3.1 cm into wall (placement check)")  # fmt: skip
    rows = [
        ("T", "horizon", k, i, 100 * k + i, 0.125 * k, k == 0, 10, "ok", "") for k in (0, 1) for i in range(3)
    ]
    rows += [("T", "horizon", 1, 3, 103, 0.125, False, 0, "error", err), ("T", "horizon", 1, 4, 104, 0.125, False, 0,
             "error", "RuntimeError: worker died")]  # fmt: skip
    df = pd.DataFrame(rows, columns=["task", "axis", "level", "episode", "seed", "param", "success", "steps",
                                     "status", "error"])  # fmt: skip
    df = df.assign(run_id="r", policy="p", data_regime="", scene="robocasa", wall_s=1.0, video="", failure="",
                   progress=None, shared_from="")  # fmt: skip
    manifest = {"plan": {"tasks": ["T"], "levels": {"horizon": [0, 1]}, "episodes": 5}}
    a = summarize(df, manifest)["axes"]["horizon"]
    assert a["infeasible"] == {"T": {"1": 1}}  # the worker that died is an ordinary error, retried
    assert next(r for r in a["levels"] if r["level"] == 1)["n"] == 3
    (line,) = [
        x for x in report_caveats([("run", {"gamma": 0.5, "axes": {"horizon": a}})]) if "Infeasible" in x
    ]
    assert "T: level 1 × 1" in line and "never counted as policy failures" in line
