import math

import pytest
from scipy.stats import barnard_exact, binomtest, boschloo_exact

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.metrics import (
    UndeterminedBreakError,
    below_floor,
    blackbox_reference,
    break_level,
    break_levels,
    clopper_pearson_ci,
    cochran_armitage,
    compare_levels,
    compare_paired_levels,
    difference_ci,
    holm,
    isotonic_decreasing,
    kstar,
    mcnemar_exact,
    monotone_decreasing_test,
    rollouts_needed,
    success_rate,
    wilson_ci,
    wilson_half_width,
)


def test_wilson_hand_value():
    # 7/10, z = 1.959964: centre (0.7 + 0.19207)/1.38415 = 0.64449, half 0.24772
    lo, hi = wilson_ci(7, 10)
    assert lo == pytest.approx(0.39678, abs=1e-5)
    assert hi == pytest.approx(0.89221, abs=1e-5)


@pytest.mark.parametrize("k,n", [(0, 5), (5, 5), (3, 50), (25, 50), (49, 50), (1, 1)])
def test_cis_match_scipy(k, n):
    r = binomtest(k, n)
    w = r.proportion_ci(method="wilson")
    e = r.proportion_ci(method="exact")
    assert wilson_ci(k, n) == pytest.approx((w.low, w.high), abs=1e-12)
    assert clopper_pearson_ci(k, n) == pytest.approx((e.low, e.high), abs=1e-12)


def test_normal_quantiles_are_scipy_stats_norm_bit_for_bit():
    # metrics uses scipy.special's ndtri/ndtr instead of importing scipy.stats (~1 s at start-up); reports
    # must not change by one bit (scipy/stats/_continuous_distns.py: norm._ppf = ndtri, _cdf = ndtr, _sf(x) = ndtr(-x))
    from scipy.stats import norm

    from indgen_vla.core.stats.metrics import _z

    for conf in (0.5, 0.8, 0.9, 0.95, 0.99, 0.999):
        assert _z(conf) == float(norm.ppf(0.5 + conf / 2))
    for x in ([9, 5, 1], [3, 5, 4], [1, 4, 9], [10, 0, 10]):
        t = cochran_armitage([0, 1, 2], x, [10, 10, 10])
        assert t.p_decreasing == float(norm.cdf(t.statistic))
        assert t.p_two_sided == float(2 * norm.sf(abs(t.statistic)))


def test_difference_ci_is_newcombes_method_10():
    # Newcombe (1998), Stat. Med. 17:873, Table II example (a): 56/70 − 48/80 = 0.2000, 95 % CI 0.0524 to 0.3339
    a, b = (56 / 70, *wilson_ci(56, 70)), (48 / 80, *wilson_ci(48, 80))
    lo, hi = difference_ci(a, b)
    assert lo == pytest.approx(0.0524, abs=5e-5) and hi == pytest.approx(0.3339, abs=5e-5)
    # example (h): 10/10 − 0/10 = 1, CI 0.6075 to 1 (the interval of a sure drop stays inside [−1, 1])
    lo, hi = difference_ci((1.0, *wilson_ci(10, 10)), (0.0, *wilson_ci(0, 10)))
    assert lo == pytest.approx(0.6075, abs=5e-5) and hi == pytest.approx(1.0)


def test_clopper_pearson_edges_hand():
    # 0/10: upper = 1 - 0.025**(1/10) = 0.30850
    lo, hi = clopper_pearson_ci(0, 10)
    assert lo == 0.0 and hi == pytest.approx(1 - 0.025**0.1, abs=1e-12)
    assert clopper_pearson_ci(10, 10)[1] == 1.0


def test_empty_and_bad_counts():
    assert wilson_ci(0, 0) == (0.0, 1.0)
    assert math.isnan(success_rate(0, 0).rate)
    with pytest.raises(ConfigError):
        wilson_ci(3, 2)
    with pytest.raises(ConfigError):
        success_rate(1, 2, method="agresti")


def test_break_level_per_direction():
    rates = {-3: 0.0, -2: 0.1, -1: 0.5, 0: 0.9, 1: 0.6, 2: 0.25, 3: 0.19}
    assert break_levels(rates, 0.2) == {"pos": 3, "neg": -2}
    assert break_levels({0: 0.9, 1: 0.8}, 0.2) == {"pos": None}
    assert break_level({0: 0.1, 1: 0.9}) == 0
    # a level without usable data before the break is a hole: k* is undetermined, never skipped over
    with pytest.raises(UndeterminedBreakError, match="level 1 has no usable data"):
        break_level({0: 0.9, 1: float("nan"), 2: 0.1})
    assert break_level({0: 0.9, 1: 0.1, 2: float("nan")}) == 1  # a hole after the break does not matter
    assert break_levels({-2: 0.0, -1: float("nan"), 0: 0.9, 1: 0.1}, signed=True) == {
        "pos": 1,
        "neg": "undetermined",
    }
    with pytest.raises(UndeterminedBreakError):  # no break, but the last level is unknown
        break_level({0: 0.9, 1: 0.8, 2: float("nan")})
    # exactly gamma does not break (S < gamma breaks)
    assert break_level({0: 1.0, 1: 0.2}, 0.2) is None


def test_kstar_paper_convention():
    assert kstar({0: 1.0, 1: 1.0, 2: 1.0, 3: 0.0}) == 3
    assert kstar({0: 1.0, 1: 1.0, 2: 1.0, 3: 0.86, 4: 0.5, 5: 0.3}) == 6  # K+1 when none breaks
    # negative side: K+1 is one step beyond the extreme level in that direction, -4 over 0..-3
    assert kstar({0: 1.0, -1: 0.9, -2: 0.8, -3: 0.5}) == -4
    assert kstar({0: 1.0, -1: 0.9, -2: 0.1, -3: 0.5}) == -2
    with pytest.raises(ConfigError, match="one direction"):
        kstar({-1: 0.9, 0: 1.0, 1: 0.9})
    with pytest.raises(ConfigError):
        break_level({0: 1.0}, gamma=0)


def test_blackbox_reference():
    cfg, mean = blackbox_reference({"a": [0.5, 0.7], "b": [0.9, 0.8], "c": [1.0, 0.0]})
    assert cfg == "b" and mean == pytest.approx(0.85)
    with pytest.raises(ConfigError):
        blackbox_reference({})


def test_cochran_armitage_hand_value():
    # scores 0,1,2; x = 9,5,1 of n = 10 each. p = 0.5, T = 0*4 + 1*0 + 2*(-4) = -8
    # Var = 0.25 * (10*(0+1+4) - (30)^2/30) = 0.25 * (50 - 30) = 5; z = -8/sqrt(5) = -3.5777
    t = cochran_armitage([0, 1, 2], [9, 5, 1], [10, 10, 10])
    assert t.statistic == pytest.approx(-8 / math.sqrt(5))
    assert t.p_decreasing == pytest.approx(0.000173, rel=1e-2)
    flat = cochran_armitage([0, 1], [5, 5], [5, 5])  # all successes: no trend evidence
    assert flat.p_decreasing == 0.5


def test_holm_hand_value():
    assert holm([0.01, 0.04, 0.03, 0.005]) == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])
    assert holm([]) == []


def test_compare_levels_matches_scipy():
    a = {0: (45, 50), 1: (30, 50), 2: (5, 50)}
    b = {0: (44, 50), 1: (10, 50), 2: (5, 50), 3: (0, 50)}
    rows = compare_levels(a, b, test="boschloo")
    assert [r["level"] for r in rows] == [0, 1, 2]
    p1 = boschloo_exact([[30, 10], [20, 40]], alternative="two-sided").pvalue
    p0 = boschloo_exact([[45, 44], [5, 6]], alternative="two-sided").pvalue
    assert rows[1]["p_value"] == pytest.approx(p1)
    assert rows[0]["p_value"] == pytest.approx(p0)
    assert rows[2]["p_value"] == 1.0  # identical tables
    assert rows[1]["p_holm"] == pytest.approx(min(1, 3 * p1))
    barn = compare_levels({0: (8, 10)}, {0: (2, 10)}, test="barnard")[0]["p_value"]
    assert barn == pytest.approx(barnard_exact([[8, 2], [2, 8]]).pvalue)


def test_rollouts_needed():
    assert rollouts_needed(0.1) == 93  # hand-computed: n=92 gives 0.1001, n=93 gives 0.0996
    assert wilson_half_width(93) <= 0.1 < wilson_half_width(92)
    assert rollouts_needed(0.1, p=0.9) < 93
    with pytest.raises(ConfigError):
        rollouts_needed(0.7)


def test_data_floor():
    assert below_floor(4) and not below_floor(5)
    assert below_floor(24, planned=50) and not below_floor(25, planned=50)  # fewer than half planned
    assert below_floor(1, planned=4) and not below_floor(5, planned=None)


def test_isotonic_pava_hand_values():
    # 0.5 < 0.7 rises: pool with weights 10, 30 -> (5 + 21) / 40 = 0.65
    assert isotonic_decreasing([0.9, 0.5, 0.7, 0.1], [10, 10, 30, 10]) == pytest.approx(
        [0.9, 0.65, 0.65, 0.1]
    )
    # 0.2 < 0.6: pool -> 0.4, which equals the next value: all 0.4
    assert isotonic_decreasing([0.2, 0.6, 0.4], [10, 10, 10]) == pytest.approx([0.4, 0.4, 0.4])
    assert isotonic_decreasing([1.0, 0.5], [3, 1]) == [1.0, 0.5]  # already non-increasing


def test_monotone_test_hand_values():
    # x = 9, 5, 1 of 10: already decreasing, so the isotonic fit is the raw rates; common rate 0.5.
    t = monotone_decreasing_test([9, 5, 1], [10, 10, 10])
    ll_fit = 2 * (9 * math.log(0.9) + math.log(0.1)) + 10 * math.log(0.5)
    assert t.fitted == pytest.approx((0.9, 0.5, 0.1))
    assert t.statistic == pytest.approx(2 * (ll_fit - 30 * math.log(0.5)))
    assert t.method == "exact" and t.p_decreasing < 0.001
    # two levels of 2 episodes, 2 successes in all: tables (2,0), (1,1), (0,2) have null probabilities
    # 1/6, 4/6, 1/6; only (2,0) shows a decrease, so the exact p-value is 1/6.
    t = monotone_decreasing_test([2, 0], [2, 2])
    assert t.p_decreasing == pytest.approx(1 / 6)
    assert t.statistic == pytest.approx(8 * math.log(2))  # fit (1, 0): 2·(0 − 4 ln ½)
    rising = monotone_decreasing_test([1, 5, 9], [10, 10, 10])  # rises: the fit pools to one rate
    assert rising.statistic == 0.0 and rising.p_decreasing == 1.0
    with pytest.raises(ConfigError, match="n = 0"):
        monotone_decreasing_test([0, 1], [0, 3])


def test_monotone_test_matches_chi_bar_squared_for_large_n():
    from scipy.stats import chi2

    # Three equal-n levels: the LRT's null is 1/3·χ²0 + 1/2·χ²1 + 1/6·χ²2 (level probabilities of the
    # simple order, Robertson et al. 1988); the Monte Carlo permutation p-value must agree for large n.
    t = monotone_decreasing_test([1040, 1000, 980], [2000, 2000, 2000], draws=10000)
    assert t.method.startswith("monte carlo")
    asymptotic = 0.5 * chi2.sf(t.statistic, 1) + chi2.sf(t.statistic, 2) / 6
    assert 0.005 < asymptotic < 0.2 and t.p_decreasing == pytest.approx(asymptotic, abs=0.008)
    # a curve that holds then collapses: monotone but far from linear; both tests see it
    t = monotone_decreasing_test([10, 10, 10, 10, 0], [10] * 5)
    assert t.p_decreasing < 0.001


def test_mcnemar_is_binomtest_on_discordant_pairs():
    assert mcnemar_exact(8, 1) == pytest.approx(binomtest(8, 9, 0.5).pvalue)
    assert mcnemar_exact(8, 1) == pytest.approx(2 * 10 / 512)  # hand: 2·(C(9,0)+C(9,1))/2^9
    assert mcnemar_exact(0, 0) == 1.0
    for a in range(25):  # the binomial-CDF form equals scipy's binomtest everywhere, ties (p = 1) included
        for b in range(25):
            if a + b:
                assert mcnemar_exact(a, b) == pytest.approx(
                    binomtest(a, a + b, 0.5).pvalue, rel=1e-9, abs=1e-300
                )
    pairs = {
        0: [(True, True)] * 9 + [(True, False)],
        1: [(True, False)] * 8 + [(False, True)] + [(False, False)] * 3,
    }
    rows = compare_paired_levels(pairs)
    r1 = rows[1]
    assert (r1["pairs"], r1["a_only"], r1["b_only"], r1["successes_a"], r1["successes_b"]) == (12, 8, 1, 8, 1)
    assert r1["p_value"] == pytest.approx(binomtest(8, 9).pvalue)
    assert rows[0]["p_value"] == 1.0 and r1["p_holm"] == pytest.approx(min(1.0, 2 * r1["p_value"]))
