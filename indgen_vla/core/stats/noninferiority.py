"""Paired non-inferiority of two success rates (``indgen gate``): H0 Δ = p_B − p_A ≤ −M against Δ > −M, tested with
an exact unconditional test on Tango's score statistic, so its size holds at the margin for every n it runs at.

Tango's (1998) score statistic orders the tables; its p-value is the largest tail probability over the nuisance
parameter (the share of discordant pairs) on the boundary Δ = −M, summed exactly over the trinomial of the discordant
counts (Berger & Sidik 2003 call it the exact unconditional test). The asymptotic score test alone errs above its
level at small n (docs/statistics.md); beyond ``N_EXACT`` pairs the asymptotic test is used, whose measured size there
the same page lists. Power and the "more pairs would decide it" projections are exact sums over the same tables.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.sample_size import first_extra, paired_power

# pairs up to which the test is exact (about 1-3 s for a new n of 1000); beyond, Tango's asymptotic score test
N_EXACT = 1000
TIE = 1e-12  # statistics closer than this are one value: the test compares with this tolerance
GRID = 160  # nuisance values on the boundary Δ = −M over which the tail's supremum is taken


def _check(n: int, margin: float, alpha: float) -> None:
    if n < 1:
        raise ConfigError(f"need at least one pair, got {n}")
    if not 0 < margin < 1:
        raise ConfigError(f"margin must be in (0, 1), got {margin}")
    if not 0 < alpha < 0.5:
        raise ConfigError(f"alpha must be in (0, 0.5), got {alpha}")


def tango_z(x, y, n: int, margin: float):
    """Tango's score statistic for H0 Δ = −margin: large when B is no worse. ``x``: pairs where only A (baseline)
    succeeded, ``y``: only B (candidate); arrays or numbers. The variance is at the restricted MLE of the
    A-only probability, the root of 2n q² − [(x + y) + M(2n + x − y)] q + x M (1 + M) = 0 that keeps q − M ≥ 0."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    m = margin
    b = (x + y) + m * (2 * n + x - y)
    q = (b + np.sqrt(np.maximum(b * b - 8 * n * x * m * (1 + m), 0.0))) / (4 * n)
    var = n * (2 * q - m * (1 + m))
    num = y - x + n * m
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(var > 1e-12, num / np.sqrt(np.maximum(var, 1e-300)), np.sign(num) * np.inf)
    return z


@lru_cache(maxsize=64)
def _tables(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (A-only, B-only) count of n pairs and its log multinomial coefficient."""
    x, y = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = x + y <= n
    x, y = x[keep], y[keep]
    lg = math.lgamma(n + 1) - _lgam(x + 1) - _lgam(y + 1) - _lgam(n - x - y + 1)
    return x, y, lg


def _lgam(a: np.ndarray) -> np.ndarray:
    from scipy.special import gammaln

    return gammaln(a)


def trinomial_pmf(n: int, q_x: float, q_y: float) -> np.ndarray:
    """P(A-only = x, B-only = y) over ``_tables(n)`` for discordant probabilities ``q_x``, ``q_y``."""
    x, y, lg = _tables(n)
    with np.errstate(divide="ignore", invalid="ignore"):
        lp = lg + _xlog(x, q_x) + _xlog(y, q_y) + _xlog(n - x - y, 1 - q_x - q_y)
    return np.exp(lp)


def _xlog(k: np.ndarray, p: float) -> np.ndarray:
    """k · log p with 0 · log 0 = 0."""
    if p <= 0:
        return np.where(k > 0, -np.inf, 0.0)
    return k * math.log(p)


def _nuisance(margin: float, grid: int = GRID) -> np.ndarray:
    """A-only probabilities q_x on the boundary (q_y = q_x − M ≥ 0, q_x + q_y ≤ 1), denser near the ends."""
    lo, hi = margin, (1 + margin) / 2
    u = (1 - np.cos(np.linspace(0, math.pi, grid))) / 2
    return lo + (hi - lo) * u


@lru_cache(maxsize=256)
def critical_z(n: int, margin: float, alpha: float) -> float:
    """The least z with sup over the boundary of P(Z ≥ z) ≤ α: the test rejects H0 (non-inferior) when Z ≥ this.
    Exact for n ≤ ``N_EXACT``; beyond, the normal quantile (the asymptotic score test)."""
    _check(n, margin, alpha)
    if n > N_EXACT:
        from scipy.stats import norm

        return float(norm.isf(alpha))
    x, y, _ = _tables(n)
    z = tango_z(x, y, n, margin)
    order = np.argsort(-z, kind="stable")
    zs = z[order]
    sup = np.zeros(len(zs))
    for q in _nuisance(margin):
        np.maximum(sup, np.cumsum(trinomial_pmf(n, q, q - margin)[order]), out=sup)
    # a cut must not split tied statistics: the tail at index i counts every table with z ≥ zs[i]
    last_of_tie = np.r_[zs[:-1] - zs[1:] > TIE, True]
    ok = (sup <= alpha) & last_of_tie
    if not ok.any():
        return math.inf
    return float(zs[np.flatnonzero(ok)[-1]])


def p_value(x: int, y: int, n: int, margin: float) -> float:
    """The exact unconditional p-value of (x A-only, y B-only of n pairs) against Δ ≤ −margin (asymptotic past
    ``N_EXACT``)."""
    z0 = float(tango_z(x, y, n, margin))
    if n > N_EXACT:
        from scipy.stats import norm

        return float(norm.sf(z0))
    xs, ys, _ = _tables(n)
    tail = tango_z(xs, ys, n, margin) >= z0 - TIE
    return float(min(1.0, max(trinomial_pmf(n, q, q - margin)[tail].sum() for q in _nuisance(margin))))


def non_inferior(x: int, y: int, n: int, margin: float, alpha: float) -> bool:
    """Whether the pairs show B no worse than A by more than ``margin`` at one-sided level ``alpha``."""
    return bool(tango_z(x, y, n, margin) >= critical_z(n, margin, alpha) - TIE)


def power(n: int, q_x: float, q_y: float, margin: float, alpha: float) -> float:
    """P(non-inferiority shown) with n pairs whose A-only and B-only probabilities are ``q_x``, ``q_y``."""
    crit = critical_z(n, margin, alpha)
    x, y, _ = _tables(n) if n <= N_EXACT else _tables_sparse(n, q_x, q_y)
    rej = tango_z(x, y, n, margin) >= crit - TIE
    return float(min(1.0, trinomial_pmf_any(n, x, y, q_x, q_y)[rej].sum()))


def _tables_sparse(n: int, q_x: float, q_y: float):
    """The tables carrying all but ~1e-12 of the mass past ``N_EXACT`` (a window of ±9 sd around the means)."""

    def window(q: float) -> np.ndarray:
        sd = math.sqrt(max(n * q * (1 - q), 1.0))
        return np.arange(max(0, int(n * q - 9 * sd)), min(n, int(n * q + 9 * sd)) + 1)

    x, y = np.meshgrid(window(q_x), window(q_y), indexing="ij")
    keep = x + y <= n
    return x[keep], y[keep], None


def trinomial_pmf_any(n: int, x: np.ndarray, y: np.ndarray, q_x: float, q_y: float) -> np.ndarray:
    """Trinomial probabilities of the given (x, y) tables."""
    lg = math.lgamma(n + 1) - _lgam(x + 1) - _lgam(y + 1) - _lgam(n - x - y + 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.exp(lg + _xlog(x, q_x) + _xlog(y, q_y) + _xlog(n - x - y, 1 - q_x - q_y))


def _tables_for(n: int, q_x: float, q_y: float):
    """The (x, y) tables of n pairs worth summing over: all of them up to ``N_EXACT``, else the mass-carrying window."""
    if n <= N_EXACT:
        return _tables(n)[:2]
    return _tables_sparse(n, q_x, q_y)[:2]


def conditional_power(x: int, y: int, n: int, extra: int, q_x: float, q_y: float, margin: float,
                      alpha: float) -> float:  # fmt: skip
    """P(non-inferiority shown on all n + extra pairs) when the first n gave (x, y) and the extra pairs' A-only and
    B-only probabilities are ``q_x``, ``q_y``."""
    total = n + extra
    crit = critical_z(total, margin, alpha)
    ex, ey = _tables_for(extra, q_x, q_y)
    rej = tango_z(x + ex, y + ey, total, margin) >= crit - TIE
    return float(min(1.0, trinomial_pmf_any(extra, ex, ey, q_x, q_y)[rej].sum()))


def conditional_power_worse(x: int, y: int, extra: int, q_x: float, q_y: float, alpha: float) -> float:
    """P(the two-sided exact McNemar test at ``alpha`` finds B below A after ``extra`` more pairs), the first pairs
    having given x A-only and y B-only."""
    from scipy.stats import binom

    ex, ey = _tables_for(extra, q_x, q_y)
    a, b = x + ex, y + ey
    m = a + b
    # the two-sided exact McNemar p of (a, b) with a > b is 2 P(Bin(m, 1/2) ≤ b)
    p = np.minimum(1.0, 2 * binom.cdf(np.minimum(a, b), m, 0.5))
    rej = (a > b) & (p < alpha)
    return float(min(1.0, trinomial_pmf_any(extra, ex, ey, q_x, q_y)[rej].sum()))


def project_pairs(x: int, y: int, n: int, margin: float, alpha: float, alpha_worse: float, power: float, cap: int,
                  floor: int = 1) -> tuple[int, bool, float] | None:  # fmt: skip
    """The gate's "N more pairs would decide it": the fewest extra pairs (doubling, then bisection) after which,
    if the observed pair frequencies are the true ones, the level is shown non-inferior or worse (two-sided exact
    McNemar at ``alpha_worse``) with chance ≥ ``power``, the first n pairs kept: (extra, non-inferior is the likelier,
    that chance); None when no number up to ``cap`` does."""
    qx, qy = x / n, y / n
    chances: dict[int, tuple[float, float]] = {}

    def decides(extra: int) -> bool:
        if extra + n < floor:
            return False
        chances[extra] = (conditional_power(x, y, n, extra, qx, qy, margin, alpha),
                          conditional_power_worse(x, y, extra, qx, qy, alpha_worse))  # fmt: skip
        return max(chances[extra]) >= power

    extra = first_extra(decides, cap)
    if extra is None:
        return None
    p_ni, p_worse = chances[extra]
    return extra, p_ni >= p_worse, max(p_ni, p_worse)


def pair_model(p_a: float, p_b: float, model: str = "independent") -> tuple[float, float]:
    """(A-only, B-only) probabilities of a pair with marginal rates p_a, p_b: ``independent`` outcomes, or the
    ``most-discordant`` coupling (the fewest concordant pairs the rates allow: the least power at Δ = 0)."""
    if model == "independent":
        return p_a * (1 - p_b), (1 - p_a) * p_b
    if model == "most-discordant":
        both = max(0.0, p_a + p_b - 1)
        return p_a - both, p_b - both
    raise ConfigError(f"pairing model must be independent or most-discordant, got {model!r}")


def smallest_visible_drop(n: int, p_a: float, alpha_worse: float, power_target: float = 0.8,
                          model: str = "independent") -> float | None:  # fmt: skip
    """The smallest drop d (B at p_a − d) the gate's "worse" test (two-sided exact McNemar at ``alpha_worse``) calls
    worse with chance ≥ ``power_target`` with n pairs at A's rate ``p_a``; None when no drop to 0 reaches it."""
    m = "nested" if model == "nested" else "independent"
    lo, hi = 0.0, p_a
    if paired_power(p_a, 0.0, n, alpha_worse, m) < power_target:
        return None
    for _ in range(16):  # to 1e-5 of a rate
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if paired_power(p_a, p_a - mid, n, alpha_worse, m) >= power_target else (mid, hi)
    return hi


def _wilson(s: np.ndarray, n: int, conf: float) -> tuple[np.ndarray, np.ndarray]:
    """Wilson bounds of s of n, vectorised (``metrics.wilson_ci``)."""
    from scipy.stats import norm

    z = float(norm.isf((1 - conf) / 2))
    p = s / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z / denom * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return np.maximum(0.0, centre - half), np.minimum(1.0, centre + half)


def unpaired_conditional_power(sa: int, na: int, sb: int, nb: int, extra: int, margin: float, alpha: float,
                               alpha_worse: float) -> tuple[float, float]:  # fmt: skip
    """(P the unpaired non-inferiority test passes, P the MOVER interval at 1 − α_worse lies below 0) after ``extra``
    more episodes in each run, drawn at the observed rates, the first ones kept: exact sums over the two binomials."""
    from scipy.stats import binom

    pa, pb = sa / na, sb / nb

    def window(p: float) -> np.ndarray:
        if extra <= 400:
            return np.arange(extra + 1)
        sd = math.sqrt(max(extra * p * (1 - p), 1.0))
        return np.arange(max(0, int(extra * p - 9 * sd)), min(extra, int(extra * p + 9 * sd)) + 1)

    xa, xb = np.meshgrid(window(pa), window(pb), indexing="ij")
    w = binom.pmf(xa, extra, pa) * binom.pmf(xb, extra, pb)
    ta, tb = na + extra, nb + extra
    ra, rb = (sa + xa) / ta, (sb + xb) / tb
    ni_ok = (
        mover_lower(sa + xa, ta, sb + xb, tb, 1 - 2 * alpha) >= unpaired_critical(ta, tb, margin, alpha) - TIE
    )
    la, _ = _wilson(sa + xa, ta, 1 - alpha_worse)
    _, ub = _wilson(sb + xb, tb, 1 - alpha_worse)
    worse = (rb - ra) + np.hypot(ub - rb, ra - la) < 0
    return float(min(1.0, w[ni_ok].sum())), float(min(1.0, w[worse].sum()))


# ------------------------------------------------------------------------------------------ unpaired runs (MOVER)
def mover_lower(sa, na: int, sb, nb: int, conf: float):
    """Lower end of the MOVER interval of Δ = p_B − p_A from the two Wilson intervals (``metrics.difference_ci``),
    vectorised: the unpaired test's statistic."""
    sa, sb = np.asarray(sa, dtype=float), np.asarray(sb, dtype=float)
    _, ua = _wilson(sa, na, conf)
    lb, _ = _wilson(sb, nb, conf)
    ra, rb = sa / na, sb / nb
    return (rb - ra) - np.hypot(rb - lb, ua - ra)


@lru_cache(maxsize=256)
def unpaired_critical(na: int, nb: int, margin: float, alpha: float) -> float:
    """The least MOVER lower end c with sup over the boundary (p_B = p_A − M) of P(lower end ≥ c) ≤ α, by exact
    sums over the two binomials: the unpaired non-inferiority test, whose size holds where the interval's alone
    did not (7.2 % at 25 episodes a run, docs/statistics.md)."""
    from scipy.stats import binom

    _check(min(na, nb), margin, alpha)
    sa, sb = np.meshgrid(np.arange(na + 1), np.arange(nb + 1), indexing="ij")
    t = mover_lower(sa, na, sb, nb, 1 - 2 * alpha).ravel()
    order = np.argsort(-t, kind="stable")
    ts = t[order]
    sup = np.zeros(len(ts))
    for pa in margin + (1 - margin) * (1 - np.cos(np.linspace(0, math.pi, GRID))) / 2:
        w = np.outer(
            binom.pmf(np.arange(na + 1), na, pa), binom.pmf(np.arange(nb + 1), nb, pa - margin)
        ).ravel()
        np.maximum(sup, np.cumsum(w[order]), out=sup)
    ok = (sup <= alpha) & np.r_[
        ts[:-1] - ts[1:] > TIE, True
    ]  # ties within TIE: one cut, as the test reads them
    return float(ts[np.flatnonzero(ok)[-1]]) if ok.any() else math.inf


def unpaired_non_inferior(sa: int, na: int, sb: int, nb: int, margin: float, alpha: float) -> bool:
    """Whether independent runs show B no worse than A by more than ``margin`` at one-sided level ``alpha``."""
    t = float(mover_lower(sa, na, sb, nb, 1 - 2 * alpha))
    return t >= unpaired_critical(na, nb, margin, alpha) - TIE


def pass_chance(rates: Sequence[float], n: int, margin: float, alpha: float, model: str = "independent",
                drop: float = 0.0, at: int | None = None) -> float:  # fmt: skip
    """P(the gate passes) with n pairs a level when the baseline's levels succeed at ``rates`` and the candidate
    equals it except for ``drop`` at level index ``at`` (None: no drop anywhere)."""
    out = 1.0
    for i, p in enumerate(rates):
        pb = max(0.0, p - drop) if i == at else p
        out *= power(n, *pair_model(p, pb, model), margin, alpha)
    return out
