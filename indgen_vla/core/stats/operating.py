"""Operating characteristics of every decision the toolkit prints: its size (the chance of the wrong call at the null
or its boundary) and its power, by exact enumeration where the tables are small and seeded simulation otherwise.
``scripts/operating_characteristics.py`` writes them to docs/results/statistics.md; the default tests assert the sizes."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.stats import binom, norm

from indgen_vla.core.stats import noninferiority as ni
from indgen_vla.core.stats.metrics import cochran_armitage, holm, mcnemar_exact, success_rate, wilson_ci
from indgen_vla.core.stats.sample_size import more_to_decide, verdict_counts

CHECK_GRID = (
    400  # boundary points the measured size is taken over: finer than, and apart from, the test's own grid
)


# ------------------------------------------------------------------------------------------------ the gate's tests
def _wilson(s: np.ndarray, n: int, z: float) -> tuple[np.ndarray, np.ndarray]:
    p = s / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z / denom * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return np.maximum(0.0, centre - half), np.minimum(1.0, centre + half)


def newcombe_lower_cells(both, a_only, b_only, neither, conf: float) -> np.ndarray:
    """``contrasts.paired_difference_ci``'s lower end, vectorised over the four cells of many tables."""
    both, x, y, nei = (np.asarray(v, dtype=float) for v in (both, a_only, b_only, neither))
    n = both + x + y + nei
    z = float(norm.isf((1 - conf) / 2))
    sb, sa = both + y, both + x
    pb, pa = sb / n, sa / n
    lb, _ = _wilson(sb, n, z)
    _, ua = _wilson(sa, n, z)
    margins = sb * (n - sb) * sa * (n - sa)
    cross = both * nei - x * y
    with np.errstate(divide="ignore", invalid="ignore"):
        psi = np.where((margins == 0) | ((cross >= 0) & (cross <= n / 2)), 0.0,
                       np.where(cross > n / 2, cross - n / 2, cross) / np.sqrt(np.maximum(margins, 1e-300)))  # fmt: skip
    d = pb - pa
    lo = d - np.sqrt(np.maximum(0.0, (pb - lb) ** 2 + (ua - pa) ** 2 - 2 * psi * (pb - lb) * (ua - pa)))
    return np.maximum(-1.0, lo)


def _quadrinomial(n: int, p11: float, p10: float, p01: float):
    """Every (both, A-only, B-only, neither) table of n pairs with its probability (small n only)."""
    out = []
    for both in range(n + 1):
        x, y = np.meshgrid(np.arange(n - both + 1), np.arange(n - both + 1), indexing="ij")
        keep = x + y <= n - both
        x, y = x[keep], y[keep]
        nei = n - both - x - y
        p00 = max(0.0, 1 - p11 - p10 - p01)
        lg = math.lgamma(n + 1) - ni._lgam(both + 1) - ni._lgam(x + 1) - ni._lgam(y + 1) - ni._lgam(nei + 1)
        with np.errstate(divide="ignore", invalid="ignore"):
            lp = (
                lg
                + ni._xlog(np.full_like(x, both), p11)
                + ni._xlog(x, p10)
                + ni._xlog(y, p01)
                + ni._xlog(nei, p00)
            )
        out.append((np.full_like(x, both), x, y, nei, np.exp(lp)))
    return tuple(np.concatenate(c) for c in zip(*out, strict=True))


def newcombe_size(
    n: int, margin: float, alpha: float, rates: Sequence[float] = (0.3, 0.5, 0.55, 0.7, 0.9)
) -> dict:
    """Largest P(Newcombe's (1 − 2α) lower end > −M) at Δ = −M over baseline rates ``rates`` and every coupling of
    the pair (A-only probability from M to its largest), by exact enumeration of the four-cell tables."""
    worst = (0.0, None)
    for pa in rates:
        pb = pa - margin
        if pb < 0:
            continue
        for qx in np.linspace(margin, min(pa, 1 - pb), 25):
            qy, p11 = qx - margin, pa - qx
            if p11 < -1e-12 or qy < -1e-12:
                continue
            both, x, y, nei, w = _quadrinomial(n, max(p11, 0.0), qx, max(qy, 0.0))
            size = float(w[newcombe_lower_cells(both, x, y, nei, 1 - 2 * alpha) > -margin].sum())
            worst = max(worst, (size, (pa, round(float(qx), 3))), key=lambda t: t[0])
    return {"size": worst[0], "at": worst[1]}


def exact_size(n: int, margin: float, alpha: float, grid: int = CHECK_GRID) -> dict:
    """Largest P(the gate's test shows non-inferiority) at Δ = −M over ``grid`` boundary points (its size), exact."""
    crit = ni.critical_z(n, margin, alpha)
    worst, at = 0.0, None
    qs = np.linspace(margin, (1 + margin) / 2, grid)
    for q in qs:
        x, y = ni._tables_for(n, q, q - margin)
        rej = ni.tango_z(x, y, n, margin) >= crit - ni.TIE
        s = float(ni.trinomial_pmf_any(n, x, y, q, q - margin)[rej].sum())
        if s > worst:
            worst, at = s, float(q)
    return {"size": worst, "at_a_only": at}


def equivalence_size(n: int, margin: float, alpha: float, exact: bool, rates=(0.3, 0.5, 0.7, 0.9)) -> float:
    """Largest P("within ±M" shown) at Δ = −M (by symmetry, +M) over baseline ``rates`` and 15 couplings each: the
    report's paired equivalence test (``exact``: two exact one-sided tests; else Newcombe's 1 − 2α interval inside
    ±M, the test before), exact sums over the four-cell tables."""
    worst = 0.0
    for pa in rates:
        for qx in np.linspace(margin, min(pa, 1 - pa + margin), 15):
            qy, p11 = qx - margin, pa - qx
            if p11 < 0 or qy < 0:
                continue
            both, x, y, nei, w = _quadrinomial(n, p11, qx, qy)
            if exact:
                xs, ys = (np.asarray(v, dtype=float) for v in (x, y))
                crit = ni.critical_z(n, margin, alpha) - ni.TIE
                ok = (ni.tango_z(xs, ys, n, margin) >= crit) & (ni.tango_z(ys, xs, n, margin) >= crit)
            else:
                lo = newcombe_lower_cells(both, x, y, nei, 1 - 2 * alpha)
                hi = -newcombe_lower_cells(both, y, x, nei, 1 - 2 * alpha)
                ok = (lo > -margin) & (hi < margin)
            worst = max(worst, float(w[ok].sum()))
    return worst


def unpaired_size(n: int, margin: float, alpha: float, exact: bool, grid: int = CHECK_GRID) -> float:
    """Largest P(non-inferiority shown) at p_B = p_A − M over ``grid`` values of p_A, two runs of n episodes:
    the gate's exact test (``exact``) or the MOVER interval alone (the gate before), exact sums."""
    s = np.arange(n + 1)
    sa, sb = np.meshgrid(s, s, indexing="ij")
    t = ni.mover_lower(sa, n, sb, n, 1 - 2 * alpha)
    rej = t >= ni.unpaired_critical(n, n, margin, alpha) - ni.TIE if exact else t > -margin
    return max(float(np.outer(binom.pmf(s, n, pa), binom.pmf(s, n, pa - margin))[rej].sum())
               for pa in np.linspace(margin, 1, grid))  # fmt: skip


def asymptotic_size(n: int, margin: float, alpha: float, grid: int = 100) -> float:
    """The size of Tango's asymptotic score test alone (Z ≥ z₁₋α) at n pairs: what the exact test corrects."""
    z = float(norm.isf(alpha))
    worst = 0.0
    for q in np.linspace(margin, (1 + margin) / 2, grid):
        x, y = ni._tables_for(n, q, q - margin)
        rej = ni.tango_z(x, y, n, margin) >= z
        worst = max(worst, float(ni.trinomial_pmf_any(n, x, y, q, q - margin)[rej].sum()))
    return worst


# ------------------------------------------------------------------------------------------- verdicts at γ, k*
def verdict_sizes(gamma: float, ci: str, ns: Sequence[int]) -> dict:
    """Largest exact chance over ``ns`` of calling a level at S = γ broken, and intact (nominal 2.5 % each)."""
    broken, intact = (0.0, None), (0.0, None)
    for n in ns:
        i, b = verdict_counts(n, gamma, ci)
        pb = float(binom.cdf(b, n, gamma)) if b is not None else 0.0
        pi = float(binom.sf(i - 1, n, gamma)) if i is not None else 0.0
        broken, intact = max(broken, (pb, n), key=lambda t: t[0]), max(intact, (pi, n), key=lambda t: t[0])
    return {"broken": broken, "intact": intact}


def kstar_wrong(rates: Sequence[float], n: int, gamma: float, ci: str) -> dict:
    """Exact chances, for one direction's true rates (outward from level 0, independent levels of n episodes), that
    k* is determined at the true break, determined at a wrong level, or left undetermined."""
    i_min = [verdict_counts(n, gamma, ci)[0]] * len(rates)
    b_max = verdict_counts(n, gamma, ci)[1]
    p_int = [
        float(binom.sf(i - 1, n, p)) if i is not None else 0.0 for i, p in zip(i_min, rates, strict=True)
    ]
    p_brk = [float(binom.cdf(b_max, n, p)) if b_max is not None else 0.0 for p in rates]
    true_k = next((k for k, p in enumerate(rates) if p < gamma), None)
    right = wrong = 0.0
    walk = 1.0  # chance every level before k is intact
    for k in range(len(rates)):
        det = walk * p_brk[k]
        right, wrong = (right + det, wrong) if k == true_k else (right, wrong + det)
        walk *= p_int[k]
    # every level intact: "no break through the last level", right only when no true break
    right, wrong = (right + walk, wrong) if true_k is None else (right, wrong + walk)
    return {"right": right, "wrong": wrong, "undetermined": max(0.0, 1 - right - wrong), "true_k": true_k}


# -------------------------------------------------------------------------------- "N more would decide it"
def report_projection(p_true: float, n: int, gamma: float, ci: str, power: float | None) -> dict:
    """Over first stages of n episodes at ``p_true`` that print "first level below γ ... not yet significant", the
    chance the projected extra episodes then decide the level (exact); ``power`` None: the old projection (the
    observed rate rounded, ~50 %), else ``sample_size.more_to_decide`` at that power."""
    intact, broken = verdict_counts(n, gamma, ci)
    mass = decided = min_claim = 0.0
    min_claim = 1.0
    for s in range(n + 1):
        w = float(binom.pmf(s, n, p_true))
        undecided = (broken is None or s > broken) and (intact is None or s < intact)
        if w < 1e-12 or not undecided or s / n >= gamma:
            continue
        extra = _old_more(s, n, gamma, ci) if power is None else more_to_decide(s, n, gamma, ci, power)
        if extra is None:
            continue
        b = verdict_counts(n + extra, gamma, ci)[1]
        if b is None or b < s:
            continue
        mass += w
        decided += w * float(binom.cdf(b - s, extra, p_true))
        min_claim = min(min_claim, float(binom.cdf(b - s, extra, s / n)))
    return {"printed": mass, "decided": decided / mass if mass else math.nan, "claim_at_observed": min_claim}


def _old_more(s: int, n: int, gamma: float, ci: str) -> int | None:
    """The projection before issue 53: the first total whose interval at the observed rate, rounded, is below γ."""
    rate = s / n
    for total in range(n + 1, n + 5001):
        if success_rate(round(rate * total), total, method=ci).ci_high < gamma:
            return total - n
    return None


# ----------------------------------------------------------------------------------------------- series trends
def series_fwer(levels: Sequence[float], n: int, steps: int, draws: int, seed: int, holm_on: bool,
                checkpoint_sd: float = 0.0) -> float:  # fmt: skip
    """Seeded simulation: the chance that a series with no trend (each level's rate the same at every step, up to a
    checkpoint effect of ``checkpoint_sd`` on the logit shared by all levels) flags at least one trend at α = 0.05
    (Cochran–Armitage per level, a rise and a fall), with or without Holm over the table."""
    rng = np.random.default_rng(seed)
    logit = np.log(np.asarray(levels) / (1 - np.asarray(levels)))
    hits = 0
    for _ in range(draws):
        eff = rng.normal(0, checkpoint_sd, steps) if checkpoint_sd else np.zeros(steps)
        ps = 1 / (1 + np.exp(-(logit[None, :] + eff[:, None])))
        hits += series_flagged(rng.binomial(n, ps), n, holm_on)
    return hits / draws


def series_flagged(counts: np.ndarray, n: int, holm_on: bool = True) -> bool:
    """Whether ``indgen series``'s table flags a trend in one series (``counts``: checkpoints × levels, n episodes
    each): Cochran–Armitage per level, a rise and a fall, every level in the family as
    ``series_report._holm_trends`` has it (a level whose counts do not vary tests at p = 0.5 each way)."""
    steps = counts.shape[0]
    pvals = []
    for k in range(counts.shape[1]):
        t = cochran_armitage(list(range(steps)), [int(x) for x in counts[:, k]], [n] * steps)
        pvals += [1 - t.p_decreasing, t.p_decreasing]
    return any(p < 0.05 for p in (holm(pvals) if holm_on else pvals))


def pooled_ood_size(
    levels: Sequence[float], n: int, steps: int, draws: int, seed: int, checkpoint_sd: float
) -> float:
    """Seeded simulation: the size of the pooled OOD Cochran–Armitage trend (levels ≠ 0 summed, two one-sided tests
    at 2.5 % each) when a checkpoint effect on the logit is shared by the levels and nothing trends."""
    rng = np.random.default_rng(seed)
    logit = np.log(np.asarray(levels) / (1 - np.asarray(levels)))
    hits = 0
    for _ in range(draws):
        eff = rng.normal(0, checkpoint_sd, steps)
        ps = 1 / (1 + np.exp(-(logit[None, :] + eff[:, None])))
        s = rng.binomial(n, ps).sum(axis=1)
        t = cochran_armitage(list(range(steps)), list(s), [n * len(levels)] * steps)
        hits += min(t.p_decreasing, 1 - t.p_decreasing) < 0.025
    return hits / draws


# -------------------------------------------------------------------------------------------- the CI recipe
def recipe_pass(rates: Sequence[float], n: int, margin: float, alpha: float, drop: float, draws: int, seed: int,
                model: str = "independent", old: bool = False) -> dict:  # fmt: skip
    """Seeded simulation of the CI job: a paired smoke of n episodes per level against the baseline, the candidate
    equal to it but for ``drop`` at the level likeliest to pass it. New rule: pass iff non-inferiority is shown at every
    level (exit 0). ``old``: the recipe before issue 53 (Newcombe's bound; exit 5 turned into a pass), passing unless
    a level is significantly worse (Holm-corrected exact McNemar). Returns the simulated chance with its 95 % interval
    and, for the new rule, the exact product of the per-level powers."""
    rng = np.random.default_rng(seed)
    at = max(range(len(rates)), key=lambda i: rates[i]) if drop else None
    cells = []
    for i, p in enumerate(rates):
        pb = max(0.0, p - drop) if i == at else p
        qx, qy = ni.pair_model(p, pb, model)
        cells.append((p - qx, qx, qy))
    passes = 0
    crit = ni.critical_z(n, margin, alpha)
    for _ in range(draws):
        ok, pvals, deltas = True, [], []
        for p11, qx, qy in cells:
            both, x, y, _ = rng.multinomial(n, [p11, qx, qy, max(0.0, 1 - p11 - qx - qy)])
            if old:
                pvals.append(mcnemar_exact(x, y))
                deltas.append(y - x)
            elif ni.tango_z(x, y, n, margin) < crit - ni.TIE:
                ok = False
                break
        if old:
            worse = any(ph < alpha and d < 0 for ph, d in zip(holm(pvals), deltas, strict=True))
            ok = not worse
        passes += ok
    lo, hi = wilson_ci(passes, draws)
    out = {"simulated": passes / draws, "ci": (lo, hi), "draws": draws}
    if not old:
        out["exact"] = ni.pass_chance(rates, n, margin, alpha, model, drop, at)
    return out


def gate_projection(n: int, p: float, margin: float, alpha: float, power: float = 0.8, model: str = "independent",
                    cap: int = 5000) -> dict:  # fmt: skip
    """Over the first stages of n pairs of two equal policies at rate p that leave a one-level gate undecided, the
    chance the projected extra pairs decide it (non-inferior, or worse by exact McNemar) when p is the truth, and
    the least chance the projection claimed at the observed frequencies (exact sums over both stages)."""
    qx, qy = ni.pair_model(p, p, model)
    xs, ys, _ = ni._tables(n)
    w = ni.trinomial_pmf(n, qx, qy)
    mass = decided = 0.0
    claim = 1.0
    for x, y, wt in zip(xs, ys, w, strict=True):
        x, y = int(x), int(y)
        if wt < 1e-6 or ni.non_inferior(x, y, n, margin, alpha) or (x > y and mcnemar_exact(x, y) < alpha):
            continue
        got = ni.project_pairs(x, y, n, margin, alpha, alpha, power, cap)
        if got is None:
            continue
        extra, _, chance = got
        ex, ey = ni._tables_for(extra, qx, qy)
        pe = ni.trinomial_pmf_any(extra, ex, ey, qx, qy)
        a, b, total = x + ex, y + ey, n + extra
        shown = ni.tango_z(a, b, total, margin) >= ni.critical_z(total, margin, alpha) - ni.TIE
        worse = (a > b) & (np.minimum(1.0, 2 * binom.cdf(np.minimum(a, b), a + b, 0.5)) < alpha)
        mass += wt
        decided += wt * float(pe[shown | worse].sum())
        claim = min(claim, chance)
    return {"printed": mass, "decided": decided / mass if mass else math.nan, "claim_at_observed": claim}
