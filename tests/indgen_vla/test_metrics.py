import math

import pytest
from scipy.stats import barnard_exact, binomtest, boschloo_exact

from indgen_vla.errors import ConfigError
from indgen_vla.metrics import (
    blackbox_reference,
    break_level,
    break_levels,
    clopper_pearson_ci,
    cochran_armitage,
    compare_levels,
    holm,
    kstar,
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
    assert break_level({0: 0.9, 1: float("nan"), 2: 0.1}) == 2
    # exactly gamma does not break (S < gamma breaks)
    assert break_level({0: 1.0, 1: 0.2}, 0.2) is None


def test_kstar_paper_convention():
    assert kstar({0: 1.0, 1: 1.0, 2: 1.0, 3: 0.0}) == 3
    assert kstar({0: 1.0, 1: 1.0, 2: 1.0, 3: 0.86, 4: 0.5, 5: 0.3}) == 6  # K+1 when none breaks
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
