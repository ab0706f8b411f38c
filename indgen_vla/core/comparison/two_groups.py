"""``indgen compare --a RUN... --b RUN...``: two groups of runs (one per training seed), paired within a seed.

Run i of group A and run i of group B form stratum i (e.g. training seed i of each regime). When the two runs
of a stratum share their episodes (same task, axis, level, episode index and seed), each level's outcomes are
paired, and the strata are combined by the matched-pairs Mantel–Haenszel test (``groups.stratified_mcnemar``),
Holm-corrected over the levels of an axis. Seed-level summaries — k* per direction and the mean success over
the out-of-distribution levels |k| >= 1 — are compared across seeds with Welch t-intervals, and an equivalence
test (TOST, ``--margin``) says whether "no difference" may be claimed.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from indgen_vla.core.comparison.two_runs import check_levels
from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.protocol.fingerprint import check_comparable, protocol_section
from indgen_vla.core.protocol.interface import declared_reads
from indgen_vla.core.reporting.caveats import compare_caveats, rate_text
from indgen_vla.core.reporting.html_page import markdown_page
from indgen_vla.core.runs.records import RunDir, write_result
from indgen_vla.core.stats.metrics import (
    MIN_N,
    UNDETERMINED,
    UndeterminedBreakError,
    below_floor,
    holm,
    kstar,
    pooled_text,
    success_rate,
)
from indgen_vla.core.stats.pairing import pair_episodes
from indgen_vla.core.stats.seed_groups import mean_difference, ood_area, stratified_mcnemar, tost


def _ok(df):
    return df[df["status"] == "ok"]


def _pairs(a, b, axis: str) -> dict[int, list[tuple[bool, bool]]]:
    """Level -> (success A, success B) per episode pair of one stratum; refuses runs that are not paired."""
    pairs, why = pair_episodes(a, b, axis)
    if pairs is None:
        raise RunDirError(f"a pair of runs is not paired: {why}; evaluate both with the same --seed and plan")
    return pairs


def _rates(df) -> dict[int, float]:
    return {int(k): float(g["success"].mean()) for k, g in _ok(df).groupby("level")}


def _floored(rates: dict[int, float], df) -> dict[int, float]:
    """``rates`` as ``report`` reads them for a seed's k*: a level below the data floor (fewer than 5 finished
    episodes, or under half its recorded ones, errors included) is NaN, never a measurement (``levels.usable_rates``)."""
    finished, recorded = _ok(df)["level"].value_counts(), df["level"].value_counts()
    return {
        int(k): math.nan if below_floor(int(finished.get(k, 0)), int(m)) else rates[int(k)]
        for k, m in recorded.items()
    }


def compare_groups(
    episodes_a: list, episodes_b: list, gamma: float = 0.2, margin: float = 0.10, alpha: float = 0.05
) -> dict[str, Any]:
    """The compare.json dict for two equally long lists of episode tables (stratum i = run i of each group)."""
    if len(episodes_a) != len(episodes_b) or not episodes_a:
        raise RunDirError(
            f"--a has {len(episodes_a)} run(s) and --b {len(episodes_b)}; give one run per training seed on each "
            "side, in the same seed order"
        )
    axes = sorted(set.intersection(*(set(df["axis"]) for df in episodes_a + episodes_b)))
    if not axes:
        raise RunDirError("the runs share no axis; compare runs evaluated on the same axis")
    out: dict[str, Any] = {
        "test": "mcnemar_exact" if len(episodes_a) == 1 else "mcnemar_exact_stratified",
        "paired": True, "strata": len(episodes_a), "gamma": gamma, "alpha": alpha, "margin": margin, "axes": {},
    }  # fmt: skip
    for axis in axes:
        pairs = [_pairs(a, b, axis) for a, b in zip(episodes_a, episodes_b, strict=True)]
        levels = sorted(set().union(*pairs))
        rows = []
        for k in levels:
            strata = [
                (
                    sum(x and not y for x, y in p.get(k, [])),
                    sum(y and not x for x, y in p.get(k, [])),
                    len(p.get(k, [])),
                )
                for p in pairs
            ]
            test = stratified_mcnemar(strata)
            n = sum(s[2] for s in strata)
            succ_a = sum(x for p in pairs for x, _ in p.get(k, []))
            succ_b = sum(y for p in pairs for _, y in p.get(k, []))
            ra, rb = success_rate(succ_a, n), success_rate(succ_b, n)  # pooled over the strata's pairs
            rows.append({
                "level": int(k), "pairs": n, "successes_a": succ_a, "successes_b": succ_b,
                "rate_a": ra.rate, "rate_b": rb.rate, "ci_a": [ra.ci_low, ra.ci_high], "ci_b": [rb.ci_low, rb.ci_high],
                "a_only": test.a_only, "b_only": test.b_only, "p_value": test.p_value,
            })  # fmt: skip
        for r, p in zip(rows, holm([r["p_value"] for r in rows]), strict=True):
            r["p_holm"] = p
        tasks = sorted(set().union(*(df.loc[df["axis"] == axis, "task"] for df in episodes_a + episodes_b)))
        out["axes"][axis] = {"levels": rows, "tasks": tasks,
                             **_seed_level(episodes_a, episodes_b, axis, gamma, margin)}  # fmt: skip
    out["caveats"] = compare_caveats(out, alpha)  # what no outcome of these pairs could show, said first
    return out


def _seed_level(episodes_a: list, episodes_b: list, axis: str, gamma: float, margin: float) -> dict:
    """Per-seed k* (each direction) and OOD area for both groups, their B − A differences and the TOST."""
    per: dict[str, dict[str, list]] = {"a": {}, "b": {}}
    for side, group in (("a", episodes_a), ("b", episodes_b)):
        for df in group:
            rows = df[df["axis"] == axis]
            rates = _rates(rows)
            usable = _floored(rates, rows)
            signed = any(k < 0 for k in rates)
            for d in ("pos", "neg") if signed else ("pos",):
                own = {k: r for k, r in usable.items() if (k >= 0 if d == "pos" else k <= 0)}
                try:
                    k = kstar(own, gamma)  # K+1 when none breaks
                except (
                    UndeterminedBreakError
                ):  # a level before the break is below the data floor, as report says
                    k = UNDETERMINED
                per[side].setdefault(f"kstar_{d}", []).append(k)
            per[side].setdefault("ood_area", []).append(ood_area(rates))
    res = {}
    for name in per["a"]:
        a, b = per["a"][name], per["b"][name]
        if UNDETERMINED in a + b:  # no difference of k* while a seed's k* is unknown
            res[name] = {"a": a, "b": b, "diff": math.nan, "ci": [math.nan, math.nan]}
            continue
        md = mean_difference(a, b)
        res[name] = {"a": a, "b": b, "diff": md.diff, "ci": [md.ci_low, md.ci_high]}
    res["ood_area"]["tost_p"] = tost(per["a"]["ood_area"], per["b"]["ood_area"], margin)
    return {"seed_level": res}


def verdict(result: dict, label_a: str, label_b: str) -> str:
    """What the data show, never more: one sentence per axis (``axis_verdicts``)."""
    return " ".join(axis_verdicts(result, label_a, label_b).values())


def axis_verdicts(result: dict, label_a: str, label_b: str) -> dict[str, str]:
    """Per axis: differing levels after Holm, the seed-level differences with CIs, equivalence (TOST)."""
    alpha, margin = result["alpha"], result["margin"]
    parts = {}
    for axis, ax in result["axes"].items():
        sig = [r for r in ax["levels"] if r["p_holm"] < alpha]
        lv = ", ".join(f"L{r['level']:+d} ({rate_text(r['successes_a'], r['pairs'])} vs "
                       f"{rate_text(r['successes_b'], r['pairs'])}, p_holm = {r['p_holm']:.2g})" for r in sig)  # fmt: skip
        sl = ax["seed_level"]
        area = sl["ood_area"]
        text = (f"{axis} ({_pool(ax, result['strata'])}): " + (f"{len(sig)} level(s) differ after Holm ({lv})" if sig else
                "no level differs after Holm") + f"; OOD mean success {label_b} − {label_a} = "
                f"{100 * area['diff']:+.1f} points, 95% CI [{_pts(area['ci'][0])}, {_pts(area['ci'][1])}] over "
                f"{len(area['a'])} vs {len(area['b'])} seeds")  # fmt: skip
        tp = area["tost_p"]
        if not math.isnan(tp):
            text += (f"; equivalent within ±{100 * margin:.0f} points (TOST p = {tp:.2g})" if tp < alpha else
                     f"; equivalence within ±{100 * margin:.0f} points not shown (TOST p = {tp:.2g})")  # fmt: skip
        elif min(len(area["a"]), len(area["b"])) >= 2:
            text += ("; no interval and no equivalence test: the seeds' OOD means do not vary at all (more seeds "
                     "or episodes per seed would give them a spread)")  # fmt: skip
        for d in ("pos", "neg"):
            if f"kstar_{d}" in sl:
                k = sl[f"kstar_{d}"]
                text += f"; k* {d} {label_a} {k['a']} vs {label_b} {k['b']}"
                if UNDETERMINED in k["a"] + k["b"]:
                    text += (
                        f" ({UNDETERMINED}: a level before the break is below the {MIN_N}-episode data floor)"
                    )
        parts[axis] = text + "."
    return parts


def _pool(ax: dict, strata: int) -> str:
    """What an axis's level rates pool and how they are compared: "task milk; paired, stratified by seed (2 seeds)"."""
    how = "paired, stratified by seed" if strata > 1 else "paired"
    return f"{pooled_text(ax.get('tasks') or [])}; {how} ({strata} run pair{'s' * (strata != 1)})"


def _pts(x: float) -> str:
    return "n/a" if math.isnan(x) else f"{100 * x:+.1f}"


def _tost_p(p: float) -> str:
    return "n/a (needs two or more runs per side whose OOD areas vary)" if math.isnan(p) else f"{p:.3g}"


def _ci3(ci: list[float]) -> str:
    return "n/a (no spread across runs)" if math.isnan(ci[0]) else f"[{ci[0]:.3f}, {ci[1]:.3f}]"


def render_markdown(result: dict, label_a: str, label_b: str) -> str:
    """compare.md for groups: per-level paired table, then the seed-level endpoints."""
    lines = [f"# Comparison: {label_a} (A, {result['strata']} run(s)) vs {label_b} (B, {result['strata']} run(s))", "",
             *[x for c in result.get("caveats", []) for x in (c, "")],
             "Paired episode by episode within each stratum (run i of A with run i of B: same episodes); per level the "
             "exact matched-pairs test on the discordant pairs pooled over strata (stratified McNemar), Holm-corrected "
             "per axis. Seed-level endpoints: Welch t-intervals across runs; TOST for equivalence.", "",
             f"**Verdict.** {result['verdict']}", ""]  # fmt: skip
    lines += protocol_section(result.get("protocol", []))
    for axis, ax in result["axes"].items():
        lines += [f"## Axis `{axis}`", "", f"Rates pooled over the strata's pairs ({_pool(ax, result['strata'])}): "
                  "successes/pairs = rate [Wilson 95 % CI].", "",
                  "| level | pairs | A | B | A only | B only | p | p (Holm) |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for r in ax["levels"]:
            lines.append(f"| {r['level']} | {r['pairs']} | {rate_text(r['successes_a'], r['pairs'])} | "
                         f"{rate_text(r['successes_b'], r['pairs'])} | {r['a_only']} | {r['b_only']} | "
                         f"{r['p_value']:.3g} | {r['p_holm']:.3g} |")  # fmt: skip
        lines += ["", "| endpoint | A per run | B per run | B − A | 95% CI |", "|---|---|---|---|---|"]
        for name, e in ax["seed_level"].items():
            fmt = (
                (lambda v: f"{v:.3f}")
                if name == "ood_area"
                else (lambda v: v if isinstance(v, str) else f"{v:+d}")
            )
            diff = "n/a" if math.isnan(e["diff"]) else f"{e['diff']:+.3f}"
            lines.append(f"| {name} | {', '.join(fmt(v) for v in e['a'])} | {', '.join(fmt(v) for v in e['b'])} | "
                         f"{diff} | {_ci3(e['ci'])} |")  # fmt: skip
        lines += [
            "",
            f"OOD area TOST p (margin ±{result['margin']}): {_tost_p(ax['seed_level']['ood_area']['tost_p'])}",
            "",
            "kstar_pos / kstar_neg: each run's k* (Definition 2): the first level below γ, or K+1 when no level "
            "through the last one run (K) breaks, e.g. +2 for a run at levels 0..1 that never broke.",
            "",
        ]
    return "\n".join(lines)


def groups_dir(first_a: str | Path, out: str | Path | None = None) -> Path:
    """Where ``compare --a RUN... --b RUN...`` writes: ``out``, else FIRST_A/compare_groups."""
    return Path(out) if out else Path(first_a) / "compare_groups"


def compare_run_groups(
    runs_a: list[str | Path], runs_b: list[str | Path], *, gamma: float = 0.2, alpha: float = 0.05,
    margin: float = 0.10, out: str | Path | None = None, label_a: str | None = None, label_b: str | None = None,
    allow_protocol_mismatch: bool = False,
) -> dict[str, Any]:  # fmt: skip
    """``indgen compare --a RUN... --b RUN...``: the two groups' stratified tests and seed-level endpoints, written
    to ``groups_dir`` as compare.json and compare.md; returns the result."""
    check_levels(gamma, alpha)
    if not runs_a or not runs_b:
        raise ConfigError("give both groups: --a RUN... --b RUN... (one run per training seed each)")
    if not 0 < margin < 1:
        raise ConfigError(f"--margin must be in (0, 1), got {margin}")
    runs_a, runs_b = [RunDir.open(p) for p in runs_a], [RunDir.open(p) for p in runs_b]
    seen: dict = {}  # a run listed twice would count its episodes twice: evidence that is not there
    for r in runs_a + runs_b:
        keys = [k for k in (r.path.resolve(), r.manifest.get("run_id")) if k is not None]
        twin = next((seen[k] for k in keys if k in seen), None)
        if twin is not None:
            raise ConfigError(
                f"run {r.path} is the same run as {twin} (given twice to --a/--b); each training seed's run "
                "counts once: drop the repeat"
            )
        seen.update(dict.fromkeys(keys, r.path))
    protocol = check_comparable([(str(r.path), r.manifest.get("fingerprint")) for r in runs_a + runs_b],
                                allow_protocol_mismatch, "pooled or paired")  # fmt: skip
    result = compare_groups([r.episodes() for r in runs_a], [r.episodes() for r in runs_b], gamma,
                            margin, alpha)  # fmt: skip
    la, lb = label_a or "A", label_b or "B"
    result.update(
        label_a=la, label_b=lb, runs_a=[str(r.path) for r in runs_a], runs_b=[str(r.path) for r in runs_b]
    )
    result["protocol"] = protocol
    result["reads_observations"] = {
        side: declared_reads(r.manifest.get("reads_observations") for r in runs)
        for side, runs in (("a", runs_a), ("b", runs_b))
    }
    result["caveats"] = compare_caveats(result, alpha)  # again, now that the sides' policies are known
    result["verdicts"] = axis_verdicts(result, la, lb)
    result["verdict"] = " ".join(result["verdicts"].values())
    out, text = groups_dir(runs_a[0].path, out), render_markdown(result, la, lb)
    write_result(out, "compare", result, text)

    # report.html: the verdicts first
    # which run directories each side pools
    groups = "; ".join(
        f"{side} = `{lbl}`: {', '.join(f'`{r}`' for r in result[f'runs_{side.lower()}'])}"
        for side, lbl in (("A", la), ("B", lb))
    )
    markdown_page(out, f"Group comparison: {la} vs {lb}", text, [*result["verdicts"].values(), groups],
                  caveats=result["caveats"])  # fmt: skip
    return result
