"""Calibration of the decisions docs/statistics.md lists, asserted in the default suite (seconds): the verdicts at γ
by exact enumeration, the printed real error of a Wilson verdict, the "N more episodes" claim, the CI recipe's pass
chances, the series table's family-wise error (seeded simulation) and the size of compare's two tests. The gate's
size: test_noninferiority."""

from itertools import product

import numpy as np
import pytest
from scipy.stats import binom

from indgen_vla.core.comparison.gate_plan import plan_episodes
from indgen_vla.core.comparison.series_report import _holm_trends, _trend
from indgen_vla.core.reporting.levels import direction_verdict
from indgen_vla.core.stats import operating as oc
from indgen_vla.core.stats.breakpoint import kstar_status, verdict_from_ci
from indgen_vla.core.stats.metrics import exact_2x2, mcnemar_exact, wilson_ci
from indgen_vla.core.stats.noninferiority import pass_chance
from indgen_vla.core.stats.sample_size import verdict_error


@pytest.mark.parametrize("gamma", [0.1, 0.2, 0.5])
def test_clopper_pearson_verdicts_hold_their_level_at_every_n(gamma):
    v = oc.verdict_sizes(gamma, "clopper-pearson", range(5, 301))
    assert v["broken"][0] <= 0.025 and v["intact"][0] <= 0.025


def test_wilson_verdicts_err_above_their_level_and_say_so():
    """Wilson's "intact" at γ = 0.2 errs 5.8 % at n = 5 and 3.3 % at n = 10 (nominal 2.5 %): the verdict line prints
    that chance, computed at its own n."""
    v = oc.verdict_sizes(0.2, "wilson", range(5, 301))
    assert v["intact"] == (pytest.approx(0.05792), 5)
    rows = [{"level": 0, "n": 10, "successes": 10, "rate": 1.0, "ci_low": 0.72, "ci_high": 1.0,
             "insufficient": False, "decision": "intact"}]  # fmt: skip
    line = direction_verdict(rows, None, 0.2)
    assert f"n = 10: {100 * verdict_error(10, 0.2, 'wilson', 'intact'):.1f} %" in line and "3.3 %" in line


@pytest.mark.parametrize("n", [10, 20, 50])
def test_more_episodes_decide_with_the_stated_chance_at_the_observed_rate(n):
    """Every "about N more episodes would decide it" the report prints (γ = 0.2, Wilson) decides the level with
    chance ≥ 80 % if the observed rate is the true one (exact)."""
    for p in (0.05, 0.1, 0.15):
        r = oc.report_projection(p, n, 0.2, "wilson", 0.8)
        assert r["claim_at_observed"] >= 0.8


def test_the_ci_recipe_passes_equal_policies_and_fails_a_20_point_drop():
    """docs/loop.md's recipe (3 levels at 95, 90, 90 %, M = 0.1, the planned episodes, exit 5 a failure): exact."""
    rates = (0.95, 0.9, 0.9)
    n = plan_episodes(rates, 0.1)["episodes"]
    assert pass_chance(rates, n, 0.1, 0.05) >= 0.8
    for at in range(3):
        assert pass_chance(rates, n, 0.1, 0.05, drop=0.2, at=at) <= 0.2


def test_the_series_table_is_holm_corrected():
    """A null series of 5 checkpoints × 7 levels (seeded, 300 series): uncorrected one-sided tests flagged a trend in
    about half of them; Holm keeps the family-wise error near 5 % (300 draws: ±2.5 points)."""
    levels = (0.95, 0.9, 0.8, 0.6, 0.4, 0.3, 0.2)
    assert oc.series_fwer(levels, 50, 5, 300, 3, holm_on=False) > 0.35
    assert oc.series_fwer(levels, 50, 5, 300, 3, holm_on=True) <= 0.075


def test_the_simulated_series_rule_is_the_one_series_runs():
    """``series_flagged`` (what ``series_fwer`` counts) equals the flags of series_report's own ``_trend`` and
    ``_holm_trends`` on 300 seeded series, null and trending, levels that do not vary included: the size above is
    measured on the rule ``indgen series`` prints, not on a copy of it."""
    rng = np.random.default_rng(5)
    steps, n, seen = [1000, 2000, 3000, 4000, 5000], 20, set()
    for i in range(300):
        rates = np.clip(
            rng.choice([0.0, 0.2, 0.5, 0.9, 1.0], 4) + (i % 2) * 0.04 * np.arange(5)[:, None], 0, 1
        )
        counts = rng.binomial(n, rates)
        trend = {
            str(k): _trend(steps, [{"successes": int(c), "n": n} for c in counts[:, k]]) for k in range(4)
        }
        _holm_trends(trend, list(trend))
        real = any(t[f"{side}_holm"] < 0.05 for t in trend.values() for side in ("p_rising", "p_falling"))
        assert oc.series_flagged(counts, n) == real, counts
        seen.add(real)
    assert seen == {True, False}


@pytest.mark.parametrize(
    ("n_a", "n_b", "alpha"), [(5, 5, 0.05), (10, 10, 0.05), (10, 10, 0.025), (6, 12, 0.05)]
)
def test_compares_unpaired_test_holds_its_size(n_a, n_b, alpha):
    """compare's unpaired test (``metrics.exact_2x2``, scipy's Boschloo, whose supremum over the nuisance rate is
    searched numerically) calls equal rates different with chance ≤ α at every common rate (exact sums over all
    tables, 199 rates); Holm over L levels then errs ≤ α at every level's α / L. Measured: 4.2 % at 10 + 10."""
    p = np.array([[exact_2x2(a, n_a, b, n_b) for b in range(n_b + 1)] for a in range(n_a + 1)])
    size = max(float(np.outer(binom.pmf(range(n_a + 1), n_a, r), binom.pmf(range(n_b + 1), n_b, r))[p <= alpha].sum())
               for r in np.linspace(0.005, 0.995, 199))  # fmt: skip
    assert 0 < size <= alpha


@pytest.mark.parametrize("pairs", [10, 20, 50])
def test_compares_paired_test_holds_its_size(pairs):
    """compare's paired test (exact McNemar, ``metrics.mcnemar_exact``) calls equal rates different with chance ≤ 5 %
    whatever the chance d that a pair is discordant (exact sums over the discordant count and its split)."""
    rej = [
        sum(binom.pmf(a, m, 0.5) for a in range(m + 1) if mcnemar_exact(a, m - a) <= 0.05)
        for m in range(pairs + 1)
    ]
    size = max(
        float(binom.pmf(range(pairs + 1), pairs, d) @ np.array(rej)) for d in np.linspace(0.01, 1, 100)
    )
    assert 0 < size <= 0.05


@pytest.mark.parametrize(
    ("rates", "n"), [((0.9, 0.6, 0.2, 0.1), 8), ((0.9, 0.8, 0.7), 12), ((0.95, 0.21, 0.19), 10)]
)
def test_kstar_chances_are_the_sums_over_what_the_report_decides(rates, n):
    """docs/results/statistics.md's k* table (``operating.kstar_wrong``) against brute force: every count of every
    level, each level's verdict from its Wilson interval and k*'s status from ``kstar_status``, as the report has
    them; a level at exactly γ is not a break."""
    true_k = next((k for k, p in enumerate(rates) if p < 0.2), None)
    got = {"right": 0.0, "wrong": 0.0, "undetermined": 0.0}
    for counts in product(range(n + 1), repeat=len(rates)):
        w = float(np.prod([binom.pmf(s, n, p) for s, p in zip(counts, rates, strict=True)]))
        verdicts = {k: verdict_from_ci(*wilson_ci(s, n), 0.2) for k, s in enumerate(counts)}
        st = kstar_status(verdicts, list(range(len(rates))))
        key = "undetermined" if not st["determined"] else "right" if st["earliest"] == true_k else "wrong"
        got[key] += w
    want = oc.kstar_wrong(rates, n, 0.2, "wilson")
    assert got == {k: pytest.approx(want[k], abs=1e-12) for k in got}
