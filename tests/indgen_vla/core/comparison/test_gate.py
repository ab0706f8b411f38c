"""``indgen gate``: exit codes, the non-inferiority bound, Holm over the levels, the projection of episodes needed."""

import json
import math

import pytest
from scipy.stats import binom, binomtest

from indgen_vla.app.cli import main
from indgen_vla.core.comparison.gate import GateConfig, gate
from indgen_vla.core.runs.records import RunDir
from indgen_vla.core.stats import noninferiority as ni
from tests.indgen_vla.core.reporting.test_report import make_run
from tests.indgen_vla.core.runs.test_records import rec

Z90 = 1.6448536269514722  # the 95 % one-sided normal quantile: the (1 − 2α) interval at α = 0.05


def test_identical_perfect_runs_pass_exactly_where_the_exact_test_clears_the_margin(tmp_path, capsys):
    """n/n against n/n (no discordant pair): at the boundary point where only the baseline succeeds in a pair, with
    chance M, such a table has chance (1 − M)^n, so margin 0.1 needs 0.9^n ≤ 0.05: n ≥ 29 (Newcombe's interval, used
    before, passed at 25, where the true error there is 0.9^25 = 7.2 %). 20 episodes are undecided with 9 more
    projected, and 29 pass."""
    a, b = (make_run(tmp_path / s, {0: (20, 20), 1: (20, 20)}, regime=s) for s in ("a", "b"))
    res = gate(GateConfig(str(a.path), str(b.path), margin=0.1))
    assert res["exit_code"] == 5 and res["verdict"] == "underpowered" and res["paired"]
    for r in res["levels"]:
        assert r["delta_ci"][0] == pytest.approx(-(Z90**2) / (20 + Z90**2))
        assert r["p_non_inferior"] == pytest.approx(0.9**20, rel=1e-6)
        assert r["verdict"] == "undecided" and r["more_episodes"] == 9 and r["projected"] == "non-inferior"
    assert res["more_episodes"] == 9 and "FAIL (exit 5)" in res["lines"][-1]
    a, b = (make_run(tmp_path / f"{s}28", {0: (28, 28), 1: (28, 28)}, regime=s) for s in ("a", "b"))
    assert gate(GateConfig(str(a.path), str(b.path), margin=0.1))["exit_code"] == 5
    a, b = (make_run(tmp_path / f"{s}29", {0: (29, 29), 1: (29, 29)}, regime=s) for s in ("a", "b"))
    assert main(["gate", str(a.path), str(b.path), "--margin", "0.1"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("protocol: a / standin:noop: no protocol fingerprint")  # make_run writes none
    out = [x for x in out if not x.startswith("protocol:")]
    assert out[0].startswith("pick_y L0: non-inferior within 10 pp — baseline 29/29 = 100% [88, 100]")
    assert "(task t)" in out[0] and "paired n=29, discordant 0/0" in out[0]
    assert "smallest drop this run could call a regression: " in out[0]
    assert out[-1].startswith("PASS (exit 0)") and "paired exact McNemar, Holm over 2 level(s)" in out[-1]


def test_worse_is_the_holm_corrected_exact_mcnemar(tmp_path, capsys):
    a = make_run(tmp_path / "a", {0: (20, 20), 1: (20, 20)}, regime="a")
    b = make_run(tmp_path / "b", {0: (20, 20), 1: (12, 20)}, regime="b")
    assert main(["gate", str(a.path), str(b.path), "--json"]) == 1
    res = json.loads(capsys.readouterr().out)  # strict JSON: no NaN
    row = {r["level"]: r for r in res["levels"]}
    p = binomtest(0, 8, 0.5).pvalue  # 8 discordant pairs, all favouring the baseline
    assert row[1]["p"] == pytest.approx(p) and row[1]["p_holm"] == pytest.approx(min(1, 2 * p))
    assert row[1]["verdict"] == "worse" and row[1]["discordant"] == [8, 0]
    assert row[0]["verdict"] == "undecided" and res["verdict"] == "worse"


def test_a_real_drop_inside_the_margin_passes(tmp_path):
    """400/400 against 380/400: the drop is significant (20 discordant pairs, one way), but the 90 % interval of Δ
    lies above −10 pp, and the margin is what the gate was told to tolerate."""
    a = make_run(tmp_path / "a", {0: (400, 400)}, regime="a")
    b = make_run(tmp_path / "b", {0: (380, 400)}, regime="b")
    res = gate(GateConfig(str(a.path), str(b.path), margin=0.1))
    (r,) = res["levels"]
    assert r["p_holm"] < 1e-5 and r["delta_ci"][0] > -0.1 and res["exit_code"] == 0
    assert gate(GateConfig(str(a.path), str(b.path), margin=0.03))["exit_code"] == 1


def test_unpaired_runs_use_boschloo_and_project_both_sides(tmp_path, capsys):
    """Runs with other episode counts are not paired: Boschloo, the MOVER interval, and an unpaired projection."""
    a = make_run(tmp_path / "a", {0: (30, 30)}, regime="a")
    b = make_run(tmp_path / "b", {0: (19, 20)}, regime="b")
    assert main(["gate", str(a.path), str(b.path), "--margin", "0.15"]) == 5
    out = capsys.readouterr().out
    assert "unpaired Boschloo (the runs do not hold the same episodes on pick_y (30 vs 20:" in out
    assert "pick_y L0: undecided (neither shown; about " in out and "would show it non-inferior" in out
    res = gate(GateConfig(str(a.path), str(b.path), margin=0.15))
    extra = res["levels"][0]["more_episodes"]
    assert "with 80% chance if the observed rates are the true ones" in out

    # the projection's claim, summed here over the candidate's extra successes with the gate's own test: with that
    # many more episodes drawn at the observed rates (30/30 stays perfect) the level passes with chance >= 80 %
    def chance(more: int) -> float:
        return sum(binom.pmf(k, more, 0.95) for k in range(more + 1)
                   if ni.unpaired_non_inferior(30 + more, 30 + more, 19 + k, 20 + more, 0.15, 0.05))  # fmt: skip

    assert chance(extra) >= 0.8 > chance(extra - 1)


def test_bad_input_exits_2_in_one_line(tmp_path, capsys):
    a = make_run(tmp_path / "a", {0: (9, 10), 1: (9, 10)}, regime="a")
    b = make_run(tmp_path / "b", {0: (9, 10)}, regime="b")
    assert main(["gate", str(a.path), str(b.path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "planned levels [0, 1]" in err and "same evaluate command" in err
    assert main(["gate", str(a.path), str(tmp_path / "nope")]) == 2
    assert main(["gate", str(a.path), str(a.path), "--margin", "1.5"]) == 2
    assert "--margin must be in (0, 1)" in capsys.readouterr().err
    c = RunDir.create_or_resume(tmp_path / "c", {"plan": {"x": 1}, "axes": {"scale": {"signed": False}}})
    c.append([rec(0, i, axis="scale") for i in range(10)])
    assert main(["gate", str(a.path), str(c.path)]) == 2
    assert "runs axes ['pick_y'] but" in capsys.readouterr().err


def test_below_the_floor_is_undecided_not_tested(tmp_path):
    a, b = (make_run(tmp_path / s, {0: (2, 2), 1: (2, 2)}, regime=s) for s in ("a", "b"))
    res = gate(GateConfig(str(a.path), str(b.path), margin=0.3))
    assert res["exit_code"] == 5 and res["holm_over"] == 0
    assert all(not r["tested"] and math.isnan(r["p_holm"]) for r in res["levels"])
    # 10 episodes: the first n where the exact test clears a margin of 0.3 with no discordant pair (0.7^10 = 2.8 %)
    assert res["more_episodes"] == 8
    assert "below the data floor in a run" in res["lines"][2]


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory):
    """Real runs of one protocol (pick_place, pick_y level 0, 150 steps): the oracle twice at 2 and at 10 episodes,
    standin:random at 10."""
    root = tmp_path_factory.mktemp("gate_runs")
    flags = [
        "--scene",
        "pick_place",
        "--axis",
        "pick_y",
        "--levels",
        "0",
        "--max-steps",
        "150",
        "--workers",
        "1",
    ]
    runs = {}
    for name, policy, n in (("o2a", "oracle", 2), ("o2b", "oracle", 2), ("o10a", "oracle", 10),
                            ("o10b", "oracle", 10), ("r10", "random", 10)):  # fmt: skip
        runs[name] = root / name
        assert main(["evaluate", "--policy", f"standin:{policy}", *flags, "--episodes", str(n),
                     "--out", str(runs[name])]) == 0  # fmt: skip
    return runs


@pytest.mark.slow
def test_gate_on_evaluated_runs(evaluated, capsys):
    """1 for the oracle as baseline against standin:random, 5 for two oracle runs of 2 episodes a level (the projection
    says 8 more), 0 for two oracle runs of 10 = 2 + 8 episodes at margin 0.3 (docs/loop.md)."""
    r = evaluated
    # oracle and random are both 'standin' policies of other chunk sizes: the fingerprint check lists it
    assert main(["gate", str(r["o10a"]), str(r["r10"]), "--allow-protocol-mismatch"]) == 1
    out = capsys.readouterr().out
    assert "pick_y L0: worse — baseline 10/10 = 100% [72, 100] vs candidate 0/10 = 0% [0, 28]" in out
    assert "**Cannot answer** (standin:random (candidate))" in out and "WORSE (exit 1)" in out
    assert main(["gate", str(r["o2a"]), str(r["o2b"]), "--margin", "0.3"]) == 5
    out = capsys.readouterr().out
    assert "about 8 more episodes per level in each run would decide every one" in out
    assert main(["gate", str(r["o10a"]), str(r["o10b"]), "--margin", "0.3"]) == 0
    assert "PASS (exit 0)" in capsys.readouterr().out


def test_plan_sizes_the_smoke_from_the_baseline(tmp_path, capsys):
    """A pilot at 90, 95, 90 % on three levels: 168 episodes a level pass equal policies with chance >= 80 % (the
    docs/loop.md recipe's number); the drop of 2M is named with its chance; a CANDIDATE with --plan is refused."""
    a = make_run(tmp_path / "a", {-1: (18, 20), 0: (19, 20), 1: (18, 20)}, regime="a")
    assert main(["gate", "--plan", str(a.path), "--margin", "0.1"]) == 0
    out = capsys.readouterr().out
    assert "--episodes 168" in out and "two equal policies pass with chance 80.8%" in out
    assert "a drop of 20 pp at one level" in out
    assert main(["gate", "--plan", str(a.path), str(a.path)]) == 2
    assert "--plan takes one run directory" in capsys.readouterr().err
    assert main(["gate", str(a.path)]) == 2
    assert "needs BASELINE and CANDIDATE" in capsys.readouterr().err


def test_plan_tries_the_drop_only_where_a_level_can_fall_by_2m(tmp_path, capsys):
    """A level at 0 % cannot drop 20 points: the drop is tried at a level that can (its chance of passing is then
    small, not the equal policies' 80 %); a baseline with no level at 20 % or more says no drop can be tried."""
    from indgen_vla.core.comparison.gate_plan import plan_episodes

    plan = plan_episodes([2 / 3, 1.0, 0.0], 0.1)
    assert plan["drop_level_index"] in (0, 1) and plan["pass_drop_2m"] < 0.05 < plan["pass_equal"]
    a = make_run(tmp_path / "a", {-1: (4, 6), 0: (6, 6), 1: (0, 6)}, regime="a")
    assert main(["gate", "--plan", str(a.path), "--margin", "0.1"]) == 0
    out = capsys.readouterr().out
    assert "pick_y L+1, the likeliest" not in out and "a drop of 20 pp at one level (pick_y L" in out
    assert plan_episodes([0.1, 0.15], 0.1)["pass_drop_2m"] is None
    b = make_run(tmp_path / "b", {0: (2, 20), 1: (3, 20)}, regime="b")
    assert main(["gate", "--plan", str(b.path), "--margin", "0.1", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["drop_level_index"] is None
    assert main(["gate", "--plan", str(b.path), "--margin", "0.1"]) == 0
    assert "no level's rate is 20% or more, so no drop of 20 pp can be tried" in capsys.readouterr().out


def test_a_level_line_says_when_its_interval_and_the_exact_test_disagree(tmp_path, capsys):
    """12/25 against the same 12/25 (no discordant pair), M = 0.1: Newcombe's 90 % interval is about [−6, +6] pp,
    inside the margin, but the exact test's p is 0.072 > α (the interval alone errs above α at the margin), so the
    level is undecided; the line must not print a CI above −M beside "neither shown" without saying why."""
    a, b = (make_run(tmp_path / s, {0: (12, 25)}, regime=s) for s in ("a", "b"))
    res = gate(GateConfig(str(a.path), str(b.path), margin=0.1))
    (r,) = res["levels"]
    assert r["delta_ci"][0] > -0.1 and r["p_non_inferior"] > 0.05 and r["verdict"] == "undecided"
    (line,) = [x for x in res["lines"] if x.startswith("pick_y L0")]
    assert (
        f"lower end ({100 * r['delta_ci'][0]:+.1f} pp) is above −10 pp" in line
        and "exact test decides" in line
    )
    c, d = (make_run(tmp_path / f"{s}29", {0: (29, 29)}, regime=s) for s in ("a", "b"))  # agree: no note
    assert "exact test decides" not in "\n".join(
        gate(GateConfig(str(c.path), str(d.path), margin=0.1))["lines"]
    )


def test_past_the_exact_range_the_gate_names_the_asymptotic_test(tmp_path):
    """Past ni.N_EXACT pairs the non-inferiority test is Tango's asymptotic score test (size 5.15 % at 1,500 pairs,
    docs/statistics.md): the verdict line must not call it exact there, and does below."""
    n = ni.N_EXACT + 1
    a, b = (make_run(tmp_path / s, {0: (n - 10, n)}, regime=s) for s in ("a", "b"))
    res = gate(GateConfig(str(a.path), str(b.path), margin=0.05))
    assert res["levels"][0]["pairs"] == n and res["exit_code"] == 0
    assert f"past {ni.N_EXACT} pairs its asymptotic score test" in res["lines"][-1]
    c, d = (make_run(tmp_path / f"{s}29", {0: (29, 29)}, regime=s) for s in ("a", "b"))
    assert "asymptotic" not in gate(GateConfig(str(c.path), str(d.path), margin=0.1))["lines"][-1]
