"""Fixed-design episodes and paired power, against binomial cases computed by hand and brute-force enumeration."""

import itertools
import math

import pytest
from scipy.stats import binom

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.breakpoint import verdict_from_ci
from indgen_vla.core.stats.metrics import CI_METHODS, mcnemar_exact, wilson_ci
from indgen_vla.core.stats.sample_size import (
    decided_rates,
    fixed_design,
    pair_probabilities,
    paired_power,
    pairs_for_power,
    stable_episodes,
    verdict_counts,
    verdict_error,
)


def test_four_episodes_decide_095_against_005_at_gamma_half_by_hand():
    """γ = 0.5, δ = 0.45, α = 0.25, Wilson 95 % (z = 1.96, z² = 3.8416). With n successes of n the lower end is
    n/(n + z²): 3/6.84 = 0.439 < 0.5 (n = 3 never decides intact), 4/7.84 = 0.510 >= 0.5. At n = 4, 3/4 has lower
    end 0.301 and 1/4 upper end 0.699, 0/4 upper end z²/(4 + z²) = 0.490 < 0.5: intact only at 4/4, broken only at
    0/4, each with chance 0.95⁴ = 0.8145, so each verdict is missed with chance 0.1855 <= 0.25."""
    assert wilson_ci(4, 4)[0] == pytest.approx(4 / (4 + 1.96**2), abs=1e-3)
    assert verdict_counts(3, 0.5)[0] is None
    assert verdict_counts(4, 0.5) == (4, 0)
    d = fixed_design(0.5, 0.45, 0.25)
    assert d.episodes == 4
    assert d.p_wrong_intact == pytest.approx(1 - 0.95**4)
    assert d.p_wrong_broken == pytest.approx(1 - 0.95**4)


@pytest.mark.parametrize("ci", sorted(CI_METHODS))
def test_verdict_counts_equal_the_report_verdict_at_every_count(ci):
    for n in (1, 2, 5, 13):
        for gamma in (0.1, 0.2, 0.5, 0.8):
            v = [verdict_from_ci(*CI_METHODS[ci](s, n), gamma) for s in range(n + 1)]
            intact = next((s for s, x in enumerate(v) if x == "intact"), None)
            broken = max((s for s, x in enumerate(v) if x == "broken"), default=None)
            assert verdict_counts(n, gamma, ci) == (intact, broken)


def test_decided_rates_are_binomial_tail_sums():
    n, gamma, delta = 30, 0.2, 0.1
    intact, broken = verdict_counts(n, gamma)
    hi = sum(math.comb(n, s) * 0.3**s * 0.7 ** (n - s) for s in range(intact, n + 1))
    lo = sum(math.comb(n, s) * 0.1**s * 0.9 ** (n - s) for s in range(broken + 1))
    assert decided_rates(n, gamma, delta) == (pytest.approx(1 - hi), pytest.approx(1 - lo))


def test_the_found_design_meets_alpha_and_one_fewer_episode_does_not():
    d = fixed_design(0.2, 0.1, 0.025)
    assert d.p_wrong_intact <= 0.025 and d.p_wrong_broken <= 0.025
    assert max(decided_rates(d.episodes - 1, 0.2, 0.1)) > 0.025


def test_paired_power_by_hand():
    """T0 always succeeds, level k always fails (nested): every pair is T0-only, so McNemar's p is 2 · 0.5ⁿ:
    0.0625 at 5 pairs (no), 0.03125 at 6 (yes). At level k = 0.5, nested: a pair is discordant with chance 0.5
    and only 6 of 6 discordant rejects at 6 pairs: power 0.5⁶ = 1/64."""
    assert paired_power(1.0, 0.0, 5, 0.05, "nested") == 0.0
    assert paired_power(1.0, 0.0, 6, 0.05, "nested") == pytest.approx(1.0)
    assert pairs_for_power(1.0, 0.0, 0.05, 0.8, "nested") == 6
    assert paired_power(1.0, 0.5, 6, 0.05, "nested") == pytest.approx(1 / 64)


def test_paired_power_equals_enumeration_of_every_pair_outcome():
    """Independent outcomes, 5 pairs: sum over all 4⁵ joint outcomes of P × [McNemar rejects towards a drop]."""
    p0, p1, n, alpha = 0.9, 0.3, 5, 0.1
    cell = {(1, 0): p0 * (1 - p1), (0, 1): (1 - p0) * p1, (1, 1): p0 * p1, (0, 0): (1 - p0) * (1 - p1)}
    want = 0.0
    for pairs in itertools.product(cell, repeat=n):
        b = sum(x == (1, 0) for x in pairs)
        c = sum(x == (0, 1) for x in pairs)
        if b > c and mcnemar_exact(b, c) <= alpha:
            want += math.prod(cell[x] for x in pairs)
    assert paired_power(p0, p1, n, alpha, "independent") == pytest.approx(want)


def test_bad_inputs_are_one_line_errors():
    with pytest.raises(ConfigError, match="γ − δ"):
        fixed_design(0.1, 0.2, 0.05)
    with pytest.raises(ConfigError, match="pairing model"):
        paired_power(0.9, 0.5, 10, 0.05, "copula")


def test_the_first_passing_n_is_not_stable_and_the_stable_one_is():
    """γ 0.2 ± 0.1, α 0.025, Wilson: 274 is the first n meeting both targets, 275-277, 280, 281, 284 miss again,
    and every n from 285 through 1.5 × 274 meets them (checked here one by one)."""
    design = fixed_design(0.2, 0.1, 0.025)
    stable, fails = stable_episodes(design)
    assert (design.episodes, stable, fails) == (274, 285, [275, 276, 277, 280, 281, 284])
    assert all(max(decided_rates(n, 0.2, 0.1)) <= 0.025 for n in range(285, 412))


def test_the_most_discordant_coupling_is_the_least_power():
    """T0 at 0.95 and level k at 0.75: the most discordant pairs (both succeed only where they must: 0.7) give less
    power than independent outcomes at 50 pairs, which give less than nested ones (the exact test's discreteness can
    swap the first two at other n: budget prints all three)."""
    assert pair_probabilities(0.95, 0.75, "most-discordant") == pytest.approx((0.25, 0.05))
    powers = [paired_power(0.95, 0.75, 50, 0.05 / 6, m) for m in ("most-discordant", "independent", "nested")]
    assert powers == sorted(powers) and powers[0] < powers[2]


def test_verdict_error_is_the_exact_tail_at_gamma():
    """Wilson at n = 10, γ = 0.2: 5/10 has lower end 0.237 ≥ 0.2 (intact) and 4/10 0.168: P(S ≥ 5 | 0.2) = 3.28 %,
    above the nominal 2.5 %; Clopper–Pearson stays below it at every n up to 300."""
    assert verdict_error(10, 0.2, "wilson", "intact") == pytest.approx(1 - binom.cdf(4, 10, 0.2))
    assert verdict_error(10, 0.2, "wilson", "intact") > 0.025
    for n in range(5, 301, 7):
        assert verdict_error(n, 0.2, "clopper-pearson", "intact") <= 0.025
        assert verdict_error(n, 0.2, "clopper-pearson", "broken") <= 0.025
