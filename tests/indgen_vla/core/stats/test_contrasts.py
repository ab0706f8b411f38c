"""Paired contrasts (each level against T0, one axis against another) against hand-computed values."""

import dataclasses
import json
import math

import pandas as pd
import pytest
from scipy.stats import binomtest

from indgen_vla.app.cli import main
from indgen_vla.core.errors import RunDirError
from indgen_vla.core.runs.records import RunDir
from indgen_vla.core.stats.contrasts import (
    fmt_vs_t0,
    pair_axes,
    paired_difference_ci,
    paired_equivalence,
    t0_contrasts,
)
from tests.indgen_vla.core.reporting.test_report import make_run
from tests.indgen_vla.core.runs.test_records import rec


def table(cells, axis="pick_y", task="t", seed_offset=0):
    """Episode rows from {level: [(episode, success or None for an error), ...]} (seed 1000 + episode)."""
    rows = [dataclasses.asdict(rec(k, i, success=bool(s), status="error" if s is None else "ok", task=task,
                                   axis=axis)) for k, eps in cells.items() for i, s in eps]  # fmt: skip
    df = pd.DataFrame(rows)
    return df.assign(seed=df["seed"] + seed_offset)


def discordant(both, t0_only, k_only, neither, start=0):
    """(level-0 cells, level-k cells) of episodes start.. with the given 2x2 counts, in that order."""
    kinds = [(1, 1)] * both + [(1, 0)] * t0_only + [(0, 1)] * k_only + [(0, 0)] * neither
    return (
        [(start + i, a) for i, (a, _) in enumerate(kinds)],
        [(start + i, b) for i, (_, b) in enumerate(kinds)],
    )


def test_exact_mcnemar_and_holm_by_hand():
    t0, l1 = discordant(30, 9, 3, 8)  # 50 pairs: T0 alone succeeds 9 times, level 1 alone 3
    l2 = [
        (i, int(i < 27)) for i in range(50)
    ]  # level 2 solves 27 of T0's 39 successes (episodes 0..38), nothing else
    res = t0_contrasts(table({0: t0, 1: l1, 2: l2}), [0, 1, 2], ["t"])
    v1, v2 = res["levels"][1], res["levels"][2]
    assert v1["n_pairs"] == 50 and v1["discordant"] == [9, 3] and v1["successes"] == [39, 33]
    assert v1["delta"] == pytest.approx(-0.12)  # (3 − 9) / 50
    p1 = 2 * (1 + 12 + 66 + 220) / 2**12  # two-sided binomial(12, 1/2) at 3: 2·P(X <= 3) = 598/4096 = 0.146
    assert v1["p"] == pytest.approx(p1) == pytest.approx(binomtest(9, 12).pvalue)
    assert v2["discordant"] == [12, 0]
    p2 = 2 / 2**12  # all 12 discordant pairs one way
    assert v2["p"] == pytest.approx(p2)
    # Holm by hand: p2 < p1, so p2 · 2, then max(p2 · 2, p1 · 1)
    assert v2["p_holm"] == pytest.approx(2 * p2) and v1["p_holm"] == pytest.approx(p1)
    assert v1["unpaired"] == [0, 0] and res["tasks"] == {}  # one task: no per-task split
    assert (
        fmt_vs_t0(v1)
        == "Δ vs T0 −12 pp [−25, +2] (paired n=50, discordant 9/3, exact McNemar p=0.15, Holm p=0.15)"
    )


def test_newcombe_interval_matches_the_published_example():
    # Cavo et al. 2012 (Fagerland, Lydersen & Laake, "Statistical analysis of contingency tables", ch. 8):
    # 59 both, 6 first only, 16 second only, 80 neither; Newcombe square-and-add −0.0621 (95% CI −0.1186 to −0.0046)
    lo, hi = paired_difference_ci(both=59, a_only=16, b_only=6, neither=80)
    assert (lo, hi) == (pytest.approx(-0.1186, abs=5e-5), pytest.approx(-0.0046, abs=5e-5))
    # equivalence is two exact one-sided tests at α (the interval inside the margin erred 11 % at 50 pairs): at
    # α = 0.025 the published interval lies inside ±0.12, yet the exact test needs ±0.13 (its p at 0.12: 3.5 %)
    eq = paired_equivalence(59, 16, 6, 80, margin=0.12, alpha=0.025)
    assert eq["ci"][0] == pytest.approx(-0.1186, abs=5e-5) and eq["equivalent"] is False
    assert paired_equivalence(59, 16, 6, 80, margin=0.13, alpha=0.025)["equivalent"] is True
    assert all(math.isnan(x) for x in paired_difference_ci(0, 0, 0, 0))


def test_no_change_is_never_claimed_from_a_few_concordant_pairs():
    lo, hi = paired_difference_ci(both=5, a_only=0, b_only=0, neither=0)
    # five successes on both sides: ±(1 − Wilson's lower bound of 5/5) = ±(1 − 5 / (5 + z²)) = ±0.4345, not [0, 0]
    assert (lo, hi) == (pytest.approx(-0.434482, abs=1e-6), pytest.approx(0.434482, abs=1e-6))
    assert paired_equivalence(5, 0, 0, 0, margin=0.10)["equivalent"] is False
    assert paired_equivalence(380, 2, 3, 15, margin=0.05)["equivalent"] is True  # 400 pairs, 5 discordant


def test_pairs_stay_within_their_task():
    # task a: T0 succeeds, level 1 fails; task b: the reverse. Pairs within task: 5 and 5 discordant, Δ = 0
    a = table({0: [(i, 1) for i in range(5)], 1: [(i, 0) for i in range(5)]}, task="a")
    b = table({0: [(i, 0) for i in range(5)], 1: [(i, 1) for i in range(5)]}, task="b")
    res = t0_contrasts(pd.concat([a, b]), [0, 1], ["a", "b"])
    v = res["levels"][1]
    assert (
        v["n_pairs"] == 10 and v["discordant"] == [5, 5] and v["p"] == pytest.approx(1.0) and v["delta"] == 0
    )
    assert res["tasks"]["a"][1]["discordant"] == [5, 0]
    assert res["tasks"]["a"][1]["p"] == pytest.approx(2 / 32)  # binomial(5, 1/2): 2 · 1/32
    assert res["tasks"]["b"][1]["discordant"] == [0, 5]


def test_incomplete_pairing_is_counted_and_unpaired_seeds_refused():
    t0 = [(i, 1) for i in range(10)]
    l1 = [(i, i % 2) for i in range(7)] + [(7, None), (12, 1)]  # episode 7 errored, 12 has no T0 partner
    v = t0_contrasts(table({0: t0, 1: l1}), [0, 1], ["t"])["levels"][1]
    assert v["n_pairs"] == 7 and v["unpaired"] == [3, 1] and v["discordant"] == [4, 0]
    assert "unpaired: 3 at T0, 1 here" in fmt_vs_t0(v)
    assert t0_contrasts(table({1: l1}), [0, 1], ["t"]) is None  # no level 0 in the run
    assert t0_contrasts(table({0: t0}), [0], ["t"]) is None  # level 0 only
    shifted = pd.concat([table({0: t0}), table({1: l1}, seed_offset=7)])
    assert "another seed at level 1" in t0_contrasts(shifted, [0, 1], ["t"])["unpaired_reason"]


def test_pair_axes_matches_levels_and_refuses_unpaired_axes():
    comp = table({0: [(i, 1) for i in range(6)], 1: [(i, 0) for i in range(6)], 3: [(0, 1)]}, axis="c")
    single = table({0: [(i, 1) for i in range(6)], 1: [(i, i < 4) for i in range(5)], 2: [(0, 1)]}, axis="p")
    p = pair_axes(comp, single, "c", "p")
    assert sorted(p.pairs) == [0, 1] and p.only_a == (3,) and p.only_b == (2,)
    assert sum(a and not b for a, b in p.pairs[1]) == 0 and sum(b and not a for a, b in p.pairs[1]) == 4
    assert p.unpaired == {0: (0, 0), 1: (1, 0)}
    assert p.describe().startswith(
        "11 episode pairs (task t; matched on scene, task, level, episode and seed)"
    )
    assert "pairing incomplete: 1 finished episode(s) of A" in p.describe()
    with pytest.raises(RunDirError, match="share no level"):
        pair_axes(comp[comp["level"] == 3], single, "c", "p")
    with pytest.raises(RunDirError, match="seeds differ"):
        pair_axes(comp, table({0: [(0, 1)]}, axis="p", seed_offset=3), "c", "p")


def _run(path, cells_by_axis, tasks=("t",), seed_offset=0, steps=None):
    """A run dir written by RunDir from {axis: {level: [(episode, success)]}}, every task alike."""
    manifest = {"plan": {"tasks": list(tasks), "episodes": 50}, "policy": "standin:noop",
                "axes": {a: {"signed": False} for a in cells_by_axis}}  # fmt: skip
    if steps:
        manifest["resolved"] = {"environment": {"successors": {a: {"steps": s} for a, s in steps.items()}}}
    run = RunDir.create_or_resume(path, manifest)
    recs = [dataclasses.replace(rec(k, i, success=bool(s), task=t, axis=a), seed=1000 + i + seed_offset)
            for a, cells in cells_by_axis.items() for t in tasks for k, eps in cells.items() for i, s in eps]  # fmt: skip
    run.append(recs)
    return run


def test_report_states_the_change_from_t0(tmp_path, capsys):
    t0, l1 = discordant(30, 9, 3, 8)
    run = _run(tmp_path / "r", {"distractor": {0: t0, 1: l1}}, tasks=("a", "b"))
    assert main(["report", str(run.path), "--margin", "0.1"]) == 0
    out = capsys.readouterr().out
    lv = {
        r["level"]: r
        for r in json.loads((run.path / "summary.json").read_text())["axes"]["distractor"]["levels"]
    }
    v = lv[1]["vs_t0"]
    assert "vs_t0" not in lv[0] and v["n_pairs"] == 100 and v["discordant"] == [18, 6]  # both tasks alike
    assert v["p"] == pytest.approx(binomtest(18, 24).pvalue) and v["p_holm"] == v["p"]
    assert v["equivalence"]["margin"] == 0.1 and v["equivalence"]["equivalent"] is False
    assert "Δ vs T0 −12 pp" in out and "paired n=100, discordant 18/6" in out
    md = (run.path / "report.md").read_text()
    assert "**Change from T0**" in md and "| 1 | −12 [" in md and "Δ vs T0 per task" in md
    assert "L1 differs from T0" in md  # p = 0.023 < 0.05, one level
    assert "no level shown within ±10 pp of T0" in md
    assert main(["report", str(run.path), "--margin", "1.5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--margin must be in (0, 1)" in err


def test_report_stays_compact_without_level_0(tmp_path):
    run = _run(tmp_path / "r", {"pick_y": {1: [(i, 1) for i in range(6)], 2: [(i, 0) for i in range(6)]}})
    assert main(["report", str(run.path)]) == 0
    axis = json.loads((run.path / "summary.json").read_text())["axes"]["pick_y"]
    assert "vs_t0" not in axis and not any("vs_t0" in r for r in axis["levels"])
    assert "Change from T0" not in (run.path / "report.md").read_text()


def test_compare_two_axes_of_one_run(tmp_path, capsys):
    t0 = [(i, 1) for i in range(12)]
    comp = {0: t0, 1: [(i, i < 2) for i in range(12)]}  # 2/12
    single = {0: t0, 1: [(i, i < 10) for i in range(12)]}  # 10/12: 8 pairs only the component solves
    run = _run(tmp_path / "r", {"pick_y+distractor": comp, "pick_y": single})
    assert main(["compare", str(run.path), "--axes", "pick_y+distractor:pick_y"]) == 0
    out_dir = run.path / "compare_pick_y_distractor_vs_pick_y"
    res = json.loads((out_dir / "compare.json").read_text())
    assert res["paired"] is True and res["test"] == "mcnemar_exact"
    assert res["contrast"]["axis_a"] == "pick_y+distractor" and res["contrast"]["within_run"] is True
    rows = {r["level"]: r for r in res["axes"]["pick_y+distractor vs pick_y"]["levels"]}
    assert (rows[1]["pairs"], rows[1]["a_only"], rows[1]["b_only"]) == (12, 0, 8)
    assert rows[1]["p_value"] == pytest.approx(2 / 2**8)  # binomial(8, 1/2), all one way
    assert rows[1]["p_holm"] == rows[1]["p_value"]  # level 0 (T0 on both) is outside the Holm family
    assert math.isnan(rows[0]["p_holm"]) and rows[0]["p_value"] == 1.0
    assert rows[1]["delta"] == pytest.approx(8 / 12)
    md = (out_dir / "compare.md").read_text()
    assert "## Axes `pick_y+distractor` (A) vs `pick_y` (B), paired" in md
    assert "paired: axis `pick_y+distractor` (A) against axis `pick_y` (B)" in md
    assert "1 level(s) differ" in res["verdict"] and (out_dir / "plots").is_dir()
    capsys.readouterr()


def test_compare_two_rows_of_a_grid_tests_level_0_too(tmp_path, capsys):
    """Rows j = 2 and j = 0 of pick_y x distractor start from different scenes: level 0 is a tested level (Holm over
    both), and the held level is no step to match."""
    from indgen_vla.core.comparison.two_axes import same_start

    assert same_start("pick_y@distractor=0", "pick_y") and same_start(
        "pick_y@distractor=2", "goal_y@distractor=2"
    )
    assert not same_start("pick_y@distractor=2", "pick_y@distractor=0")
    row2 = {0: [(i, i < 4) for i in range(12)], 1: [(i, i < 2) for i in range(12)]}  # 4/12, 2/12
    row0 = {0: [(i, 1) for i in range(12)], 1: [(i, i < 10) for i in range(12)]}  # 12/12, 10/12
    steps = {"pick_y@distractor=2": {"pick_y": 0.025, "distractor": 1.0, "held_level": 2.0},
             "pick_y@distractor=0": {"pick_y": 0.025, "distractor": 1.0, "held_level": 0.0}}  # fmt: skip
    run = _run(tmp_path / "r", {"pick_y@distractor=2": row2, "pick_y@distractor=0": row0}, steps=steps)
    assert main(["compare", str(run.path), "--axes", "pick_y@distractor=2:pick_y@distractor=0"]) == 0
    (out_dir,) = run.path.glob("compare_*")
    res = json.loads((out_dir / "compare.json").read_text())
    assert res["contrast"]["same_t0"] is False
    rows = {r["level"]: r for r in res["axes"]["pick_y@distractor=2 vs pick_y@distractor=0"]["levels"]}
    p0, p1 = 2 / 2**8, 2 / 2**8  # binomial(8, 1/2), all one way, at both levels
    assert (rows[0]["b_only"], rows[1]["b_only"]) == (8, 8) and rows[0]["p_value"] == pytest.approx(p0)
    assert rows[0]["p_holm"] == pytest.approx(min(1.0, 2 * min(p0, p1)))  # Holm over levels 0 and 1
    assert "level 0 differs (another held level" in (out_dir / "compare.md").read_text()
    capsys.readouterr()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--axes", "pick_y"], "--axes takes A_AXIS:B_AXIS"),
        (["--axes", "scale:pick_y"], "axis 'scale' has no episodes in"),
        (["--axes", "pick_y:pick_y"], "names pick_y twice within one run"),
        (["--axes", "pick_y+distractor:pick_y", "--test", "boschloo"], "drop --test boschloo"),
        (["--axes", "pick_y+distractor:pick_y", "--a", "x"], "not groups"),
    ],
)
def test_compare_axes_refuses_bad_input_in_one_line(tmp_path, capsys, argv, message):
    run = _run(tmp_path / "r", {"pick_y+distractor": {0: [(0, 1)]}, "pick_y": {0: [(0, 1)]}})
    assert main(["compare", str(run.path), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


def test_compare_axes_across_runs_refuses_unpaired_plans(tmp_path, capsys):
    cells = {0: [(i, 1) for i in range(5)], 1: [(i, 0) for i in range(5)]}
    steps = {"pick_y+distractor": {"pick_y": 0.025, "distractor": 1.0}}
    a = _run(tmp_path / "a", {"pick_y+distractor": cells}, steps=steps)
    b = _run(tmp_path / "b", {"pick_y": cells}, steps={"pick_y": {"pick_y": 0.025}})
    assert main(["compare", str(a.path), str(b.path), "--axes", "pick_y+distractor:pick_y"]) == 0
    res = json.loads((a.path / "compare_pick_y_distractor_vs_pick_y" / "compare.json").read_text())
    assert res["contrast"]["within_run"] is False and res["label_a"].endswith(": pick_y+distractor")
    capsys.readouterr()
    other_seed = _run(tmp_path / "c", {"pick_y": cells}, seed_offset=9)
    assert main(["compare", str(a.path), str(other_seed.path), "--axes", "pick_y+distractor:pick_y"]) == 2
    assert "seeds differ" in capsys.readouterr().err
    other_step = _run(tmp_path / "d", {"pick_y": cells}, steps={"pick_y": {"pick_y": 0.05}})
    assert main(["compare", str(a.path), str(other_step.path), "--axes", "pick_y+distractor:pick_y"]) == 2
    assert "moves 0.025 per level on pick_y+distractor but 0.05 on pick_y" in capsys.readouterr().err
    assert main(["compare", str(a.path), str(b.path)]) == 2  # no shared axis: the refusal names --axes
    assert "contrast two axes with --axes A_AXIS:B_AXIS" in capsys.readouterr().err
    far = _run(tmp_path / "e", {"pick_y": {2: [(0, 1)]}})
    assert main(["compare", str(a.path), str(far.path), "--axes", "pick_y+distractor:pick_y"]) == 2
    assert "share no level" in capsys.readouterr().err


def test_adaptive_ladders_pair_only_what_ran(tmp_path):
    """An adaptive run (the real sequential rule decides which episodes run): the pooled rows pool different tasks
    at different levels, and Δ vs T0 uses only the (task, episode) pairs both levels ran."""
    from indgen_vla.core.reporting.summary import summarize
    from indgen_vla.core.runs.records import EpisodeRecord
    from indgen_vla.core.stats.sprt import SequentialRule, plan_next

    rule = SequentialRule(max_episodes=20, round_size=5)
    rates = {"easy": {0: 1.0, 1: 0.9, 2: 0.6, 3: 0.0}, "hard": {0: 1.0, 1: 0.0, 2: 0.0, 3: 0.0}}
    recs = []
    for task, curve in rates.items():
        outcomes: dict[int, dict[int, bool]] = {}
        while (p := plan_next(rule, [0, 1, 2, 3], outcomes, "kstar")).to_run:
            for k, eps in p.to_run.items():
                for i in eps:
                    ok = (i * 7919 % 10) < 10 * curve[k]  # a fixed pattern with the level's rate
                    outcomes.setdefault(k, {})[i] = ok
                    recs.append(EpisodeRecord(run_id="r", policy="p", data_regime="", scene="s", task=task,
                                              axis="pick_y", level=k, param=0.025 * k, episode=i, seed=1000 + i,
                                              success=ok, steps=1, status="ok", error=""))  # fmt: skip
    plan = {"tasks": list(rates), "levels": {"pick_y": [0, 1, 2, 3]}, "episodes": 20,
            "adaptive": {"mode": "kstar", **{f: getattr(rule, f) for f in ("gamma", "delta", "alpha", "beta",
                                                                          "round_size", "thresholds")}}}  # fmt: skip
    run = RunDir.create_or_resume(
        tmp_path / "r", {"plan": plan, "policy": "p", "axes": {"pick_y": {"signed": False}}}
    )
    run.append(recs)
    df = run.episodes()
    ax = summarize(df, run.manifest)["axes"]["pick_y"]
    rows = {r["level"]: r for r in ax["levels"]}
    assert (
        rows[0]["pooled_from"] == 2 and rows[2]["pooled_from"] == 1
    )  # "hard" broke at 1: level 2 pools "easy" only
    ran = {(t, k): set(g["episode"]) for (t, k), g in df.groupby(["task", "level"])}
    for k in (1, 2, 3):
        v = rows[k]["vs_t0"]
        expect = sum(len(ran.get((t, k), set()) & ran[(t, 0)]) for t in rates)
        assert v["n_pairs"] == expect
        assert v["unpaired"] == [sum(len(ran[(t, 0)]) for t in rates) - expect, rows[k]["n"] - expect]
    assert ax["tasks"]["hard"]["levels"][2]["vs_t0"]["n_pairs"] == 0  # never ran: no pairs, no test
    # the pooled rate says which tasks it pools where that is a subset, and the report says why that matters
    from indgen_vla.core.reporting.report import _fmt_rate, pool_warnings

    assert "pooled_only" not in rows[0] and rows[2]["pooled_only"] == ["easy"]
    if not rows[2]["insufficient"]:
        assert "; task easy only)" in _fmt_rate(rows[2])
    (note,) = pool_warnings("p", ax)
    assert "level(s) 2 (1 of 2)" in note and "not comparable across levels" in note


def test_verdict_tells_levels_below_the_floor_from_no_pairs():
    from indgen_vla.core.stats.contrasts import t0_verdict

    below = {"p": math.nan, "n_pairs": 3}
    assert t0_verdict([{"level": 1, "vs_t0": below}], None).startswith("not tested yet: T0 or every other")
    assert t0_verdict([{"level": 1, "vs_t0": below | {"n_pairs": 0}}], None) == (
        "no level has episodes paired with T0 yet"
    )
    one = {"p": 1.0, "p_holm": 1.0, "n_pairs": 5}  # one tested level: "1 level", not "1 levels"
    assert "(exact McNemar, Holm over 1 level, α = 0.05)" in t0_verdict([{"level": 1, "vs_t0": one}], None)
    assert "Holm over 2 levels" in t0_verdict([{"level": k, "vs_t0": one} for k in (1, 2)], None)


def test_an_equivalence_cell_says_when_its_interval_and_the_exact_tests_disagree(tmp_path, capsys):
    """12/25 at T0 and the same 12/25 at L1 (no discordant pair), ±10 pp: the 90 % Newcombe interval (about ±6 pp)
    lies inside the margin, but the exact TOST cannot show equivalence with 25 pairs (0.9^25 > α), so "not shown"
    beside that interval must say the exact tests decide, not the interval."""
    run = make_run(tmp_path / "r", {0: (12, 25), 1: (12, 25)})
    assert main(["report", str(run.path), "--margin", "0.1"]) == 0
    out = " ".join(capsys.readouterr().out.split())  # the terminal wraps at its width (80 under pytest-xdist)
    (line,) = [x for x in out.split("L1: Δ vs T0")[1:2]]
    assert "within ±10 pp (90% CI): not shown (the exact tests decide, not the CI) [−6, +6]" in line
    assert "not shown (the exact tests decide, not the CI)" in (run.path / "report.md").read_text()
