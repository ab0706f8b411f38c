import math
import random

import numpy as np
import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.sprt import (
    SequentialRule,
    kstar_from_decisions,
    level_order,
    operating_characteristic,
    plan_next,
)


def test_thresholds_and_increments_by_hand():
    r = SequentialRule(
        gamma=0.2, delta=0.1, alpha=0.05, beta=0.1, round_size=5, max_episodes=50, thresholds="wald"
    )
    assert r.upper == pytest.approx(math.log(0.9 / 0.05))  # A = log((1-β)/α) = 2.8904
    assert r.lower == pytest.approx(math.log(0.1 / 0.95))  # B = log(β/(1-α)) = -2.2513
    assert r.step_success == pytest.approx(math.log(0.1 / 0.3))  # -1.0986
    assert r.step_failure == pytest.approx(math.log(0.9 / 0.7))  # +0.2513
    assert r.boundaries() == [5, 10, 15, 20, 25, 30, 35, 40, 45, 50]
    assert SequentialRule(round_size=20, max_episodes=50).boundaries() == [20, 40, 50]


def test_hand_computed_decisions():
    r = SequentialRule(
        gamma=0.2, delta=0.1, alpha=0.05, beta=0.05, round_size=5, max_episodes=50, thresholds="wald"
    )
    # A = -B = log(19) = 2.944. 0/10: Λ = 10·0.2513 = 2.513 < A -> continue; 0/15: 3.770 >= A -> broken.
    d = r.decide([False] * 10)
    assert (d.verdict, d.episodes, d.next_boundary) == ("continue", 10, 15)
    assert d.llr == pytest.approx(2.5131, abs=1e-4)
    d = r.decide([False] * 15)
    assert (d.verdict, d.episodes, d.successes) == ("broken", 15, 0)
    # 3/5: Λ = 3·(-1.0986) + 2·0.2513 = -2.793 > B -> continue; 5/5: -5.493 <= B -> intact at 5.
    assert r.decide([True, True, True, False, False]).verdict == "continue"
    assert r.decide([True] * 5).verdict == "intact"
    # 2/5: Λ = -2.197 + 0.754 = -1.443; 3/10: -3.2958 + 1.7592 = -1.5366 (both continue);
    # 5/15: -5.493 + 2.513 = -2.980 <= B -> intact at 15.
    seq = [True, True, False, False, False, True, False, False, False, False, True, True, False, False, False]
    assert r.decide(seq[:5]).verdict == "continue"
    assert r.decide(seq[:10]).llr == pytest.approx(-1.5366, abs=1e-4)
    assert r.decide(seq[:10]).verdict == "continue"
    d = r.decide(seq)
    assert (d.verdict, d.episodes, d.successes) == ("intact", 15, 5)


def test_decisions_only_at_round_boundaries_and_extra_outcomes_ignored():
    r = SequentialRule(alpha=0.05, beta=0.05, round_size=5, max_episodes=50, thresholds="wald")
    # 5 successes in 4 episodes is impossible; 3 successes of 3 would already be past B, but no look before 5.
    assert r.decide([True] * 3).verdict == "continue"
    assert r.decide([True] * 3).episodes == 0
    base = r.decide([True] * 5)
    more = r.decide([True] * 5 + [False] * 30)  # a run that went further (or another worker count)
    assert base == more and base.episodes == 5


def test_truncation_and_errors():
    r = SequentialRule(alpha=0.05, beta=0.05, round_size=10, max_episodes=20, thresholds="wald")
    # 2/20 (rate 0.1): Λ = 2·(-1.0986) + 18·0.2513 = 2.326 < A -> undetermined at the cap
    d = r.decide([True, True] + [False] * 18)
    assert (d.verdict, d.episodes, d.n) == ("undetermined", 20, 20)
    # error episodes (None) use their index but are not counted in n
    d = r.decide([None] * 10 + [True] * 10)
    assert (d.n, d.successes, d.episodes) == (10, 10, 20)
    assert d.verdict == "intact"
    with pytest.raises(ConfigError, match="True, False or None"):
        r.decide([0.5] * 10)


@pytest.mark.parametrize(
    "kw,match",
    [
        ({"gamma": 0}, "gamma"),
        ({"delta": 0.2}, "delta"),
        ({"alpha": 0.5}, "alpha"),
        ({"beta": 0}, "beta"),
        ({"round_size": 0}, "round size"),
        ({"max_episodes": 2.5}, "max episodes"),
    ],
)
def test_rule_validation(kw, match):
    with pytest.raises(ConfigError, match=match):
        SequentialRule(**kw)


def test_operating_characteristic_matches_enumeration_and_stated_errors():
    r = SequentialRule(round_size=2, max_episodes=6)
    for p in (0.1, 0.3, 0.7):
        oc = operating_characteristic(r, p)
        # brute force over all 2^6 sequences
        tot = {"broken": 0.0, "intact": 0.0, "undetermined": 0.0}
        en = 0.0
        for bits in range(64):
            seq = [bool(bits >> i & 1) for i in range(6)]
            w = math.prod(p if o else 1 - p for o in seq)
            d = r.decide(seq)
            tot[d.verdict] += w
            en += w * d.episodes
        assert oc.p_broken == pytest.approx(tot["broken"])
        assert oc.p_intact == pytest.approx(tot["intact"])
        assert oc.p_undetermined == pytest.approx(tot["undetermined"])
        assert oc.expected_episodes == pytest.approx(en)
    default = SequentialRule()
    assert operating_characteristic(default, default.p_intact).p_broken <= default.alpha
    assert operating_characteristic(default, default.p_broken).p_intact <= default.beta


def test_level_order():
    assert level_order(range(-3, 4)) == {"pos": [0, 1, 2, 3], "neg": [0, -1, -2, -3]}
    assert level_order([0, 1, 2]) == {"pos": [0, 1, 2]}
    assert level_order([2, 1, 3], signed=False) == {"pos": [1, 2, 3]}
    with pytest.raises(ConfigError):
        level_order([])


R = SequentialRule(alpha=0.05, beta=0.05, round_size=5, max_episodes=20, thresholds="wald")


def _fill(outcomes, plan, truth):
    for k, eps in plan.to_run.items():
        for i in eps:
            outcomes.setdefault(k, {})[i] = truth[k](i)


def test_kstar_mode_on_hand_example():
    # level 0, +1 always succeed (intact after 5); +2 always fails (broken after 15); +3 must never run.
    truth = {0: lambda i: True, 1: lambda i: True, 2: lambda i: False, 3: lambda i: True}
    outcomes: dict = {}
    plan = plan_next(R, [0, 1, 2, 3], outcomes, "kstar")
    assert plan.to_run == {0: [0, 1, 2, 3, 4]}
    rounds = 0
    while not plan.done:
        _fill(outcomes, plan, truth)
        plan = plan_next(R, [0, 1, 2, 3], outcomes, "kstar")
        rounds += 1
    assert 3 not in outcomes
    assert {k: len(v) for k, v in outcomes.items()} == {0: 5, 1: 5, 2: 15}
    assert plan.kstar["pos"]["k"] == 2 and plan.kstar["pos"]["text"] == "k* = +2, determined"
    assert rounds == 1 + 1 + 3
    assert plan.episodes_used == 25


def test_curve_mode_decides_every_level_and_signed_directions():
    truth = {k: (lambda i: True) if abs(k) <= 1 else (lambda i: False) for k in range(-2, 3)}
    outcomes: dict = {}
    plan = plan_next(R, range(-2, 3), outcomes, "curve")
    assert sorted(plan.to_run) == [-2, -1, 0, 1, 2]
    while not plan.done:
        _fill(outcomes, plan, truth)
        plan = plan_next(R, range(-2, 3), outcomes, "curve")
    assert {k: d.verdict for k, d in plan.decisions.items()} == {
        -2: "broken",
        -1: "intact",
        0: "intact",
        1: "intact",
        2: "broken",
    }
    assert plan.kstar["pos"]["k"] == 2 and plan.kstar["neg"]["k"] == -2


def test_undetermined_level_gives_interval_and_direction_continues():
    # level 1 at rate 0.2 exactly (1 in 5): undetermined at 20; level 2 all failures: broken.
    truth = {0: lambda i: True, 1: lambda i: i % 5 == 0, 2: lambda i: False}
    outcomes: dict = {}
    plan = plan_next(R, [0, 1, 2], outcomes, "kstar")
    while not plan.done:
        _fill(outcomes, plan, truth)
        plan = plan_next(R, [0, 1, 2], outcomes, "kstar")
    assert plan.decisions[1].verdict == "undetermined"
    st = plan.kstar["pos"]
    assert st["text"] == "k* ∈ [+1, +2]" and not st["determined"]
    assert st["k"] == 2  # rate at level 1 is 4/20 = 0.2, not below γ: the point estimate moves on


def test_plan_is_independent_of_completion_order_and_resume():
    rng = random.Random(3)
    truth = {k: [rng.random() < p for _ in range(20)] for k, p in {0: 0.9, 1: 0.5, 2: 0.15, 3: 0.05}.items()}

    def drive(shuffle_seed):
        outcomes: dict = {}
        plan = plan_next(R, [0, 1, 2, 3], outcomes, "kstar")
        order = random.Random(shuffle_seed)
        while not plan.done:
            jobs = [(k, i) for k, eps in plan.to_run.items() for i in eps]
            order.shuffle(jobs)  # workers finish in any order; a kill mid-round leaves holes
            for k, i in jobs[: max(1, len(jobs) // 2)]:
                outcomes.setdefault(k, {})[i] = truth[k][i]
            plan = plan_next(R, [0, 1, 2, 3], outcomes, "kstar")
        return plan.decisions, outcomes

    d1, o1 = drive(0)
    d2, o2 = drive(1)
    assert d1 == d2 and o1 == o2


def test_kstar_from_decisions_and_bad_mode():
    r = SequentialRule(alpha=0.05, beta=0.05, round_size=10, max_episodes=10, thresholds="wald")
    dec = {0: r.decide([True] * 10), 1: r.decide([True] + [False] * 9)}  # 1/10: Λ=1.16, undetermined
    assert dec[1].verdict == "undetermined"
    assert kstar_from_decisions(dec, [0, 1], 0.2) == 1  # rate 0.1 < γ at the cap: the fixed rule
    with pytest.raises(ConfigError, match="adaptive mode"):
        plan_next(r, [0, 1], {}, "greedy")


def test_exact_thresholds_meet_alpha_beta_and_are_tight():
    from indgen_vla.core.stats.sprt import _oc

    r = SequentialRule(thresholds="exact")
    wald = SequentialRule(thresholds="wald")
    assert 0 < r.upper < wald.upper and wald.lower < r.lower < 0  # less conservative than Wald's
    oc_i, oc_b = operating_characteristic(r, r.p_intact), operating_characteristic(r, r.p_broken)
    assert oc_i.p_broken <= r.alpha and oc_b.p_intact <= r.beta
    # tight: any lower A (or higher B) breaks the stated error rate
    assert _oc(r, r.p_intact, r.upper - 1e-6, r.lower)[0] > r.alpha
    assert _oc(r, r.p_broken, r.upper, r.lower + 1e-6)[1] > r.beta
    # and it spends fewer episodes than Wald's thresholds where the answer is clear
    assert (
        operating_characteristic(r, 0.9).expected_episodes
        <= operating_characteristic(wald, 0.9).expected_episodes
    )
    assert (
        operating_characteristic(r, 0.5).expected_episodes
        < operating_characteristic(wald, 0.5).expected_episodes
    )
    assert r.as_dict()["thresholds"] == "exact"
    with pytest.raises(ConfigError, match="thresholds"):
        SequentialRule(thresholds="pocock")


# ---------------------------------------------------------------- the paper's until-failure design (§5.3)
def _run_until_failure(rule, levels, truth, mode="until-failure"):
    """Drive ``plan_next`` to the end; ``truth[k]`` is level k's outcome list. Returns (plan, outcomes)."""
    outcomes: dict = {}
    plan = plan_next(rule, levels, outcomes, mode)
    while not plan.done:
        for k, eps in plan.to_run.items():
            for i in eps:
                outcomes.setdefault(k, {})[i] = truth[k][i]
        plan = plan_next(rule, levels, outcomes, mode)
    return plan, outcomes


def _trials(successes: int, n: int = 10) -> list[bool]:
    return [True] * successes + [False] * (n - successes)


def test_until_failure_stops_after_the_first_level_observed_below_gamma():
    """10/10, 6/10, 1/10: level 2 is the first below γ = 0.2, so levels 3 and 4 never run and k* = +2. Wilson
    95 % CIs by hand: 10/10 [72.2, 100] % and 6/10 [31.3, 83.2] % lie above γ (intact); 1/10 [1.8, 40.4] % straddles
    it (undetermined): the break is observed, not decided."""
    from indgen_vla.core.stats.sprt import UntilFailure

    rule = UntilFailure(gamma=0.2, max_episodes=10)
    truth = {0: _trials(10), 1: _trials(6), 2: _trials(1), 3: _trials(10), 4: _trials(10)}
    plan = plan_next(rule, range(5), {}, "until-failure")
    assert plan.to_run == {0: list(range(10))}  # one level at a time, all its trials at once
    plan = plan_next(rule, range(5), {0: {i: True for i in range(7)}}, "until-failure")
    assert plan.to_run == {0: [7, 8, 9]} and plan.decisions[0].verdict == "continue"
    plan, outcomes = _run_until_failure(rule, range(5), truth)
    assert {k: len(v) for k, v in outcomes.items()} == {0: 10, 1: 10, 2: 10}
    assert {k: d.verdict for k, d in plan.decisions.items()} == {0: "intact", 1: "intact", 2: "undetermined"}
    assert plan.kstar["pos"]["k"] == 2 and plan.episodes_used == 30
    text = plan.kstar["pos"]["text"]
    assert (
        text.startswith("k* = +2 observed (1/10 < γ = 0.2, 95 % Wilson CI 2-40 %)")
        and "not a statistically" in text
    )
    # the SPRT's kstar walk on the same 10 trials: 1/10 is "undetermined" at the cap, never "broken", so it walks on
    sprt = SequentialRule(max_episodes=10)
    assert sprt.decide(truth[2]).verdict == "undetermined"
    assert plan_next(sprt, range(5), outcomes, "kstar").to_run == {3: [0, 1, 2, 3, 4]}


def test_until_failure_without_a_break_runs_every_level_and_a_low_ci_says_so():
    from indgen_vla.core.stats.sprt import UntilFailure

    rule = UntilFailure(gamma=0.2, max_episodes=10)
    plan, outcomes = _run_until_failure(
        rule, range(3), {k: _trials(2) for k in range(3)}
    )  # 2/10 = γ: not below
    assert len(outcomes) == 3 and plan.kstar["pos"]["k"] is None
    assert plan.kstar["pos"]["text"] == "no level observed below γ = 0.2 through +2"
    # 0/20 (Wilson upper 16.1 % < γ): the observed break is also significant
    rule20 = UntilFailure(gamma=0.2, max_episodes=20)
    plan, _ = _run_until_failure(
        rule20, range(3), {0: _trials(20, 20), 1: _trials(0, 20), 2: _trials(20, 20)}
    )
    assert plan.decisions[1].verdict == "broken" and plan.kstar["pos"]["k"] == 1
    assert plan.kstar["pos"]["text"].endswith("its CI lies below γ too")


def test_until_failure_signed_directions_errors_and_rule_checks():
    from indgen_vla.core.stats.sprt import UntilFailure, make_rule, plan_entry, rule_from_plan

    rule = UntilFailure(gamma=0.2, max_episodes=5)
    truth = {
        0: _trials(5, 5),
        1: _trials(0, 5),
        -1: _trials(5, 5),
        -2: [None, None, False, False, True],
        2: [True] * 5,
    }
    plan, outcomes = _run_until_failure(rule, range(-2, 3), truth)
    assert 2 not in outcomes and plan.kstar["pos"]["k"] == 1
    # level -2: 1/3 finished episodes (two errors count as finished, not in n), 33 % ≥ γ: no break on that side
    assert (plan.decisions[-2].n, plan.decisions[-2].successes, plan.kstar["neg"]["k"]) == (3, 1, None)
    assert make_rule("until-failure", 0.3, 0.1, 0.025, 5, 10) == UntilFailure(0.3, 10)
    assert plan_entry("until-failure", UntilFailure(0.3, 10)) == {"mode": "until-failure", "gamma": 0.3}
    assert rule_from_plan({"mode": "until-failure", "gamma": 0.3}, 10) == UntilFailure(0.3, 10)
    with pytest.raises(ConfigError, match="goes with an UntilFailure rule"):
        plan_next(SequentialRule(), [0, 1], {}, "until-failure")
    with pytest.raises(ConfigError, match="gamma must be in"):
        UntilFailure(gamma=1.0)


@pytest.mark.parametrize(
    ("episodes", "round_size", "alpha"), [(50, 5, 0.025), (20, 5, 0.025), (100, 10, 0.05), (30, 1, 0.05)]
)
def test_the_calibrated_rule_keeps_its_errors_beyond_the_indifference_zone(episodes, round_size, alpha):
    """adaptive.md: P(broken) ≤ α at every S ≥ γ + δ and P(intact) ≤ β at every S ≤ γ − δ, for the rule any
    --episodes / --round-size / --adaptive-alpha gives (exact OC on a grid of 41 rates each side), and the calibrated
    thresholds use most of α at the boundary where the episodes allow it."""
    from indgen_vla.core.stats.sprt import make_rule

    rule = make_rule("kstar", 0.2, 0.1, alpha, round_size, episodes)
    for s in np.linspace(0.3, 1.0, 41):
        assert operating_characteristic(rule, float(s)).p_broken <= alpha + 1e-12
    for s in np.linspace(0.0, 0.1, 41):
        assert operating_characteristic(rule, float(s)).p_intact <= alpha + 1e-12
    if episodes >= 50:
        assert operating_characteristic(rule, 0.3).p_broken > 0.8 * alpha
