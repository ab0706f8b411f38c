"""``indgen report``: summary.json, report.md and success-vs-level plots from run directories."""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from indgen_vla.errors import ConfigError, RunDirError
from indgen_vla.metrics import DEFAULT_GAMMA, break_levels, cochran_armitage, success_rate
from indgen_vla.records import REPORT, SUMMARY, RunDir, atomic_write_json, atomic_write_text


def _axis_signed(manifest: dict[str, Any], axis: str, levels: Sequence[int]) -> bool:
    info = manifest.get("axes", {}).get(axis, {})
    return bool(info["signed"]) if "signed" in info else any(k < 0 for k in levels)


def summarize(episodes, manifest: dict[str, Any], gamma: float = DEFAULT_GAMMA, ci: str = "wilson") -> dict:
    """The summary.json dict: per axis, per level n/successes/rate/CI, break levels and trend tests.

    Rows with status "error" are excluded from n and counted in ``errors``.
    """
    out: dict[str, Any] = {"gamma": gamma, "ci": ci, "axes": {}}
    for axis in sorted(episodes["axis"].unique()) if len(episodes) else []:
        df = episodes[episodes["axis"] == axis]
        levels_out, rates = [], {}
        for level in sorted(df["level"].unique()):
            d = df[df["level"] == level]
            ok = d[d["status"] == "ok"]
            r = success_rate(int(ok["success"].sum()), len(ok), method=ci)
            levels_out.append({
                "level": int(level), "param": float(d["param"].iloc[0]), "n": r.n, "successes": r.successes,
                "rate": r.rate, "ci_low": r.ci_low, "ci_high": r.ci_high, "errors": int(len(d) - len(ok)),
            })  # fmt: skip
            rates[int(level)] = r.rate
        signed = _axis_signed(manifest, axis, list(rates))
        entry: dict[str, Any] = {
            "signed": signed,
            "levels": levels_out,
            "break_level": break_levels(rates, gamma, signed=signed),
            "trend": _trend(levels_out, signed),
        }
        out["axes"][axis] = entry
    return out


def _trend(levels: list[dict], signed: bool) -> dict:
    """One-sided Cochran–Armitage test per direction: the post-hoc ordering check of appendix B."""
    res = {}
    for name, keep in (
        (("pos", lambda k: k >= 0), ("neg", lambda k: k <= 0)) if signed else (("pos", lambda k: True),)
    ):
        rows = [r for r in levels if keep(r["level"]) and r["n"] > 0]
        if len(rows) >= 2:
            t = cochran_armitage(
                [abs(r["level"]) for r in rows], [r["successes"] for r in rows], [r["n"] for r in rows]
            )
            res[name] = {"z": t.statistic, "p_decreasing": t.p_decreasing}
    return res


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


def _fmt_rate(row: dict) -> str:
    if row["n"] == 0:
        return "—"
    return f"{100 * row['rate']:.0f}% [{100 * row['ci_low']:.0f}, {100 * row['ci_high']:.0f}] (n={row['n']})"


def _fmt_break(b: dict, signed: bool) -> str:
    def one(k):
        return "none" if k is None else f"L{k}"

    return f"+: {one(b['pos'])}, −: {one(b.get('neg'))}" if signed else one(b["pos"])


def render_markdown(summaries: list[tuple[str, dict]], title: str = "Inductive generalization report") -> str:
    """A levels × runs table per axis with rate, CI, n and k*."""
    gamma = summaries[0][1]["gamma"]
    lines = [f"# {title}", "", f"Success rate with {summaries[0][1]['ci']} 95 % CI; break level k* = first level "
             f"with success < γ = {gamma} (per direction for signed axes).", ""]  # fmt: skip
    axes = sorted({a for _, s in summaries for a in s["axes"]})
    for axis in axes:
        present = [(label, s["axes"][axis]) for label, s in summaries if axis in s["axes"]]
        levels = sorted({r["level"] for _, a in present for r in a["levels"]})
        params = {r["level"]: r["param"] for _, a in present for r in a["levels"]}
        lines += [f"## Axis `{axis}`", "", "| level | param | " + " | ".join(lbl for lbl, _ in present) + " |",
                  "|---|---|" + "---|" * len(present)]  # fmt: skip
        for k in levels:
            cells = []
            for _, a in present:
                row = next((r for r in a["levels"] if r["level"] == k), None)
                cells.append(_fmt_rate(row) if row else "")
            lines.append(f"| {k} | {params[k]:.4g} | " + " | ".join(cells) + " |")
        lines.append(
            "| **k\\*** | | "
            + " | ".join(_fmt_break(a["break_level"], a["signed"]) for _, a in present)
            + " |"
        )
        errs = [(lbl, sum(r["errors"] for r in a["levels"])) for lbl, a in present]
        if any(e for _, e in errs):
            lines += [
                "",
                "Episodes with errors (excluded from n): " + ", ".join(f"{lbl}: {e}" for lbl, e in errs),
            ]
        lines.append("")
    return "\n".join(lines)


def plot_axis(curves: list[tuple[str, dict]], axis: str, gamma: float, path: Path) -> Path:
    """Success vs level in the style of the paper's Fig. 3: level 0 centred, γ line, CI bands."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 3.6), dpi=120)
    all_levels: list[int] = []
    signed = False
    for label, a in curves:
        rows = [r for r in a["levels"] if r["n"] > 0]
        ks = [r["level"] for r in rows]
        all_levels += ks
        signed |= a["signed"]
        line = ax.plot(ks, [r["rate"] for r in rows], marker="o", label=label)[0]
        ax.fill_between(ks, [r["ci_low"] for r in rows], [r["ci_high"] for r in rows], alpha=0.2,
                        color=line.get_color())  # fmt: skip
    ax.axhline(gamma, ls="--", color="grey", lw=1, label=f"γ = {gamma}")
    if signed and all_levels:
        m = max(abs(k) for k in all_levels)
        ax.set_xlim(-m - 0.5, m + 0.5)
        ax.axvline(0, color="black", lw=0.5, alpha=0.4)
    if all_levels:
        ax.set_xticks(sorted(set(all_levels)))
    ax.set_ylim(-0.03, 1.03)
    ax.set_xlabel(f"level k along {axis}")
    ax.set_ylabel("success rate")
    ax.set_title(axis)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower left" if not signed else "lower center")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def write_run_report(run: RunDir, gamma: float = DEFAULT_GAMMA, ci: str = "wilson") -> dict:
    """Write summary.json, report.md and plots/*.png inside one run directory; return the summary."""
    summary = summarize(run.episodes(), run.manifest, gamma, ci)
    atomic_write_json(run.path / SUMMARY, summary)
    label = run_label(run)
    atomic_write_text(run.path / REPORT, render_markdown([(label, summary)], f"Report: {label}"))
    for axis, a in summary["axes"].items():
        plot_axis([(label, a)], axis, gamma, run.path / "plots" / f"{_safe(axis)}.png")
    return summary


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in name)


def report_main(args: argparse.Namespace) -> int:
    """CLI: ``indgen report RUN... [--gamma] [--ci] [--out]``."""
    if not 0 < args.gamma <= 1:
        raise ConfigError(f"--gamma must be in (0, 1], got {args.gamma}")
    runs = [RunDir.open(p) for p in args.runs]
    results = []
    for run in runs:
        if len(run.episodes()) == 0:
            raise RunDirError(
                f"{run.path} has no finished episodes yet; run or resume 'indgen evaluate' first"
            )
        results.append((run_label(run), write_run_report(run, args.gamma, args.ci)))
        print(f"{run.path}: wrote {SUMMARY}, {REPORT}, plots/")
    if len(runs) > 1:
        labels = [lbl for lbl, _ in results]
        if len(set(labels)) < len(labels):  # disambiguate identical labels by folder name
            results = [(f"{lbl} ({r.path.name})", s) for (lbl, s), r in zip(results, runs, strict=True)]
        out = Path(args.out) if args.out else runs[0].path / "overlay"
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise RunDirError(
                f"cannot write to --out {out}: {e.strerror}; choose another directory"
            ) from None
        atomic_write_text(out / REPORT, render_markdown(results, "Inductive generalization: run comparison"))
        for axis in sorted({a for _, s in results for a in s["axes"]}):
            curves = [(lbl, s["axes"][axis]) for lbl, s in results if axis in s["axes"]]
            plot_axis(curves, axis, args.gamma, out / "plots" / f"{_safe(axis)}.png")
        print(f"overlay: {out / REPORT}, {out / 'plots'}/")
    print_tables(results)
    return 0


def print_tables(results: list[tuple[str, dict]]) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console()
    for label, s in results:
        for axis, a in s["axes"].items():
            t = Table(title=f"{label} — {axis} (γ = {s['gamma']})")
            for col in ("level", "param", "n", "success", "95% CI"):
                t.add_column(col, justify="right")
            for r in a["levels"]:
                rate = "—" if math.isnan(r["rate"]) else f"{100 * r['rate']:.0f}%"
                t.add_row(str(r["level"]), f"{r['param']:.4g}", str(r["n"]), rate,
                          f"[{100 * r['ci_low']:.0f}, {100 * r['ci_high']:.0f}]")  # fmt: skip
            console.print(t)
            console.print(f"break level k*: {_fmt_break(a['break_level'], a['signed'])}")
