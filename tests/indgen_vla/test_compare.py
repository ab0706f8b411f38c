import json

import pytest
from scipy.stats import boschloo_exact

from indgen_vla.cli import main
from tests.indgen_vla.test_report import make_run


def test_compare_against_scipy_and_hand_holm(tmp_path, capsys):
    a = make_run(tmp_path / "a", {0: (19, 20), 1: (15, 20), 2: (12, 20)}, regime="h-only")
    b = make_run(tmp_path / "b", {0: (20, 20), 1: (4, 20), 2: (11, 20)}, regime="h+mg")
    assert main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "c")]) == 0
    res = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert res["test"] == "boschloo"
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


def test_compare_never_overstates(tmp_path):
    a = make_run(tmp_path / "a", {0: (9, 10), 1: (5, 10)})
    b = make_run(tmp_path / "b", {0: (8, 10), 1: (4, 10)}, regime="h+mg")
    assert main(["compare", str(a.path), str(b.path), "--test", "barnard"]) == 0
    res = json.loads((a.path / "compare" / "compare.json").read_text())
    assert res["test"] == "barnard"
    assert "no level differs at α = 0.05 after Holm" in res["verdict"]
    assert "does not show the runs are equal" in res["verdict"]


def test_compare_bad_inputs(tmp_path, capsys):
    a = make_run(tmp_path / "a", {0: (9, 10)})
    assert main(["compare", str(a.path), str(tmp_path / "nope")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["compare", str(a.path), str(a.path), "--alpha", "2"]) == 2


def test_break_levels_read_as_signed_sides():
    from indgen_vla.compare import _k

    assert _k({"pos": 2, "neg": -3}) == "+2 / −3"
    assert _k({"pos": None, "neg": -1}) == "none / −1"
    assert _k({"pos": 4}) == "4" and _k({"pos": None}) == "none"
