import json
import math

import pytest

from indgen_vla.app.cli import main
from indgen_vla.core.reporting.report import plot_axis, render_markdown
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.runs.records import RunDir
from tests.indgen_vla.core.runs.test_records import rec


def make_run(path, successes_by_level, regime="h-only", errors=0, **manifest):
    run = RunDir.create_or_resume(path, {"plan": {"x": 1}, "data_regime": regime, "policy": "standin:noop",
                                         "axes": {"pick_y": {"signed": True}}, **manifest})  # fmt: skip
    recs = []
    for level, (s, n) in successes_by_level.items():
        recs += [rec(level, i, success=i < s) for i in range(n)]
    recs += [rec(0, 100 + i, status="error") for i in range(errors)]
    run.append(recs)
    return run


def test_summary_schema_and_values(tmp_path):
    run = make_run(tmp_path, {-1: (1, 10), 0: (9, 10), 1: (5, 10), 2: (1, 10)}, errors=2)
    s = summarize(run.episodes(), run.manifest, gamma=0.2)
    ax = s["axes"]["pick_y"]
    lv = {r["level"]: r for r in ax["levels"]}
    assert lv[0]["n"] == 10 and lv[0]["successes"] == 9 and lv[0]["errors"] == 2
    assert lv[0]["rate"] == pytest.approx(0.9)
    assert lv[0]["ci_low"] == pytest.approx(0.59585, abs=1e-4)  # Wilson 9/10
    assert lv[-1]["param"] == pytest.approx(-0.025)
    assert ax["break_level"] == {"pos": 2, "neg": -1}
    assert ax["trend"]["pos"]["p_decreasing"] < 0.05


def test_report_cli_writes_outputs(tmp_path, capsys):
    a = make_run(tmp_path / "a", {0: (10, 10), 1: (8, 10), -1: (9, 10)}, regime="h-only")
    b = make_run(tmp_path / "b", {0: (10, 10), 1: (1, 10), -1: (2, 10), -2: (1, 10)}, regime="h+mg")
    assert main(["report", str(a.path), str(b.path), "--out", str(tmp_path / "cmp")]) == 0
    summary = json.loads((a.path / "summary.json").read_text())
    assert summary["gamma"] == 0.2
    assert summary["axes"]["pick_y"]["break_level"] == {"pos": None, "neg": None}
    assert (a.path / "plots" / "pick_y.png").stat().st_size > 1000
    md = (tmp_path / "cmp" / "report.md").read_text()
    assert "h-only" in md and "h+mg" in md and "| **k\\*** |" in md
    # the interval's name as the verdicts print it (it read "with wilson 95 % CI" beside "Wilson 95 % CI")
    assert "Success rate with Wilson 95 % CI" in md and "wilson 95" not in md
    assert "wilson 95" not in (a.path / "plots" / "pick_y.svg").read_text()
    assert "wilson 95" not in (a.path / "report.html").read_text()
    assert (tmp_path / "cmp" / "plots" / "pick_y.png").exists()
    b_sum = json.loads((b.path / "summary.json").read_text())
    assert b_sum["axes"]["pick_y"]["break_level"] == {"pos": 1, "neg": -2}  # 2/10 is not < 0.2
    assert not math.isnan(b_sum["axes"]["pick_y"]["levels"][0]["rate"])


def test_run_report_draws_the_svg_headline_and_leaves_pngs_to_indgen_report(tmp_path):
    # a run's own report (evaluate's end) writes the success curve as SVG without matplotlib and inlines it in
    # report.html; indgen report adds the PNGs, which every later report of the run then redraws (never stale)
    from xml.etree import ElementTree

    from indgen_vla.core.reporting.report import write_run_report

    run = make_run(tmp_path / "r", {0: (9, 10), 1: (5, 10), 2: (1, 10), -1: (8, 10)})
    write_run_report(run)
    plots = run.path / "plots"
    assert sorted(p.name for p in plots.iterdir()) == ["pick_y.svg"]
    svg = ElementTree.parse(plots / "pick_y.svg").getroot()  # well-formed XML
    ns = "{http://www.w3.org/2000/svg}"
    assert len(svg.findall(f"{ns}circle")) == 4 + 1  # a point per level and k* (+2) ringed
    texts = "".join(t.text or "" for t in svg.iter(f"{ns}text"))
    assert "n = 10 per level" in texts and "γ = 0.2" in texts and "level k along pick_y" in texts
    html = (run.path / "report.html").read_text()
    assert html.count("data:image/svg+xml;base64,") == 1 and "draws every plot" in html
    assert main(["report", str(run.path)]) == 0
    assert sorted(p.name for p in plots.iterdir()) == ["pick_y.png", "pick_y.svg"]  # no failure modes, stages
    html = (run.path / "report.html").read_text()
    assert "data:image/svg+xml" not in html and html.count("data:image/png;base64,") == 1
    before = (plots / "pick_y.png").stat().st_mtime_ns
    run.append([rec(3, i, success=False) for i in range(10)])  # resumed: PNGs once drawn are kept current
    write_run_report(run)
    assert (plots / "pick_y.png").stat().st_mtime_ns > before
    assert (run.path / "report.html").read_text().count("data:image/png;base64,") == 1
    assert write_run_report(run, plots=False)["axes"]["pick_y"]["levels"][-1]["level"] == 3


def test_report_bad_inputs(tmp_path, capsys):
    assert main(["report", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: run directory") and "Traceback" not in err and err.count("\n") == 1
    empty = RunDir.create_or_resume(tmp_path / "empty", {"plan": {}})
    assert main(["report", str(empty.path)]) == 2
    assert "no finished episodes" in capsys.readouterr().err
    make_run(tmp_path / "ok", {0: (1, 2)})
    assert main(["report", str(tmp_path / "ok"), "--gamma", "1.5"]) == 2
    assert "--gamma" in capsys.readouterr().err


def test_labels_show_local_checkpoints_relative_to_the_working_directory(tmp_path, monkeypatch):
    from indgen_vla.core.reporting.report import _short_spec

    monkeypatch.chdir(tmp_path)
    assert _short_spec(f"lerobot:{tmp_path}/ckpts/a") == "lerobot:ckpts/a"
    assert _short_spec("lerobot:/elsewhere/b") == "lerobot:/elsewhere/b"
    assert _short_spec("openpi:ws://gpu:8000") == "openpi:ws://gpu:8000"
    assert _short_spec("lerobot:org/model") == "lerobot:org/model" and _short_spec(None) is None


def _run_with(path, rows, plan):
    """A run dir from (task, level, episode, success, status) rows and a manifest plan."""
    from indgen_vla.core.runs.records import EpisodeRecord

    run = RunDir.create_or_resume(
        path, {"plan": plan, "policy": "standin:noop", "axes": {"pick_y": {"signed": True}}}
    )
    recs = [EpisodeRecord(run_id="r", policy="p", data_regime="", scene="s", task=t, axis="pick_y", level=k,
                          param=0.025 * k, episode=i, seed=1000 + i, success=ok, steps=1, status=st,
                          error="boom" if st == "error" else "")
            for t, k, i, ok, st in rows]  # fmt: skip
    run.append(recs)
    return run


def test_per_task_summary_and_pooled_curve(tmp_path):
    # task a holds at level 1 (5/6) and breaks at 2 (0/6); task b breaks at 1 (1/6); pooled level 1 = 6/12
    outcomes = {("a", 0): 6, ("a", 1): 5, ("a", 2): 0, ("b", 0): 6, ("b", 1): 1, ("b", 2): 0}
    rows = [(t, k, i, i < s, "ok") for (t, k), s in outcomes.items() for i in range(6)]
    plan = {"tasks": ["a", "b"], "levels": {"pick_y": [0, 1, 2]}, "episodes": 6}
    run = _run_with(tmp_path / "r", rows, plan)
    s = summarize(run.episodes(), run.manifest)
    ax = s["axes"]["pick_y"]
    assert ax["pooled_tasks"] == ["a", "b"]
    assert [(r["level"], r["successes"], r["n"], r["planned"]) for r in ax["levels"]] == [
        (0, 12, 12, 12), (1, 6, 12, 12), (2, 0, 12, 12)]  # fmt: skip
    assert ax["break_level"] == {"pos": 2, "neg": None}
    ta, tb = ax["tasks"]["a"], ax["tasks"]["b"]
    assert [r["successes"] for r in ta["levels"]] == [6, 5, 0] and ta["levels"][1]["planned"] == 6
    assert ta["break_level"]["pos"] == 2 and tb["break_level"]["pos"] == 1
    assert tb["levels"][1]["ci_low"] == pytest.approx(0.030053, abs=1e-5)  # Wilson 1/6
    md = render_markdown([("run", s)])
    assert "Every rate below: pooled over 2 tasks: a, b." in md and "k* per task" in md
    assert "| a | +: L2, −: none |" in md and "| b | +: L1, −: none |" in md
    assert (
        "| **across tasks** | +: L1 ×1, L2 ×1 (2 tasks; median L1 to L2); −: none ×2 (2 tasks; median none) |"
        in md
    )
    assert plot_axis([("run", ax)], "pick_y", 0.2, tmp_path / "p.png").stat().st_size > 1000


def test_data_floor_and_visible_errors(tmp_path, capsys):
    # level 0: 5 ok of 5; level 1: 1 ok + 3 errors of 4 planned; level 2: 4 of 4 ok but n < 5 -> both short
    rows = [("t", 0, i, True, "ok") for i in range(5)] + [("t", 1, 0, True, "ok")]
    rows += [("t", 1, i, False, "error") for i in (1, 2, 3)] + [("t", 2, i, False, "ok") for i in range(4)]
    run = _run_with(tmp_path / "r", rows, {"tasks": ["t"], "levels": {"pick_y": [0, 1, 2, 3]}, "episodes": 4})
    s = summarize(run.episodes(), run.manifest)
    lv = {r["level"]: r for r in s["axes"]["pick_y"]["levels"]}
    assert [lv[k]["insufficient"] for k in range(4)] == [False, True, True, True]
    assert lv[3]["n"] == 0 and lv[3]["param"] is None  # planned, never run: still listed
    assert lv[1]["errors"] == 3
    # level 2 (0/4) would break, but it is below the floor and level 1 before it has no usable data
    assert s["axes"]["pick_y"]["break_level"]["pos"] == "undetermined"
    assert s["axes"]["pick_y"]["monotone"] == {} and s["axes"]["pick_y"]["trend"] == {}
    assert s["axes"]["pick_y"]["break_point"] == {}  # nor a fitted crossing from levels 1-2 (it was L1.x)
    md = render_markdown([("run", s)])
    assert "insufficient data (n = 1 of 4; 3 errors)" in md and "insufficient data (n = 0 of 4)" in md
    assert "| 2 | 0.05 | insufficient data (n = 4 of 4) |" in md
    rows_md = [line for line in md.splitlines() if line.startswith(("| 1 |", "| 2 |", "| 3 |"))]
    # three curve rows and three change-from-T0 rows: no rate, and no change from T0, below the floor
    assert len(rows_md) == 6 and not any("%" in line for line in rows_md)
    assert "| 2 | insufficient data | 4 |" in md and "| 3 | no pairs | 0 |" in md
    assert "undetermined" in md and "level 1 has 3 error episode(s) of 4 (75 % > 10 %)" in md
    assert main(["report", str(run.path)]) == 0
    out = capsys.readouterr().out
    assert "insufficient data (n = 1 of 4; 3" in out and "undetermined" in out
    assert "break point (S = γ): —" in out


def test_monotone_test_is_shown_per_direction(tmp_path):
    run = make_run(tmp_path, {-2: (2, 10), -1: (6, 10), 0: (10, 10), 1: (10, 10), 2: (9, 10)})
    s = summarize(run.episodes(), run.manifest)
    mono = s["axes"]["pick_y"]["monotone"]
    from indgen_vla.core.stats.metrics import monotone_decreasing_test

    expect = monotone_decreasing_test([10, 6, 2], [10, 10, 10])
    assert mono["neg"]["p_decreasing"] == pytest.approx(expect.p_decreasing) and mono["neg"]["levels"] == [
        0,
        -1,
        -2,
    ]
    assert mono["pos"]["p_decreasing"] > 0.1
    md = render_markdown([("run", s)])
    row = next(line for line in md.splitlines() if line.startswith("| monotone decrease"))
    assert f"−: p = {expect.p_decreasing:.2g} (exact)" in row and "+: p = " in row
    assert any(line.startswith("| linear trend (Cochran–Armitage)") for line in md.splitlines())


def test_verdicts_kstar_status_and_break_point(tmp_path):
    from indgen_vla.core.stats.metrics import wilson_ci

    counts = {-3: (0, 20), -2: (2, 20), -1: (12, 20), 0: (20, 20), 1: (15, 20), 2: (5, 20), 3: (0, 20)}
    run = make_run(tmp_path / "r", counts)
    s = summarize(run.episodes(), run.manifest, gamma=0.2)
    ax = s["axes"]["pick_y"]
    want = {}
    for k, (x, n) in counts.items():  # by hand from the Wilson bounds: broken < 0.2 <= intact
        lo, hi = wilson_ci(x, n)
        want[k] = "broken" if hi < 0.2 else ("intact" if lo >= 0.2 else "undetermined")
    assert {r["level"]: r["decision"] for r in ax["levels"]} == want
    assert want[2] == "undetermined" and want[3] == "broken"  # 5/20: CI [0.11, 0.47] straddles 0.2
    assert ax["kstar_status"]["pos"]["text"] == "k* ∈ [+2, +3]"
    assert ax["kstar_status"]["neg"]["text"] == "k* ∈ [-3, -2]"
    bp = ax["break_point"]["pos"]
    # the curve falls from 0.75 at +1 to 0.25 at +2 and 0 at +3: it crosses 0.2 between +1 and +3
    assert 1 < bp["level"] < 3 and bp["ci"]["level"][0] <= bp["level"] <= bp["ci"]["level"][1]
    assert bp["param"] == pytest.approx(0.025 * bp["level"], rel=1e-6)
    md = render_markdown([("x", s)], "t")
    assert "k\\* status" in md and "k* ∈ [+2, +3]" in md and "break point (S = γ)" in md


def test_a_black_box_run_shows_condition_2_validated_next_to_kstar(tmp_path):
    """Appendix B: where the scene family says T0 is empirical (protocol regime "black-box", RoboCasa365), the
    report says per direction whether the monotone test validates the ordering; a vanilla run shows no such row."""
    from indgen_vla.core.stats.metrics import monotone_decreasing_test

    levels = {-2: (2, 10), -1: (6, 10), 0: (10, 10), 1: (10, 10), 2: (9, 10)}
    vanilla = make_run(tmp_path / "v", levels)
    s = summarize(vanilla.episodes(), vanilla.manifest)
    assert s["axes"]["pick_y"]["regime"] == "vanilla" and s["axes"]["pick_y"]["condition2"] is None
    assert "condition 2" not in render_markdown([("run", s)])
    manifest = {**vanilla.manifest, "resolved": {"environment": {"protocol": {"regime": "black-box"}}}}
    s = summarize(vanilla.episodes(), manifest)
    c = s["axes"]["pick_y"]["condition2"]
    p_neg = monotone_decreasing_test([10, 6, 2], [10, 10, 10]).p_decreasing
    assert c["directions"]["neg"] == {"p": pytest.approx(p_neg), "validated": True}  # 10 -> 6 -> 2 of 10
    assert c["directions"]["pos"]["validated"] is False  # 10, 10, 9 of 10: not shown to be harder
    row = next(
        line for line in render_markdown([("run", s)]).splitlines() if line.startswith("| condition 2")
    )
    assert "−: validated (monotone decrease" in row and "+: NOT validated" in row


def test_kstar_status_of_an_unfinished_adaptive_run_speaks_only_of_levels_run(tmp_path):
    """An adaptive run stopped after level +1's first look: +2 and +3 were planned, not run, so the status must not
    say "no level through +3 is decided broken" (the summary's and the live plan's text agree)."""
    from indgen_vla.core.stats.sprt import SequentialRule, plan_entry, plan_next

    rule = SequentialRule(max_episodes=20, round_size=5)
    outcomes = {0: dict.fromkeys(range(20), True), 1: {i: i < 2 for i in range(5)}}  # 20/20, then 2/5
    plan = {"tasks": ["t"], "levels": {"pick_y": [0, 1, 2, 3]}, "episodes": 20,
            "adaptive": plan_entry("kstar", rule)}  # fmt: skip
    run = RunDir.create_or_resume(tmp_path / "r", {"plan": plan, "axes": {"pick_y": {"signed": False}}})
    run.append([rec(k, i, success=ok) for k, eps in outcomes.items() for i, ok in eps.items()])
    ax = summarize(run.episodes(), run.manifest)["axes"]["pick_y"]
    assert [r["decision"] for r in ax["levels"]] == ["intact", "undetermined", "undetermined", "undetermined"]
    want = "k* at or beyond +1 (no level through +1 is decided broken; +2, +3 not run)"
    assert ax["kstar_status"]["pos"]["text"] == want
    assert plan_next(rule, [0, 1, 2, 3], outcomes, "kstar").kstar["pos"]["text"] == want
    nothing = summarize(run.episodes().iloc[:0], run.manifest)["axes"]["pick_y"]["kstar_status"]["pos"]
    assert nothing["text"] == "k* at or beyond 0 (no level run yet; 0, +1, +2, +3 planned)"


def test_a_declared_blind_policy_opens_report_terminal_and_compare_with_cannot_answer(tmp_path, capsys):
    """T0 passed (10/10) by a policy that declares it reads no observation: every output says first that its
    curve is the scene's difficulty for chance, and still prints the rates; a run made before the declaration
    existed (no manifest field) reports as before."""
    blind = make_run(tmp_path / "blind", {0: (10, 10), 1: (9, 10)}, reads_observations=False)
    old = make_run(tmp_path / "old", {0: (10, 10), 1: (9, 10)}, regime="h+mg")
    assert main(["report", str(blind.path)]) == 0
    said = "Cannot answer (h-only / standin:noop): the policy declares it reads no observation"
    terminal = " ".join(capsys.readouterr().out.split())  # rich wraps long lines
    assert said in terminal and terminal.index(said) < terminal.index("success")  # before the table
    md = (blind.path / "report.md").read_text()
    assert md.splitlines()[2] == (
        "**Cannot answer** (h-only / standin:noop): the policy declares it reads no observation, so it can neither "
        "generalize nor fail to: its per-level rates measure each level's difficulty for a policy acting blind "
        "(chance), not generalization; k*, the trend tests and the change from T0 describe the scene, not the "
        "policy. The rates below are kept as that baseline."
    )
    assert "| 0 | 0 | 100% [72, 100] (n=10) intact |" in md
    assert main(["report", str(old.path)]) == 0
    assert json.loads((old.path / "summary.json").read_text())["reads_observations"] is None  # unknown
    assert "declares it reads no observation" not in (old.path / "report.md").read_text()
    out = tmp_path / "cmp"
    assert main(["compare", str(blind.path), str(old.path), "--out", str(out)]) == 0
    cmp = (out / "compare.md").read_text().splitlines()
    assert cmp[2].startswith("**Cannot answer** (h-only / standin:noop (A)): the policy declares it reads no")
    assert "a difference from it says how far the other policy is from chance" in cmp[2]
    assert "declares" not in cmp[4] and json.loads((out / "compare.json").read_text())[
        "reads_observations"
    ] == {"a": False, "b": None}


def test_write_reports_returns_each_runs_summary_and_prints_nothing(tmp_path, capsys):
    """The library call behind ``indgen report``: keyword arguments named like the flags, the (label, summary) of
    every run back (labels told apart by folder), terminal output left to the CLI."""
    from indgen_vla.core.reporting.report import write_reports

    a = make_run(tmp_path / "a", {0: (10, 10), 1: (8, 10)})
    b = make_run(tmp_path / "b", {0: (10, 10), 1: (1, 10)})  # same regime and policy: the same label
    results = write_reports(
        [a.path, b.path], gamma=0.3, ci="clopper-pearson", out=tmp_path / "o", margin=None
    )
    assert [label for label, _ in results] == ["h-only / standin:noop (a)", "h-only / standin:noop (b)"]
    assert results[1][1] == json.loads((b.path / "summary.json").read_text())
    assert results[1][1]["gamma"] == 0.3 and (tmp_path / "o" / "report.md").is_file()
    assert capsys.readouterr().out == ""


def test_infeasible_cells_are_not_errors_a_rerun_could_retry():
    """An episode whose seed rules the level out (placement check) repeats on every re-run: the error warning leaves
    it out (its own caveat names it), and still counts the other errors of that level."""
    from indgen_vla.core.reporting.report import error_warnings

    level = {"level": -2, "n": 6, "errors": 2}
    axis = {"levels": [level], "infeasible": {"cream_cheese": {"-2": 1}}}
    assert error_warnings("x", axis) == ["**Warning** (x): level -2 has 1 error episode(s) of 8 (12 % > 10 %); "
                                         "errors that grow with the level bias the curve: re-run the same "
                                         "evaluate command to retry them."]  # fmt: skip
    axis["infeasible"]["milk"] = {"-2": 1}  # pooled over tasks: both are the seed's
    assert error_warnings("x", axis) == []
