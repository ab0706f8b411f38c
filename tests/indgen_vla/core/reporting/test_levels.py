"""Verdict sentences and the episodes a level still needs, against hand-computed values."""

import pytest
from scipy.stats import binom

from indgen_vla.core.reporting.levels import (
    axis_verdicts,
    direction_verdict,
    episodes_to_decide,
    kstar_status_of,
    verdict_line,
)
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.stats.metrics import success_rate
from indgen_vla.core.stats.sprt import make_rule, operating_characteristic, plan_entry
from tests.indgen_vla.core.reporting.test_report import make_run


def row(level, successes, n, decision, planned=None, insufficient=False, **extra):
    r = success_rate(successes, n)
    return {"level": level, "successes": successes, "n": n, "rate": r.rate, "ci_low": r.ci_low,
            "ci_high": r.ci_high, "decision": decision, "planned": planned, "insufficient": insufficient, **extra}  # fmt: skip


def test_episodes_to_decide_reaches_80_percent_by_hand():
    # 0/N: Wilson's upper bound is z^2 / (N + z^2) < 0.2  <=>  N > 4 z^2 = 15.37, so N = 16: 6 more after 10 (at an
    # observed rate of 0 the extra episodes fail for sure)
    assert episodes_to_decide(0, 10, 0.2) == 6
    # 1/10 held at 10 %: the old projection (106 episodes' worth of the rounded rate) decided only about half the
    # time; 96 more decide it with chance >= 80 %: the kept success plus Bin(96, 0.1) at most the broken count of 106
    more = episodes_to_decide(1, 10, 0.2)
    broken = max(s for s in range(11 + more) if success_rate(s, 10 + more).ci_high < 0.2)
    assert more == 96 and binom.cdf(broken - 1, more, 0.1) >= 0.8
    assert episodes_to_decide(19, 100, 0.2) is None  # 19 % is too close to γ for any feasible run


def test_a_significant_break_and_an_open_one_read_differently():
    rows = [row(0, 10, 10, "intact"), row(1, 0, 10, "broken")]
    assert (
        direction_verdict(rows, 1, 0.2)
        == "breaks at +1 (0 %, n = 10, 95 % CI [0, 28]), significantly below γ = 0.2 (Wilson 95 % CI; chance of this "
        "call at S = γ with n = 10: 0.0 %)"
    )
    rows = [row(0, 10, 10, "intact"), row(1, 1, 10, "undetermined")]
    assert direction_verdict(rows, 1, 0.2) == (
        "first level below γ: +1 (10 %, n = 10, 95 % CI [2, 40]); not yet significant: about 96 more episodes at +1 "
        "would decide it with 80% chance if the rate holds"
    )


def test_no_break_and_a_hole_before_the_break():
    rows = [row(0, 10, 10, "intact"), row(-1, 5, 10, "undetermined")]
    assert (
        direction_verdict(rows, None, 0.2)
        == "no level below γ = 0.2 through -1 (-1 not yet significantly above it)"
    )
    assert (
        direction_verdict(rows[:1], None, 0.2)
        == "no break through 0: every level is significantly at or above γ = 0.2 (Wilson 95 % CI; chance of this "
        "call at S = γ with n = 10: 3.3 %, the largest over its levels)"
    )
    # levels of 6 and 8 episodes: the call at n = 8 errs 5.6 %, at n = 6 (the smallest) 1.7 %: the larger is quoted
    mixed = [row(0, 6, 6, "intact"), row(1, 8, 8, "intact")]
    assert "with n = 8: 5.6 %, the largest over its levels" in direction_verdict(mixed, None, 0.2)
    hole = [row(0, 10, 10, "intact"), row(1, 0, 1, "undetermined", planned=10, insufficient=True)]
    assert direction_verdict(hole, "undetermined", 0.2) == (
        "undetermined: level +1 has too little data (n = 1 of 10); finish it (re-run the same evaluate command: "
        "it runs what is missing and retries errors)"
    )
    recorded = [
        row(0, 10, 10, "intact"),
        {**row(1, 0, 1, "undetermined", planned=2, insufficient=True), "errors": 1},
    ]
    assert direction_verdict(recorded, "undetermined", 0.2).endswith(
        "every planned episode is recorded; a re-run retries those that ended in error, but one ruled out by the "
        "level (an infeasible cell) stays so: only more --episodes add to n"
    )
    smoke = [
        row(0, 2, 2, "undetermined", planned=2, insufficient=True)
    ]  # --episodes 2: done, yet below the floor
    assert direction_verdict(smoke, "undetermined", 0.2) == (
        "undetermined: level 0 has too little data (n = 2 of 2); every planned episode ran, and under 5 never "
        "give a k*: run --episodes 5 or more"
    )


def test_an_adaptive_level_names_the_rules_next_look():
    rows = [row(0, 1, 10, "undetermined", planned=15, sequential={"verdict": "continue"})]
    assert direction_verdict(rows, 0, 0.2).endswith("not yet decided: the rule looks again at 15 episodes")


@pytest.mark.parametrize("signed", [True, False])
def test_axis_verdicts_split_the_directions_of_a_signed_axis(signed):
    rows = [row(-1, 0, 10, "broken"), row(0, 10, 10, "intact"), row(1, 10, 10, "intact")]
    rows = rows if signed else rows[1:]
    v = axis_verdicts(rows, {"pos": None, "neg": -1} if signed else {"pos": None}, 0.2, signed)
    assert v["pos"].startswith("no break through +1")
    if signed:
        assert v["neg"].startswith("breaks at -1") and verdict_line(v, True).startswith("+: no break")
        assert "; −: breaks at -1" in verdict_line(v, True)
    else:
        assert set(v) == {"pos"} and verdict_line(v, False) == v["pos"]


def test_a_signed_axis_run_on_one_side_says_the_other_was_not_evaluated():
    """pick_y at --levels 0:1: the − direction is level 0 alone, not a break at 0 (it read "first level below γ: 0")."""
    rows = [row(0, 0, 10, "broken"), row(1, 0, 10, "broken")]
    v = axis_verdicts(rows, {"pos": 0, "neg": 0}, 0.2, True)
    assert (
        v["pos"].startswith("breaks at 0")
        and v["neg"] == "not evaluated (no level on this side of 0 was run)"
    )
    status = kstar_status_of(
        rows, True
    )  # the k* status row agrees (it said "−: no break through 0, determined")
    assert status["neg"]["text"] == v["neg"] and not status["neg"]["determined"]
    assert status["pos"]["text"] == "k* = 0, determined"


def test_a_decided_break_after_an_undecided_level_names_the_interval_of_kstar():
    """+1 at 3/10 (CI [11, 60]) is neither intact nor broken, +2 at 0/20 is broken: k* is +1 or +2. The verdict
    said only "breaks at +2 ..." (the terminal prints no other k* line); it now adds the interval and why."""
    rows = [row(0, 10, 10, "intact"), row(1, 3, 10, "undetermined"), row(2, 0, 20, "broken")]
    v = axis_verdicts(rows, {"pos": 2}, 0.2, signed=False)["pos"]
    assert v.startswith("breaks at +2 (0 %, n = 20, 95 % CI [0, 16]), significantly below γ = 0.2")
    assert v.endswith("; k* ∈ [+1, +2]: +1 not shown at or above γ")
    rows[1] = row(
        1, 9, 10, "intact"
    )  # every level before the break intact: k* = +2, determined, nothing added
    assert axis_verdicts(rows, {"pos": 2}, 0.2, signed=False)["pos"].endswith("(Wilson 95 % CI; chance of this call "
                                                                               "at S = γ with n = 20: 1.2 %)")  # fmt: skip


def test_a_sequential_break_prints_its_own_error_not_only_a_wilson_interval_that_reaches_gamma(tmp_path):
    """Default rule: 1 success in 20 crosses the SPRT's bound (broken) while the level's Wilson interval [1, 25] %
    still reaches γ = 0.2. The line quotes the rule's exact error at S = γ + δ (2.5 %, what it guarantees) and says
    that inside [γ − δ, γ + δ] either call may come (at S = γ "broken" comes with chance 26 %)."""
    rule = make_rule("kstar", 0.2, 0.1, 0.025, 5, 50)
    run = make_run(tmp_path / "r", {0: (20, 20), 1: (1, 20)},
                   plan={"episodes": 50, "adaptive": plan_entry("kstar", rule)})  # fmt: skip
    ax = summarize(run.episodes(), run.manifest, gamma=0.2)["axes"]["pick_y"]
    lv = {r["level"]: r for r in ax["levels"]}
    assert lv[1]["decision"] == "broken" and lv[1]["ci_high"] > 0.2
    assert lv[1]["sequential"]["error_at"]["broken"][1] == pytest.approx(
        operating_characteristic(rule, 0.3).p_broken
    )
    assert ax["verdict"]["pos"].endswith(
        "decided below γ = 0.2 by the sequential rule (chance of this call at S = 0.3: 2.5 %; between 0.1 and 0.3 "
        "either call may come, and the interval is descriptive after stopping)"
    )
