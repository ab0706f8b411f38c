"""``indgen certify --evaluation-states --run DIR``: the oracle plays the exact initial states of the run's episodes
(an oracle run's own outcomes are reproduced state for state), and ``report`` splits the policy's failures by
whether the oracle solved the state."""

from __future__ import annotations

import json

import pandas as pd

from indgen_vla.app.api import evaluate
from indgen_vla.app.cli import main
from indgen_vla.core.reporting.oracle_states import states_entry, states_lines


def test_the_oracle_replays_an_oracle_runs_states_exactly(tmp_path, capsys):
    out = tmp_path / "run"
    evaluate(policy="standin:oracle", scene="pick_place", axis="pick_y", levels="0:1", episodes=1, out=out,
             quiet=True, workers=1)  # fmt: skip
    assert main(["certify", "--evaluation-states", "--run", str(out)]) == 0
    assert "evaluated states of" in capsys.readouterr().out
    states = json.loads((out / "oracle_states.json").read_text())["states"]
    run = pd.read_parquet(out / "episodes.parquet")
    mine = {
        (r.task, r.axis, int(r.level), int(r.episode)): (int(r.seed), bool(r.success))
        for r in run.itertuples()
    }
    assert {
        (s["task"], s["axis"], s["level"], s["episode"]): (s["seed"], s["solved"]) for s in states
    } == mine
    assert main(["report", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    # every planned level's certificate basis (the shipped pick_place milk pick_y 0 and 1: held-out)
    assert summary["axes"]["pick_y"]["certification_basis"] == {"milk": {"held-out": [0, 1]}}
    entry = summary["axes"]["pick_y"]["oracle_states"]
    solved = sum(e["oracle_solved"] for lv in entry.values() for e in lv.values())
    assert solved == int(run["success"].sum())  # and the policy (the oracle itself) failed no solved state
    assert "**Oracle on the evaluated states**" in (out / "report.md").read_text()
    assert "Oracle on the evaluated states" in (out / "report.html").read_text()


def test_failures_are_split_by_whether_the_oracle_solved_the_state():
    states = {("t", "a", 1, 0): True, ("t", "a", 1, 1): False, ("t", "a", 1, 2): True, ("t", "a", 1, 3): None,
              ("t", "a", 0, 0): True}  # fmt: skip
    eps = pd.DataFrame({"task": "t", "axis": ["a"] * 5 + ["b"], "level": [1, 1, 1, 1, 0, 0],
                        "episode": [0, 1, 2, 3, 0, 0], "success": [False, False, True, False, True, True],
                        "status": "ok", "shared_from": ["", "", "", "", "", "a"]})  # fmt: skip
    entry = states_entry(states, eps, "a")
    assert entry["t"]["1"] == {"states": 3, "oracle_solved": 2, "oracle_unsolved": 1, "policy_failed_solved": 1,
                               "policy_failed_unsolved": 1, "unsolved_episodes": [1]}  # fmt: skip
    assert (
        states_entry(states, eps, "b")["t"]["0"]["oracle_solved"] == 1
    )  # a shared T0 reads its owner's state
    (line,) = states_lines("R", "a", entry)
    assert "1 were on states the oracle solved (policy failures) and 1 on states it did not" in line
    assert (
        "t level +1: 1 of 2 solved states failed by the policy, 1 of 1 unsolved ones (episodes [1])" in line
    )
