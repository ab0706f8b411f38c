"""``indgen compare RUN_A RUN_B``: per-level exact tests (Barnard/Boschloo) with Holm correction,
the difference in break levels, an overlay plot and a verdict sentence that never overstates."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from indgen_vla.errors import ConfigError, RunDirError
from indgen_vla.metrics import break_levels, compare_levels
from indgen_vla.records import RunDir, atomic_write_json, atomic_write_text
from indgen_vla.report import plot_axis, run_label, summarize


def _counts(axis_summary: dict) -> dict[int, tuple[int, int]]:
    return {r["level"]: (r["successes"], r["n"]) for r in axis_summary["levels"]}


def compare_summaries(sa: dict, sb: dict, test: str = "boschloo", gamma: float = 0.2) -> dict[str, Any]:
    """The compare.json dict for two run summaries (axes present in both)."""
    out: dict[str, Any] = {"test": test, "gamma": gamma, "axes": {}}
    for axis in sorted(set(sa["axes"]) & set(sb["axes"])):
        a, b = sa["axes"][axis], sb["axes"][axis]
        rows = compare_levels(_counts(a), _counts(b), test=test)
        signed = a["signed"] or b["signed"]
        rates_a = {r["level"]: r["rate"] for r in a["levels"]}
        rates_b = {r["level"]: r["rate"] for r in b["levels"]}
        out["axes"][axis] = {
            "levels": rows,
            "break_level_a": break_levels(rates_a, gamma, signed),
            "break_level_b": break_levels(rates_b, gamma, signed),
        }
    return out


def verdict(result: dict, label_a: str, label_b: str, alpha: float = 0.05) -> str:
    """One cautious sentence per axis: which levels differ after Holm, and the k* of each run."""
    sentences = []
    for axis, ax in result["axes"].items():
        sig = [r for r in ax["levels"] if not math.isnan(r["p_holm"]) and r["p_holm"] < alpha]
        ka, kb = ax["break_level_a"], ax["break_level_b"]
        k_text = f"k* {_k(ka)} ({label_a}) vs {_k(kb)} ({label_b})"
        if not sig:
            sentences.append(
                f"{axis}: no level differs at α = {alpha} after Holm correction "
                f"(this does not show the runs are equal); {k_text}."
            )
        else:
            parts = [f"L{r['level']} ({100 * r['rate_a']:.0f}% vs {100 * r['rate_b']:.0f}%, p_holm = {r['p_holm']:.3g})"
                     for r in sig]  # fmt: skip
            sentences.append(
                f"{axis}: {len(sig)} level(s) differ at α = {alpha} after Holm: {', '.join(parts)}; {k_text}."
            )
    return " ".join(sentences) if sentences else "the runs share no axis to compare."


def _k(b: dict) -> str:
    """Break levels as "+2 / −3" (signed axes: positive side / negative side) or "3"; "none" when none in range."""

    def one(k, signed: bool) -> str:
        if k is None:
            return "none"
        return f"{k:+d}".replace("-", "−") if signed else str(k)

    if "neg" in b:
        return f"{one(b['pos'], True)} / {one(b['neg'], True)}"
    return one(b["pos"], False)


def render_markdown(result: dict, label_a: str, label_b: str, text: str) -> str:
    lines = [f"# Comparison: {label_a} (A) vs {label_b} (B)", "",
             "Break levels k* (first level with success < γ) read \"positive side / negative side\" on signed axes.", "",
             f"Two-sided {result['test'].capitalize()} exact test per level, Holm-corrected per axis.", "",
             f"**Verdict.** {text}", ""]  # fmt: skip
    for axis, ax in result["axes"].items():
        lines += [f"## Axis `{axis}`", "", "| level | A | B | p | p (Holm) |", "|---|---|---|---|---|"]
        for r in ax["levels"]:
            lines.append(
                f"| {r['level']} | {r['successes_a']}/{r['n_a']} | {r['successes_b']}/{r['n_b']} | "
                f"{r['p_value']:.3g} | {r['p_holm']:.3g} |"
            )
        lines += ["", f"Break level k*: A {_k(ax['break_level_a'])}, B {_k(ax['break_level_b'])}", ""]
    return "\n".join(lines)


def compare_main(args: argparse.Namespace) -> int:
    """CLI handler for ``indgen compare``."""
    if not 0 < args.alpha < 1:
        raise ConfigError(f"--alpha must be in (0, 1), got {args.alpha}")
    if not 0 < args.gamma <= 1:
        raise ConfigError(f"--gamma must be in (0, 1], got {args.gamma}")
    ra, rb = RunDir.open(args.run_a), RunDir.open(args.run_b)
    sa = summarize(ra.episodes(), ra.manifest, args.gamma)
    sb = summarize(rb.episodes(), rb.manifest, args.gamma)
    if not set(sa["axes"]) & set(sb["axes"]):
        raise RunDirError(f"{ra.path} and {rb.path} share no axis; compare runs evaluated on the same axis")
    la, lb = run_label(ra), run_label(rb)
    if la == lb:
        la, lb = f"{la} ({ra.path.name})", f"{lb} ({rb.path.name})"
    result = compare_summaries(sa, sb, args.test, args.gamma)
    result["label_a"], result["label_b"] = la, lb
    result["verdict"] = verdict(result, la, lb, args.alpha)
    out = Path(args.out) if args.out else ra.path / "compare"
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise RunDirError(f"cannot write to --out {out}: {e.strerror}; choose another directory") from None
    atomic_write_json(out / "compare.json", result)
    atomic_write_text(out / "compare.md", render_markdown(result, la, lb, result["verdict"]))
    for axis in result["axes"]:
        plot_axis(
            [(la, sa["axes"][axis]), (lb, sb["axes"][axis])], axis, args.gamma, out / "plots" / f"{axis}.png"
        )
    print(render_markdown(result, la, lb, result["verdict"]))
    print(f"wrote {out / 'compare.json'}, {out / 'compare.md'}, {out / 'plots'}/")
    return 0
