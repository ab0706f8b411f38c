"""Paired contrasts inside the plan: each level of an axis against its level 0 (T0), and one axis against another.

Episode i of a task gets the same seed, hence the same initial state, at every level of every axis
(``plan.plan_jobs``), so level k and level 0 of one axis, or level k of two axes, are paired episode by episode
on (scene, task, episode[, level]) with equal seeds. Per level the evidence is the discordant pairs, tested with
the exact McNemar test (``metrics.compare_paired_levels``) and Holm-corrected over the levels of the axis. Pairs
never cross tasks, so the pooled test is stratified by task: the matched-pairs Mantel–Haenszel test reduces to the
exact binomial on the discordant counts summed over tasks (``groups.stratified_mcnemar``). Δ gets Newcombe's
square-and-add interval for paired proportions, and "no change" is claimed only by an equivalence test (two
one-sided tests, each the exact non-inferiority test of ``noninferiority``), never from a large p-value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.stats.frames import group_items
from indgen_vla.core.stats.metrics import compare_paired_levels, pooled_text, usable_levels, wilson_ci
from indgen_vla.core.stats.noninferiority import non_inferior

ALPHA = 0.05  # the level of the report's Δ-vs-T0 verdicts (Holm) and of its equivalence tests
EPISODE_KEY = ("scene", "task", "episode")  # what pairs two levels of one axis; "level" too between two axes
TEST = "exact McNemar on the discordant pairs (pairs within task: stratified by task)"


def check_margin(margin: float | None) -> None:
    """``--margin`` of ``report`` and ``compare --axes``: a difference of rates, strictly between 0 and 1."""
    if margin is not None and not 0 < margin < 1:
        raise ConfigError(f"--margin must be in (0, 1), e.g. 0.1 for ±10 points; got {margin}")


def paired_difference_ci(
    both: int, a_only: int, b_only: int, neither: int, conf: float = 0.95
) -> tuple[float, float]:
    """Newcombe's square-and-add interval for Δ = p_B − p_A of paired binary outcomes: the Wilson intervals of the two
    rates, combined with their estimated correlation (Newcombe 1998, method 10, as recommended and written by
    Fagerland, Lydersen & Laake 2014); (NaN, NaN) without a pair.

    Args:
        both, a_only, b_only, neither: pairs where both sides succeeded, only A, only B, neither.
    """
    if min(both, a_only, b_only, neither) < 0:
        raise ConfigError(f"paired counts must be >= 0, got {both}, {a_only}, {b_only}, {neither}")
    n = both + a_only + b_only + neither
    if n == 0:
        return math.nan, math.nan
    sb, sa = both + b_only, both + a_only  # successes of B and of A
    pb, pa = sb / n, sa / n
    lb, ub = wilson_ci(sb, n, conf)
    la, ua = wilson_ci(sa, n, conf)
    margins = sb * (n - sb) * sa * (n - sa)
    cross = both * neither - a_only * b_only
    if margins == 0 or 0 <= cross <= n / 2:
        psi = 0.0
    else:
        psi = (cross - n / 2 if cross > n / 2 else cross) / math.sqrt(margins)
    d = pb - pa
    lo = d - math.sqrt(max(0.0, (pb - lb) ** 2 + (ua - pa) ** 2 - 2 * psi * (pb - lb) * (ua - pa)))
    hi = d + math.sqrt(max(0.0, (pa - la) ** 2 + (ub - pb) ** 2 - 2 * psi * (pa - la) * (ub - pb)))
    return max(-1.0, lo), min(1.0, hi)


def paired_equivalence(
    both: int, a_only: int, b_only: int, neither: int, margin: float, alpha: float = ALPHA
) -> dict:
    """Equivalence of paired rates within ±margin by two one-sided tests at level α, each the gate's exact
    unconditional non-inferiority test (``noninferiority``), one per direction: its size holds at ±margin, where
    the 1 − 2α Newcombe interval inside ±margin (used before, and still reported as ``ci``) erred 11 % at 50 pairs
    for a nominal 5 % (docs/statistics.md). One claim across several levels ("no level changes") needs each level
    shown at α (an intersection–union test: no multiplicity correction)."""
    if not 0 < margin < 1:
        raise ConfigError(f"equivalence margin must be in (0, 1), got {margin}")
    lo, hi = paired_difference_ci(both, a_only, b_only, neither, conf=1 - 2 * alpha)
    n = both + a_only + b_only + neither
    shown = (
        bool(n)
        and non_inferior(a_only, b_only, n, margin, alpha)
        and non_inferior(b_only, a_only, n, margin, alpha)
    )
    return {"margin": margin, "alpha": alpha, "ci": [lo, hi], "equivalent": shown}


def paired_delta(
    row: dict, margin: float | None, alpha: float = ALPHA
) -> tuple[float, list[float], dict | None]:
    """Δ = B − A of one ``compare_paired_levels`` row, its 95 % interval and (with a margin) its equivalence test."""
    n, a_only, b_only = row["pairs"], row["a_only"], row["b_only"]
    both = row["successes_a"] - a_only
    cell = (both, a_only, b_only, n - both - a_only - b_only)
    delta = row["rate_b"] - row["rate_a"] if n else math.nan
    return (
        delta,
        list(paired_difference_ci(*cell)),
        None if margin is None else paired_equivalence(*cell, margin, alpha),
    )


def pair_frame(a, b, on: Sequence[str]):
    """Episodes finished ok on both sides with the same key ``on``, one row each: ``on``, B's ``level``,
    ``success_a``, ``success_b`` and ``same_seed`` (False where the sides were not planned alike)."""
    import pandas as pd

    cols_b = list(dict.fromkeys([*on, "level", "seed", "success"]))
    a_ok, b_ok = a[a["status"] == "ok"], b[b["status"] == "ok"]
    try:
        m = a_ok[[*on, "seed", "success"]].merge(
            b_ok[cols_b], on=list(on), suffixes=("_a", "_b"), validate="one_to_many"
        )
    except pd.errors.MergeError:
        raise RunDirError(
            "a run holds the same episode twice (same scene, task, axis, level and episode); "
            "rebuild it from its journal by re-running the same evaluate command"
        ) from None
    return m.assign(same_seed=m["seed_a"] == m["seed_b"])


def _vs_rows(
    m, ok_a: int, ok_b: dict[int, int], levels: Sequence[int], margin: float | None, usable: set[int] | None
) -> dict[int, dict]:
    """Per level k the paired contrast of B (level k) against A, Holm over the levels tested.

    Args:
        m: ``pair_frame`` rows of one group of pairs (all tasks, or one).
        ok_a, ok_b: episodes finished ok on side A (one count: every level's partner pool) and on side B per level,
            so that the episodes left without a partner are counted.
        usable: the levels above the data floor on both sides (None: all); the others keep their counts but are not
            tested (``insufficient``), as a level below the floor never yields a printed rate.
    """
    pairs: dict[int, list[tuple[bool, bool]]] = {int(k): [] for k in levels}
    for k, x, y in zip(m["level"], m["success_a"], m["success_b"], strict=True):
        pairs[int(k)].append((bool(x), bool(y)))
    tested = [k for k in pairs if usable is None or k in usable]
    rows = compare_paired_levels({k: pairs[k] for k in tested})
    rows += [{**compare_paired_levels({k: pairs[k]})[0], "p_value": math.nan, "p_holm": math.nan}
             for k in pairs if k not in tested]  # fmt: skip
    out = {}
    for r in rows:
        k, n = r["level"], r["pairs"]
        delta, ci, eq = paired_delta(r, margin)
        out[k] = {
            "delta": delta, "ci": ci, "n_pairs": n, "successes": [r["successes_a"], r["successes_b"]],
            "discordant": [r["a_only"], r["b_only"]], "p": r["p_value"], "p_holm": r["p_holm"],
            "unpaired": [ok_a - n, ok_b.get(k, 0) - n], "insufficient": k not in tested,
        }  # fmt: skip
        if eq is not None:
            out[k]["equivalence"] = eq
    return dict(sorted(out.items()))


def t0_contrasts(
    df, levels: Sequence[int], tasks: Sequence[str], margin: float | None = None, usable: dict | None = None
) -> dict | None:
    """Each level k != 0 of one axis against level 0: pooled over tasks and, with several tasks, per task.

    ``usable``: the levels above the data floor, pooled (key None) and per task (None: every level); a level is
    tested only when it and level 0 are.

    Returns:
        {"levels": {k: vs_t0}, "tasks": {task: {k: vs_t0}}}, {"unpaired_reason": ...} when level 0 and a level k
        disagree on an episode's seed, or None when the axis has no finished level-0 episode or no other level.
    """
    others = [int(k) for k in levels if k != 0]
    t0, rest = df[df["level"] == 0], df[df["level"] != 0]
    if not others or not (t0["status"] == "ok").any():
        return None
    m = pair_frame(t0, rest, EPISODE_KEY)
    if not m["same_seed"].all():
        bad = m[~m["same_seed"]].iloc[0]
        return {"unpaired_reason": f"episode {bad['episode']} of task {bad['task']} has another seed at level "
                                   f"{bad['level']} than at level 0, so the levels are not paired"}  # fmt: skip
    ok0 = dict(group_items(t0[t0["status"] == "ok"].groupby("task").size()))
    okk = dict(group_items(rest[rest["status"] == "ok"].groupby(["task", "level"]).size()))
    pooled_okk: dict[int, int] = {}
    for (_, k), c in okk.items():
        pooled_okk[k] = pooled_okk.get(k, 0) + c

    def floor(key):
        keep = None if usable is None else usable.get(key, set())
        return keep if keep is None or 0 in keep else set()

    out: dict = {
        "levels": _vs_rows(m, sum(ok0.values()), pooled_okk, others, margin, floor(None)),
        "tasks": {},
    }
    if len(tasks) > 1:
        groups = dict(iter(m.groupby("task", sort=False)))
        for t in tasks:
            out["tasks"][t] = _vs_rows(groups.get(t, m.iloc[:0]), ok0.get((t,), 0),
                                       {k: c for (tt, k), c in okk.items() if tt == t}, others, margin,
                                       floor(t))  # fmt: skip
    return out


def add_vs_t0(axis: dict, df, margin: float | None = None) -> None:
    """summary.json's ``vs_t0``: per level row (pooled and per task) and, per axis, the test and its verdict."""
    tasks = axis.get("tasks", {})
    usable = {
        None: usable_levels(axis["levels"]),
        **{t: usable_levels(e["levels"]) for t, e in tasks.items()},
    }
    res = t0_contrasts(df, [r["level"] for r in axis["levels"]], list(tasks), margin, usable)
    if res is None:
        return
    head = {"test": TEST, "paired_on": [*EPISODE_KEY, "seed"], "alpha": ALPHA, "margin": margin}
    if "unpaired_reason" in res:
        axis["vs_t0"] = {**head, **res}
        return
    for r in axis["levels"]:
        if r["level"] in res["levels"]:
            r["vs_t0"] = res["levels"][r["level"]]
    for t, e in tasks.items():
        for r in e["levels"]:
            if r["level"] in res["tasks"].get(t, {}):
                r["vs_t0"] = res["tasks"][t][r["level"]]
    rows = [r for r in axis["levels"] if "vs_t0" in r]
    tested = [r["level"] for r in rows if not math.isnan(r["vs_t0"]["p"])]
    axis["vs_t0"] = {**head, "holm_over": tested, "verdict": t0_verdict(rows, margin)}


def _k(k: int) -> str:
    return f"L{k}".replace("-", "−")


def pp(x: float) -> str:
    """A difference of rates in percentage points, signed: "−12", "+3", "0"."""
    if math.isnan(x):
        return "n/a"
    return "0" if round(100 * x) == 0 else f"{100 * x:+.0f}".replace("-", "−")


def t0_verdict(rows: list[dict], margin: float | None, alpha: float = ALPHA) -> str:
    """What the Δ-vs-T0 tests show for one axis, never more: levels that differ after Holm; "no change" only where
    the equivalence test shows it."""
    tested = [r for r in rows if not math.isnan(r["vs_t0"]["p"])]
    if not tested:
        if any(r["vs_t0"]["n_pairs"] for r in rows):
            return "not tested yet: T0 or every other level is below the data floor"
        return "no level has episodes paired with T0 yet"
    differ = [r for r in tested if r["vs_t0"]["p_holm"] < alpha]
    over = f"{len(tested)} level{'s' * (len(tested) != 1)}"
    text = (f"{', '.join(_k(r['level']) for r in differ)} differ{'s' * (len(differ) == 1)} from T0"
            if differ else "no level differs from T0") + f" (exact McNemar, Holm over {over}, α = {alpha:g})"  # fmt: skip
    if margin is None:
        return text + ("" if differ else "; this does not show they are equal (--margin M tests equivalence)")
    eq = [r for r in tested if r["vs_t0"]["equivalence"]["equivalent"]]
    within = f"within ±{100 * margin:.0f} pp of T0 (paired TOST, α = {alpha:g})"
    if len(eq) == len(tested):
        return f"{text}; every level tested is {within}"
    shown = f"{', '.join(_k(r['level']) for r in eq)} {within}" if eq else f"no level shown {within}"
    return f"{text}; {shown}"


def fmt_vs_t0(v: dict) -> str:
    """One contrast in words: "Δ vs T0 −12 pp [−25, +2] (paired n=50, discordant 9/3, exact McNemar p=0.15, Holm p=0.3)"."""
    if not v["n_pairs"]:
        return "Δ vs T0: no pairs (level not run, or no episode finished at both levels)"
    if v.get("insufficient"):
        return (
            f"Δ vs T0: insufficient data (paired n={v['n_pairs']}; this level or T0 is below the data floor)"
        )
    lo, hi = v["ci"]
    return (f"Δ vs T0 {pp(v['delta'])} pp [{pp(lo)}, {pp(hi)}] (paired n={v['n_pairs']}, discordant "
            f"{v['discordant'][0]}/{v['discordant'][1]}, exact McNemar p={v['p']:.2g}, Holm p={v['p_holm']:.2g})"
            + _unpaired(v))  # fmt: skip


def _unpaired(v: dict) -> str:
    a, b = v["unpaired"]
    return f"; unpaired: {a} at T0, {b} here" if a or b else ""


def _eq_cell(v: dict) -> str:
    e = v.get("equivalence")
    if e is None or math.isnan(e["ci"][0]):
        return "—"
    inside = -e["margin"] < e["ci"][0] and e["ci"][1] < e["margin"]
    # the CI alone errs above α at ±M (docs/statistics.md §1): where it disagrees with the exact tests, say who decides
    why = " (the exact tests decide, not the CI)" if inside != e["equivalent"] else ""
    return f"{'yes' if e['equivalent'] else 'not shown'}{why} [{pp(e['ci'][0])}, {pp(e['ci'][1])}]"


def render_vs_t0(present: list[tuple[str, dict]]) -> list[str]:
    """report.md's Δ-vs-T0 block of one axis: a table per run that has level 0, and a task × level table when it
    pools several tasks; nothing for runs without level 0."""
    lines: list[str] = []
    for label, a in present:
        head = a.get("vs_t0")
        if head is None:
            continue
        if "unpaired_reason" in head:
            lines += ["", f"Change from T0 ({label}): not tested, {head['unpaired_reason']}."]
            continue
        rows = [r for r in a["levels"] if "vs_t0" in r]
        margin = head["margin"]
        tasks = a.get("pooled_tasks") or []
        lines += ["", f"**Change from T0** ({label}): Δ = rate at level k − rate at level 0 over the episodes run at "
                  "both (paired: same task, episode and seed), 95 % Newcombe CI; " + TEST + ", Holm over the levels "
                  f"tested; {pooled_text(tasks)}"
                  + (f"; equivalence within ±{100 * margin:.0f} pp: two exact one-sided tests at α = {ALPHA:g} (TOST; "
                     "the 90 % CI is shown)" if margin else "")
                  + ".", "", f"Verdict: {head['verdict']}.", "",
                  "| level | Δ vs T0 (pp) [95% CI] | pairs | discordant T0 only / level only | p | p (Holm) | "
                  "unpaired T0 / level |" + (" equivalent [90% CI] |" if margin else ""),
                  "|---|---|---|---|---|---|---|" + ("---|" if margin else "")]  # fmt: skip
        for r in rows:
            v = r["vs_t0"]
            if not v["n_pairs"] or v.get("insufficient"):
                what = "insufficient data" if v["n_pairs"] else "no pairs"
                lines.append(f"| {r['level']} | {what} | {v['n_pairs']} | | | | {v['unpaired'][0]} / {v['unpaired'][1]} |"
                             + (" — |" if margin else ""))  # fmt: skip
                continue
            lo, hi = v["ci"]
            lines.append(f"| {r['level']} | {pp(v['delta'])} [{pp(lo)}, {pp(hi)}] | {v['n_pairs']} | "
                         f"{v['discordant'][0]} / {v['discordant'][1]} | {v['p']:.2g} | {v['p_holm']:.2g} | "
                         f"{v['unpaired'][0]} / {v['unpaired'][1]} |" + (f" {_eq_cell(v)} |" if margin else ""))  # fmt: skip
        if any(sum(r["vs_t0"]["unpaired"]) for r in rows):
            lines += ["", "Pairing incomplete: an episode finished at one level only (not run yet, an error, or "
                      "skipped by the adaptive rule) has no partner; Δ and the test use the pairs only."]  # fmt: skip
        lines += _per_task(a, rows)
    return lines


def _per_task(a: dict, rows: list[dict]) -> list[str]:
    """Task × level table of Δ vs T0 (discordant pairs, Holm p within the task) when the axis pools several tasks."""
    tasks = a.get("tasks", {})
    if len(tasks) < 2:
        return []
    ks = [r["level"] for r in rows]
    lines = ["", "Δ vs T0 per task, pp [95 % Newcombe CI] (paired n; discordant T0 only / level only; Holm p within "
             "the task):", "",
             "| task | " + " | ".join(_k(k) for k in ks) + " |", "|---|" + "---|" * len(ks)]  # fmt: skip
    for t in sorted(tasks):
        by = {r["level"]: r.get("vs_t0") for r in tasks[t]["levels"]}
        cells = []
        for k in ks:
            v = by.get(k)
            cells.append("—" if not v or not v["n_pairs"] else "insufficient data" if v.get("insufficient") else
                         f"{pp(v['delta'])} [{pp(v['ci'][0])}, {pp(v['ci'][1])}] (n={v['n_pairs']}; "
                         f"{v['discordant'][0]}/{v['discordant'][1]}; p {v['p_holm']:.2g})")  # fmt: skip
        lines.append(f"| {t} | " + " | ".join(cells) + " |")
    return lines


def t0_lines(a: dict) -> list[str]:
    """The terminal's Δ-vs-T0 lines of one axis (pooled rows), or [] when the axis has no level 0."""
    head = a.get("vs_t0")
    if head is None:
        return []
    if "unpaired_reason" in head:
        return [f"change from T0: not tested, {head['unpaired_reason']}"]
    tasks = a.get("pooled_tasks") or []
    out = [f"change from T0 (paired within task, {pooled_text(tasks)}): {head['verdict']}"]
    for r in a["levels"]:
        if "vs_t0" in r:
            eq = r["vs_t0"].get("equivalence")
            tail = f"; within ±{100 * eq['margin']:.0f} pp (90% CI): {_eq_cell(r['vs_t0'])}" if eq else ""
            out.append(f"  {_k(r['level'])}: {fmt_vs_t0(r['vs_t0'])}{tail}")
    return out


@dataclass(frozen=True)
class AxisPairs:
    """Episodes of axis A (run A) and axis B (run B) paired on (scene, task, level, episode) with equal seeds."""

    pairs: dict[int, list[tuple[bool, bool]]]  # shared level -> (success on A, success on B) per pair
    # shared level -> episodes finished ok on A / on B without an ok partner
    unpaired: dict[int, tuple[int, int]]
    only_a: tuple[int, ...]  # levels that only axis A ran (not compared)
    only_b: tuple[int, ...]
    tasks: tuple[str, ...]  # the tasks the pairs come from

    def describe(self) -> str:
        """The pairing in one line (compare.md's "Pairs:")."""
        n = sum(len(p) for p in self.pairs.values())
        ua, ub = (sum(u[i] for u in self.unpaired.values()) for i in (0, 1))
        text = (
            f"{n} episode pairs ({pooled_text(self.tasks)}; matched on scene, task, level, episode and seed)"
        )
        if ua or ub:
            text += (
                f"; pairing incomplete: {ua} finished episode(s) of A and {ub} of B have no finished partner"
            )
        for side, ks in (("A", self.only_a), ("B", self.only_b)):
            if ks:
                text += f"; level(s) {', '.join(map(str, ks))} only on {side}, not compared"
        return text


def pair_axes(ea, eb, axis_a: str, axis_b: str) -> AxisPairs:
    """Pair axis A's episodes (table ``ea``) with axis B's (``eb``, may be the same run) level by level; refuses, in
    one line, axes that share no level and episodes whose seeds differ (runs made with another --seed)."""
    a, b = ea[ea["axis"] == axis_a], eb[eb["axis"] == axis_b]
    la, lb = {int(k) for k in a["level"]}, {int(k) for k in b["level"]}
    shared = sorted(la & lb)
    if not shared:
        raise RunDirError(f"axes {axis_a} (levels {_span(la)}) and {axis_b} (levels {_span(lb)}) share no level; "
                          "evaluate them on common levels (--levels)")  # fmt: skip
    a, b = a[a["level"].isin(shared)], b[b["level"].isin(shared)]
    m = pair_frame(a, b, ("scene", "task", "level", "episode"))
    if not m["same_seed"].all():
        raise RunDirError(f"episode seeds differ between {axis_a} and {axis_b} (runs made with another --seed), so "
                          "their episodes are not paired; compare runs evaluated with the same --seed")  # fmt: skip
    pairs: dict[int, list[tuple[bool, bool]]] = {k: [] for k in shared}
    for k, x, y in zip(m["level"], m["success_a"], m["success_b"], strict=True):
        pairs[int(k)].append((bool(x), bool(y)))
    ok_a = dict(group_items(a[a["status"] == "ok"].groupby("level").size()))
    ok_b = dict(group_items(b[b["status"] == "ok"].groupby("level").size()))
    unpaired = {k: (ok_a.get((k,), 0) - len(pairs[k]), ok_b.get((k,), 0) - len(pairs[k])) for k in shared}
    return AxisPairs(pairs, unpaired, tuple(sorted(la - lb)), tuple(sorted(lb - la)),
                     tuple(sorted(set(m["task"]))))  # fmt: skip


def _span(levels: set[int]) -> str:
    return f"{min(levels)}..{max(levels)}" if levels else "none"
