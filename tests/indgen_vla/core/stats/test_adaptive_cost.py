"""The adaptive rule's simulated cost: against its exact operating characteristic, hand-counted deterministic
ladders, and T0 run once for the axes that share it."""

import numpy as np
import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.adaptive_cost import Curve, assumed_curve, simulate_protocol, simulate_task
from indgen_vla.core.stats.sprt import make_rule, operating_characteristic


@pytest.mark.parametrize("p", [0.05, 0.25, 0.9])
def test_one_level_costs_what_the_exact_operating_characteristic_says(p):
    """One level, the default rule: the simulated mean episodes equal the exact OC's E[N] within 4 standard errors."""
    rule = make_rule("curve", 0.2, 0.1, 0.025, 5, 50)
    cost = simulate_protocol(
        rule, "curve", 1, {"a": [0]}, Curve(rates={"a": {0: p}}), {}, 50, replicates=600, seed=3
    )
    t = np.asarray(cost.totals)
    exact = operating_characteristic(rule, p).expected_episodes
    assert abs(t.mean() - exact) < 4 * t.std() / np.sqrt(600)  # 600 simulated tasks behind the draws


def test_deterministic_ladders_cost_what_the_rule_says_by_hand():
    """Rates 1, 1, 0 on levels 0..2. SPRT (γ 0.2, δ 0.1): a success moves Λ by −1.0986, a failure by +0.2513; the
    calibrated thresholds are A = 3.116, B = −2.980 (docs/adaptive.md), so 5 successes decide "intact" at the first
    look and 15 failures "broken" at the third (12.4 steps of 0.2513 reach A): 5 + 5 + 15 = 25 episodes in 5
    rounds (kstar walks 0, then 1, then 2). until-failure with 10 a level: 30, in 3 rounds."""
    rng = np.random.default_rng(0)
    rates = {"a": {0: 1.0, 1: 1.0, 2: 0.0}}
    kstar = simulate_task(
        make_rule("kstar", 0.2, 0.1, 0.025, 5, 50), "kstar", {"a": [0, 1, 2]}, rates, {}, rng
    )
    assert kstar.per_round == (5, 5, 5, 5, 5) and kstar.episodes == 25
    walk = simulate_task(make_rule("until-failure", 0.2, 0.1, 0.025, 5, 10), "until-failure", {"a": [0, 1, 2]},
                         rates, {}, rng)  # fmt: skip
    assert walk.per_round == (10, 10, 10)


def test_axes_sharing_t0_roll_it_out_once():
    rng = np.random.default_rng(0)
    rule = make_rule("kstar", 0.2, 0.1, 0.025, 5, 50)
    levels = {"a": [0, 1, 2], "b": [0, 1, 2]}
    rates = {"a": {0: 1.0, 1: 1.0, 2: 0.0}, "b": {0: 1.0, 1: 1.0, 2: 0.0}}
    apart = simulate_task(rule, "kstar", levels, rates, {}, rng)
    shared = simulate_task(rule, "kstar", levels, rates, {"b": "a"}, rng)
    assert apart.episodes == 50 and shared.episodes == 45  # level 0's 5 episodes once


def test_protocol_sums_its_tasks_and_pilot_uncertainty_widens_it():
    rule = make_rule("kstar", 0.2, 0.1, 0.025, 5, 50)
    lv = {"a": [-2, -1, 0, 1, 2]}
    point = simulate_protocol(rule, "kstar", 4, lv, assumed_curve([0.9, 0.5, 0.1], ["a"], lv), {}, 1000, 100)
    pilot = Curve(counts={"a": {k: (s, 10) for k, s in zip(lv["a"], (1, 5, 9, 5, 1), strict=True)}})
    wide = simulate_protocol(rule, "kstar", 4, lv, pilot, {}, 1000, 100)
    s, w = point.summary(), wide.summary()
    assert s["p5"] <= s["expected"] <= s["p95"] <= 1000
    assert all(sum(r) == t for r, t in zip(point.rounds, point.totals, strict=True))
    assert w["p95"] - w["p5"] > s["p95"] - s["p5"]


def test_assume_needs_a_rate_per_level():
    with pytest.raises(ConfigError, match="one rate per"):
        assumed_curve([0.9, 0.5], ["a"], {"a": [0, 1, 2]})
