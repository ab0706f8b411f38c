"""``indgen gate``: exit codes, the non-inferiority bound, Holm over the levels, the projection of episodes needed."""

import json
import math

import pytest
from scipy.stats import binomtest

from indgen_vla.app.cli import main
from indgen_vla.core.comparison.gate import GateConfig, gate
from indgen_vla.core.runs.records import RunDir
from tests.indgen_vla.core.reporting.test_report import make_run
from tests.indgen_vla.core.runs.test_records import rec

Z90 = 1.6448536269514722  # the 95 % one-sided normal quantile: the (1 − 2α) interval at α = 0.05


def test_identical_perfect_runs_pass_exactly_where_the_bound_clears_the_margin(tmp_path, capsys):
    """n/n against n/n (no discordant pair): Newcombe's lower end is −z²/(n + z²) (the Wilson bound of n/n is
    n/(n + z²), the correlation term vanishes), so margin 0.1 needs n > 9 z² = 24.35: 20 episodes are undecided with
    5 more projected, and 25 pass."""
    a, b = (make_run(tmp_path / s, {0: (20, 20), 1: (20, 20)}, regime=s) for s in ("a", "b"))
    res = gate(GateConfig(str(a.path), str(b.path), margin=0.1))
    assert res["exit_code"] == 5 and res["verdict"] == "underpowered" and res["paired"]
    for r in res["levels"]:
        assert r["delta_ci"][0] == pytest.approx(-(Z90**2) / (20 + Z90**2))
        assert r["verdict"] == "undecided" and r["more_episodes"] == 5 and r["projected"] == "non-inferior"
    assert res["more_episodes"] == 5
    a, b = (make_run(tmp_path / f"{s}25", {0: (25, 25), 1: (25, 25)}, regime=s) for s in ("a", "b"))
    assert main(["gate", str(a.path), str(b.path), "--margin", "0.1"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("protocol: a / standin:noop: no protocol fingerprint")  # make_run writes none
    out = [x for x in out if not x.startswith("protocol:")]
    assert out[0].startswith("pick_y L0: non-inferior within 10 pp — baseline 25/25 = 100% [87, 100]")
    assert "(task t)" in out[0] and "paired n=25, discordant 0/0" in out[0]
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
    assert "unpaired Boschloo (the runs did not plan the same episodes" in out
    assert "pick_y L0: undecided (neither shown; about " in out and "would show it non-inferior" in out
    res = gate(GateConfig(str(a.path), str(b.path), margin=0.15))
    extra = res["levels"][0]["more_episodes"]
    # the projection keeps the rates: with that many more episodes in each run the gate passes, one fewer it does not
    for more, code in ((extra, 0), (extra - 1, 5)):
        bb = make_run(tmp_path / f"b{more}", {0: (round(0.95 * (20 + more)), 20 + more)}, regime="b")
        aa = make_run(tmp_path / f"a{more}", {0: (30 + more, 30 + more)}, regime="a")
        assert gate(GateConfig(str(aa.path), str(bb.path), margin=0.15))["exit_code"] == code


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
    # 7 episodes: −z²/(7 + z²) = −0.279 > −0.3, the first n above the floor (5) where the bound clears it
    assert res["more_episodes"] == 5
    assert "below the data floor in a run" in res["lines"][2]


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory):
    """Real runs of one protocol (pick_place, pick_y level 0, 150 steps): the oracle twice at 2 and at 7 episodes,
    standin:random at 7."""
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
    for name, policy, n in (("o2a", "oracle", 2), ("o2b", "oracle", 2), ("o7a", "oracle", 7), ("o7b", "oracle", 7),
                            ("r7", "random", 7)):  # fmt: skip
        runs[name] = root / name
        assert main(["evaluate", "--policy", f"standin:{policy}", *flags, "--episodes", str(n),
                     "--out", str(runs[name])]) == 0  # fmt: skip
    return runs


@pytest.mark.slow
def test_gate_on_evaluated_runs(evaluated, capsys):
    """1 for the oracle as baseline against standin:random, 5 for two oracle runs of 2 episodes a level (the projection
    says 5 more), 0 for two oracle runs of 7 = 2 + 5 episodes at margin 0.3 (docs/loop.md)."""
    r = evaluated
    # oracle and random are both 'standin' policies of other chunk sizes: the fingerprint check lists it
    assert main(["gate", str(r["o7a"]), str(r["r7"]), "--allow-protocol-mismatch"]) == 1
    out = capsys.readouterr().out
    assert "pick_y L0: worse — baseline 7/7 = 100% [65, 100] vs candidate 0/7 = 0% [0, 35]" in out
    assert "**Cannot answer** (standin:random (candidate))" in out and "WORSE (exit 1)" in out
    assert main(["gate", str(r["o2a"]), str(r["o2b"]), "--margin", "0.3"]) == 5
    out = capsys.readouterr().out
    assert "about 5 more episodes per level in each run would decide every one" in out
    assert main(["gate", str(r["o7a"]), str(r["o7b"]), "--margin", "0.3"]) == 0
    assert "PASS (exit 0)" in capsys.readouterr().out
