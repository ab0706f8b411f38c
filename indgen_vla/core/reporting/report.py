"""``indgen report``: summary.json, report.md and success-vs-level plots from run directories."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.protocol.fingerprint import check_comparable, protocol_section
from indgen_vla.core.protocol.training_support import TRAINED_NOTE, trained_text
from indgen_vla.core.reporting.caveats import report_caveats
from indgen_vla.core.reporting.failures import plot_failures, render_breakdown
from indgen_vla.core.reporting.figures import (
    AXES_PLOT,
    axis_order,
    axis_specs,
    overview_lines,
    plot_axes,
    plot_axis,
)
from indgen_vla.core.reporting.grid import grid_lines, plot_grids
from indgen_vla.core.reporting.html_report import write_overlay_html, write_run_html
from indgen_vla.core.reporting.levels import fmt_condition2, verdict_line
from indgen_vla.core.reporting.oracle_states import attach_oracle_states
from indgen_vla.core.reporting.partial_credit import plot_progress, render_levels
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.reporting.svg_plot import write_axis_svg
from indgen_vla.core.runs.records import (
    REPORT,
    SECTIONS,
    SUMMARY,
    RunDir,
    atomic_write_json,
    atomic_write_text,
)
from indgen_vla.core.stats.breakpoint import kstar_spread
from indgen_vla.core.stats.contrasts import check_margin, render_vs_t0, t0_lines
from indgen_vla.core.stats.metrics import DEFAULT_GAMMA, MIN_N, UNDETERMINED, ci_name, pooled_text


def run_label(run: RunDir) -> str:
    """The label a run gets in tables and legends: its data regime, else its policy, else its folder."""
    m = run.manifest
    parts = [p for p in (m.get("data_regime"), _short_spec(m.get("policy"))) if p]
    return " / ".join(parts) if parts else run.path.name


def _short_spec(spec: str | None) -> str | None:
    """A policy spec whose local path lies under the working directory, shown relative to it (shorter labels)."""
    family, sep, target = (spec or "").partition(":")
    if not sep or not target.startswith("/"):
        return spec
    try:
        return f"{family}:{Path(target).relative_to(Path.cwd())}"
    except ValueError:
        return spec


def insufficient_text(row: dict) -> str:
    """What a level below the data floor prints instead of a rate, e.g. "insufficient data (n = 1 of 4; 3 errors)"."""
    if row.get("not_run"):  # the until-failure design stopped below it
        return "not run (past the observed break)"
    of = f" of {row['planned']}" if row.get("planned") else ""
    errs = f"; {row['errors']} error{'s' * (row['errors'] != 1)}" if row.get("errors") else ""
    return f"insufficient data (n = {row['n']}{of}{errs})"


def _fmt_rate(row: dict) -> str:
    if row.get("insufficient", row["n"] == 0):
        return insufficient_text(row)
    errs = f"; {row['errors']} error{'s' * (row['errors'] != 1)}" if row.get("errors") else ""
    verdict = f" {row['decision']}" if row.get("decision") else ""
    return (f"{100 * row['rate']:.0f}% [{100 * row['ci_low']:.0f}, {100 * row['ci_high']:.0f}] (n={row['n']}{errs}"
            f"{partial_pool_text(row)}){verdict}")  # fmt: skip


def partial_pool_text(row: dict) -> str:
    """ "; task t1 only" beside a pooled rate of an adaptive run that pools a subset of its tasks at that level."""
    return f"; {pooled_text(row['pooled_only'])} only" if row.get("pooled_only") else ""


def _fmt_break(b: dict, signed: bool) -> str:
    def one(k):
        if k == UNDETERMINED:
            return UNDETERMINED
        return "none" if k is None else f"L{k}"

    return f"+: {one(b['pos'])}, −: {one(b.get('neg'))}" if signed else one(b["pos"])


def _spread(a: dict) -> str:
    """One run's per-task k* per direction, counted (``breakpoint.kstar_spread``)."""
    tasks = a.get("tasks", {}).values()
    if not a["signed"]:
        return kstar_spread([t["break_level"]["pos"] for t in tasks], minus="−")
    return "; ".join(
        f"{sign}: {kstar_spread([t['break_level'].get(d) for t in tasks], minus='−')}"
        for d, sign in (("pos", "+"), ("neg", "−"))
    )


def _fmt_tests(tests: dict, signed: bool, method: bool = False) -> str:
    """p-values per direction, e.g. "+: p = 0.0004 (exact), −: p = 0.2"; "—" where a side has < 2 levels."""

    def one(side: str) -> str:
        t = tests.get(side)
        if t is None:
            return "— (< 2 usable levels)"
        return f"p = {t['p_decreasing']:.2g}" + (f" ({t['method']})" if method else "")

    return f"+: {one('pos')}, −: {one('neg')}" if signed else one("pos")


def _fmt_status(status: dict, signed: bool) -> str:
    """k* with its certainty per direction, from the three-way level verdicts."""
    if not status:
        return "—"
    return "; ".join(
        f"{'+' if d == 'pos' else '−'}: {status[d]['text']}" for d in ("pos", "neg") if d in status
    )


def _verdict_or_status(a: dict) -> str:
    """The axis's verdict sentence; a summary written before verdicts existed shows its k* status instead."""
    if "verdict" in a:
        return verdict_line(a["verdict"], a["signed"])
    return (
        f"{_fmt_break(a['break_level'], a['signed'])} ({_fmt_status(a.get('kstar_status', {}), a['signed'])})"
    )


def _fmt_point(bp: dict, signed: bool) -> str:
    """Where the fitted curve crosses γ per direction: fractional level, parameter and bootstrap CI."""
    parts = []
    for d in ("pos", "neg"):
        if d not in bp:
            continue
        b, side = bp[d], "+" if d == "pos" else "−"
        if b.get("level") is None:
            where = {"below": "below γ at the first level", "above": "no crossing in range"}.get(
                b.get("crossing"), "—"
            )
            parts.append(f"{side}: {where}")
            continue
        lo, hi = b["ci"]["level"]
        ci = f" [{lo:.2f}, {hi:.2f}]" if lo is not None and hi is not None else ""
        parts.append(f"{side}: L{b['level']:.2f}{ci} (param {b['param']:.4g}; {b['method']})")
    return "; ".join(parts) or "—"


def _param(p: float | None) -> str:
    return "—" if p is None else f"{p:.4g}"


def error_warnings(label: str, axis_summary: dict, limit: float = 0.10) -> list[str]:
    """One line per level whose error rate exceeds ``limit``: errors that grow with the level bias the curve. An
    infeasible cell (the summary's ``infeasible``: the seed rules the level out) is no such error: a re-run repeats it,
    and its own caveat names it."""
    out, infeasible = [], axis_summary.get("infeasible") or {}
    for r in axis_summary["levels"]:
        total = r["n"] + r["errors"]
        errors = r["errors"] - sum(int(v.get(str(r["level"]), 0)) for v in infeasible.values())
        if total and errors / total > limit:
            out.append(f"**Warning** ({label}): level {r['level']} has {errors} error episode(s) of {total} "
                       f"({100 * errors / total:.0f} % > {100 * limit:.0f} %); errors that grow with the level "
                       "bias the curve: re-run the same evaluate command to retry them.")  # fmt: skip
    return out


def pool_warnings(label: str, axis_summary: dict) -> list[str]:
    """One line when an adaptive run's pooled rows pool different tasks at different levels (a task's ladder stops
    at its break): such a pooled curve can rise past a break and is not comparable across levels."""
    partial = [r for r in axis_summary["levels"] if r.get("pooled_only")]
    if not partial:
        return []
    n = len(axis_summary.get("pooled_tasks") or [])
    where = ", ".join(f"{r['level']} ({len(r['pooled_only'])} of {n})" for r in partial)
    return [f"**Note** ({label}): the pooled rows at level(s) {where} pool only the tasks whose ladder ran them "
            "(--adaptive stops a task at its break), so the pooled curve is not comparable across levels: read "
            "each task's k* and their spread across tasks (below)."]  # fmt: skip


def _pools(present: list[tuple[str, dict]]) -> str:
    """Which tasks each run's pooled curve pools (one line)."""
    texts = {lbl: pooled_text(a.get("pooled_tasks") or []) for lbl, a in present}
    if len(set(texts.values())) == 1:
        return f"Every rate below: {next(iter(texts.values()))}."
    return "Rates by run: " + "; ".join(f"{lbl}: {t}" for lbl, t in texts.items()) + "."


def render_markdown(
    summaries: list[tuple[str, dict]],
    title: str = "Inductive generalization report",
    order: Sequence[str] = (),
) -> str:
    """A levels × runs table per axis with rate, CI, n, errors and k*, the trend tests, and k* per task; with two
    or more axes first the axes × levels overview (``figures.overview_lines``, in ``order``), then the grids of
    held axes (``grid.grid_lines``)."""
    s0 = summaries[0][1]
    gamma = s0["gamma"]
    caveats = report_caveats(summaries)  # what the study cannot answer comes first, before any rate
    lines = [f"# {title}", "", *[x for c in caveats for x in (c, "")],
             f"Success rate with {ci_name(s0['ci'])} 95 % CI; n = finished episodes (episodes with status \"error\" are "
             "excluded from n and counted beside it). Break level k* = first level with success < "
             f"γ = {gamma} (per direction for signed axes). A level with n < {s0.get('min_n', MIN_N)} or fewer "
             "than half its planned episodes finished shows \"insufficient data\": it gives no rate and no k* "
             "(k* is \"undetermined\" when such a level comes before the break). Trend tests are one-sided "
             "(success falls with |k|), per direction, on the levels with enough data. param \"—\": no episode, or "
             "the pooled tasks use different parameters (see each task in summary.json).", ""]  # fmt: skip
    lines += overview_lines(summaries, order or None)
    lines += grid_lines(summaries, _fmt_rate, _fmt_break)  # held axes A@B=j: (level of A) × (held level of B)
    axes = sorted({a for _, s in summaries for a in s["axes"]})
    for axis in axes:
        present = [(label, s["axes"][axis]) for label, s in summaries if axis in s["axes"]]
        levels = sorted({r["level"] for _, a in present for r in a["levels"]})
        params = {}
        for _, a in present:
            for r in a["levels"]:
                if params.get(r["level"]) is None:
                    params[r["level"]] = r["param"]
        note = [TRAINED_NOTE, ""] if any(a.get("trained") for _, a in present) else []
        lines += [f"## Axis `{axis}`", "", _pools(present), "", *note,
                  "| level | param | " + " | ".join(lbl for lbl, _ in present) + " |",
                  "|---|---|" + "---|" * len(present)]  # fmt: skip
        for k in levels:
            cells = []
            for _, a in present:
                row = next((r for r in a["levels"] if r["level"] == k), None)
                cells.append((_fmt_rate(row) if row else "") + trained_text(a, k))
            lines.append(f"| {k} | {_param(params[k])} | " + " | ".join(cells) + " |")
        lines.append(
            "| **k\\*** | | "
            + " | ".join(_fmt_break(a["break_level"], a["signed"]) for _, a in present)
            + " |"
        )
        lines.append(
            "| k\\* status | | "
            + " | ".join(_fmt_status(a.get("kstar_status", {}), a["signed"]) for _, a in present)
            + " |"
        )
        lines.append("| verdict | | " + " | ".join(_verdict_or_status(a) for _, a in present) + " |")
        if any(a.get("design") for _, a in present):
            lines.append("| design | | " + " | ".join(a.get("design") or "—" for _, a in present) + " |")
        lines.append(
            "| break point (S = γ) | | "
            + " | ".join(_fmt_point(a.get("break_point", {}), a["signed"]) for _, a in present)
            + " |"
        )
        lines.append(
            "| monotone decrease (isotonic LRT) | | "
            + " | ".join(_fmt_tests(a.get("monotone", {}), a["signed"], method=True) for _, a in present)
            + " |"
        )
        if any(a.get("condition2") for _, a in present):
            lines.append(
                "| condition 2, black-box (appendix B) | | "
                + " | ".join(fmt_condition2(a.get("condition2"), a["signed"]) for _, a in present)
                + " |"
            )
        lines.append(
            "| linear trend (Cochran–Armitage) | | "
            + " | ".join(_fmt_tests(a.get("trend", {}), a["signed"]) for _, a in present)
            + " |"
        )
        warnings = [w for lbl, a in present for w in [*error_warnings(lbl, a), *pool_warnings(lbl, a)]]
        if warnings:
            lines += ["", *warnings]
        lines += render_vs_t0(present)
        lines += render_breakdown(present)
        lines += render_levels(present)
        if any(len(a.get("tasks", {})) > 1 for _, a in present):
            tasks = sorted({t for _, a in present for t in a.get("tasks", {})})
            lines += [
                "",
                "k* per task (the pooled rows above mix these tasks):",
                "",
                "| task | " + " | ".join(lbl for lbl, _ in present) + " |",
                "|---|" + "---|" * len(present),
            ]
            for t in tasks:
                cells = [
                    _fmt_break(a["tasks"][t]["break_level"], a["signed"]) if t in a.get("tasks", {}) else ""
                    for _, a in present
                ]
                lines.append(f"| {t} | " + " | ".join(cells) + " |")
            lines.append("| **across tasks** | " + " | ".join(_spread(a) for _, a in present) + " |")
        lines.append("")
    return "\n".join(lines)


def write_run_report(
    run: RunDir, gamma: float = DEFAULT_GAMMA, ci: str = "wilson", episodes=None, margin: float | None = None,
    plots: bool | None = None,
) -> dict:  # fmt: skip
    """Write summary.json, report.md, report.html and plots/<axis>.svg (the headline curve, no matplotlib) inside one
    run directory, and with ``plots`` the PNG set (``draw_run_plots``, ~2 s: ``indgen report``); ``None``: the PNGs
    only where an earlier report drew them (kept current, never stale); return the summary (``episodes``:
    ``run.episodes()`` when the caller has it already)."""
    episodes = run.episodes() if episodes is None else episodes
    summary = summarize(episodes, run.manifest, gamma, ci, margin)
    attach_oracle_states(summary, run.path, episodes)  # indgen certify --evaluation-states, when it ran
    atomic_write_json(run.path / SUMMARY, summary)
    label = run_label(run)
    extra = [p.read_text() for p in sorted((run.path / SECTIONS).glob("*.md"))]  # e.g. indgen real's voids
    order = axis_order([(label, summary)], [run.manifest])
    text = render_markdown([(label, summary)], f"Report: {label}", order)
    atomic_write_text(run.path / REPORT, "\n".join([text, *extra]))
    for axis, a in summary["axes"].items():
        write_axis_svg(label, a, axis, gamma, run.path / "plots" / f"{_safe(axis)}.svg", summary["ci"])
    if plots or (plots is None and pngs_drawn(run.path / "plots")):
        draw_run_plots(run.path / "plots", label, summary, gamma, order, run.manifest)

    write_run_html(run.path, run.manifest, summary, episodes, "\n".join([text, *extra]), label, order)
    return summary


def draw_run_plots(
    plots: Path, label: str, summary: dict, gamma: float, order: Sequence[str], manifest: dict
) -> None:
    """One run's PNGs (matplotlib): per axis success vs level, failure modes and stage shares, the all-axes figure
    and the grids."""
    for axis, a in summary["axes"].items():
        plot_axis([(label, a)], axis, gamma, plots / f"{_safe(axis)}.png", summary["ci"])
        plot_failures([(label, a)], axis, plots / f"{_safe(axis)}_failures.png")
        plot_progress([(label, a)], axis, plots / f"{_safe(axis)}_progress.png")
    plot_axes([(label, summary)], gamma, plots / AXES_PLOT, order, axis_specs([manifest]))
    plot_grids([(label, summary)], gamma, plots)


def pngs_drawn(plots: Path) -> bool:
    """Whether a report has drawn PNGs in ``plots`` (``indgen report``): later reports of the run redraw them."""
    return plots.is_dir() and any(plots.glob("*.png"))


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)


def overlay_dir(first_run: str | Path, out: str | Path | None = None) -> Path:
    """Where several runs' overlay goes: ``out``, else FIRST_RUN/overlay."""
    return Path(out) if out else Path(first_run) / "overlay"


def write_reports(
    runs: Sequence[str | Path], *, gamma: float = DEFAULT_GAMMA, ci: str = "wilson", out: str | Path | None = None,
    margin: float | None = None,
) -> list[tuple[str, dict]]:  # fmt: skip
    """``indgen report``: each run's summary.json, report.md and plots, and for several runs their overlay in ``out``
    (default FIRST_RUN/overlay); return each run's (label, summary), labels told apart by folder name."""
    if not 0 < gamma <= 1:
        raise ConfigError(f"--gamma must be in (0, 1], got {gamma}")
    check_margin(margin)
    runs = [RunDir.open(p) for p in runs]
    results = []
    for run in runs:
        episodes = run.episodes()
        if len(episodes) == 0:
            raise RunDirError(
                f"{run.path} has no finished episodes yet; run or resume 'indgen evaluate' first"
            )
        results.append((run_label(run), write_run_report(run, gamma, ci, episodes, margin, plots=True)))
    if len(runs) > 1:
        labels = [lbl for lbl, _ in results]
        if len(set(labels)) < len(labels):  # disambiguate identical labels by folder name
            results = [(f"{lbl} ({r.path.name})", s) for (lbl, s), r in zip(results, runs, strict=True)]
        out = overlay_dir(runs[0].path, out)
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise RunDirError(
                f"cannot write to --out {out}: {e.strerror}; choose another directory"
            ) from None

        protocol = check_comparable(
            [(lbl, r.manifest.get("fingerprint")) for (lbl, _), r in zip(results, runs, strict=True)],
            allow=True,
        )  # side by side, never pooled: differences are shown, not refused
        order = axis_order(results, [r.manifest for r in runs])
        text = render_markdown(results, "Inductive generalization: run comparison", order)
        atomic_write_text(
            out / REPORT, text + "\n" + "\n".join(protocol_section(protocol)) if protocol else text
        )
        for axis in sorted({a for _, s in results for a in s["axes"]}):
            curves = [(lbl, s["axes"][axis]) for lbl, s in results if axis in s["axes"]]
            plot_axis(
                curves,
                axis,
                gamma,
                out / "plots" / f"{_safe(axis)}.png",
                results[0][1]["ci"],
                "side by side, not compared (indgen compare tests the difference)",
            )
            plot_failures(curves, axis, out / "plots" / f"{_safe(axis)}_failures.png")
            plot_progress(curves, axis, out / "plots" / f"{_safe(axis)}_progress.png")
        plot_axes(results, gamma, out / "plots" / AXES_PLOT, order, axis_specs([r.manifest for r in runs]))
        plot_grids(results, gamma, out / "plots")

        write_overlay_html(out, results, text, order)
    return results


def print_tables(results: list[tuple[str, dict]]) -> None:
    """Rich tables per run and axis; a level below the data floor prints "insufficient data (...)", no rate."""
    from rich.console import Console
    from rich.table import Table

    console = Console()
    for line in report_caveats(results):  # first, as in report.md: what the study cannot answer
        console.print(line.replace("**", ""), markup=False, highlight=False)
    for label, s in results:
        for axis, a in s["axes"].items():
            t = Table(
                title=f"{label} — {axis} (γ = {s['gamma']}; {pooled_text(a.get('pooled_tasks') or [])})"
            )
            for col in ("level", "param", "n", "errors", "success", "95% CI"):
                t.add_column(col, justify="right")
            for r in a["levels"]:
                if r.get("insufficient", r["n"] == 0):
                    rate, ci = insufficient_text(r), ""
                else:
                    rate = f"{100 * r['rate']:.0f}%" + (
                        f" ({pooled_text(r['pooled_only'])} only)" if r.get("pooled_only") else ""
                    )
                    ci = f"[{100 * r['ci_low']:.0f}, {100 * r['ci_high']:.0f}]"
                t.add_row(str(r["level"]), _param(r["param"]), str(r["n"]), str(r["errors"]), rate, ci)
            console.print(t)
            if a["signed"] and "verdict" in a:
                console.print("break level k* (first level below γ):")
                for d, side in (("pos", "+"), ("neg", "−")):
                    console.print(f"  {side}: {a['verdict'][d]}")
            else:
                console.print(f"break level k* (first level below γ): {_verdict_or_status(a)}")
            console.print(f"break point (S = γ): {_fmt_point(a.get('break_point', {}), a['signed'])}")
            console.print(
                f"monotone decrease (isotonic LRT): {_fmt_tests(a.get('monotone', {}), a['signed'], True)}"
            )
            if a.get("condition2"):  # black-box regime: k* stands only where the ordering is validated
                console.print(
                    f"condition 2, black-box (appendix B): {fmt_condition2(a['condition2'], a['signed'])}"
                )
            for line in t0_lines(a):
                console.print(line, markup=False, highlight=False)
            for w in [*error_warnings(label, a), *pool_warnings(label, a)]:
                console.print(w.replace("**", ""))
