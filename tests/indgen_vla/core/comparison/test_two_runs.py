import json
import math

import pytest
from scipy.stats import binomtest, boschloo_exact

from indgen_vla.app.cli import main
from indgen_vla.core.runs.records import RunDir
from tests.indgen_vla.core.reporting.test_report import make_run
from tests.indgen_vla.core.runs.test_records import rec


def test_compare_against_scipy_and_hand_holm(tmp_path, capsys):
    a = make_run(tmp_path / "a", {0: (19, 20), 1: (15, 20), 2: (12, 20)}, regime="h-only")
    b = make_run(tmp_path / "b", {0: (20, 20), 1: (4, 20), 2: (11, 20)}, regime="h+mg")
    assert (
        main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "c"), "--test", "boschloo"]) == 0
    )
    res = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert res["test"] == "boschloo" and res["paired"] is False
    rows = {r["level"]: r for r in res["axes"]["pick_y"]["levels"]}
    p = {k: boschloo_exact([[rows[k]["successes_a"], rows[k]["successes_b"]],
                            [20 - rows[k]["successes_a"], 20 - rows[k]["successes_b"]]]).pvalue
         for k in (0, 1, 2)}  # fmt: skip
    for k in (0, 1, 2):
        assert rows[k]["p_value"] == pytest.approx(p[k])
    # Holm by hand: sort ascending, multiply by 3, 2, 1, running max, cap at 1
    order = sorted(p, key=p.get)
    expect, running = {}, 0.0
    for rank, k in enumerate(order):
        running = max(running, min(1.0, (3 - rank) * p[k]))
        expect[k] = running
    for k in (0, 1, 2):
        assert rows[k]["p_holm"] == pytest.approx(expect[k])
    assert rows[1]["p_holm"] < 0.05 and "1 level(s) differ" in res["verdict"] and "L1" in res["verdict"]
    assert (tmp_path / "c" / "plots" / "pick_y.png").exists()


def _wilson(s: int, n: int) -> tuple[float, float]:
    ci = binomtest(s, n).proportion_ci(method="wilson")
    return ci.low, ci.high


def test_unpaired_delta_is_the_mover_wilson_interval(tmp_path):
    a = make_run(tmp_path / "a", {0: (19, 20), 1: (15, 20)})
    b = make_run(tmp_path / "b", {0: (20, 20), 1: (4, 20)}, regime="h+mg")
    assert (
        main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "c"), "--test", "boschloo"]) == 0
    )
    res = json.loads((tmp_path / "c" / "compare.json").read_text())
    row = {r["level"]: r for r in res["axes"]["pick_y"]["levels"]}[1]
    # by hand (Newcombe 1998 method 10): B 4/20 − A 15/20 = −0.55; lower end −√((pB−lB)² + (uA−pA)²) etc.
    (la, ua), (lb, ub) = _wilson(15, 20), _wilson(4, 20)
    lo, hi = -0.55 - math.hypot(0.2 - lb, ua - 0.75), -0.55 + math.hypot(ub - 0.2, 0.75 - la)
    assert row["delta"] == pytest.approx(-0.55)
    assert row["delta_ci"] == [pytest.approx(lo), pytest.approx(hi)]
    assert res["delta_interval"].startswith("Newcombe unpaired")
    md = (tmp_path / "c" / "compare.md").read_text()
    assert f"| −55 [{round(100 * lo):+d}, {round(100 * hi):+d}] |".replace("-", "−") in md
    assert "4/20 = 20% [8, 42]" in res["verdict"] and "B − A (pp) −55 [" in res["verdict"]


def test_compare_never_overstates(tmp_path):
    a = make_run(tmp_path / "a", {0: (9, 10), 1: (5, 10)})
    b = make_run(tmp_path / "b", {0: (8, 10), 1: (4, 10)}, regime="h+mg")
    assert main(["compare", str(a.path), str(b.path), "--test", "barnard"]) == 0
    res = json.loads((a.path / "compare" / "compare.json").read_text())
    assert res["test"] == "barnard"
    assert "no level differs at α = 0.05 (unpaired Barnard, Holm-corrected)" in res["verdict"]
    assert "does not show the runs are equal" in res["verdict"]


def test_compare_bad_inputs(tmp_path, capsys):
    a = make_run(tmp_path / "a", {0: (9, 10)})
    assert main(["compare", str(a.path), str(tmp_path / "nope")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["compare", str(a.path), str(a.path), "--alpha", "2"]) == 2


def test_break_levels_read_as_signed_sides():
    from indgen_vla.core.comparison.two_runs import _k

    assert _k({"pos": 2, "neg": -3}) == "+2 / −3"
    assert _k({"pos": None, "neg": -1}) == "none / −1"
    assert _k({"pos": 4}) == "4" and _k({"pos": None}) == "none"
    assert _k({"pos": "undetermined", "neg": -1}) == "undetermined / −1"


def _paired_run(path, outcomes, regime, seed_offset=0):
    """A run whose episode i at each level succeeds as ``outcomes[level][i]`` says (seed 1000 + i)."""
    run = RunDir.create_or_resume(path, {"plan": {"x": 1}, "data_regime": regime, "policy": "standin:noop",
                                         "axes": {"pick_y": {"signed": True}}})  # fmt: skip
    recs = []
    for level, outs in outcomes.items():
        for i, o in enumerate(outs):
            r = rec(level, i, success=o == 1, status="error" if o is None else "ok")
            recs.append(type(r)(**{**r.__dict__, "seed": r.seed + seed_offset}))
    run.append(recs)
    return run


def test_paired_runs_use_exact_mcnemar(tmp_path, capsys):
    # level 1: A succeeds alone on 8 episodes, B alone on 1, both on 2, neither on 1 (one error dropped)
    a_out = {0: [1] * 12, 1: [1] * 8 + [0] + [1, 1] + [0] + [1]}
    b_out = {0: [1] * 11 + [0], 1: [0] * 8 + [1] + [1, 1] + [0] + [None]}
    a, b = _paired_run(tmp_path / "a", a_out, "h-only"), _paired_run(tmp_path / "b", b_out, "h+mg")
    assert main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "c")]) == 0
    res = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert res["test"] == "mcnemar_exact" and res["paired"] is True
    rows = {r["level"]: r for r in res["axes"]["pick_y"]["levels"]}
    assert (rows[1]["pairs"], rows[1]["a_only"], rows[1]["b_only"]) == (12, 8, 1)
    p1 = binomtest(8, 9, 0.5).pvalue  # hand: 2·(1 + 9)/512 = 0.0390625
    assert rows[1]["p_value"] == pytest.approx(p1) == pytest.approx(20 / 512)
    assert rows[0]["p_value"] == pytest.approx(1.0)  # one discordant pair: binomtest(0, 1) = 1
    assert rows[1]["p_holm"] == pytest.approx(min(1, 2 * p1))
    assert "24 episode pairs (1 dropped" in res["axes"]["pick_y"]["pairing"]
    md = (tmp_path / "c" / "compare.md").read_text()
    assert "paired: two-sided exact McNemar" in md and "| A only | B only |" in md
    assert "paired exact McNemar" in res["verdict"]
    # Δ = 3/12 − 10/12 with Newcombe's paired interval, computed here from scipy's Wilson intervals:
    # both 2, A only 8, B only 1, neither 1; φ = (2·1 − 8·1) / √(3·9·10·2) (negative: no continuity shift)
    (la, ua), (lb, ub) = _wilson(10, 12), _wilson(3, 12)
    pa, pb, phi = 10 / 12, 3 / 12, -6 / math.sqrt(3 * 9 * 10 * 2)
    lo = pb - pa - math.sqrt((pb - lb) ** 2 + (ua - pa) ** 2 - 2 * phi * (pb - lb) * (ua - pa))
    hi = pb - pa + math.sqrt((pa - la) ** 2 + (ub - pb) ** 2 - 2 * phi * (pa - la) * (ub - pb))
    assert rows[1]["delta"] == pytest.approx(pb - pa)
    assert rows[1]["delta_ci"] == [pytest.approx(lo), pytest.approx(hi)]
    assert res["delta_interval"].startswith("Newcombe paired") and "| −58 [" in md
    assert (
        main(["compare", str(a.path), str(b.path), "--test", "boschloo", "--out", str(tmp_path / "u")]) == 0
    )
    assert json.loads((tmp_path / "u" / "compare.json").read_text())["test"] == "boschloo"


def test_unpaired_runs_fall_back_to_boschloo(tmp_path, capsys):
    outs = {0: [1, 1, 0, 1, 1, 1], 1: [0, 1, 0, 0, 1, 0]}
    a = _paired_run(tmp_path / "a", outs, "h-only")
    b = _paired_run(tmp_path / "b", outs, "h+mg", seed_offset=7)  # another --seed: same keys, other seeds
    assert main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "c")]) == 0
    res = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert res["test"] == "boschloo" and res["paired"] is False and "seeds differ" in res["unpaired_reason"]
    assert "unpaired Boschloo" in res["verdict"]
    assert main(["compare", str(a.path), str(b.path), "--test", "mcnemar"]) == 2
    assert "needs runs paired episode by episode" in capsys.readouterr().err
    c = _paired_run(tmp_path / "c3", {0: outs[0][:4], 1: outs[1]}, "h+mg")  # fewer episodes at level 0
    assert main(["compare", str(a.path), str(c.path), "--out", str(tmp_path / "d")]) == 0
    res = json.loads((tmp_path / "d" / "compare.json").read_text())
    assert res["test"] == "boschloo" and "do not hold the same episodes on" in res["unpaired_reason"]


def test_compare_reports_break_point_difference(tmp_path):
    a = make_run(tmp_path / "a", {0: (20, 20), 1: (14, 20), 2: (4, 20), 3: (0, 20)})
    b = make_run(tmp_path / "b", {0: (20, 20), 1: (19, 20), 2: (12, 20), 3: (1, 20)}, regime="h+mg")
    assert main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "c")]) == 0
    d = json.loads((tmp_path / "c" / "compare.json").read_text())["axes"]["pick_y"]["break_point_diff"]["pos"]
    assert d["level"] > 0.5 and d["ci"]["level"][0] <= d["level"] <= d["ci"]["level"][1]  # B breaks later
    assert "Break point B − A" in (tmp_path / "c" / "compare.md").read_text()


def test_break_point_difference_uses_only_levels_above_the_data_floor():
    """A level with 2 episodes (below the floor) must not move the compared break points: the result equals
    the one computed without that level's rows."""
    import pandas as pd

    from indgen_vla.core.comparison.two_runs import break_point_diff

    def episodes(rates: dict[int, tuple[int, int]]):
        rows = [{"axis": "pick_y", "status": "ok", "level": k, "param": 0.02 * k, "success": i < s}
                for k, (s, n) in rates.items() for i in range(n)]  # fmt: skip
        return pd.DataFrame(rows)

    ea = episodes({0: (10, 10), 1: (8, 10), 2: (3, 10)})
    eb = episodes({0: (10, 10), 1: (6, 10), 2: (0, 2)})  # level 2: n = 2 < 5
    got = break_point_diff(ea, eb, "pick_y", 0.5, ({0, 1, 2}, {0, 1}))
    want = break_point_diff(ea, eb[eb["level"] != 2], "pick_y", 0.5)
    assert got == want and got != break_point_diff(ea, eb, "pick_y", 0.5)


def test_compare_runs_returns_what_compare_json_holds_and_prints_nothing(tmp_path, capsys):
    """The library call behind ``indgen compare RUN_A RUN_B``: the result comes back, compare.md is its rendering,
    and nothing is printed (the CLI prints it)."""
    from indgen_vla.core.comparison.two_runs import compare_runs, markdown

    a = make_run(tmp_path / "a", {0: (19, 20), 1: (15, 20)}, regime="h-only")
    b = make_run(tmp_path / "b", {0: (20, 20), 1: (4, 20)}, regime="h+mg")
    result = compare_runs(a.path, b.path, gamma=0.2, alpha=0.05, test="boschloo", out=None, label_a="A",
                          label_b="B", allow_protocol_mismatch=False)  # fmt: skip
    assert result["verdict"] == json.loads((a.path / "compare" / "compare.json").read_text())["verdict"]
    assert (a.path / "compare" / "compare.md").read_text() == markdown(result)
    assert (result["label_a"], result["label_b"]) == ("A", "B") and capsys.readouterr().out == ""


def test_an_unfinished_side_is_named_first_and_a_finished_one_is_not(tmp_path, capsys):
    """B planned 10 episodes at each of levels 0 and 1 and holds 7 + 10 (cut short, or still being recorded): compare
    says so above everything else; A, complete, gets no line."""
    plan = {"episodes": 10, "levels": {"pick_y": [0, 1]}, "tasks": ["t"]}
    a = make_run(tmp_path / "a", {0: (9, 10), 1: (5, 10)}, plan=plan)
    b = make_run(tmp_path / "b", {0: (6, 7), 1: (2, 10)}, regime="h+mg", plan=plan)
    assert main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "c")]) == 0
    out = capsys.readouterr().out
    line = "holds 17 of its 20 planned episodes on the compared axes, so its rates and this comparison are provisional"
    assert out.count("**Unfinished**") == 1 and f"(B) {line}" in out
    result = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert [(u["side"], u["done"], u["planned"]) for u in result["unfinished"]] == [("B", 17, 20)]
    assert result["caveats"][0].startswith("**Unfinished**")
