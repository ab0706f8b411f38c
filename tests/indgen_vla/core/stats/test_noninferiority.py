"""The gate's paired non-inferiority test: Tango's statistic against a numerical restricted MLE, its exact p-value and
critical value agreeing, its size at the margin by exact enumeration, and the projections' sums."""

import math

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from scipy.stats import norm

from indgen_vla.core.stats import noninferiority as ni
from indgen_vla.core.stats.contrasts import paired_difference_ci
from indgen_vla.core.stats.operating import exact_size, newcombe_lower_cells


@pytest.mark.parametrize("x,y,n,m", [(5, 2, 30, 0.1), (0, 0, 25, 0.1), (10, 3, 50, 0.2), (3, 12, 40, 0.1),
                                     (0, 5, 20, 0.15), (7, 0, 60, 0.05)])  # fmt: skip
def test_tango_statistic_uses_the_restricted_mle(x, y, n, m):
    """Z = (y − x + nM) / sqrt(n (q̃x + q̃y − M²)) with (q̃x, q̃y = q̃x − M) maximising the trinomial likelihood."""

    def nll(q):
        terms = [(x, q), (y, q - m), (n - x - y, 1 - 2 * q + m)]
        return -sum(k * math.log(p) for k, p in terms if k)

    q = minimize_scalar(nll, bounds=(m + 1e-12, (1 + m) / 2 - 1e-12), method="bounded",
                        options={"xatol": 1e-13}).x  # fmt: skip
    want = (y - x + n * m) / math.sqrt(n * (2 * q - m - m * m))
    assert float(ni.tango_z(x, y, n, m)) == pytest.approx(want, rel=1e-6, abs=1e-6)


def test_the_p_value_and_the_critical_value_agree_on_every_table():
    n, m, a = 18, 0.1, 0.05
    for x in range(n + 1):
        for y in range(n + 1 - x):
            assert (ni.p_value(x, y, n, m) <= a + 1e-12) == ni.non_inferior(x, y, n, m, a), (x, y)


def test_perfect_runs_need_the_exact_count():
    """No discordant pair: its chance at the boundary point (A-only with chance M, never B-only) is (1 − M)^n, the
    largest over the boundary; so M = 0.1 needs 0.9^n ≤ 0.05, n ≥ 29."""
    assert ni.p_value(0, 0, 28, 0.1) == pytest.approx(0.9**28, rel=1e-9)
    assert not ni.non_inferior(0, 0, 28, 0.1, 0.05) and ni.non_inferior(0, 0, 29, 0.1, 0.05)


@pytest.mark.parametrize(
    "n,m", [(10, 0.1), (25, 0.1), (50, 0.1), (100, 0.1), (15, 0.2), (40, 0.2), (60, 0.05)]
)
def test_the_size_holds_at_the_margin(n, m):
    """Exact enumeration over every table at 400 boundary points apart from the test's own: the chance of calling
    a level non-inferior when Δ = −M is at most α, plus 0.1 point for the supremum taken on a grid."""
    assert exact_size(n, m, 0.05)["size"] <= 0.05 + 0.001


def test_newcombes_interval_erred_above_its_level():
    """The gate before: Newcombe's interval (vectorised here, checked against contrasts.paired_difference_ci) called a
    level non-inferior at Δ = −0.1 with chance 7.2 % at 25 pairs when every pair had the same outcome but 10 %."""
    rng = np.random.default_rng(0)
    for _ in range(50):
        c = rng.multinomial(40, [0.4, 0.2, 0.1, 0.3])
        assert newcombe_lower_cells(*c, 0.9) == pytest.approx(paired_difference_ci(*c, 0.9)[0], abs=1e-12)
    both, x, y, nei = np.zeros(1), np.zeros(1), np.zeros(1), np.full(1, 25.0)
    assert (
        newcombe_lower_cells(both, x, y, nei, 0.9)[0] > -0.1
    )  # 0/0 of 25: passed, with chance 0.9^25 = 7.2 %


def test_power_and_conditional_power_are_the_sums_they_say():
    n, m, a = 40, 0.1, 0.05
    crit = ni.critical_z(n, m, a)
    pmf = ni.trinomial_pmf(n, 0.1, 0.1)
    xs, ys, _ = ni._tables(n)
    assert ni.power(n, 0.1, 0.1, m, a) == pytest.approx(pmf[ni.tango_z(xs, ys, n, m) >= crit - 1e-12].sum())
    # 20 pairs seen (2 A-only, 1 B-only), 20 more: the second stage's tables, the first kept
    want = sum(w for (ex, ey), w in zip(zip(*ni._tables(20)[:2], strict=True), ni.trinomial_pmf(20, 0.1, 0.05), strict=True)
               if ni.non_inferior(2 + ex, 1 + ey, 40, m, a))  # fmt: skip
    assert ni.conditional_power(2, 1, 20, 20, 0.1, 0.05, m, a) == pytest.approx(want)
    assert ni.critical_z(ni.N_EXACT + 1, m, a) == pytest.approx(norm.isf(a))


@pytest.mark.parametrize("n,m", [(10, 0.1), (25, 0.1), (50, 0.2), (40, 0.05)])
def test_the_unpaired_size_holds_where_the_interval_alone_did_not(n, m):
    from indgen_vla.core.stats.operating import unpaired_size

    assert unpaired_size(n, m, 0.05, exact=True, grid=200) <= 0.05 + 0.001
    if (n, m) == (25, 0.1):
        assert unpaired_size(n, m, 0.05, exact=False, grid=200) > 0.07  # the MOVER interval alone: 7.2 %


def test_the_reports_equivalence_holds_its_size_where_newcombes_did_not():
    from indgen_vla.core.stats.operating import equivalence_size

    assert equivalence_size(50, 0.2, 0.05, exact=True, rates=(0.5, 0.7)) <= 0.05 + 0.001
    assert equivalence_size(25, 0.1, 0.05, exact=False) > 0.07  # Newcombe inside ±M: 7.2 %


def test_the_projection_reaches_the_chance_it_prints():
    """20 pairs, 1 A-only and 1 B-only: the extra pairs printed decide the level with chance >= 80 % at the observed
    frequencies (the chance returned is the exact sum over the extra pairs' tables)."""
    extra, ni_likelier, chance = ni.project_pairs(1, 1, 20, 0.1, 0.05, 0.05, 0.8, 5000)
    assert ni_likelier and chance >= 0.8
    assert chance == pytest.approx(ni.conditional_power(1, 1, 20, extra, 0.05, 0.05, 0.1, 0.05))
