"""Pure metric functions (paper §4 and appendix B); each is tested against hand values and scipy."""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass

from indgen_vla.errors import ConfigError

DEFAULT_GAMMA = 0.2  # the paper's Table 1 threshold


def _z(conf: float) -> float:
    from scipy.stats import norm

    if not 0 < conf < 1:
        raise ConfigError(f"confidence level must be in (0, 1), got {conf}")
    return float(norm.ppf(0.5 + conf / 2))


def _check_counts(successes: int, n: int) -> None:
    if n < 0 or successes < 0 or successes > n:
        raise ConfigError(f"need 0 <= successes <= n, got successes={successes}, n={n}")


def wilson_ci(successes: int, n: int, conf: float = 0.95) -> tuple[float, float]:
    """Wilson score interval; (0, 1) when n == 0 (nothing is known)."""
    _check_counts(successes, n)
    if n == 0:
        return 0.0, 1.0
    z = _z(conf)
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z / denom * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return max(0.0, centre - half), min(1.0, centre + half)


def clopper_pearson_ci(successes: int, n: int, conf: float = 0.95) -> tuple[float, float]:
    """Exact (Clopper–Pearson) interval from beta quantiles; (0, 1) when n == 0."""
    from scipy.stats import beta

    _check_counts(successes, n)
    if n == 0:
        return 0.0, 1.0
    alpha = 1 - conf
    lo = 0.0 if successes == 0 else float(beta.ppf(alpha / 2, successes, n - successes + 1))
    hi = 1.0 if successes == n else float(beta.ppf(1 - alpha / 2, successes + 1, n - successes))
    return lo, hi


CI_METHODS = {"wilson": wilson_ci, "clopper-pearson": clopper_pearson_ci}


@dataclass(frozen=True)
class Rate:
    """Success rate of one level with its confidence interval."""

    n: int
    successes: int
    rate: float
    ci_low: float
    ci_high: float


def success_rate(successes: int, n: int, method: str = "wilson", conf: float = 0.95) -> Rate:
    """S(π, T_k) with a 95 % interval; the rate is NaN when no episode finished."""
    try:
        ci = CI_METHODS[method]
    except KeyError:
        raise ConfigError(f"unknown CI method {method!r}; use one of {sorted(CI_METHODS)}") from None
    lo, hi = ci(successes, n, conf)
    return Rate(n=n, successes=successes, rate=successes / n if n else float("nan"), ci_low=lo, ci_high=hi)


def break_level(rates: Mapping[int, float], gamma: float = DEFAULT_GAMMA) -> int | None:
    """k* = the first evaluated level, in increasing |k|, whose success rate is below γ; None if none.

    Pass one direction at a time (levels 0..K or 0..-K); NaN rates (no finished episode) are skipped.
    """
    if not 0 < gamma <= 1:
        raise ConfigError(f"gamma must be in (0, 1], got {gamma}")
    for k in sorted(rates, key=abs):
        r = rates[k]
        if not math.isnan(r) and r < gamma:
            return k
    return None


def break_levels(
    rates: Mapping[int, float], gamma: float = DEFAULT_GAMMA, signed: bool | None = None
) -> dict:
    """Break level per direction: ``{"pos": k|None}`` plus ``"neg"`` for signed axes (DESIGN.md)."""
    if signed is None:
        signed = any(k < 0 for k in rates)
    out = {"pos": break_level({k: r for k, r in rates.items() if k >= 0}, gamma)}
    if signed:
        out["neg"] = break_level({k: r for k, r in rates.items() if k <= 0}, gamma)
    return out


def kstar(rates: Mapping[int, float], gamma: float = DEFAULT_GAMMA) -> int:
    """Definition 2's k*: first level with S < γ, or K+1 when none breaks (K = largest evaluated level)."""
    k = break_level(rates, gamma)
    return (max(rates, key=abs) + 1) if k is None else k


def blackbox_reference(success: Mapping[Hashable, Sequence[float]]) -> tuple[Hashable, float]:
    """Definition 3: T0 = argmax over canonical configurations of mean success over reference policies.

    Args:
        success: configuration -> success rates of the reference policies on it.

    Returns:
        The chosen configuration and its mean success (ties go to the first configuration given).
    """
    if not success:
        raise ConfigError("black-box reference level needs at least one canonical configuration")
    best, best_mean = None, -math.inf
    for config, rates in success.items():
        if len(rates) == 0:
            raise ConfigError(f"configuration {config!r} has no reference-policy success rates")
        mean = sum(rates) / len(rates)
        if mean > best_mean:
            best, best_mean = config, mean
    return best, best_mean


@dataclass(frozen=True)
class TrendTest:
    """Cochran–Armitage test for a linear trend in proportions across ordered levels."""

    statistic: float  # z; negative when success falls as the score grows
    p_decreasing: float  # one-sided p-value for "success decreases with level"
    p_two_sided: float


def cochran_armitage(scores: Sequence[float], successes: Sequence[int], n: Sequence[int]) -> TrendTest:
    """Validate a level ordering post hoc (appendix B): does success fall as the level rises?

    Uses the standard statistic T = Σ t_i (x_i − n_i p̄) with variance p̄(1−p̄)(Σ n_i t_i² − (Σ n_i t_i)²/N).
    """
    from scipy.stats import norm

    if not len(scores) == len(successes) == len(n) or len(scores) < 2:
        raise ConfigError("trend test needs at least two levels with matching scores, successes and n")
    for x, m in zip(successes, n, strict=True):
        _check_counts(x, m)
    big_n, r = sum(n), sum(successes)
    if big_n == 0:
        raise ConfigError("trend test needs at least one finished episode")
    p = r / big_n
    t_stat = sum(t * (x - m * p) for t, x, m in zip(scores, successes, n, strict=True))
    s1 = sum(m * t for t, m in zip(scores, n, strict=True))
    s2 = sum(m * t * t for t, m in zip(scores, n, strict=True))
    var = p * (1 - p) * (s2 - s1 * s1 / big_n)
    if var <= 0:  # all successes, all failures, or a single score: no evidence of a trend
        return TrendTest(0.0, 0.5, 1.0)
    z = t_stat / math.sqrt(var)
    return TrendTest(statistic=z, p_decreasing=float(norm.cdf(z)), p_two_sided=float(2 * norm.sf(abs(z))))


def holm(p_values: Sequence[float]) -> list[float]:
    """Holm–Bonferroni adjusted p-values (step-down, monotone, capped at 1), in the input order."""
    m = len(p_values)
    order = sorted(range(m), key=lambda i: p_values[i])
    adjusted = [0.0] * m
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p_values[i]))
        adjusted[i] = running
    return adjusted


def exact_2x2(successes_a: int, n_a: int, successes_b: int, n_b: int, test: str = "boschloo") -> float:
    """Two-sided unconditional exact test of equal success rates (scipy's Barnard or Boschloo)."""
    from scipy.stats import barnard_exact, boschloo_exact

    _check_counts(successes_a, n_a)
    _check_counts(successes_b, n_b)
    if n_a == 0 or n_b == 0:
        return float("nan")
    if successes_a / n_a == successes_b / n_b:
        return 1.0  # identical tables; scipy's statistic is undefined (0/0) there
    table = [[successes_a, successes_b], [n_a - successes_a, n_b - successes_b]]
    if test == "barnard":
        return float(barnard_exact(table, alternative="two-sided").pvalue)
    if test == "boschloo":
        return float(boschloo_exact(table, alternative="two-sided").pvalue)
    raise ConfigError(f"unknown exact test {test!r}; use 'barnard' or 'boschloo'")


def compare_levels(
    a: Mapping[int, tuple[int, int]], b: Mapping[int, tuple[int, int]], test: str = "boschloo"
) -> list[dict]:
    """Per-level exact tests between two runs with Holm correction over the shared levels.

    Args:
        a, b: level -> (successes, n) for each run.

    Returns:
        One dict per shared level with ``level, n_a, successes_a, rate_a, n_b, successes_b, rate_b,
        p_value, p_holm`` (the compare.json schema).
    """
    levels = sorted(set(a) & set(b), key=lambda k: (abs(k), k))
    rows = []
    for k in levels:
        (sa, na), (sb, nb) = a[k], b[k]
        rows.append({
            "level": k, "n_a": na, "successes_a": sa, "rate_a": sa / na if na else float("nan"),
            "n_b": nb, "successes_b": sb, "rate_b": sb / nb if nb else float("nan"),
            "p_value": exact_2x2(sa, na, sb, nb, test),
        })  # fmt: skip
    valid = [i for i, r in enumerate(rows) if not math.isnan(r["p_value"])]
    adjusted = holm([rows[i]["p_value"] for i in valid])
    for r in rows:
        r["p_holm"] = float("nan")
    for i, p in zip(valid, adjusted, strict=True):
        rows[i]["p_holm"] = p
    rows.sort(key=lambda r: r["level"])
    return rows


def wilson_half_width(n: int, p: float = 0.5, conf: float = 0.95) -> float:
    """Half-width of the Wilson interval at true rate ``p`` with ``n`` rollouts."""
    z = _z(conf)
    return z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))


def rollouts_needed(half_width: float, p: float = 0.5, conf: float = 0.95, max_n: int = 10**7) -> int:
    """Smallest n whose Wilson interval half-width at rate ``p`` is at most ``half_width``.

    p = 0.5 is the worst case; pass the expected success rate for a tighter answer.
    """
    if not 0 < half_width < 0.5:
        raise ConfigError(f"half-width must be in (0, 0.5), got {half_width}")
    if not 0 <= p <= 1:
        raise ConfigError(f"expected rate p must be in [0, 1], got {p}")
    lo, hi = 1, 1
    while wilson_half_width(hi, p, conf) > half_width:
        lo, hi = hi, hi * 2
        if hi > max_n:
            raise ConfigError(f"more than {max_n} rollouts needed for half-width {half_width}")
    while lo < hi:  # the half-width decreases monotonically in n
        mid = (lo + hi) // 2
        if wilson_half_width(mid, p, conf) <= half_width:
            hi = mid
        else:
            lo = mid + 1
    return lo
