"""``indgen compare RUN_A RUN_B``: per-level exact tests with Holm correction — exact McNemar on episode pairs
when the two runs share seeds and plan, Boschloo (or Barnard) otherwise — the difference in break levels, an
overlay plot and a verdict sentence that never overstates. ``--axes A:B`` contrasts two axes of one run or of two
runs, paired on the plan's common seeds (``compare_axes``); ``--a/--b`` two groups of runs (``compare_groups``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from indgen_vla.core.comparison.two_axes import as_one_axis, check_plans, compare_axes, parse_axes
from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.protocol.fingerprint import check_comparable, protocol_section
from indgen_vla.core.reporting.caveats import compare_caveats, rate_text
from indgen_vla.core.reporting.failures import failure_shift, plot_failures, render_shift
from indgen_vla.core.reporting.figures import plot_axis
from indgen_vla.core.reporting.html_page import markdown_page
from indgen_vla.core.reporting.partial_credit import compare_progress, plot_progress, render_compare
from indgen_vla.core.reporting.report import _safe, run_label
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.runs.records import RunDir, write_result
from indgen_vla.core.stats.breakpoint import break_point_difference, cells_from_frame
from indgen_vla.core.stats.contrasts import check_margin, paired_delta, pp
from indgen_vla.core.stats.metrics import (
    UNDETERMINED,
    compare_levels,
    compare_paired_levels,
    difference_ci,
    pooled_text,
    success_rate,
    usable_levels,
)
from indgen_vla.core.stats.pairing import pair_episodes

TESTS = ("auto", "mcnemar", "boschloo", "barnard")
DELTA_CI = {
    True: "Newcombe paired (method 10), 95 %",
    False: "Newcombe unpaired (MOVER of Wilson intervals), 95 %",
}


def _counts(axis_summary: dict) -> dict[int, tuple[int, int]]:
    return {r["level"]: (r["successes"], r["n"]) for r in axis_summary["levels"]}


def compare_summaries(
    sa: dict, sb: dict, test: str = "auto", gamma: float = 0.2, episodes: tuple | None = None
) -> dict[str, Any]:
    """The compare.json dict for two runs (axes present in both).

    Args:
        sa, sb: the runs' summaries (``summary.summarize``); break levels are read from them, so a level below
            the data floor never yields a k*.
        test: "auto" (exact McNemar when the runs are paired, else Boschloo), "mcnemar" (refuse unpaired
            runs), "boschloo" or "barnard" (unpaired tests, even for paired runs).
        episodes: the two runs' episode tables (``RunDir.episodes()``), needed for pairing.
    """
    if test not in TESTS:
        raise ConfigError(f"unknown test {test!r}; use one of {', '.join(TESTS)}")
    axes = sorted(set(sa["axes"]) & set(sb["axes"]))
    pairing: dict[str, tuple] = {}
    if test in ("auto", "mcnemar"):
        if episodes is None:
            reason = "no episode tables given"
            pairing = {axis: (None, reason) for axis in axes}
        else:
            pairing = {axis: pair_episodes(episodes[0], episodes[1], axis) for axis in axes}
        unpaired = [why for p, why in pairing.values() if p is None]
        if unpaired and test == "mcnemar":
            raise ConfigError(f"--test mcnemar needs runs paired episode by episode, but {unpaired[0]}; "
                              "use --test auto or boschloo")  # fmt: skip
        paired = bool(axes) and not unpaired
    else:
        paired = False
    name = "mcnemar_exact" if paired else ("boschloo" if test in ("auto", "mcnemar") else test)
    out: dict[str, Any] = {
        "test": name,
        "paired": paired,
        "gamma": gamma,
        "delta_interval": DELTA_CI[paired],
        "reads_observations": reads_observations(sa, sb),
        "axes": {},
    }
    if not paired and pairing:
        out["unpaired_reason"] = next(why for p, why in pairing.values() if p is None)
    for axis in axes:
        a, b = sa["axes"][axis], sb["axes"][axis]
        if paired:
            rows = compare_paired_levels(pairing[axis][0])
        else:
            rows = compare_levels(_counts(a), _counts(b), test=name)
        add_deltas(rows, paired)
        out["axes"][axis] = {
            "levels": rows,
            "break_level_a": a["break_level"],
            "break_level_b": b["break_level"],
            "failures": failure_shift(a["levels"], b["levels"]),
        }
        if paired:
            out["axes"][axis]["pairing"] = pairing[axis][1]
        if (
            episodes is not None
        ):  # partial credit, beside the binary test (indgen_vla.core.reporting.partial_credit)
            out["axes"][axis]["progress"] = compare_progress(episodes[0], episodes[1], axis, paired)
    return out


def add_deltas(rows: list[dict], paired: bool) -> None:
    """Each level row's Δ = B − A with its 95 % interval (``delta``, ``delta_ci``): Newcombe's paired interval on
    the episode pairs (``contrasts.paired_delta``), or for unpaired runs the MOVER combination of the two Wilson
    intervals (``metrics.difference_ci``); NaN without episodes on a side."""
    for r in rows:
        if paired:
            r["delta"], r["delta_ci"], _ = paired_delta(r, None)
        elif r["n_a"] and r["n_b"]:
            a, b = (success_rate(r[f"successes_{s}"], r[f"n_{s}"]) for s in ("a", "b"))
            r["delta"] = b.rate - a.rate
            r["delta_ci"] = list(difference_ci((b.rate, b.ci_low, b.ci_high), (a.rate, a.ci_low, a.ci_high)))
        else:
            r["delta"], r["delta_ci"] = math.nan, [math.nan, math.nan]


def break_point_diff(ea, eb, axis: str, gamma: float, usable: tuple[set, set] | None = None) -> dict:
    """B − A in the continuous break point per direction, CI from independent bootstraps ({} if < 2 levels);
    ``usable``: each run's levels above the data floor (the summaries' rows), the only ones it may use."""

    def cells(e, keep):
        ok = e[(e["axis"] == axis) & (e["status"] == "ok")]
        ok = ok if keep is None else ok[ok["level"].isin(keep)]
        return cells_from_frame(ok[["level", "param", "success", "status"]])

    ca, cb = (cells(e, keep) for e, keep in zip((ea, eb), usable or (None, None), strict=True))
    if len({c.level for c in ca}) < 2 or len({c.level for c in cb}) < 2:
        return {}
    return break_point_difference(ca, cb, gamma)


def _fmt_bp_diff(d: dict) -> str:
    parts = []
    for side in ("pos", "neg"):
        b = d.get(side)
        if b is None:
            continue
        lo, hi = b["ci"]["level"]
        if b["level"] is None:
            parts.append(
                f"{'+' if side == 'pos' else '−'}: undefined (a run does not cross γ inside the range)"
            )
        else:
            ci = f" [{lo:+.2f}, {hi:+.2f}]" if lo is not None and hi is not None else ""
            parts.append(f"{'+' if side == 'pos' else '−'}: {b['level']:+.2f} levels{ci}")
    return "; ".join(parts)


def test_description(result: dict) -> str:
    """Which test ran and whether it is paired, in words (compare.md and the verdict say it)."""
    if result.get("contrast"):
        c = result["contrast"]
        same = c.get("same_t0", True)
        zero = ("the same initial state on both axes; pooled over tasks, pairs within task); level 0 is T0 on both "
                "axes, shown as a check of the pairing, outside the Holm family" if same else "the same seed on both "
                "axes; pooled over tasks, pairs within task); level 0 differs (another held level: two rows of a "
                "grid), tested as every level is")  # fmt: skip
        return (f"paired: axis `{c['axis_a']}` (A) against axis `{c['axis_b']}` (B), two-sided exact McNemar test on "
                "the discordant episode pairs per level (episodes matched on scene, task, level, episode and seed: "
                f"{zero}")  # fmt: skip
    if result["paired"]:
        return ("paired: two-sided exact McNemar test on the discordant episode pairs per level (episodes matched "
                "on task, axis, level, episode and seed)")  # fmt: skip
    why = f"; not paired: {result['unpaired_reason']}" if result.get("unpaired_reason") else ""
    return f"unpaired: two-sided {result['test'].capitalize()} exact test per level{why}"


def verdict(result: dict, label_a: str, label_b: str, alpha: float = 0.05) -> str:
    """One cautious sentence per axis: which levels differ after Holm (paired or not), and each run's k*."""
    sentences = []
    kind = "paired exact McNemar" if result.get("paired") else f"unpaired {result['test'].capitalize()}"
    for axis, ax in result["axes"].items():
        sig = [r for r in ax["levels"] if not math.isnan(r["p_holm"]) and r["p_holm"] < alpha]
        ka, kb = ax["break_level_a"], ax["break_level_b"]
        k_text = f"k* {_k(ka)} ({label_a}) vs {_k(kb)} ({label_b})" + (
            f"; {ax['tasks']}" if ax.get("tasks") else ""
        )
        if not sig:
            sentences.append(
                f"{axis}: no level differs at α = {alpha} ({kind}, Holm-corrected) "
                f"(this does not show the runs are equal); {k_text}."
            )
        else:
            parts = [f"L{r['level']} ({rate_text(r['successes_a'], r['n_a'])} vs "
                     f"{rate_text(r['successes_b'], r['n_b'])}"
                     + (f", B − A (pp) {_fmt_delta(r)}" if "delta" in r else "") + f", p_holm = {r['p_holm']:.3g})"
                     for r in sig]  # fmt: skip
            sentences.append(
                f"{axis}: {len(sig)} level(s) differ at α = {alpha} ({kind}, Holm-corrected): "
                f"{', '.join(parts)}; {k_text}."
            )
    return " ".join(sentences) if sentences else "the runs share no axis to compare."


def _k(b: dict) -> str:
    """Break levels as "+2 / −3" (signed axes: positive side / negative side) or "3"; "none" when none in range,
    "undetermined" when a level without enough data lies before the break."""

    def one(k, signed: bool) -> str:
        if k is None:
            return "none"
        if k == UNDETERMINED:
            return UNDETERMINED
        return f"{k:+d}".replace("-", "−") if signed else str(k)

    if "neg" in b:
        return f"{one(b['pos'], True)} / {one(b['neg'], True)}"
    return one(b["pos"], False)


def render_markdown(result: dict, label_a: str, label_b: str, text: str) -> str:
    paired = result.get("paired", False)
    caveats = compare_caveats(result)  # what the comparison cannot answer comes first
    lines = [f"# Comparison: {label_a} (A) vs {label_b} (B)", "", *[x for c in caveats for x in (c, "")],
             "Break levels k* (first level with success < γ) read \"positive side / negative side\" on signed axes; "
             "a level below the data floor never yields a k* (\"undetermined\" when one precedes the break).", "",
             f"Test: {test_description(result)}; Holm-corrected per axis.", "",
             f"**Verdict.** {text}", ""]  # fmt: skip
    lines += protocol_section(result.get("protocol", []))
    for axis, ax in result["axes"].items():
        delta = "delta" in (ax["levels"] or [{}])[0]  # an axis contrast: B − A with its interval per level
        head = (
            f"Axes `{ax['axis_a']}` (A) vs `{ax['axis_b']}` (B), paired"
            if "axis_a" in ax
            else f"Axis `{axis}`"
        )
        lines += [f"## {head}", ""] + ([f"A and B: successes/n = rate [Wilson 95 % CI]; {ax['tasks']}.", ""]
                                       if ax.get("tasks") else [])  # fmt: skip
        if paired:
            lines += [f"Pairs: {ax.get('pairing', '')}.", ""]
        if delta and result.get("delta_interval"):
            lines += [
                f"B − A: difference of the rates in percentage points, {result['delta_interval']} CI.",
                "",
            ]
        cols = ["level", "A", "B", *(["A only", "B only"] if paired else []), "p", "p (Holm)",
                *(["B − A (pp) [95% CI]"] if delta else [])]  # fmt: skip
        lines += ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
        for r in ax["levels"]:
            disc = f"{r['a_only']} | {r['b_only']} | " if paired else ""
            lines.append(
                f"| {r['level']} | {rate_text(r['successes_a'], r['n_a'])} | {rate_text(r['successes_b'], r['n_b'])} | {disc}"
                f"{_p(r['p_value'])} | {_p(r['p_holm'])} |" + (f" {_fmt_delta(r)} |" if delta else "")
            )
        if ax.get("equivalence"):
            lines += ["", ax["equivalence"]]
        lines += ["", f"Break level k*: A {_k(ax['break_level_a'])}, B {_k(ax['break_level_b'])}"]
        if ax.get("break_point_diff"):
            lines += ["", f"Break point B − A (where the fitted curve crosses γ; 95 % bootstrap CI): "
                      f"{_fmt_bp_diff(ax['break_point_diff'])}"]  # fmt: skip
        lines += [*render_shift(ax.get("failures", {"modes": []}), label_a, label_b)]
        lines += [*render_compare(ax.get("progress")), ""]
    return "\n".join(lines)


def reads_observations(sa: dict, sb: dict) -> dict[str, bool | None]:
    """Each side's policy declaration from its summary (None: a run made before policies declared it)."""
    return {"a": sa.get("reads_observations"), "b": sb.get("reads_observations")}


def pairing_note(result: dict) -> str:
    """Whether a comparison's curves are paired, for its plots' titles."""
    if result.get("paired") or result.get("contrast"):
        return "paired episode by episode (same seeds): exact McNemar per level, compare.md"
    return f"unpaired: {result.get('test', 'boschloo').capitalize()} per level, compare.md"


def tasks_text(ta: list[str], tb: list[str]) -> str:
    """The tasks both runs' rates on one axis pool, or each run's where they differ (``metrics.pooled_text``)."""
    if ta == tb:
        return pooled_text(ta)
    return f"A: {pooled_text(ta)}; B: {pooled_text(tb)} (rates pool different tasks)"


def _p(x: float) -> str:
    return "—" if math.isnan(x) else f"{x:.3g}"


def _fmt_delta(r: dict) -> str:
    if math.isnan(r["delta"]):
        return "no pairs" if "pairs" in r else "n/a"
    lo, hi = r["delta_ci"]
    return f"{pp(r['delta'])} [{pp(lo)}, {pp(hi)}]"


def check_levels(gamma: float, alpha: float) -> None:
    """γ in (0, 1] and α in (0, 1), or one line naming the flag."""
    if not 0 < alpha < 1:
        raise ConfigError(f"--alpha must be in (0, 1), got {alpha}")
    if not 0 < gamma <= 1:
        raise ConfigError(f"--gamma must be in (0, 1], got {gamma}")


def axes_dir(run_a: str | Path, axes: str, out: str | Path | None = None) -> Path:
    """Where ``compare --axes A:B`` writes: ``out``, else RUN_A/compare_A_vs_B."""
    axis_a, axis_b = parse_axes(axes)
    return Path(out) if out else Path(run_a) / f"compare_{_safe(axis_a)}_vs_{_safe(axis_b)}"


def compare_run_axes(
    run_a: str | Path, run_b: str | Path | None = None, *, axes: str, gamma: float = 0.2, alpha: float = 0.05,
    test: str = "auto", margin: float = 0.10, out: str | Path | None = None, label_a: str | None = None,
    label_b: str | None = None, allow_protocol_mismatch: bool = False,
) -> dict[str, Any]:  # fmt: skip
    """``indgen compare RUN [RUN_B] --axes A:B``: axis A of ``run_a`` against axis B of ``run_b`` (default: the same
    run), paired episode by episode; writes compare.json, compare.md and overlay plots to ``axes_dir``; returns the
    result."""
    check_levels(gamma, alpha)
    if test in ("boschloo", "barnard"):
        raise ConfigError(f"--axes compares paired episodes (exact McNemar); drop --test {test}")
    check_margin(margin)
    axis_a, axis_b = parse_axes(axes)
    if not run_a:
        raise ConfigError("--axes needs a run directory: indgen compare RUN --axes A_AXIS:B_AXIS")
    ra = RunDir.open(run_a)
    rb = RunDir.open(run_b) if run_b else ra
    within = rb.path.resolve() == ra.path.resolve()
    if within and axis_a == axis_b:
        raise ConfigError(
            f"--axes names {axis_a} twice within one run; name two axes, e.g. pick_y+distractor:pick_y"
        )
    ea = ra.episodes()
    eb = ea if within else rb.episodes()
    check_plans(ra, rb, ea, eb, axis_a, axis_b)
    la = label_a or (axis_a if within else f"{run_label(ra)}: {axis_a}")
    lb = label_b or (axis_b if within else f"{run_label(rb)}: {axis_b}")
    if la == lb:
        la, lb = f"{la} ({ra.path.name})", f"{lb} ({rb.path.name})"
    protocol = [] if within else check_comparable(
        [(la, ra.manifest.get("fingerprint")), (lb, rb.manifest.get("fingerprint"))],
        allow_protocol_mismatch, "paired or compared")  # fmt: skip
    sa = summarize(ea, ra.manifest, gamma)
    sb = sa if within else summarize(eb, rb.manifest, gamma)
    result = compare_axes(ea, eb, sa, sb, axis_a, axis_b, margin, alpha)
    result["contrast"].update(run_a=str(ra.path), run_b=str(rb.path), within_run=within)
    result.update(label_a=la, label_b=lb, protocol=protocol, reads_observations=reads_observations(sa, sb))
    key, ax = next(iter(result["axes"].items()))
    usable = (usable_levels(sa["axes"][axis_a]["levels"]), usable_levels(sb["axes"][axis_b]["levels"]))
    ax["break_point_diff"] = break_point_diff(as_one_axis(ea, axis_a, key), as_one_axis(eb, axis_b, key), key,
                                              gamma, usable)  # fmt: skip
    for d in ax["break_point_diff"].values():  # the axes' parameters are different quantities: levels only
        d["param"], d["ci"]["param"] = None, [None, None]
    result["verdict"] = f"{verdict(result, la, lb, alpha)} {ax['equivalence']}"
    dest = axes_dir(ra.path, axes, out)
    _write(dest, result, [(key, _safe(key), [(la, sa["axes"][axis_a]), (lb, sb["axes"][axis_b])])], gamma)
    return result


def unfinished(summary: dict, axes, label: str, side: str) -> dict | None:
    """A run still short of its planned episodes on the compared axes (an evaluate cut short, a real run being
    recorded, an adaptive run between rounds): its finished and planned counts; None when it is complete."""
    rows = [r for axis in axes if axis in summary["axes"] for r in summary["axes"][axis]["levels"]]
    planned = sum(int(r.get("planned") or 0) for r in rows)
    done = sum(min(int(r.get("planned") or 0), r["n"] + r.get("errors", 0)) for r in rows)
    return {"label": label, "side": side, "done": done, "planned": planned} if done < planned else None


def _write(out: Path, result: dict, plots: list[tuple[str, str, list]], gamma: float) -> None:
    """compare.json, compare.md and per compared axis (title, file stem, curves) its overlay plots."""
    result["caveats"] = compare_caveats(result)  # human-readable: what the comparison cannot answer
    write_result(out, "compare", result, markdown(result))
    for axis, stem, curves in plots:
        plot_axis(curves, axis, gamma, out / "plots" / f"{stem}.png", "wilson", pairing_note(result))
        plot_failures(curves, axis, out / "plots" / f"{stem}_failures.png")
        plot_progress(curves, axis, out / "plots" / f"{stem}_progress.png")

    pools = [f"Tasks pooled (`{a}`): {x['tasks']}" for a, x in result["axes"].items() if x.get("tasks")]
    sides = f"A = `{result['label_a']}`, B = `{result['label_b']}` (B − A: B's rate minus A's)"
    verdicts = [result["verdict"], sides, f"Test: {pairing_note(result)}", *pools]
    title = f"Comparison: {result['label_a']} vs {result['label_b']}"
    markdown_page(out, title, markdown(result), verdicts, out / "plots", caveats=result["caveats"])


def markdown(result: dict) -> str:
    """compare.md of a two-run or two-axis comparison that ``compare_runs``/``compare_run_axes`` returned."""
    return render_markdown(result, result["label_a"], result["label_b"], result["verdict"])


def compare_dir(run_a: str | Path, out: str | Path | None = None) -> Path:
    """Where ``compare RUN_A RUN_B`` writes: ``out``, else RUN_A/compare."""
    return Path(out) if out else Path(run_a) / "compare"


def compare_runs(
    run_a: str | Path, run_b: str | Path, *, gamma: float = 0.2, alpha: float = 0.05, test: str = "auto",
    out: str | Path | None = None, label_a: str | None = None, label_b: str | None = None,
    allow_protocol_mismatch: bool = False,
) -> dict[str, Any]:  # fmt: skip
    """``indgen compare RUN_A RUN_B``: per-level exact tests of every shared axis, written to ``compare_dir`` as
    compare.json, compare.md and overlay plots; returns the result."""
    check_levels(gamma, alpha)
    ra, rb = RunDir.open(run_a), RunDir.open(run_b)
    ea, eb = ra.episodes(), rb.episodes()  # built once: each call makes a new DataFrame of every row
    sa = summarize(ea, ra.manifest, gamma)
    sb = summarize(eb, rb.manifest, gamma)
    if not set(sa["axes"]) & set(sb["axes"]):
        raise RunDirError(f"{ra.path} and {rb.path} share no axis; compare runs evaluated on the same axis, or "
                          "contrast two axes with --axes A_AXIS:B_AXIS")  # fmt: skip
    la, lb = label_a or run_label(ra), label_b or run_label(rb)
    if la == lb:
        la, lb = f"{la} ({ra.path.name})", f"{lb} ({rb.path.name})"
    protocol = check_comparable([(la, ra.manifest.get("fingerprint")), (lb, rb.manifest.get("fingerprint"))],
                                allow_protocol_mismatch, "paired or compared")  # fmt: skip
    result = compare_summaries(sa, sb, test, gamma, episodes=(ea, eb))
    result["label_a"], result["label_b"] = la, lb
    result["protocol"] = protocol
    for axis, ax in result["axes"].items():
        usable = (usable_levels(sa["axes"][axis]["levels"]), usable_levels(sb["axes"][axis]["levels"]))
        ax["tasks"] = tasks_text(*(s["axes"][axis].get("pooled_tasks") or [] for s in (sa, sb)))
        ax["break_point_diff"] = break_point_diff(ea, eb, axis, gamma, usable)
    result["unfinished"] = [u for side, lbl, s in (("A", la, sa), ("B", lb, sb))
                            if (u := unfinished(s, result["axes"], lbl, side))]  # fmt: skip
    result["verdict"] = verdict(result, la, lb, alpha)
    plots = [(axis, axis, [(la, sa["axes"][axis]), (lb, sb["axes"][axis])]) for axis in result["axes"]]
    _write(compare_dir(ra.path, out), result, plots, gamma)
    return result
