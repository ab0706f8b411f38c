"""``indgen reference``: T0 by Definition 3 on even episodes, the ordering tested on odd ones."""

import json

import pytest

from indgen_vla.app.cli import main
from indgen_vla.core.runs.records import RunDir
from indgen_vla.core.stats.metrics import cochran_armitage, monotone_decreasing_test
from tests.indgen_vla.core.runs.test_records import rec


def _run(path, successes, regime, axis="pick_x"):
    """10 episodes per level; episode i succeeds when i < successes[level]."""
    run = RunDir.create_or_resume(path, {"plan": {"x": 1}, "data_regime": regime, "policy": "standin:noop"})
    run.append([rec(k, i, success=i < s, axis=axis) for k, s in successes.items() for i in range(10)])
    return run


A = {-2: 2, -1: 5, 0: 8, 1: 10, 2: 6}
B = {-2: 1, -1: 4, 0: 9, 1: 9, 2: 3}


def test_reference_picks_t0_on_even_episodes_and_tests_on_odd(tmp_path, capsys):
    a, b = _run(tmp_path / "a", A, "gr00t"), _run(tmp_path / "b", B, "pi05")
    assert main(["reference", str(a.path), str(b.path), "--out", str(tmp_path / "ref")]) == 0
    res = json.loads((tmp_path / "ref" / "reference.json").read_text())
    # even episodes 0,2,4,6,8: A has 1,3,4,5,3 successes at levels -2..2, B has 1,2,5,5,2 (of 5 each)
    means = {c["level"]: c["mean_success"] for c in res["configurations"]}
    assert means == pytest.approx({-2: 0.2, -1: 0.5, 0: 0.9, 1: 1.0, 2: 0.5})
    assert res["reference"] == {"task": "t", "level": 1, "mean_success": 1.0}
    # odd episodes 1,3,5,7,9 of A: 1, 2, 4, 5, 3 successes at levels -2..2
    held = {
        r["level"]: (r["successes"], r["n"], r["offset"])
        for r in res["ordering"]["gr00t / standin:noop"]["levels"]
    }
    assert held == {-2: (1, 5, -3), -1: (2, 5, -2), 0: (4, 5, -1), 1: (5, 5, 0), 2: (3, 5, 1)}
    neg = res["ordering"]["gr00t / standin:noop"]["tests"]["neg"]
    assert neg["offsets"] == [0, -1, -2, -3]
    assert neg["monotone_p"] == pytest.approx(monotone_decreasing_test([5, 4, 2, 1], [5] * 4).p_decreasing)
    assert neg["cochran_armitage_p"] == pytest.approx(
        cochran_armitage([0, 1, 2, 3], [5, 4, 2, 1], [5] * 4).p_decreasing
    )
    assert neg["monotone_p"] < 0.05
    md = (tmp_path / "ref" / "reference.md").read_text()
    assert (
        "T0 = task `t`, level 1" in md
        and "even episode indices" in md
        and "| t | 1 | 5/5 | 5/5 | 100% |" in md
    )
    assert "monotone decrease p =" in capsys.readouterr().out


def test_reference_held_out_episodes_do_not_move_t0(tmp_path):
    # level 0 fails on every odd episode of A: the choice (made on even episodes) must not change
    a = _run(tmp_path / "a", A, "gr00t")
    b = RunDir.create_or_resume(tmp_path / "b", {"plan": {"x": 1}, "data_regime": "pi05", "policy": "p"})
    b.append(
        [
            rec(k, i, success=(i < s) and (i % 2 == 0 or k != 1), axis="pick_x")
            for k, s in B.items()
            for i in range(10)
        ]
    )
    assert main(["reference", str(a.path), str(b.path), "--out", str(tmp_path / "r")]) == 0
    assert json.loads((tmp_path / "r" / "reference.json").read_text())["reference"]["level"] == 1


def test_reference_bad_inputs(tmp_path, capsys):
    a = _run(tmp_path / "a", A, "x")
    b = _run(tmp_path / "b", B, "y", axis="horizon")
    assert main(["reference", str(a.path), str(b.path)]) == 2
    assert "share axes (none)" in capsys.readouterr().err
    assert main(["reference", str(a.path), "--axis", "horizon"]) == 2
    assert "--axis horizon: not evaluated by every run" in capsys.readouterr().err
    assert main(["reference", str(a.path), "--task", "nope"]) == 2
    assert "--task nope" in capsys.readouterr().err
    assert main(["reference", str(tmp_path / "missing")]) == 2


def test_reference_level_restricts_t0_to_the_canonical_configurations(tmp_path, capsys):
    """--level 0: T0 is the canonical configuration (here two RoboCasa kitchens of one task) with the best level-0
    success, even where a perturbed level scores higher; the ordering is tested over T0's kitchen's levels."""
    runs = []
    for name, regime in (("a", "gr00t"), ("b", "pi05")):
        run = RunDir.create_or_resume(
            tmp_path / name, {"plan": {"x": 1}, "data_regime": regime, "policy": "p"}
        )
        cells = {
            ("T@11-34", 0): 6,
            ("T@11-34", 1): 10,
            ("T@15-34", 0): 8,
            ("T@15-34", 1): 5,
            ("T@15-34", 2): 2,
        }
        run.append(
            [
                rec(k, i, success=i < s, task=t, axis="base_y")
                for (t, k), s in cells.items()
                for i in range(10)
            ]
        )
        runs.append(run)
    out = tmp_path / "ref"
    assert main(["reference", *(str(r.path) for r in runs), "--level", "0", "--out", str(out)]) == 0
    res = json.loads((out / "reference.json").read_text())
    assert res["reference"]["task"] == "T@15-34" and res["reference"]["level"] == 0
    assert res["candidate_level"] == 0 and {c["level"] for c in res["configurations"]} == {0}
    levels = [r["level"] for r in res["ordering"]["gr00t / p"]["levels"]]
    assert levels == [0, 1, 2] and "level-0 configurations only" in (out / "reference.md").read_text()
    # without --level the perturbed cell (T@11-34, level 1: 10/10) would have been T0
    assert main(["reference", *(str(r.path) for r in runs), "--out", str(tmp_path / "ref2")]) == 0
    assert json.loads((tmp_path / "ref2" / "reference.json").read_text())["reference"]["task"] == "T@11-34"
    capsys.readouterr()
    assert main(["reference", str(runs[0].path), "--level", "5"]) != 0
    assert "--level 5: no run evaluated level 5" in capsys.readouterr().err
