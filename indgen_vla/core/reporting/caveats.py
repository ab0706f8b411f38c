"""The first lines of report.md, compare.md and the terminal: where a study cannot answer its question (a policy
that fails T0, too few episodes for any verdict), it says so before any rate."""

from __future__ import annotations

import math
from collections.abc import Sequence

from indgen_vla.core.reporting.certification_view import (
    basis_lines,
    certification_caveats,
    infeasible_caveats,
)
from indgen_vla.core.reporting.oracle_states import states_lines
from indgen_vla.core.stats.metrics import (
    MIN_N,
    ci_name,
    exact_2x2,
    mcnemar_exact,
    pooled_text,
    success_rate,
    usable_rows,
)

MAX_SEARCH = 10_000  # the largest episode count a "would need n" hint searches


def best_holm_p(n: int, m: int, paired: bool = True, test: str = "boschloo") -> float:
    """The smallest Holm-adjusted p any outcome can give: every one of ``n`` episodes (pairs) favouring one side at
    each of ``m`` tested levels (paired: exact McNemar with n discordant pairs; else ``test`` on n/n vs 0/n)."""
    if n <= 0 or m <= 0:
        return 1.0
    p = mcnemar_exact(n, 0) if paired else exact_2x2(n, n, 0, n, test)
    return min(1.0, m * p)


def needed_pairs(m: int, alpha: float) -> int | None:
    """The fewest pairs a level with which a paired McNemar test over ``m`` levels can reach Holm p < α."""
    return next((n for n in range(1, MAX_SEARCH) if best_holm_p(n, m) < alpha), None)


def break_undecidable(n: int, gamma: float, ci: str = "wilson") -> bool:
    """True when even 0/n successes leave the CI's upper end at or above γ: no level can be decided broken."""
    return n > 0 and success_rate(0, n, ci).ci_high >= gamma


def needed_for_break(gamma: float, ci: str = "wilson") -> int | None:
    """The fewest episodes a level with which 0/n puts the CI's upper end below γ."""
    return next((n for n in range(1, MAX_SEARCH) if not break_undecidable(n, gamma, ci)), None)


def rate_text(successes: int, n: int) -> str:
    """A count with its rate and Wilson 95 % CI, as compare.md and verdicts print it: "5/5 = 100% [57, 100]"."""
    if not n:
        return f"{successes}/{n}"
    r = success_rate(successes, n)
    return f"{successes}/{n} = {100 * r.rate:.0f}% [{100 * r.ci_low:.0f}, {100 * r.ci_high:.0f}]"


def blind_caveat(label: str, compared: bool = False) -> str:
    """The first line for a run whose policy declares it reads no observation (``PolicySpec.reads_observations``):
    T0 passed by chance on an easy scene must not read as a generalization curve."""
    what = ("a difference from it says how far the other policy is from chance, not how the two generalize"
            if compared else "k*, the trend tests and the change from T0 describe the scene, not the policy")  # fmt: skip
    return (
        f"**Cannot answer** ({label}): the policy declares it reads no observation, so it can neither generalize "
        "nor fail to: its per-level rates measure each level's difficulty for a policy acting blind (chance), not "
        f"generalization; {what}. The rates below are kept as that baseline."
    )


def axis_caveats(label: str, axis: str, a: dict, gamma: float, ci: str, alpha: float = 0.05) -> list[str]:
    """What one run's axis cannot answer: T0 below γ, a break no level could show, a change from T0 no level could
    show (each line names the run, axis, n and tasks)."""
    out = []
    where = f"{label}, `{axis}`, {pooled_text(a.get('pooled_tasks') or [])}"
    t0 = next((r for r in usable_rows(a["levels"]) if r["level"] == 0), None)
    if t0 is not None and t0["rate"] < gamma:
        out.append(f"**Cannot answer** ({where}): T0 succeeds in {t0['successes']}/{t0['n']} "
                   f"({100 * t0['rate']:.0f}% [{100 * t0['ci_low']:.0f}, {100 * t0['ci_high']:.0f}], {ci_name(ci)} 95 % CI), "
                   f"below γ = {gamma}: a policy that does not solve the base task (or acts blind to it) has no "
                   "generalization to measure; its k* is 0 by construction.")  # fmt: skip
    ran = [r["n"] for r in a["levels"] if r["n"] > 0]
    if ran and not usable_rows(a["levels"]):
        out.append(f"**Too few episodes** ({where}): every level is below the data floor (at most n = {max(ran)} a "
                   f"level; a rate needs ≥ {MIN_N} finished episodes and half the planned ones), so no rate, no k* "
                   "and no test is given.")  # fmt: skip
    ns = [r["n"] for r in usable_rows(a["levels"])]
    # --adaptive: the SPRT decides a break, not the CI
    by_sprt = any(r.get("sequential") for r in a["levels"])
    if ns and break_undecidable(max(ns), gamma, ci) and not by_sprt:
        need = needed_for_break(gamma, ci)
        # no level observed under γ: there is no observed k* to warn about, only that none could have been shown
        tail = ("the k* below is the first level whose observed rate is under γ, not a statistically decided break"
                if any(r["rate"] < gamma for r in usable_rows(a["levels"])) else
                "had one fallen under γ, its break would only have been observed, not statistically decided")  # fmt: skip
        out.append(f"**Too few episodes** ({where}): at most n = {max(ns)} a level; even 0/{max(ns)} leaves the "
                   f"{ci_name(ci)} 95 % CI above γ = {gamma}, so no level can be decided broken: {tail} "
                   f"(that needs n ≥ {need} a level).")  # fmt: skip
    head = a.get("vs_t0") or {}
    m = len(head.get("holm_over") or [])
    pairs = [r["vs_t0"]["n_pairs"] for r in a["levels"] if "vs_t0" in r and not math.isnan(r["vs_t0"]["p"])]
    if m and pairs and best_holm_p(max(pairs), m) >= alpha:
        need = needed_pairs(m, alpha)
        out.append(f"**No power against T0** ({where}): at most {max(pairs)} pairs a level and Holm over {m} "
                   f"level{'s' * (m != 1)}: even every pair discordant one way gives Holm p = "
                   f"{best_holm_p(max(pairs), m):.3g} ≥ α = {alpha:g}, so no level can be shown to differ from T0 "
                   f"(that needs ≥ {need} pairs a level).")  # fmt: skip
    return out


def design_caveats(where: str, episodes: int, tested: int, gamma: float, break_by_ci: bool = True,
                   alpha: float = 0.05) -> list[str]:  # fmt: skip
    """What a plan of at most ``episodes`` a level can never show, whatever the outcomes: a protocol's first lines.

    Args:
        where: the set-up, axis and task, in words.
        tested: levels k ≠ 0 sure to be tested against T0 (a walk that may stop early: 1; none without level 0).
        break_by_ci: whether a break is read off the Wilson CI (fixed and until-failure designs; an SPRT decides
            its own).
    """
    if episodes < MIN_N:
        return [f"**Too few episodes** ({where}): {episodes} a level is below the {MIN_N}-episode data floor, so the "
                f"report will give no rate, no k* and no test; plan --episodes {MIN_N} or more."]  # fmt: skip
    out = []
    if break_by_ci and break_undecidable(episodes, gamma):
        out.append(f"**Too few episodes** ({where}): {episodes} a level; even 0/{episodes} leaves the Wilson 95 % CI "
                   f"above γ = {gamma:g}, so no level can be shown below γ (a break is only observed; showing one "
                   f"needs n ≥ {needed_for_break(gamma)} a level).")  # fmt: skip
    if tested and best_holm_p(episodes, tested) >= alpha:
        out.append(f"**No power against T0** ({where}): {episodes} pairs a level and Holm over at least {tested} "
                   f"level{'s' * (tested != 1)}: even every pair discordant one way gives Holm p = "
                   f"{best_holm_p(episodes, tested):.3g} ≥ α = {alpha:g}, so no level can be shown to differ from T0 "
                   f"(that needs ≥ {needed_pairs(tested, alpha)} pairs a level).")  # fmt: skip
    return out


def report_caveats(summaries: Sequence[tuple[str, dict]]) -> list[str]:
    """Every run's caveat lines in the summaries' order: a ``--smoke`` run's, else a run on placeholder assets, a
    declared-blind policy (``blind_caveat``), then each axis's (``axis_caveats``); [] when none applies. A run whose
    summary predates the declaration (no ``reads_observations``) is treated as unknown: no blind line."""
    out = []
    for label, s in summaries:
        if s.get("measurement"):
            why = str(s["measurement"]).removeprefix("not a measurement").strip(" ()")
            out.append(f"**Not a measurement** ({label}): {why}; its rates are not the policy's.")
        elif s.get("placeholder_assets"):
            out.append(f"**Placeholder assets** ({label}): the scene was simulated with placeholder assets (boxes, "
                       "flat textures), not the benchmark's own; its rates describe that stand-in scene, not the "
                       "benchmark.")  # fmt: skip
        if s.get("reads_observations") is False:
            out.append(blind_caveat(label))
        for axis, a in s["axes"].items():
            out += certification_caveats(label, axis, a.get("certification") or {})
            out += basis_lines(label, axis, a.get("certification_basis") or {})
            out += states_lines(label, axis, a.get("oracle_states") or {})
            out += infeasible_caveats(label, axis, a.get("infeasible") or {})
            out += axis_caveats(label, axis, a, s["gamma"], s.get("ci", "wilson"))
    return out


def compare_caveats(result: dict, alpha: float = 0.05) -> list[str]:
    """compare.md's first lines: a side whose policy declares it reads no observation (``reads_observations``
    {"a", "b"}), a side short of its planned episodes (``unfinished``), then each axis on which no level could
    differ at α whatever the outcomes (too few episodes or pairs for the test and the Holm family)."""
    paired = bool(result.get("paired") or result.get("contrast"))
    reads = result.get("reads_observations") or {}
    out = []
    for side in ("a", "b"):
        label = result.get(f"label_{side}") or side.upper()
        if reads.get(side) is False:
            out.append(blind_caveat(label if label == side.upper() else f"{label} ({side.upper()})", True))
    for u in result.get("unfinished") or []:
        out.append(f"**Unfinished**: {u['label']} ({u['side']}) holds {u['done']} of its {u['planned']} planned "
                   "episodes on the compared axes, so its rates and this comparison are provisional; compare again "
                   "once it finishes.")  # fmt: skip
    for axis, ax in result["axes"].items():
        rows = [r for r in ax["levels"] if not math.isnan(r.get("p_holm", float("nan")))]
        if not rows:
            continue
        n = max(r["pairs"] if paired else min(r["n_a"], r["n_b"]) for r in rows)
        best = best_holm_p(n, len(rows), paired, result.get("test", "boschloo"))
        if best >= alpha:
            kind = f"{n} episode pairs" if paired else f"{n} episodes a run"
            test = ("paired exact McNemar" + (", stratified by seed" if result.get("strata", 1) > 1 else "")
                    if paired else f"unpaired {result.get('test', 'boschloo')}")  # fmt: skip
            out.append(f"**Cannot answer** (`{axis}`): at most {kind} a level and Holm over {len(rows)} level"
                       f"{'s' * (len(rows) != 1)}: even the most lopsided outcome gives Holm p = {best:.3g} ≥ "
                       f"α = {alpha:g} ({test}), so \"no level differs\" here says nothing about the policies; "
                       "run more episodes a level.")  # fmt: skip
    return out
