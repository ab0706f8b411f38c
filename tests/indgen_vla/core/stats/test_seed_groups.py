"""Group statistics against hand-computed values and scipy."""

import math

import pytest
from scipy import stats

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.seed_groups import mean_difference, ood_area, stratified_mcnemar, tost


def test_stratified_mcnemar_pools_discordant_pairs():
    # one stratum: exact McNemar = two-sided binomial on the discordant pairs, by hand: 1 vs 7 of 8
    r = stratified_mcnemar([(1, 7, 30)])
    hand = 2 * sum(math.comb(8, k) for k in (0, 1)) / 2**8  # P(X <= 1) doubled, X ~ Bin(8, 1/2)
    assert (r.a_only, r.b_only, r.pairs) == (1, 7, 30) and r.p_value == pytest.approx(hand)
    # three strata pool their discordant counts
    r = stratified_mcnemar([(0, 3, 30), (1, 2, 30), (0, 4, 30)])
    assert (r.a_only, r.b_only, r.pairs) == (1, 9, 90)
    assert r.p_value == pytest.approx(stats.binomtest(1, 10, 0.5).pvalue)
    assert stratified_mcnemar([(0, 0, 30)]).p_value == 1.0
    with pytest.raises(ConfigError):
        stratified_mcnemar([(5, 5, 8)])
    with pytest.raises(ConfigError):
        stratified_mcnemar([])


def test_mean_difference_is_welch():
    a, b = [0.2, 0.3, 0.25], [0.5, 0.45, 0.7]
    r = mean_difference(a, b)
    va, vb = stats.tvar(a) / 3, stats.tvar(b) / 3
    df = (va + vb) ** 2 / (va**2 / 2 + vb**2 / 2)
    half = stats.t.ppf(0.975, df) * math.sqrt(va + vb)
    d = sum(b) / 3 - sum(a) / 3
    assert r.diff == pytest.approx(d) and (r.ci_low, r.ci_high) == pytest.approx((d - half, d + half))
    # scipy's Welch test agrees: the interval excludes 0 exactly when p < 0.05
    p = stats.ttest_ind(b, a, equal_var=False).pvalue
    assert (r.ci_low > 0) == (p < 0.05)
    one = mean_difference([0.2], [0.4])
    assert one.diff == pytest.approx(0.2) and math.isnan(one.ci_low)


def test_tost_by_hand():
    a, b = [0.50, 0.52, 0.48], [0.51, 0.53, 0.49]  # nearly equal: equivalent within ±0.1
    d = 0.01
    se = math.sqrt(stats.tvar(a) / 3 + stats.tvar(b) / 3)
    df = 4.0  # equal variances and sizes: Welch df = 2(n-1)
    want = max(stats.t.sf((d + 0.1) / se, df), stats.t.cdf((d - 0.1) / se, df))
    assert tost(a, b, 0.1) == pytest.approx(want) and want < 0.05
    assert tost([0.1, 0.2, 0.15], [0.6, 0.7, 0.65], 0.1) > 0.5  # far apart: not equivalent
    assert math.isnan(tost([0.1], [0.2, 0.3], 0.1))
    with pytest.raises(ConfigError):
        tost(a, b, 0)


def test_ood_area():
    assert ood_area({-1: 0.5, 0: 1.0, 1: 0.3, 2: 0.1}) == pytest.approx(0.3)
    with pytest.raises(ConfigError):
        ood_area({0: 1.0, 1: float("nan")})


def test_no_spread_across_seeds_claims_neither_an_interval_nor_equivalence():
    """Three seeds at 100 % on both sides: the t-test is undefined, so no zero-width CI and no TOST p = 0."""
    same = [1.0, 1.0, 1.0]
    assert math.isnan(tost(same, same, 0.1))
    diff = mean_difference(same, same)
    assert diff.diff == 0 and math.isnan(diff.ci_low) and math.isnan(diff.ci_high)
