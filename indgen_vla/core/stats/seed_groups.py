"""Statistics for groups of runs (one run per training seed and regime): pure functions, tested by hand.

Two checkpoints trained on different data but evaluated on the same episodes are paired episode by episode;
seeds are independent replicates. So per level the evidence is the discordant pairs of every seed's pair of
runs (a stratified McNemar), and per axis the seed-level summaries (k*, the area under the out-of-distribution
curve) are compared across seeds with t-intervals and, for "no difference" claims, an equivalence test.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from indgen_vla.core.errors import ConfigError


@dataclass(frozen=True)
class PairedLevel:
    """Discordant pairs pooled over strata and the exact two-sided p-value of equal success."""

    a_only: int  # episodes A solved and B did not
    b_only: int  # episodes B solved and A did not
    pairs: int
    p_value: float


def stratified_mcnemar(strata: Sequence[tuple[int, int, int]]) -> PairedLevel:
    """Matched-pairs Mantel–Haenszel test: each stratum gives (a_only, b_only, pairs); exact binomial on the sum.

    With one stratum this is the exact McNemar test. Under H0 each discordant pair is A-only with probability
    1/2 in every stratum, so the pooled count is Binomial(total discordant, 1/2) (the MH statistic for 1:1
    matched pairs reduces to it); p = 1 when no pair is discordant.
    """
    from scipy.stats import binomtest

    if not strata:
        raise ConfigError("a paired comparison needs at least one stratum of pairs")
    for a_only, b_only, pairs in strata:
        if min(a_only, b_only) < 0 or a_only + b_only > pairs:
            raise ConfigError(f"bad paired counts a_only={a_only}, b_only={b_only}, pairs={pairs}")
    a = sum(s[0] for s in strata)
    b = sum(s[1] for s in strata)
    n = sum(s[2] for s in strata)
    p = 1.0 if a + b == 0 else float(binomtest(a, a + b, 0.5).pvalue)
    return PairedLevel(a, b, n, p)


@dataclass(frozen=True)
class MeanDifference:
    """B − A over independent replicates with a Welch t-interval (NaN bounds when either side has < 2)."""

    diff: float
    ci_low: float
    ci_high: float
    n_a: int
    n_b: int


def _welch(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
    """(mean difference b − a, its standard error, Welch–Satterthwaite degrees of freedom)."""
    from statistics import fmean, variance

    d = fmean(b) - fmean(a)
    va, vb = variance(a) / len(a), variance(b) / len(b)
    se = math.sqrt(va + vb)
    if se == 0:
        return d, 0.0, math.inf
    df = (va + vb) ** 2 / (va**2 / (len(a) - 1) + vb**2 / (len(b) - 1))
    return d, se, df


def mean_difference(a: Sequence[float], b: Sequence[float], conf: float = 0.95) -> MeanDifference:
    """Difference in means of per-seed values (B − A) with a two-sided Welch t-interval."""
    from scipy.stats import t

    if not a or not b:
        raise ConfigError("a seed-level comparison needs at least one value per side")
    if len(a) < 2 or len(b) < 2:
        d = sum(b) / len(b) - sum(a) / len(a)
        return MeanDifference(d, math.nan, math.nan, len(a), len(b))
    d, se, df = _welch(a, b)
    if se == 0:  # no spread across seeds: a t-interval does not exist (a zero-width one would overclaim)
        return MeanDifference(d, math.nan, math.nan, len(a), len(b))
    half = float(t.ppf(0.5 + conf / 2, df)) * se
    return MeanDifference(d, d - half, d + half, len(a), len(b))


def tost(a: Sequence[float], b: Sequence[float], margin: float) -> float:
    """Two one-sided Welch t-tests of |mean(b) − mean(a)| < margin; returns the TOST p-value (max of the two).

    A p-value below α supports equivalence within ±margin; NaN when either side has fewer than two values or the
    values do not vary at all (every seed the same rate: the t-test is undefined, and a few identical seeds are no
    evidence of equivalence, so this never returns p = 0 for them).
    """
    from scipy.stats import t

    if margin <= 0:
        raise ConfigError(f"equivalence margin must be > 0, got {margin}")
    if len(a) < 2 or len(b) < 2:
        return math.nan
    d, se, df = _welch(a, b)
    if se == 0:
        return math.nan
    p_lower = float(t.sf((d + margin) / se, df))  # H0: d <= -margin
    p_upper = float(t.cdf((d - margin) / se, df))  # H0: d >= +margin
    return max(p_lower, p_upper)


def ood_area(rates: Mapping[int, float]) -> float:
    """Mean success over the out-of-distribution levels |k| >= 1 (the area under the curve per level)."""
    ood = [r for k, r in rates.items() if k != 0]
    if not ood or any(math.isnan(r) for r in ood):
        raise ConfigError("the OOD area needs a finished rate at every level |k| >= 1")
    return sum(ood) / len(ood)
