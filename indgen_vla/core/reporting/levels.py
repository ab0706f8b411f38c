"""Per-level rows and verdicts of one axis: rates with CIs, the data floor, CI or sequential verdicts, k* status.

``summary.summarize`` builds the pooled rows and one entry per task with these. An adaptive run decides each
(task, axis) ladder with the sequential rule; several tasks' ladders are pooled per level afterwards
(``pool_ladders``), counting only the tasks that ran that level.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from indgen_vla.core.reporting.failures import failure_counts_by
from indgen_vla.core.reporting.partial_credit import level_progress_by
from indgen_vla.core.stats.breakpoint import kstar_status, signed_level, verdict_from_ci
from indgen_vla.core.stats.frames import group_items, py
from indgen_vla.core.stats.metrics import MIN_N, below_floor, break_levels, ci_name, success_rate
from indgen_vla.core.stats.sample_size import more_to_decide, verdict_error
from indgen_vla.core.stats.sprt import (
    UNTIL_FAILURE,
    level_outcomes,
    operating_characteristic,
    outcome_prefix,
    rule_from_plan,
)


@dataclass(frozen=True)
class LevelCounts:
    """One level's episodes (one task's, or pooled) reduced to what its summary row shows."""

    rows: int = 0  # finished rows, errors included
    n: int = 0  # rows with status "ok"
    successes: int = 0
    param: float | None = None  # one_param's answer
    failures: Mapping[str, int] = field(default_factory=dict)  # failures.failure_counts
    progress: dict | None = None  # progress.level_progress


def level_counts(df, keys: Sequence[str] = ("level",)) -> dict[tuple, LevelCounts]:
    """Every group's ``LevelCounts``, keyed by the tuple of its ``keys`` values (e.g. (task, level)), in one pass
    over ``df``: filtering the table once per level and task is O(cells × rows) on a protocol-size run."""
    keys = list(keys)
    if not len(df):
        return {}
    by = [df[k] for k in keys]
    ok = df[df["status"] == "ok"]
    n = dict(group_items(ok.groupby(keys, sort=False).size()))
    successes = dict(group_items(ok.groupby(keys, sort=False)["success"].sum()))
    param = df["param"]
    spread = dict(group_items(param.groupby(by, sort=False).max() - param.groupby(by, sort=False).min()))
    has_nan = dict(group_items(param.isna().groupby(by, sort=False).any()))
    firsts = df.drop_duplicates(keys)  # the first row of each group: one_param's unique()[0]
    first = {
        tuple(py(v) for v in k): p for *k, p in zip(*(firsts[c] for c in keys), firsts["param"], strict=True)
    }
    failures, progress = failure_counts_by(df, keys), level_progress_by(df, keys)
    return {
        k: LevelCounts(rows=rows, n=n.get(k, 0), successes=int(successes.get(k, 0)),
                       param=float(first[k]) if not has_nan[k] and spread[k] <= 1e-12 else None,
                       failures=failures.get(k, {}), progress=progress.get(k))
        for k, rows in group_items(df.groupby(by, sort=False).size())
    }  # fmt: skip


def by_task(df) -> tuple[dict, dict]:
    """Each task's rows and its ``level_counts`` keyed by (level,), from one pass over an axis's rows (a filter per
    task is O(tasks × rows) on a protocol of many tasks)."""
    counts: dict[str, dict] = {}
    for (task, level), c in level_counts(df, ("task", "level")).items():
        counts.setdefault(task, {})[(level,)] = c
    return dict(iter(df.groupby("task", sort=False))), counts


def level_rows(
    df, levels: Sequence[int], planned: int | None, ci: str, counts: Mapping[tuple, LevelCounts] | None = None
) -> list[dict]:
    """Per level n/successes/rate/CI/errors, and ``insufficient`` when below the data floor; ``counts``: ``df``'s
    ``level_counts`` keyed by (level,), when the caller has them already."""
    counts = level_counts(df) if counts is None else counts
    rows = []
    for level in levels:
        c = counts.get((int(level),), EMPTY)
        r = success_rate(c.successes, c.n, method=ci)
        rows.append({
            "level": int(level), "param": c.param, "n": r.n,
            "successes": r.successes, "rate": r.rate, "ci_low": r.ci_low, "ci_high": r.ci_high,
            "errors": c.rows - c.n, "planned": planned, "insufficient": below_floor(r.n, planned),
            "failures": dict(c.failures), "progress": c.progress,
        })  # fmt: skip
    return rows


EMPTY = LevelCounts()  # a level without a finished episode


def one_param(d) -> float | None:
    """The level's axis parameter; None when no episode ran or the pooled tasks disagree (absolute positions
    such as pick_y differ per task: each task's rows carry their own)."""
    values = d["param"].unique()
    return float(values[0]) if len(values) and (values.max() - values.min()) <= 1e-12 else None


def usable_rates(rows: list[dict]) -> dict[int, float]:
    """Rates for k*: a level below the data floor counts as missing (NaN), never as a measurement."""
    return {r["level"]: float("nan") if r["insufficient"] else r["rate"] for r in rows}


def decide(rows: list[dict], gamma: float) -> None:
    """Each level's three-way verdict from its CI (broken / intact / undetermined; below the floor: undetermined)."""
    for r in rows:
        r["decision"] = (
            "undetermined" if r["insufficient"] else verdict_from_ci(r["ci_low"], r["ci_high"], gamma)
        )


def sequential(rows: list[dict], df, adaptive: dict, episodes: int) -> None:
    """Adaptive runs: each level's verdict is the sequential rule's, on its episodes in index order; the data
    floor counts against the episodes the rule used, not the cap (a level past a decided k* was never run).
    ``df`` holds one ladder: one task's episodes of one axis. The paper's until-failure design: ``until_failure``."""
    if adaptive.get("mode") == UNTIL_FAILURE:
        until_failure(rows, float(adaptive["gamma"]), episodes)
        return
    rule = rule_from_plan(adaptive, episodes)
    per_level = level_outcomes(df)
    # the rule's exact error of each call at the near end of the other side (its guarantee; inside the indifference
    # zone either call may come, e.g. "broken" at S = γ with chance 26 % under the default rule)
    error_at = {"broken": [rule.p_intact, operating_characteristic(rule, rule.p_intact).p_broken],
                "intact": [rule.p_broken, operating_characteristic(rule, rule.p_broken).p_intact]}  # fmt: skip
    for r in rows:
        outcomes = outcome_prefix(per_level.get(r["level"], {}))
        dec = rule.decide(outcomes)
        r["sequential"] = {**dec.as_dict(), "error_at": error_at}
        r["decision"] = "undetermined" if dec.verdict == "continue" else dec.verdict
        r["planned"] = dec.episodes if dec.final else dec.next_boundary
        r["insufficient"] = dec.n == 0 or (not dec.final and below_floor(r["n"], r["planned"]))


def until_failure(rows: list[dict], gamma: float, episodes: int) -> None:
    """The paper's real-robot design (§5.3): every level's verdict is its CI's (``decide``); per direction, the first
    level with all its ``episodes`` finished and an observed rate < γ is marked ``observed_break`` (the walk stopped
    there), and the levels past it that never ran are ``not_run`` (planned 0: nothing was missed)."""
    decide(rows, gamma)
    for side in (sorted((r for r in rows if r["level"] >= 0), key=lambda r: r["level"]),
                 sorted((r for r in rows if r["level"] <= 0), key=lambda r: -r["level"])):  # fmt: skip
        stopped = False
        for r in side:
            if stopped and not r["n"] + r["errors"]:
                r.update(planned=0, not_run=True)
            elif not stopped and r["n"] + r["errors"] >= episodes and r["n"] and r["rate"] < gamma:
                r["observed_break"] = stopped = True


def design_text(adaptive: dict | None, episodes: int | None) -> str | None:
    """One line naming the paper's until-failure design and what its break is (None for the other designs)."""
    if not adaptive or adaptive.get("mode") != UNTIL_FAILURE:
        return None
    return (f"the paper's fixed design (§5.3, until failure): {episodes} episodes per level, levels in order, "
            f"stopped at the first level whose observed rate is below γ = {adaptive['gamma']:g}; that break is "
            "observed, not statistically decided (its 95 % CI is in the verdict)")  # fmt: skip


NOT_EVALUATED = "not evaluated (no level on this side of 0 was run)"  # a signed axis run one-sided


def kstar_status_of(rows: list[dict], signed: bool) -> dict:
    """Per direction where k* can lie given the verdicts ("k* = +2, determined" or "k* ∈ [+1, +3]"), speaking only
    of the levels that ran (a planned level with no finished episode is named as not run)."""
    verdicts = {r["level"]: r["decision"] for r in rows}
    ran = {r["level"] for r in rows if r["n"] + r.get("errors", 0)}  # planned but not run: n = 0, no errors
    sides = (("pos", 1), ("neg", -1)) if signed else (("pos", 1),)
    out = {}
    for d, s in sides:
        order = sorted((k for k in verdicts if s * k >= 0), key=abs)
        out[d] = (
            {"earliest": None, "latest": None, "determined": False, "text": NOT_EVALUATED}
            if signed and order == [0]  # a signed axis run on the other side only: this side has no level
            else kstar_status(verdicts, order, ran)
        )
    return out


def episodes_used(df, per_task: int | None, n_tasks: int, n_levels: int) -> dict:
    """Episodes run (finished rows, errors included) against the fixed design's tasks × levels × episodes."""
    fixed = per_task * n_tasks * n_levels if per_task else None
    return {"used": int(len(df)), "fixed_design": fixed}


def task_entry(df, levels, per_task, ci, gamma, signed, adaptive: dict | None, counts=None) -> dict:
    """One task's rows of one axis: CI verdicts, or the sequential rule's for an adaptive run, with its k*
    (``counts``: ``df``'s ``level_counts`` by (level,), when the caller has them)."""
    rows = level_rows(df, levels, per_task, ci, counts)
    if adaptive and per_task:
        sequential(rows, df, adaptive, per_task)
    else:
        decide(rows, gamma)
    return {
        "levels": rows,
        "break_level": break_levels(usable_rates(rows), gamma, signed=signed),
        "kstar_status": kstar_status_of(rows, signed),
        "episodes": episodes_used(df, per_task, 1, len(levels)),
    }


def pool_ladders(pooled: list[dict], tasks: dict[str, dict]) -> None:
    """Pooled rows of a several-task adaptive run: a level pools the tasks whose ladder ran it, and its data floor
    counts against what their rules planned (a task whose ladder broke earlier never runs the level)."""
    for r in pooled:
        ran = {
            t: row
            for t, e in tasks.items()
            for row in e["levels"]
            if row["level"] == r["level"] and row["n"] + row["errors"]
        }
        r["planned"] = sum(int(row["planned"] or 0) for row in ran.values()) or None
        r["pooled_from"] = len(ran)
        if 0 < len(ran) < len(tasks):  # a rate over a subset: say which, beside it (report.partial_pool_text)
            r["pooled_only"] = sorted(ran)
        r["insufficient"] = r["n"] == 0 or below_floor(r["n"], r["planned"])


MAX_MORE = 5000  # beyond this many extra episodes a level is called "not decidable at this rate"
DECIDE_POWER = 0.8  # the chance with which "N more episodes would decide it" decides it, if the rate holds


def episodes_to_decide(successes: int, n: int, gamma: float, ci: str = "wilson") -> int | None:
    """How many more episodes make the CI's upper bound fall below γ with chance ≥ 80 % if the observed rate is the
    true one (exact binomial sums, the episodes so far kept; None: > MAX_MORE)."""
    return more_to_decide(successes, n, gamma, ci, DECIDE_POWER, MAX_MORE)


def _error_text(n: int, gamma: float, ci: str, verdict: str) -> str:
    """The real error of a level's verdict at its n, as computed exactly (nominal 2.5 % a side for a 95 % CI)."""
    return f"{ci_name(ci)} 95 % CI; chance of this call at S = γ with n = {n}: {100 * verdict_error(n, gamma, ci, verdict):.1f} %"


def _seq_error_text(seq: dict, verdict: str) -> str:
    """A sequential call's own exact error, as a CI verdict prints its own: the printed Wilson interval is descriptive
    after stopping (it may reach past γ), and between γ − δ and γ + δ either call may come."""
    if "error_at" not in seq:  # a summary written before the rule's errors were recorded
        return ""
    (s, p), (lo, hi) = seq["error_at"][verdict], sorted(x[0] for x in seq["error_at"].values())
    return (
        f" (chance of this call at S = {s:g}: {100 * p:.1f} %; between {lo:g} and {hi:g} either call may come, "
        "and the interval is descriptive after stopping)"
    )


def _rate(r: dict) -> str:
    return (
        f"{100 * r['rate']:.0f} %, n = {r['n']}, 95 % CI [{100 * r['ci_low']:.0f}, {100 * r['ci_high']:.0f}]"
    )


def direction_verdict(rows: list[dict], k, gamma: float, ci: str = "wilson") -> str:
    """One direction's break level as a reviewer would state it, from its rows (outward from level 0) and the
    point k* (a level, None for no break in range, or "undetermined")."""
    if not rows:
        return "no levels"
    if k == "undetermined":
        hole = next(r for r in rows if r["insufficient"])
        planned = hole.get("planned")
        of = f" of {planned}" if planned else ""
        if planned and planned < MIN_N and hole["n"] >= planned:  # the level is done; the design is too small
            fix = f"every planned episode ran, and under {MIN_N} never give a k*: run --episodes {MIN_N} or more"
        elif planned and hole["n"] + hole.get("errors", 0) >= planned:  # recorded, some without an outcome
            fix = (
                "every planned episode is recorded; a re-run retries those that ended in error, but one ruled out "
                "by the level (an infeasible cell) stays so: only more --episodes add to n"
            )
        else:
            fix = "finish it (re-run the same evaluate command: it runs what is missing and retries errors)"
        return f"undetermined: level {signed_level(hole['level'])} has too little data (n = {hole['n']}{of}); {fix}"
    if k is None:
        last = signed_level(rows[-1]["level"])
        open_ = [
            signed_level(r["level"]) for r in rows if r.get("decision") != "intact" and not r["insufficient"]
        ]
        if not open_ and any(r.get("sequential") for r in rows):
            seq = next(r["sequential"] for r in rows if r.get("sequential"))
            return (f"no break through {last}: every level is decided at or above γ = {gamma:g} by the sequential "
                    f"rule{_seq_error_text(seq, 'intact')}")  # fmt: skip
        # the error is not monotone in n (Wilson at γ = 0.2: 1.7 % at n = 6, 5.6 % at 8): the largest
        if not open_:
            n = max((r["n"] for r in rows), key=lambda m: (verdict_error(m, gamma, ci, "intact"), -m))
            return (f"no break through {last}: every level is significantly at or above γ = {gamma:g} "
                    f"({_error_text(n, gamma, ci, 'intact')}, the largest over its levels)")  # fmt: skip
        return (
            f"no level below γ = {gamma:g} through {last} ({', '.join(open_)} not yet significantly above it)"
        )
    r = next(x for x in rows if x["level"] == k)
    head = f"{signed_level(k)} ({_rate(r)})"
    if r.get("observed_break"):  # the paper's until-failure design stopped here
        why = ("its CI lies below γ too" if r.get("decision") == "broken"
               else f"the CI reaches {100 * r['ci_high']:.0f} % ≥ γ")  # fmt: skip
        return (f"observed break at {head}: the paper's until-failure design stopped at the first level below "
                f"γ = {gamma:g}; observed, not statistically decided ({why})")  # fmt: skip
    if r.get("decision") == "broken" and r.get("sequential") is not None:
        return f"breaks at {head}, decided below γ = {gamma:g} by the sequential rule{_seq_error_text(r['sequential'], 'broken')}"
    if r.get("decision") == "broken":
        return f"breaks at {head}, significantly below γ = {gamma:g} ({_error_text(r['n'], gamma, ci, 'broken')})"
    seq = r.get("sequential")
    if seq is not None:  # an adaptive run: the sequential rule says when it looks next
        if r["planned"] and r["planned"] > r["n"]:
            return f"first level below γ: {head}; not yet decided: the rule looks again at {r['planned']} episodes"
        return f"first level below γ: {head}; undecided at the cap of {r['n']} episodes"
    more = episodes_to_decide(r["successes"], r["n"], gamma, ci)
    if more is None:
        return f"first level below γ: {head}; not significant, and no feasible number of episodes at this rate decides it"
    return (f"first level below γ: {head}; not yet significant: about {more} more episodes at {signed_level(k)} "
            f"would decide it with {DECIDE_POWER:.0%} chance if the rate holds")  # fmt: skip


def axis_verdicts(
    rows: list[dict],
    break_level: dict,
    gamma: float,
    signed: bool,
    ci: str = "wilson",
    status: dict | None = None,
) -> dict:
    """{"pos": sentence, "neg": sentence (signed axes)} for summary.json's human-readable ``verdict``; a decided
    break with an undecided level before it says so, since k* may then be that earlier level. ``status``: the rows'
    ``kstar_status_of``, when the caller has it."""
    out = {}
    status = kstar_status_of(rows, signed) if status is None else status
    for d, keep in (
        (("pos", lambda k: k >= 0), ("neg", lambda k: k <= 0)) if signed else (("pos", lambda k: True),)
    ):
        side = sorted((r for r in rows if keep(r["level"])), key=lambda r: abs(r["level"]))
        if signed and [r["level"] for r in side] == [0]:  # pick_y run at 0:3: this side is level 0 alone
            out[d] = NOT_EVALUATED
            continue
        out[d] = direction_verdict(side, break_level.get(d), gamma, ci)
        st, k = status.get(d) or {}, break_level.get(d)
        if isinstance(k, int) and st.get("latest") == k and not st.get("determined"):
            open_ = [signed_level(r["level"]) for r in side
                     if abs(r["level"]) < abs(k) and r.get("decision") != "intact"]  # fmt: skip
            out[d] += f"; {st['text']}: {', '.join(open_)} not shown at or above γ"
    return out


def verdict_line(verdict: dict, signed: bool) -> str:
    """The verdicts of both directions on one line: "+: …; −: …"."""
    if not signed:
        return verdict.get("pos", "—")
    return "; ".join(f"{'+' if d == 'pos' else '−'}: {verdict[d]}" for d in ("pos", "neg") if d in verdict)


# ---------------------------------------------------------------------------------- black-box regime (appendix B)
BLACK_BOX = "black-box"  # a scene family's protocol_facts()["regime"] when T0 is empirical (RoboCasa365)
BLACK_BOX_ALPHA = 0.05  # the monotone test's level for the post-hoc validation of condition 2


def run_regime(manifest: dict) -> str:
    """The run's regime from its manifest: "black-box" when the scene family says so, else "vanilla"."""
    env = (manifest.get("resolved") or {}).get("environment") or {}
    return BLACK_BOX if (env.get("protocol") or {}).get("regime") == BLACK_BOX else "vanilla"


def condition2_validation(monotone: dict, regime: str) -> dict | None:
    """Black-box regime: condition 2 (strictly harder levels) cannot be certified, so it is validated post hoc
    (appendix B): per direction, validated when the monotone test rejects "success does not fall with k" at
    ``BLACK_BOX_ALPHA``. None in the vanilla regime (condition 2 holds by construction there)."""
    if regime != BLACK_BOX:
        return None
    return {
        "regime": regime, "alpha": BLACK_BOX_ALPHA,
        "directions": {d: {"p": t["p_decreasing"], "validated": bool(t["p_decreasing"] < BLACK_BOX_ALPHA)}
                       for d, t in monotone.items()},
    }  # fmt: skip


def fmt_condition2(c: dict | None, signed: bool) -> str:
    """One cell/line: whether the black-box ordering is validated next to k*, per direction."""
    if not c:
        return "by construction (vanilla regime)"

    def one(d: str) -> str:
        t = c["directions"].get(d)
        if t is None:
            return "untested (< 2 usable levels): k* is not validated"
        if t["validated"]:
            return f"validated (monotone decrease, p = {t['p']:.2g} < {c['alpha']:g})"
        return f"NOT validated (p = {t['p']:.2g} ≥ {c['alpha']:g}): the levels are not shown to be harder"

    return f"+: {one('pos')}; −: {one('neg')}" if signed else one("pos")
