"""The paper's real-robot design (§5.3), the stack and scale presets' default: 10 trials at each level, levels in
order, and the run stops after the first level observed below γ = 0.2. Hand-computed: 10/10, 6/10, 1/10 stops after
level 2 (k* = +2, observed); Wilson 95 % CI of 1/10 = [1.8, 40.4] %, which reaches above γ: not a decided break."""

from __future__ import annotations

import json

from indgen_vla.app.cli import main

PLAN = ["real", "plan", "--setup", "stack", "--levels", "0:4", "--policy", "pi05-droid"]


def _record(run, outcome, capsys) -> list[str]:
    assert main(["real", "record", str(run), "--outcome", outcome, "--no-report"]) == 0
    return capsys.readouterr().out.strip().splitlines()


def test_the_stack_preset_stops_after_the_first_level_observed_below_gamma(tmp_path, capsys):
    run = tmp_path / "run"
    assert main([*PLAN, "--out", str(run)]) == 0  # no --adaptive: the preset's stopping, until-failure
    sheet = capsys.readouterr().out
    assert "Order: blocked" in sheet and "10 episodes at each level, levels in order" in sheet
    assert "not decided by a statistical test" in sheet
    plan = json.loads((run / "manifest.json").read_text())["plan"]
    assert plan["adaptive"] == {"mode": "until-failure", "gamma": 0.2} and plan["episodes"] == 10
    for successes in (10, 6):
        for i in range(10):
            out = _record(run, "success" if i < successes else "failure:misplaced", capsys)
        assert out[-1] == f"next: level {1 if successes == 10 else 2} episode 0"
    assert "level 1 done: 6/10 = 60 % (95 % Wilson CI 31-83 %) ≥ γ = 0.2: on to the next level" in out
    out = _record(run, "success", capsys)
    assert "level 2: 1 of 10 trials; the next level waits for the rest" in out
    for _ in range(9):
        out = _record(run, "failure:dropped", capsys)
    assert "level 2 done: 1/10 = 10 % (95 % Wilson CI 2-40 %) < γ = 0.2: the run stops here" in out[2]
    assert out[3].startswith("until-failure: every level it needs has its trials; k* = +2 observed (1/10")
    assert out[-1] == "run complete"
    assert main(["real", "status", str(run), "--json"]) == 0
    st = json.loads(capsys.readouterr().out)
    assert [(r["level"], r["n"], r["decision"]) for r in st["levels"]] == [
        (0, 10, "intact"), (1, 10, "intact"), (2, 10, "undetermined"), (3, 0, "not needed"), (4, 0, "not needed")
    ]  # fmt: skip
    from indgen_vla.core.reporting.report import render_markdown
    from indgen_vla.core.reporting.summary import summarize
    from indgen_vla.core.runs.records import RunDir

    r = RunDir.open(run)
    summary = summarize(r.episodes(), r.manifest)
    a = summary["axes"]["stack"]
    assert a["break_level"]["pos"] == 2
    assert a["verdict"]["pos"] == (
        "observed break at +2 (10 %, n = 10, 95 % CI [2, 40]): the paper's until-failure design stopped at the first "
        "level below γ = 0.2; observed, not statistically decided (the CI reaches 40 % ≥ γ)"
    )
    rows = {row["level"]: row for row in a["levels"]}
    assert rows[2]["observed_break"] and rows[3]["not_run"] and rows[4]["planned"] == 0
    assert "the paper's fixed design (§5.3, until failure): 10 episodes per level" in a["design"]
    md = render_markdown([("run", summary)])
    assert (
        "| design | | the paper's fixed design" in md
        and "| 3 | — | not run (past the observed break) |" in md
    )


def test_off_runs_every_level_and_until_failure_refuses_interleaving(tmp_path, capsys):
    assert main([*PLAN, "--adaptive", "off", "--out", str(tmp_path / "off")]) == 0
    assert "adaptive" not in json.loads((tmp_path / "off" / "manifest.json").read_text())["plan"]
    capsys.readouterr()
    assert main([*PLAN, "--order", "interleaved", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "until-failure runs one level at a time" in err
