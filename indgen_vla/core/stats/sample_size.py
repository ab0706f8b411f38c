"""Episodes a fixed design needs, computed exactly from the binomial: per level, for the verdict ``report`` gives
(its 95 % Wilson or Clopper–Pearson interval against γ), and per pair count, for the drop from T0 the report's and
``compare``'s exact McNemar test can see. Pure functions; ``indgen budget`` prints them (docs/budget.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.breakpoint import verdict_from_ci
from indgen_vla.core.stats.metrics import CI_METHODS, mcnemar_exact

MAX_EPISODES = 5000  # search cap: a design past it is answered "not reachable", never searched forever
PAIR_MODELS = ("independent", "nested", "most-discordant")


def _check_rate(name: str, p: float) -> None:
    if not 0 <= p <= 1:
        raise ConfigError(f"{name} must be in [0, 1], got {p}")


def _pmf(n: int, p: float) -> list[float]:
    """Binomial(n, p) probabilities of 0..n successes (exact sums of math.comb terms; n ≤ a few thousand)."""
    if p in (0.0, 1.0):
        return [float(s == round(p * n)) for s in range(n + 1)]
    lp, lq = math.log(p), math.log1p(-p)
    return [math.exp(math.lgamma(n + 1) - math.lgamma(s + 1) - math.lgamma(n - s + 1) + s * lp + (n - s) * lq)
            for s in range(n + 1)]  # fmt: skip


def verdict_counts(n: int, gamma: float, ci: str = "wilson") -> tuple[int | None, int | None]:
    """(fewest successes of n the report calls "intact", most it calls "broken"); None where no count does.
    The verdict is ``verdict_from_ci`` of the level's 95 % interval, monotone in the successes."""
    if ci not in CI_METHODS:
        raise ConfigError(f"--ci must be one of {', '.join(CI_METHODS)}, got {ci!r}")
    method = CI_METHODS[ci]

    def first(pred) -> int | None:  # the least s in 0..n where pred holds (pred monotone: false, then true)
        lo, hi = 0, n + 1
        while lo < hi:
            mid = (lo + hi) // 2
            lo, hi = (lo, mid) if pred(mid) else (mid + 1, hi)
        return lo if lo <= n else None

    intact = first(lambda s: verdict_from_ci(*method(s, n), gamma) == "intact")
    not_broken = first(lambda s: verdict_from_ci(*method(s, n), gamma) != "broken")
    broken = (n if not_broken is None else not_broken - 1) if not_broken != 0 else None
    return intact, broken


@dataclass(frozen=True)
class FixedDesign:
    """Episodes per level of a fixed design, and its exact error rates at S = γ ± δ."""

    episodes: int | None  # None: not reachable within MAX_EPISODES
    gamma: float
    delta: float
    alpha: float
    ci: str
    p_wrong_intact: float  # P(not decided "intact" | S = γ + δ)
    p_wrong_broken: float  # P(not decided "broken" | S = γ − δ)

    def as_dict(self) -> dict:
        """The JSON of ``indgen budget``'s ``episodes_fixed``."""
        return {"per_level": self.episodes, "gamma": self.gamma, "delta": self.delta, "alpha": self.alpha,
                "ci": f"{self.ci} 95%", "miss_intact_at": [self.gamma + self.delta, self.p_wrong_intact],
                "miss_broken_at": [self.gamma - self.delta, self.p_wrong_broken]}  # fmt: skip


def decided_rates(n: int, gamma: float, delta: float, ci: str = "wilson") -> tuple[float, float]:
    """(P a level at S = γ + δ is not called intact, P one at γ − δ is not called broken) with n episodes."""
    intact, broken = verdict_counts(n, gamma, ci)
    hi, lo = _pmf(n, gamma + delta), _pmf(n, gamma - delta)
    miss_intact = 1.0 - (sum(hi[intact:]) if intact is not None else 0.0)
    miss_broken = 1.0 - (sum(lo[: broken + 1]) if broken is not None else 0.0)
    return max(0.0, miss_intact), max(0.0, miss_broken)


def fixed_design(gamma: float, delta: float, alpha: float, ci: str = "wilson") -> FixedDesign:
    """The fewest episodes per level with which the report's verdict (``ci`` 95 % interval against γ) calls a
    level at S ≥ γ + δ intact and one at S ≤ γ − δ broken, each with chance ≥ 1 − α (exact binomial sums; the
    chances are not monotone in n, so this is the first n that meets both, as a fixed design would pick it)."""
    if not (0 < gamma < 1 and delta > 0 and 0 < gamma - delta and gamma + delta < 1):
        raise ConfigError(
            f"need 0 < γ − δ < γ + δ < 1, got γ = {gamma}, δ = {delta}; pick a smaller --adaptive-delta"
        )
    if not 0 < alpha < 0.5:
        raise ConfigError(f"error rate α must be in (0, 0.5), got {alpha}")
    for n in range(1, MAX_EPISODES + 1):
        mi, mb = decided_rates(n, gamma, delta, ci)
        if mi <= alpha and mb <= alpha:
            return FixedDesign(n, gamma, delta, alpha, ci, mi, mb)
    return FixedDesign(None, gamma, delta, alpha, ci, float("nan"), float("nan"))


def pair_probabilities(p0: float, p1: float, model: str) -> tuple[float, float]:
    """(P T0 succeeds and level k fails, P T0 fails and level k succeeds) for one seed's pair. ``independent``:
    the two outcomes of a seed are independent; ``nested``: level k succeeds only on seeds where T0 does (fewest
    discordant pairs for the same rates); ``most-discordant``: the fewest concordant pairs the rates allow (the most
    discordant pairs). No coupling gives the least power at every n: the exact test is discrete."""
    _check_rate("T0 rate", p0)
    _check_rate("level rate", p1)
    if model == "independent":
        return p0 * (1 - p1), (1 - p0) * p1
    if model == "nested":
        return max(0.0, p0 - p1), max(0.0, p1 - p0)
    if model == "most-discordant":
        both = max(0.0, p0 + p1 - 1)
        return p0 - both, p1 - both
    raise ConfigError(f"pairing model must be one of {', '.join(PAIR_MODELS)}, got {model!r}")


def paired_power(p0: float, p1: float, pairs: int, alpha: float, model: str = "independent") -> float:
    """Chance that the two-sided exact McNemar test (``metrics.mcnemar_exact``, as the report's Δ vs T0 and
    ``compare`` use it) finds level k below T0 at level ``alpha`` with ``pairs`` seed pairs: exact, summing over
    the discordant count D ~ Bin(pairs, d) and the T0-only count B | D ~ Bin(D, T0-only share)."""
    if pairs < 0:
        raise ConfigError(f"pairs must be >= 0, got {pairs}")
    a_only, b_only = pair_probabilities(p0, p1, model)
    d = a_only + b_only
    if d == 0:
        return 0.0
    from scipy.special import bdtrc

    share, power = a_only / d, 0.0
    for m, pm in enumerate(_pmf(pairs, d)):
        b = _reject_from(m, alpha)
        if pm > 1e-15 and b is not None:
            power += pm * (float(bdtrc(b - 1, m, share)) if b > 0 else 1.0)  # P(B >= b | D = m)
    return min(1.0, power)


@lru_cache(maxsize=65536)
def _reject_from(m: int, alpha: float) -> int | None:
    """The fewest T0-only pairs among m discordant ones at which the exact McNemar test rejects towards a drop
    (its p-value falls as the split grows more lopsided); None when even m of m does not reach ``alpha``."""
    if m == 0 or mcnemar_exact(m, 0) > alpha:
        return None
    lo, hi = m // 2 + 1, m  # rejects at hi; find the least b in (m/2, m] that rejects
    while lo < hi:
        mid = (lo + hi) // 2
        if mcnemar_exact(mid, m - mid) <= alpha:
            hi = mid
        else:
            lo = mid + 1
    return lo


def pairs_for_power(p0: float, p1: float, alpha: float, power: float = 0.8, model: str = "independent",
                    cap: int = 2000) -> int | None:  # fmt: skip
    """The fewest pairs whose exact McNemar power reaches ``power`` (None: not within ``cap`` pairs)."""
    if not 0 < power < 1:
        raise ConfigError(f"power must be in (0, 1), got {power}")
    return next((n for n in range(1, cap + 1) if paired_power(p0, p1, n, alpha, model) >= power), None)


def verdict_error(n: int, gamma: float, ci: str = "wilson", verdict: str = "broken") -> float:
    """The exact chance that the report calls a level ``verdict`` ("broken" or "intact") with n episodes when that
    call is wrong at its least wrong (S = γ): its real one-sided error, nominally 2.5 % for a 95 % interval (the
    chance is monotone in S, so this is its supremum over the null)."""
    from scipy.stats import binom

    intact, broken = verdict_counts(n, gamma, ci)
    if verdict == "broken":
        return 0.0 if broken is None else float(binom.cdf(broken, n, gamma))
    if verdict == "intact":
        return 0.0 if intact is None else float(binom.sf(intact - 1, n, gamma))
    raise ConfigError(f"verdict must be broken or intact, got {verdict!r}")


def more_to_decide(successes: int, n: int, gamma: float, ci: str = "wilson", power: float = 0.8,
                   cap: int = MAX_EPISODES) -> int | None:  # fmt: skip
    """Extra episodes after which a level at ``successes`` of n is called broken with chance ≥ ``power`` if its
    observed rate is the true one: the kept successes plus Bin(extra, rate) at or below the most the report calls
    broken at n + extra (exact; found by doubling then bisection, so the number returned always reaches ``power``);
    None when no number up to ``cap`` does."""
    from scipy.stats import binom

    rate = successes / n if n else 0.0

    def decides(extra: int) -> bool:
        broken = verdict_counts(n + extra, gamma, ci)[1]
        return (
            broken is not None and broken >= successes and binom.cdf(broken - successes, extra, rate) >= power
        )

    return first_extra(decides, cap)


def first_extra(decides, cap: int) -> int | None:
    """The least extra in 1..cap where ``decides(extra)`` holds, by doubling then bisection (chances that are not
    quite monotone in n can make a smaller one also hold; the one returned always does); None when cap does not."""
    lo, hi = 0, 1
    while not decides(hi):
        if hi >= cap:
            return None
        lo, hi = hi, min(cap, 2 * hi)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if decides(mid) else (mid, hi)
    return hi


def stable_episodes(design: FixedDesign, span: float = 1.5) -> tuple[int | None, list[int]]:
    """(the least n from which every n through ``span`` × the first passing n meets both error targets, the n between
    the first and that one which fail again): the chances are not monotone in n, so the first passing n can fail
    again one episode later."""
    if design.episodes is None:
        return None, []
    first = design.episodes
    top = int(span * first) + 1
    fails = [n for n in range(first, top + 1)
             if max(decided_rates(n, design.gamma, design.delta, design.ci)) > design.alpha]  # fmt: skip
    return (fails[-1] + 1 if fails else first), fails
