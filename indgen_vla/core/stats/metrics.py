"""Pure metric functions (paper §4 and appendix B); each is tested against hand values and scipy."""

from __future__ import annotations

import functools
import math
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from indgen_vla.core.errors import ConfigError

DEFAULT_GAMMA = 0.2  # the paper's Table 1 threshold


Z95 = 1.959963984540054  # float(scipy.special.ndtri(0.975)) bit for bit (a test checks): no scipy import (~0.3 s)


@functools.lru_cache(maxsize=16)  # one value per confidence level; a report asks for it per level and task
def _z(conf: float) -> float:
    if conf == 0.95:
        return Z95
    from scipy.special import ndtri  # scipy.stats.norm.ppf exactly, without importing scipy.stats (~1 s)

    if not 0 < conf < 1:
        raise ConfigError(f"confidence level must be in (0, 1), got {conf}")
    return float(ndtri(0.5 + conf / 2))


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
CI_NAMES = {"wilson": "Wilson", "clopper-pearson": "Clopper–Pearson"}  # as printed beside a rate


def ci_name(ci: str) -> str:
    """An interval method's printed name ("wilson" -> "Wilson"), every report and plot saying it one way."""
    return CI_NAMES.get(ci, ci)


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


def difference_ci(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float]:
    """Interval of rate_a − rate_b for two independent samples, each given as (rate, ci_low, ci_high): the MOVER
    combination of the two rates' own intervals (with Wilson intervals: Newcombe 1998, method 10)."""
    (pa, la, ua), (pb, lb, ub) = a, b
    d = pa - pb
    return d - math.hypot(pa - la, ub - pb), d + math.hypot(ua - pa, pb - lb)


MIN_N = 5  # data floor: fewer finished episodes than this never yields a printed rate or a k*


def below_floor(n: int, planned: int | None = None) -> bool:
    """Issue 18's data floor: a level is insufficient when n < 5 or n < half the planned episodes."""
    return n < MIN_N or (planned is not None and planned > 0 and 2 * n < planned)


def is_usable(row: Mapping[str, Any] | None) -> bool:
    """A summary level row a rate may be printed or drawn from: finished episodes, above the data floor."""
    return row is not None and row["n"] > 0 and not row.get("insufficient", False)


def usable_rows(rows: Sequence[Mapping[str, Any]]) -> list:
    """The level rows ``is_usable`` keeps, in order (a curve's points, a caveat's evidence)."""
    return [r for r in rows if is_usable(r)]


NAMED_TASKS = 4  # a task list longer than this names its first NAMED_TASKS - 1 and counts the rest


def pooled_text(tasks: Sequence[str]) -> str:
    """Which tasks a rate pools, in the one wording every report, plot and terminal line uses: "task milk", "pooled
    over 2 tasks: bread, milk", "pooled over 12 tasks: a, b, c and 9 more", "tasks unknown"."""
    if len(tasks) < 2:
        return f"task {tasks[0]}" if tasks else "tasks unknown"
    shown = tasks if len(tasks) <= NAMED_TASKS else tasks[: NAMED_TASKS - 1]
    more = f" and {len(tasks) - len(shown)} more" if len(shown) < len(tasks) else ""
    return f"pooled over {len(tasks)} tasks: {', '.join(shown)}{more}"


class UndeterminedBreakError(ConfigError):
    """k* cannot be read off: a level with no usable data lies before the first break (a hole)."""

    def __init__(self, level: int):
        self.level = level
        super().__init__(
            f"level {level} has no usable data (no or too few finished episodes) before any break, so k* "
            "would skip it; finish that level (re-run the same evaluate command) or leave it out with --levels"
        )


def break_level(rates: Mapping[int, float], gamma: float = DEFAULT_GAMMA) -> int | None:
    """k* = the first evaluated level, in increasing |k|, whose success rate is below γ; None if none.

    Pass one direction at a time (levels 0..K or 0..-K). A NaN rate marks a level without usable data
    (no finished episode, or below the data floor): when it comes before the first break, k* is unknown
    and ``UndeterminedBreakError`` is raised rather than silently skipping the hole.
    """
    if not 0 < gamma <= 1:
        raise ConfigError(f"gamma must be in (0, 1], got {gamma}")
    for k in sorted(rates, key=abs):
        r = rates[k]
        if math.isnan(r):
            raise UndeterminedBreakError(k)
        if r < gamma:
            return k
    return None


UNDETERMINED = "undetermined"


def break_levels(
    rates: Mapping[int, float], gamma: float = DEFAULT_GAMMA, signed: bool | None = None
) -> dict:
    """Break level per direction: ``{"pos": k|None|"undetermined"}`` plus ``"neg"`` for signed axes.

    ``"undetermined"`` (not None, which means "no break in the evaluated range") when a level without
    usable data precedes the first break in that direction.
    """
    if signed is None:
        signed = any(k < 0 for k in rates)

    def one(side: dict[int, float]) -> int | None | str:
        try:
            return break_level(side, gamma)
        except UndeterminedBreakError:
            return UNDETERMINED

    out = {"pos": one({k: r for k, r in rates.items() if k >= 0})}
    if signed:
        out["neg"] = one({k: r for k, r in rates.items() if k <= 0})
    return out


def kstar(rates: Mapping[int, float], gamma: float = DEFAULT_GAMMA) -> int:
    """Definition 2's k*: first level with S < γ, or K+1 when none breaks: one step beyond the extreme
    evaluated level in its direction (0..3 -> 4, 0..-3 -> -4). One direction at a time."""
    if any(k > 0 for k in rates) and any(k < 0 for k in rates):
        raise ConfigError("kstar takes one direction at a time: levels 0..K or 0..-K, not both signs")
    k = break_level(rates, gamma)
    if k is not None:
        return k
    extreme = max(rates, key=abs)
    return extreme - 1 if extreme < 0 else extreme + 1


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
    from scipy.special import ndtr  # scipy.stats.norm's cdf (sf(z) = ndtr(-z)), without importing scipy.stats

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
    return TrendTest(statistic=z, p_decreasing=float(ndtr(z)), p_two_sided=float(2 * ndtr(-abs(z))))


def isotonic_decreasing(values: Sequence[float], weights: Sequence[float]) -> list[float]:
    """Weighted pool-adjacent-violators fit, non-increasing: for binomial rates weighted by n it is the
    maximum-likelihood success curve under "success never rises with the level"."""
    if len(values) != len(weights) or any(w <= 0 for w in weights):
        raise ConfigError("isotonic fit needs one positive weight per value")
    blocks: list[list[float]] = []  # [weighted mean, weight, count]
    for v, w in zip(values, weights, strict=True):
        blocks.append([float(v), float(w), 1])
        while len(blocks) > 1 and blocks[-2][0] < blocks[-1][0]:  # a rise: pool the two blocks
            (m2, w2, c2), (m1, w1, c1) = blocks.pop(), blocks.pop()
            blocks.append([(m1 * w1 + m2 * w2) / (w1 + w2), w1 + w2, c1 + c2])
    return [m for m, _, c in blocks for _ in range(c)]


def _isotonic_rows(x, n):
    """Non-increasing isotonic fit of many success tables at once (rows of ``x``), by the min–max formula
    f_i = min_{s<=i} max_{t>=i} Av(s..t); equals ``isotonic_decreasing`` row by row."""
    import numpy as np

    k = x.shape[1]
    cx = np.concatenate([np.zeros((x.shape[0], 1)), np.cumsum(x, axis=1)], axis=1)
    cn = np.concatenate([[0.0], np.cumsum(n)])
    s_idx, t_idx = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    valid = s_idx <= t_idx
    av = (cx[:, t_idx + 1] - cx[:, s_idx]) / np.where(valid, cn[t_idx + 1] - cn[s_idx], 1.0)
    av = np.where(valid, av, -np.inf)
    max_t = np.maximum.accumulate(av[:, :, ::-1], axis=2)[:, :, ::-1]  # [b, s, i] = max_{t>=i} Av(s, t)
    return np.where(valid, max_t, np.inf).min(axis=1)  # min over s <= i


def _lrt_rows(x, n):
    """2·(log-likelihood of the isotonic fit − of one common rate), per row of ``x`` (0·log 0 = 0)."""
    import numpy as np
    from scipy.special import xlogy

    f = _isotonic_rows(x, n)
    p = x.sum(axis=1, keepdims=True) / n.sum()

    def ll(q):
        return (xlogy(x, q) + xlogy(n - x, 1 - q)).sum(axis=1)

    return np.maximum(2 * (ll(f) - ll(p)), 0.0)


def _hypergeometric_tables(n: Sequence[int], total: int):
    """Every table x (0 <= x_i <= n_i, sum x = total) with its probability under equal success rates."""
    from math import comb

    def rec(i: int, left: int):
        if i == len(n) - 1:
            if left <= n[i]:
                yield (left,)
            return
        for xi in range(max(0, left - sum(n[i + 1 :])), min(n[i], left) + 1):
            for rest in rec(i + 1, left - xi):
                yield (xi, *rest)

    denom = comb(sum(n), total)
    for t in rec(0, total):
        yield t, math.prod(comb(m, xi) for m, xi in zip(n, t, strict=True)) / denom


def _n_tables(n: Sequence[int], total: int) -> int:
    """How many tables ``_hypergeometric_tables`` yields: a DP over levels with prefix sums, O(k · total)."""
    ways = [1] + [0] * total
    for m in n:
        prefix = [0]
        for w in ways:
            prefix.append(prefix[-1] + w)
        ways = [prefix[r + 1] - prefix[max(0, r - m)] for r in range(total + 1)]
    return ways[total]


@dataclass(frozen=True)
class MonotoneTest:
    """Likelihood-ratio test of "success does not rise with the level" against "all levels equal"."""

    statistic: float  # 2·(ℓ(isotonic fit) − ℓ(common rate)); 0 when the data give no sign of a decrease
    p_decreasing: float  # permutation p-value: P(statistic >= observed | equal rates, total successes)
    method: str  # "exact" (all tables enumerated) or "monte carlo, B = <draws>"
    fitted: tuple[float, ...]  # the isotonic (non-increasing) success curve


def monotone_decreasing_test(
    successes: Sequence[int], n: Sequence[int], max_tables: int = 20000, draws: int = 4000, seed: int = 0
) -> MonotoneTest:
    """Does success fall monotonically with the level (appendix B's post-hoc ordering check)?

    Likelihood-ratio test of H0 "every level has the same rate" against the order-restricted alternative
    "rates never rise with the level" (the isotonic MLE, fitted by PAVA). Its asymptotic null is a
    chi-bar-squared mixture whose weights depend on every n_i, so the p-value is taken instead from the
    permutation distribution: given the total number of successes, tables are multivariate-hypergeometric
    under H0, which makes the test exact in finite samples (no asymptotics, no nuisance rate). Every table is
    enumerated when there are at most ``max_tables`` of them; otherwise ``draws`` tables are sampled with a
    fixed ``seed`` and p = (1 + #{T* >= T}) / (1 + draws). Unlike Cochran–Armitage it tests any monotone
    shape, not a linear trend: a curve that holds and then collapses is detected too.

    Args:
        successes, n: per level in increasing |k| (levels with n = 0 must be left out).
    """
    import numpy as np

    if len(successes) != len(n) or len(n) < 2:
        raise ConfigError("monotone test needs at least two levels with matching successes and n")
    for x, m in zip(successes, n, strict=True):
        _check_counts(x, m)
        if m == 0:
            raise ConfigError("monotone test: leave out levels with no finished episode (n = 0)")
    nn = np.asarray(n, dtype=float)
    obs = np.asarray([successes], dtype=float)
    fitted = tuple(float(v) for v in _isotonic_rows(obs, nn)[0])
    stat = float(_lrt_rows(obs, nn)[0])
    total = int(sum(successes))
    tol = 1e-9 * max(1.0, stat)
    if stat <= tol:  # the data show no decrease at all
        return MonotoneTest(0.0, 1.0, "exact", fitted)
    if _n_tables(list(n), total) <= max_tables:
        tables, probs = zip(*_hypergeometric_tables(list(n), total), strict=True)
        null = _lrt_rows(np.asarray(tables, dtype=float), nn)
        p = float(np.asarray(probs)[null >= stat - tol].sum())
        return MonotoneTest(stat, min(1.0, p), "exact", fitted)
    rng = np.random.default_rng(seed)
    sample = rng.multivariate_hypergeometric(np.asarray(n, dtype=np.int64), total, size=draws)
    null = _lrt_rows(sample.astype(float), nn)
    p = (1 + int((null >= stat - tol).sum())) / (1 + draws)
    return MonotoneTest(stat, p, f"monte carlo, B = {draws}", fitted)


def mcnemar_exact(a_only: int, b_only: int) -> float:
    """Two-sided exact McNemar test: under equal success, each discordant pair favours A with chance 1/2.

    Binomial(m, 1/2) is symmetric, so scipy's two-sided ``binomtest`` p-value is twice the smaller tail, capped at 1;
    the binomial CDF (``scipy.special.bdtr``) gives it ~100× faster, which a report of many tasks and levels needs.
    """
    from scipy.special import bdtr

    if a_only < 0 or b_only < 0:
        raise ConfigError(f"discordant counts must be >= 0, got {a_only}, {b_only}")
    if a_only + b_only == 0:
        return 1.0  # no discordant pair: no evidence of a difference
    return min(1.0, float(2 * bdtr(min(a_only, b_only), a_only + b_only, 0.5)))


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
    _add_holm(rows)
    return rows


def compare_paired_levels(pairs: Mapping[int, Sequence[tuple[bool, bool]]]) -> list[dict]:
    """Per-level exact McNemar tests on episode pairs (same seed, same initial state) with Holm correction.

    Args:
        pairs: level -> (success in A, success in B) for each episode finished ``ok`` in both runs.

    Returns:
        compare_levels' rows plus ``pairs, a_only, b_only`` (the discordant counts the test uses).
    """
    rows = []
    for k in sorted(pairs, key=lambda k: (abs(k), k)):
        ps = list(pairs[k])
        m, sa, sb = len(ps), sum(a for a, _ in ps), sum(b for _, b in ps)
        a_only, b_only = sum(a and not b for a, b in ps), sum(b and not a for a, b in ps)
        rows.append({
            "level": k, "n_a": m, "successes_a": sa, "rate_a": sa / m if m else float("nan"),
            "n_b": m, "successes_b": sb, "rate_b": sb / m if m else float("nan"),
            "pairs": m, "a_only": a_only, "b_only": b_only,
            "p_value": mcnemar_exact(a_only, b_only) if m else float("nan"),
        })  # fmt: skip
    _add_holm(rows)
    return rows


def _add_holm(rows: list[dict]) -> None:
    """Fill ``p_holm`` over the rows with a p-value (NaN for the others) and sort the rows by level."""
    valid = [i for i, r in enumerate(rows) if not math.isnan(r["p_value"])]
    adjusted = holm([rows[i]["p_value"] for i in valid])
    for r in rows:
        r["p_holm"] = float("nan")
    for i, p in zip(valid, adjusted, strict=True):
        rows[i]["p_holm"] = p
    rows.sort(key=lambda r: r["level"])


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


def usable_levels(rows: list[dict]) -> set[int]:
    """The levels above the data floor: the only ones a printed result (rate, k*, break point) may come from."""
    return {r["level"] for r in rows if not r["insufficient"]}
