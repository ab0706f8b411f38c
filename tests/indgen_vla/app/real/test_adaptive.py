"""``--adaptive kstar`` on a real run: the stopping decisions the operator is told, against hand-computed ones.

Rule (defaults of ``indgen evaluate --adaptive``): γ = 0.2, δ = 0.1, α = β = 0.025, rounds of 5, cap 20. Per
episode the log-likelihood ratio Λ gains log(0.1/0.3) = −1.0986 for a success and log(0.9/0.7) = +0.2513 for a
failure. The rule's exact thresholds (calibrated on its exact operating characteristic) lie on the Λ lattice:
"broken" needs Λ > 10·log(9/7) = 2.5131 (0/10 is *not* enough: 0.7^10 = 0.028 > α), "intact" needs
Λ ≤ 3·log(1/3) + 2·log(9/7) = −2.7932 (3 successes of 5).
"""

from __future__ import annotations

import json
import math

import pytest

from indgen_vla.app.cli import main
from indgen_vla.core.stats.sprt import SequentialRule

S, F = math.log(0.1 / 0.3), math.log(0.9 / 0.7)


def test_rule_thresholds_are_the_hand_computed_lattice_points():
    rule = SequentialRule(max_episodes=20)
    assert rule.step_success == pytest.approx(S) and rule.step_failure == pytest.approx(F)
    assert rule.upper == pytest.approx(10 * F, abs=1e-9) and rule.lower == pytest.approx(
        3 * S + 2 * F, abs=1e-9
    )
    assert 0.7**10 > 0.025 > 0.7**15  # why 0/10 continues and 0/15 is broken at p = γ + δ = 0.3


def _record(run, outcome, capsys) -> list[str]:
    assert main(["real", "record", str(run), "--outcome", outcome, "--no-report"]) == 0
    return capsys.readouterr().out.strip().splitlines()


def test_kstar_decisions_and_next_level_match_hand_computation(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["real", "plan", "--setup", "stack", "--levels", "0:3", "--episodes", "20", "--adaptive", "kstar",
                 "--policy", "pi05-droid", "--out", str(run)]) == 0  # fmt: skip
    capsys.readouterr()
    # level 0: s s s s f -> Λ_5 = 4S + F = −4.143 <= −2.793: intact after 5
    for o in ["success"] * 3:
        assert "level 0: not decided yet; the rule looks again at 5 episodes" in _record(run, o, capsys)
    _record(run, "success", capsys)
    out = _record(run, "failure:dropped", capsys)
    assert (
        "DECIDED: level 0 is intact (S ≥ γ = 0.2) after 5 episodes" in out
        and out[-1] == "next: level 1 episode 0"
    )
    # level 1: failures only. Λ_5 = 5F = 1.257, Λ_10 = 10F = 2.513 (not > threshold): continue; Λ_15 = 3.770: broken.
    # A void at episode 7 re-queues it: the look at 10 waits for it.
    for i in range(14):
        if i == 7:
            out = _record(run, "void:operator bumped the riser", capsys)
            assert (
                out[-1] == "next: level 1 episode 8"
            )  # interleaved: a voided episode returns one cycle later
            out = _record(run, "failure:misplaced", capsys)  # episode 8
            assert out[-1] == "next: level 1 episode 7"
            _record(run, "failure:misplaced", capsys)  # the voided 7, re-run
            out = _record(run, "failure:misplaced", capsys)  # 9
            assert out[0].startswith("saved: level 1 episode 9 failure")
            assert "level 1: not decided yet; the rule looks again at 15 episodes" in out  # 0/10: continue
            continue
        if i in (8, 9):
            continue
        out = _record(run, "failure:misplaced", capsys)
    out = _record(run, "failure:misplaced", capsys)
    assert out[0] == "saved: level 1 episode 14 failure (misplaced) (journal line 21)"
    assert "DECIDED: level 1 is broken (S < γ = 0.2) after 15 episodes" in out
    assert "adaptive (kstar): every level it needs is decided; k* = +1, determined" in out
    assert out[-1] == "run complete"  # levels 2 and 3 are never run
    assert main(["real", "status", str(run), "--json"]) == 0
    st = json.loads(capsys.readouterr().out)
    assert st["complete"] and [(r["level"], r["n"], r["voids"], r["decision"]) for r in st["levels"]] == [
        (0, 5, 0, "intact"), (1, 15, 1, "broken"), (2, 0, 0, "not needed"), (3, 0, 0, "not needed")]  # fmt: skip
    # the report applies the same rule to episodes.parquet and agrees
    from indgen_vla.core.reporting.summary import summarize
    from indgen_vla.core.runs.records import RunDir

    r = RunDir.open(run)
    summary = summarize(r.episodes(), r.manifest)["axes"]["stack"]
    assert [(r["level"], r["decision"], r["sequential"]["episodes_used"]) for r in summary["levels"][:2]] == [
        (0, "intact", 5), (1, "broken", 15)]  # fmt: skip
    assert summary["break_level"]["pos"] == 1


def test_plan_records_the_engines_adaptive_entry(tmp_path, capsys):
    from indgen_vla.core.stats.sprt import plan_entry

    run = tmp_path / "run"
    assert main(["real", "plan", "--setup", "scale", "--episodes", "30", "--adaptive", "curve", "--round-size", "6",
                 "--adaptive-delta", "0.15", "--policy", "pi05-droid", "--out", str(run)]) == 0  # fmt: skip
    plan = json.loads((run / "manifest.json").read_text())["plan"]
    rule = SequentialRule(delta=0.15, round_size=6, max_episodes=30)
    assert plan["adaptive"] == plan_entry("curve", rule)


def test_status_tells_levels_not_reached_yet_from_levels_the_rule_does_not_need(tmp_path, capsys):
    """``kstar`` walks the levels upward: above a level still being decided they are "not reached" (they will
    run), past a level decided broken "not needed" (they never run). γ = 0.5, δ = 0.4 so 5 episodes decide a level."""
    run = tmp_path / "run"
    assert main(["real", "plan", "--setup", "stack", "--levels", "0:3", "--episodes", "10", "--adaptive", "kstar",
                 "--gamma", "0.5", "--adaptive-delta", "0.4", "--policy", "pi05-droid", "--out", str(run)]) == 0  # fmt: skip

    def decisions() -> list:
        assert main(["real", "status", str(run), "--json"]) == 0
        return [r["decision"] for r in json.loads(capsys.readouterr().out)["levels"]]

    capsys.readouterr()
    assert decisions() == ["continue", "not reached", "not reached", "not reached"]
    assert main(["real", "status", str(run)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].endswith("no episodes, n = 0, voids 0  deciding (more episodes needed)")
    assert lines[2].endswith("no episodes, n = 0, voids 0  not reached")
    assert not any(line.startswith("  kstar:") for line in lines)  # no k* line before the first episode
    for _ in range(5):
        out = _record(run, "success", capsys)
    assert "DECIDED: level 0 is intact (S ≥ γ = 0.5) after 5 episodes" in out
    assert decisions() == ["intact", "continue", "not reached", "not reached"]
    for _ in range(5):
        out = _record(run, "failure:no_grasp", capsys)
    assert "DECIDED: level 1 is broken (S < γ = 0.5) after 5 episodes" in out and out[-1] == "run complete"
    assert decisions() == ["intact", "broken", "not needed", "not needed"]
    assert main(["real", "status", str(run)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert (
        lines[3].endswith("no episodes, n = 0, voids 0  not needed")
        and lines[5] == "  kstar: k* = +1, determined"
    )


def test_status_mid_round_and_after_an_undo_below_a_decided_level(tmp_path, capsys):
    """Before the rule's first look a level with episodes has run (k* text), and a level whose episodes were
    recorded before an undo re-opened a lower one says why it is 'not reached' with n > 0."""
    run = tmp_path / "run"
    assert main(["real", "plan", "--setup", "stack", "--levels", "0:2", "--episodes", "10", "--adaptive", "kstar",
                 "--gamma", "0.5", "--adaptive-delta", "0.4", "--policy", "pi05-droid", "--out", str(run)]) == 0  # fmt: skip
    capsys.readouterr()
    for _ in range(2):
        _record(run, "success", capsys)
    assert main(["real", "status", str(run)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "  kstar: k* at or beyond 0 (no level through 0 is decided broken; +1, +2 not run)" in out
    for _ in range(3):
        _record(run, "success", capsys)  # level 0 intact after 5 (journal lines 1-5)
    _record(run, "failure:no_grasp", capsys)  # level 1, episode 0 (line 6)
    assert main(["real", "record", str(run), "--undo", "5"]) == 0  # level 0 open again: 4 episodes
    capsys.readouterr()
    assert main(["real", "status", str(run)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "  level 1 (0.25 in): 0/1 = 0 % [0, 79], n = 1, voids 0  not reached (1 recorded before an undo " \
           "re-opened a lower level)" in out  # fmt: skip
    assert out[-1] == "next: level 0 episode 4 (1 queued)"
