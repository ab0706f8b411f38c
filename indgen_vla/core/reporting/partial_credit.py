"""Partial credit: the ordinal per-episode progress score (0..5) in reports and in ``compare``.

The scenes score each episode from privileged state (``scenes.failure``: no contact < contact < grasp < lift <
transport < success, the same predicates at every level); this module summarises the scores per level, plots
them, and tests two runs on them with exact rank tests — beside the binary McNemar/Boschloo tests, never
instead of them. Rows without a score (runs written before the column, error rows, families without contact
signals) are missing, never 0. docs/adaptive.md ("Partial credit") explains the choices.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from pathlib import Path

from indgen_vla.core.reporting.figures import count_note
from indgen_vla.core.runs.records import atomic_savefig
from indgen_vla.core.stats.frames import group_items
from indgen_vla.core.stats.metrics import holm
from indgen_vla.core.stats.pairing import PAIR_KEY

STAGES = ("no_contact", "contact", "grasp", "lift", "transport", "success")  # score = index
COLOURS = ("#9e9e9e", "#ffcc80", "#ff9800", "#64b5f6", "#1e88e5", "#4caf50")
PAIRED_TEST = "wilcoxon_signed_rank_exact"
UNPAIRED_TEST = "rank_sum_permutation"
MAX_EXACT_STATES = (
    5_000_000  # rank-sum DP size (choices × doubled rank sums) above which scipy's Monte Carlo runs
)
MC_RESAMPLES = 20_000
# signed-rank null distributions up to this size (1.6 MB) are cached, larger ones are not
NULL_CACHE_STATES = 200_000


def _scores(df) -> list[int]:
    """The finished (status ok) episodes' progress scores, missing ones left out."""
    if "progress" not in df or not len(df):
        return []
    ok = df[df["status"] == "ok"]["progress"]
    return [int(v) for v in ok if v is not None and not _isna(v)]


def _isna(v) -> bool:
    import pandas as pd

    return bool(pd.isna(v))


def level_progress(level_df) -> dict | None:
    """One level's progress: scored episodes, mean score and the count per stage (None when none is scored)."""
    s = _scores(level_df)
    if not s:
        return None
    return {"n": len(s), "mean": sum(s) / len(s), "stages": {STAGES[i]: s.count(i) for i in range(6)}}


def level_progress_by(df, keys: list[str]) -> dict[tuple, dict]:
    """``level_progress`` of every group of ``keys`` (a tuple of their values) in one pass over ``df``; groups
    without a scored episode are left out (``level_progress`` gives None for them)."""
    if "progress" not in df or not len(df):
        return {}
    ok = df[df["status"] == "ok"]
    scored = ok[ok["progress"].notna()]
    score = scored["progress"].astype("int64").rename("_score")  # int(v) of each score, as _scores takes it
    by = [scored[k] for k in keys]
    totals = dict(group_items(score.groupby(by, sort=False).sum()))
    out: dict[tuple, dict] = {}
    for k, n in group_items(score.groupby(by, sort=False).size()):
        out[k] = {"n": n, "mean": totals[k] / n, "stages": dict.fromkeys(STAGES, 0)}
    for (*key, v), c in group_items(score.groupby([*by, score], sort=False).size()):
        if 0 <= v < len(STAGES):
            out[tuple(key)]["stages"][STAGES[v]] = c
    return out


# ----------------------------------------------------------------------------------------- exact tests
def _doubled_midranks(values: Sequence[int]) -> dict[int, int]:
    """Value -> twice its midrank among ``values`` (integers, so tie sums stay exact)."""
    out, start = {}, 0
    for v in sorted(set(values)):
        t = sum(1 for x in values if x == v)
        out[v] = 2 * start + t + 1  # 2 · (start + (t + 1)/2)
        start += t
    return out


def signed_rank_exact(diffs: Sequence[int]) -> float:
    """Two-sided exact Wilcoxon signed-rank p-value of paired differences (B − A), zeros dropped, ties at
    midranks: the exact permutation distribution of W+ over the 2^m equally likely sign patterns (dynamic
    programming over the groups of tied |d|), p = P(|W+ − E| ≥ |w − E|). 1.0 when every difference is 0."""
    d = [int(x) for x in diffs if int(x) != 0]
    if not d:
        return 1.0
    mags = [abs(x) for x in d]
    ranks = _doubled_midranks(mags)
    w = sum(ranks[abs(x)] for x in d if x > 0)
    groups = tuple(sorted((mags.count(v), ranks[v]) for v in set(mags)))
    dist = _signed_rank_null(groups)
    total = sum(n * r for n, r in groups)
    dev = abs(2 * w - total)  # |W+ − E| in units of (doubled rank)/2
    import numpy as np

    sums = np.arange(len(dist))
    return float(min(1.0, dist[np.abs(2 * sums - total) >= dev].sum()))


def _signed_rank_null(groups: tuple[tuple[int, int], ...]):
    """The null distribution of doubled W+ for tie groups (size, doubled rank); small ones are cached (simulations
    repeat them), a large one is not kept: thousands of pairs make it tens of MB per level."""
    if sum(n * r for n, r in groups) <= NULL_CACHE_STATES:
        return _signed_rank_null_cached(groups)
    return _signed_rank_dp(groups)


@functools.lru_cache(maxsize=4096)
def _signed_rank_null_cached(groups: tuple[tuple[int, int], ...]):
    return _signed_rank_dp(groups)


def _signed_rank_dp(groups: tuple[tuple[int, int], ...]):
    """Independent Binomial(n, 1/2) counts of positive signs per group, each worth its rank, convolved in order.
    Each step adds only the slice where the distribution so far can be non-zero (adding q · 0 = 0 changes no bit),
    in place, and skips weights that underflow to 0: the same sums as over the whole array, 2× faster."""
    import numpy as np
    from scipy.stats import binom

    dist = np.zeros(sum(n * r for n, r in groups) + 1)
    dist[0] = 1.0
    support = 1  # dist[support:] is 0 so far
    for n, r in groups:
        nxt, term, src = np.zeros_like(dist), np.empty(support), dist[:support]
        for j, q in enumerate(binom.pmf(np.arange(n + 1), n, 0.5)):
            if q == 0:
                continue
            out = nxt[j * r : j * r + support]
            np.add(out, np.multiply(q, src, out=term), out=out)
        dist, support = nxt, support + n * r
    return dist


def sign_test(diffs: Sequence[int]) -> float:
    """Two-sided exact sign test of paired differences (zeros dropped); on 0/1 scores it is exact McNemar."""
    from scipy.stats import binomtest

    pos, neg = sum(1 for x in diffs if x > 0), sum(1 for x in diffs if x < 0)
    if pos + neg == 0:
        return 1.0
    return float(binomtest(pos, pos + neg, 0.5).pvalue)


def rank_sum_test(a: Sequence[int], b: Sequence[int], seed: int = 0) -> tuple[float, str]:
    """Two-sided Wilcoxon–Mann–Whitney permutation test of two unpaired samples (ties at midranks):
    p = P(|W_A − E| ≥ |w − E|) over all equally likely splits of the pooled scores. Exact by dynamic
    programming over the tied groups (multivariate hypergeometric) when small enough, else scipy's Monte Carlo
    ``permutation_test`` (``MC_RESAMPLES``, seeded). Returns (p, "exact" | "monte_carlo")."""
    a, b = [int(x) for x in a], [int(x) for x in b]
    if not a or not b:
        return math.nan, "exact"
    pooled = a + b
    ranks = _doubled_midranks(pooled)
    big_n, na = len(pooled), len(a)
    total = sum(ranks[x] for x in pooled)
    w = sum(ranks[x] for x in a)
    dev = abs(big_n * w - na * total)  # |W − E| · N, E = na · total / N
    if (na + 1) * (big_n * (big_n + 1) + 1) > MAX_EXACT_STATES:
        return _rank_sum_mc(a, b, ranks, seed), "monte_carlo"
    import numpy as np
    from scipy.stats import hypergeom

    width = big_n * (big_n + 1) + 1  # doubled rank sums reach N(N+1)
    dist = np.zeros((na + 1, width))  # (chosen so far, doubled rank sum) -> probability
    dist[0, 0] = 1.0
    remaining = big_n
    for v in sorted(ranks):
        t, r = pooled.count(v), ranks[v]
        nxt = np.zeros_like(dist)
        for k in range(na + 1):
            row = dist[k]
            if not row.any():
                continue
            need = na - k
            xs = np.arange(min(t, need) + 1)
            for x, p in zip(xs, hypergeom.pmf(xs, remaining, t, need), strict=True):
                if p > 0:
                    nxt[k + x, x * r :] += p * row[: width - x * r]
        dist, remaining = nxt, remaining - t
    sums = np.arange(width)
    keep = np.abs(big_n * sums - na * total) >= dev - 1e-9
    return float(min(1.0, dist[na][keep].sum())), "exact"


def _rank_sum_mc(a: list[int], b: list[int], ranks: dict[int, int], seed: int) -> float:
    import numpy as np
    from scipy.stats import permutation_test

    ra = np.array([ranks[x] for x in a], float)
    rb = np.array([ranks[x] for x in b], float)

    def stat(x, y, axis):  # |mean rank difference|: the same two-sided ordering as |W − E|
        return np.abs(np.mean(x, axis=axis) - np.mean(y, axis=axis))

    res = permutation_test((ra, rb), stat, permutation_type="independent", vectorized=True,
                           n_resamples=MC_RESAMPLES, alternative="greater", rng=np.random.default_rng(seed))  # fmt: skip
    return float(res.pvalue)


# ----------------------------------------------------------------------------------------- compare
def progress_pairs(ea, eb, axis: str) -> tuple[dict[int, list[tuple[int, int]]], int]:
    """Level -> (score A, score B) per episode pair (``pairing.PAIR_KEY``) finished ok and scored in both;
    and how many ok pairs dropped out for a missing score. Call only for runs ``pair_episodes`` calls paired."""
    cols = [*PAIR_KEY, "status", "progress"]
    a = ea[ea["axis"] == axis][cols] if "progress" in ea else None
    b = eb[eb["axis"] == axis][cols] if "progress" in eb else None
    if a is None or b is None:
        return {}, 0
    m = a.merge(b, on=list(PAIR_KEY), suffixes=("_a", "_b"))
    m = m[(m["status_a"] == "ok") & (m["status_b"] == "ok")]
    scored = m["progress_a"].notna() & m["progress_b"].notna()
    out: dict[int, list[tuple[int, int]]] = {}
    for k, x, y in zip(m["level"][scored], m["progress_a"][scored], m["progress_b"][scored], strict=True):
        out.setdefault(int(k), []).append((int(x), int(y)))
    return out, int((~scored).sum())


def compare_progress(ea, eb, axis: str, paired: bool) -> dict:
    """compare.json's ``progress`` block of one axis: per level the mean scores and an exact rank test
    (paired: Wilcoxon signed-rank on B − A; unpaired: rank-sum permutation test), Holm over the levels."""
    rows: list[dict] = []
    if paired:
        pairs, dropped = progress_pairs(ea, eb, axis)
        for k in sorted(pairs):
            ps = pairs[k]
            d = [y - x for x, y in ps]
            rows.append({
                "level": k, "pairs": len(ps), "mean_a": sum(x for x, _ in ps) / len(ps),
                "mean_b": sum(y for _, y in ps) / len(ps), "b_higher": sum(v > 0 for v in d),
                "a_higher": sum(v < 0 for v in d), "ties": sum(v == 0 for v in d),
                "p_value": signed_rank_exact(d), "method": "exact",
            })  # fmt: skip
        block = {"test": PAIRED_TEST, "paired": True, "dropped_unscored": dropped}
    else:
        a, b = ea[ea["axis"] == axis], eb[eb["axis"] == axis]
        for k in sorted(set(a["level"]) & set(b["level"])):
            sa, sb = _scores(a[a["level"] == k]), _scores(b[b["level"] == k])
            if not sa or not sb:
                continue
            p, method = rank_sum_test(sa, sb, seed=int(k) & 0xFFFF)
            rows.append({"level": int(k), "n_a": len(sa), "n_b": len(sb), "mean_a": sum(sa) / len(sa),
                         "mean_b": sum(sb) / len(sb), "p_value": p, "method": method})  # fmt: skip
        block = {"test": UNPAIRED_TEST, "paired": False}
    for r, p in zip(rows, holm([r["p_value"] for r in rows]), strict=True):
        r["p_holm"] = p
    if not rows:
        block["unavailable"] = (
            "no level has progress scores in both runs (a run predates the progress column?)"
        )
    return {**block, "levels": rows}


def render_compare(block: dict | None, alpha: float = 0.05) -> list[str]:
    """compare.md lines for one axis's ``progress`` block (after the binary table, which stays primary)."""
    if not block:
        return []
    if block.get("unavailable"):
        return ["", f"Partial credit (progress 0..5): {block['unavailable']}."]
    if block["paired"]:
        head = ("paired, two-sided exact Wilcoxon signed-rank test on the score differences B − A (ties at "
                "midranks, zero differences dropped)")  # fmt: skip
        lines = ["", f"Partial credit (progress 0..5: {' < '.join(STAGES)}; {head}; Holm over levels; secondary "
                 "to the binary test above):", "",
                 "| level | pairs | mean A | mean B | B higher | A higher | ties | p | p (Holm) |",
                 "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for r in block["levels"]:
            lines.append(f"| {r['level']} | {r['pairs']} | {r['mean_a']:.2f} | {r['mean_b']:.2f} | {r['b_higher']} | "
                         f"{r['a_higher']} | {r['ties']} | {r['p_value']:.3g} | {r['p_holm']:.3g} |")  # fmt: skip
        if block.get("dropped_unscored"):
            lines.append(f"\n{block['dropped_unscored']} pair(s) without a score in a run left out.")
    else:
        lines = ["", f"Partial credit (progress 0..5: {' < '.join(STAGES)}; unpaired, two-sided Wilcoxon–Mann–"
                 "Whitney permutation test, exact where feasible; Holm over levels; secondary to the binary test "
                 "above):", "", "| level | n A | n B | mean A | mean B | p | p (Holm) |",
                 "|---|---|---|---|---|---|---|"]  # fmt: skip
        for r in block["levels"]:
            mc = " (MC)" if r["method"] != "exact" else ""
            lines.append(f"| {r['level']} | {r['n_a']} | {r['n_b']} | {r['mean_a']:.2f} | {r['mean_b']:.2f} | "
                         f"{r['p_value']:.3g}{mc} | {r['p_holm']:.3g} |")  # fmt: skip
    sig = [r["level"] for r in block["levels"] if r["p_holm"] < alpha]
    lines.append("")
    lines.append(f"Progress differs at α = {alpha} (Holm) at level(s) {', '.join(map(str, sig))}." if sig else
                 f"No level's progress differs at α = {alpha} (Holm).")  # fmt: skip
    return lines


# ----------------------------------------------------------------------------------------- report
def render_levels(present: list[tuple[str, dict]]) -> list[str]:
    """report.md lines: mean progress and n scored per level and run (nothing when no run is scored)."""
    if not any(r.get("progress") for _, a in present for r in a["levels"]):
        return []
    lines = ["", "Mean progress per level (0 = no contact … 5 = success; n scored episodes; descriptive):", "",
             "| level | " + " | ".join(lbl for lbl, _ in present) + " |", "|---|" + "---|" * len(present)]  # fmt: skip
    for k in sorted({r["level"] for _, a in present for r in a["levels"]}):
        cells = []
        for _, a in present:
            p = next((r.get("progress") for r in a["levels"] if r["level"] == k), None)
            cells.append(f"{p['mean']:.2f} (n = {p['n']})" if p else "—")
        lines.append(f"| {k} | " + " | ".join(cells) + " |")
    return lines


def plot_progress(curves: list[tuple[str, dict]], axis: str, path: Path) -> Path | None:
    """``progress_figure`` as a PNG at ``path``; None when no run has scores."""
    fig = progress_figure(curves, axis)
    if fig is None:
        return None
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_savefig(fig, path)  # a report read while another writes never sees half a PNG
    return path


def progress_figure(curves: list[tuple[str, dict]], axis: str):
    """One panel per run: the share of each progress stage per level (success on top, so the success rate is
    the top segment) and the mean score (right axis), every stage in a legend under the panels; None when no run
    has scores."""
    if not any(r.get("progress") for _, a in curves for r in a["levels"]):
        return None
    from matplotlib.figure import Figure  # not pyplot (report.plot_axis)

    fig = Figure(figsize=(4.2 * len(curves), 3.8), dpi=120, layout="constrained")
    axes = fig.subplots(1, len(curves), squeeze=False)
    for ax, (label, a) in zip(axes[0], curves, strict=True):
        rows = [r for r in a["levels"] if r.get("progress")]
        ks = [r["level"] for r in rows]
        bottom = [0.0] * len(rows)
        for i, stage in enumerate(STAGES):
            share = [r["progress"]["stages"].get(stage, 0) / r["progress"]["n"] for r in rows]
            ax.bar(ks, share, bottom=bottom, color=COLOURS[i], label=f"{i} {stage}", width=0.8)
            bottom = [b + s for b, s in zip(bottom, share, strict=True)]
        twin = ax.twinx()
        twin.plot(ks, [r["progress"]["mean"] for r in rows], "k.-", label="mean progress")
        twin.set_ylim(0, 5.2)
        twin.set_ylabel("mean progress (0..5)", fontsize=7)
        note = count_note([r["progress"]["n"] for r in rows], a.get("pooled_tasks") or [])
        ax.set_title(f"{label}\n{note}; descriptive, no CI", fontsize=7)
        ax.set_xlabel(f"level k along {axis}")
        ax.set_ylim(0, 1)
        if ks:
            ax.set_xticks(ks)
    axes[0][0].set_ylabel("share of scored episodes")
    handles, labels = axes[0][0].get_legend_handles_labels()
    h2, l2 = fig.axes[-1].get_legend_handles_labels()
    ncol = 7 if len(curves) > 1 else 4  # 7 entries: one row under two panels, two rows under one
    fig.legend(handles + h2, labels + l2, fontsize=7, loc="outside lower center", ncol=ncol, frameon=False)
    return fig
