"""Failure modes in reports: per-level counts, the markdown breakdown, a stacked-bar panel, and what changed
between two runs. The modes themselves are classified by the scenes (``scenes.failure``) from privileged
simulator state the policy never sees; this module only counts them."""

from __future__ import annotations

from pathlib import Path

from indgen_vla.core.protocol.interface import FAILURE_MODES
from indgen_vla.core.reporting.figures import count_note
from indgen_vla.core.runs.records import atomic_savefig
from indgen_vla.core.stats.frames import group_items

UNCLASSIFIED = "unclassified"  # rows of run directories written before the failure column existed
MODES = (*FAILURE_MODES, UNCLASSIFIED)
COLOURS = {"none": "#4caf50", "no_contact": "#9e9e9e", "no_grasp": "#ff9800", "dropped": "#e53935",
           "misplaced": "#8e24aa", "timeout_holding": "#1e88e5", "unknown": "#bdbdbd", "error": "#212121",
           "unavailable": "#f5f5f5",
           UNCLASSIFIED: "#e0e0e0"}  # fmt: skip


def failure_counts(level_df) -> dict[str, int]:
    """Episodes per failure mode at one level (every finished row, errors included), in ``MODES`` order."""
    if "failure" not in level_df:
        return {UNCLASSIFIED: len(level_df)} if len(level_df) else {}
    values = level_df["failure"].fillna("").replace("", UNCLASSIFIED)
    counts = values.value_counts().to_dict()
    return {m: int(counts[m]) for m in MODES if counts.get(m)}


def failure_counts_by(df, keys: list[str]) -> dict[tuple, dict[str, int]]:
    """``failure_counts`` of every group of ``keys`` (a tuple of their values) in one pass over ``df``: a summary's
    cells without filtering the table once per cell."""
    if not len(df):
        return {}
    if "failure" not in df:
        return {k: {UNCLASSIFIED: c} for k, c in group_items(df.groupby(keys, sort=False).size())}
    values = df["failure"].fillna("").replace("", UNCLASSIFIED).rename("_mode")
    found: dict[tuple, dict[str, int]] = {}
    for (*key, mode), c in group_items(df.groupby([*(df[k] for k in keys), values], sort=False).size()):
        found.setdefault(tuple(key), {})[mode] = c
    return {k: {m: counts[m] for m in MODES if counts.get(m)} for k, counts in found.items()}


def render_breakdown(present: list[tuple[str, dict]]) -> list[str]:
    """Markdown lines: per run, one row per level with each mode's count (only modes that occur)."""
    lines = []
    for label, a in present:
        used = [m for m in MODES if any(r.get("failures", {}).get(m) for r in a["levels"])]
        if not set(used) - {"none", UNCLASSIFIED}:  # nothing classified failed: no table to show
            continue
        lines += ["", f"Failure modes ({label}; `none` = success, see docs/run-directory.md):", "",
                  "| level | " + " | ".join(used) + " |", "|---|" + "---|" * len(used)]  # fmt: skip
        for r in a["levels"]:
            f = r.get("failures", {})
            lines.append(f"| {r['level']} | " + " | ".join(str(f.get(m, 0)) for m in used) + " |")
    return lines


def classified(levels: list[dict]) -> bool:
    """Whether any episode of these summary levels carries a failure mode (runs before the column: none)."""
    return any(m != UNCLASSIFIED for r in levels for m in r.get("failures", {}))


def plot_failures(curves: list[tuple[str, dict]], axis: str, path: Path) -> Path | None:
    """``failures_figure`` as a PNG at ``path`` (None: nothing classified)."""
    fig = failures_figure(curves, axis)
    if fig is None:
        return None
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_savefig(fig, path)
    return path


def failures_figure(curves: list[tuple[str, dict]], axis: str):
    """One stacked-bar panel per run: the share of each failure mode per level, the legend beside the panels, never
    over a bar or a title (None: nothing classified)."""
    if not any(classified(a["levels"]) for _, a in curves):
        return None
    from matplotlib.figure import Figure  # not pyplot (report.plot_axis)

    fig = Figure(figsize=(4.2 * len(curves) + 1.1, 3.2), dpi=120, layout="constrained")
    axes = fig.subplots(1, len(curves), squeeze=False)
    for ax, (label, a) in zip(axes[0], curves, strict=True):
        rows = [r for r in a["levels"] if sum(r.get("failures", {}).values())]
        ks = [r["level"] for r in rows]
        bottom = [0.0] * len(rows)
        for m in MODES:
            share = [r.get("failures", {}).get(m, 0) / sum(r["failures"].values()) for r in rows]
            if any(share):
                ax.bar(ks, share, bottom=bottom, color=COLOURS[m], label=m, width=0.8)
                bottom = [b + s for b, s in zip(bottom, share, strict=True)]
        note = count_note([sum(r["failures"].values()) for r in rows], a.get("pooled_tasks") or [])
        ax.set_title(f"{label}\n{note}; descriptive, no CI", fontsize=7)
        ax.set_xlabel(f"level k along {axis}")
        ax.set_ylim(0, 1)
        if ks:
            ax.set_xticks(ks)
    axes[0][0].set_ylabel("share of episodes")
    handles, labels = {}, []
    for ax in axes[0]:
        for h, lbl in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(lbl, h)
    labels = [m for m in MODES if m in handles]
    fig.legend([handles[m] for m in labels], labels, fontsize=7, loc="outside right upper", ncol=1)
    return fig


def failure_shift(a_levels: list[dict], b_levels: list[dict]) -> dict:
    """Which failure modes changed between two runs on one axis: per mode, its count and share of all episodes of
    the shared levels in A and in B (``n_a``, ``n_b``) and the difference (B − A), largest change first."""
    shared = {r["level"] for r in a_levels} & {r["level"] for r in b_levels}

    def counts(levels: list[dict]) -> dict[str, int]:
        found: dict[str, int] = {}
        for r in levels:
            if r["level"] in shared:
                for m, c in r.get("failures", {}).items():
                    found[m] = found.get(m, 0) + c
        return found

    ca, cb = counts(a_levels), counts(b_levels)
    na, nb = sum(ca.values()), sum(cb.values())

    def share(c: dict[str, int], n: int, m: str) -> float:
        return c.get(m, 0) / n if n else 0.0

    rows = [{"mode": m, "count_a": ca.get(m, 0), "count_b": cb.get(m, 0), "share_a": share(ca, na, m),
             "share_b": share(cb, nb, m), "diff": share(cb, nb, m) - share(ca, na, m)}
            for m in MODES if m in ca or m in cb]  # fmt: skip
    return {
        "levels": sorted(shared),
        "n_a": na,
        "n_b": nb,
        "modes": sorted(rows, key=lambda r: -abs(r["diff"])),
    }


def render_shift(shift: dict, label_a: str, label_b: str) -> list[str]:
    """Markdown lines for ``failure_shift``: each mode's count and share of n in A and B over the shared levels."""
    if not shift["modes"]:
        return []
    levels = ", ".join(str(k) for k in shift["levels"])
    lines = ["", f"Failure modes, count/n and share of all episodes on the shared levels {levels} ({label_a} → "
             f"{label_b}); descriptive: no CI, not tested:", "", "| mode | A | B | B − A |", "|---|---|---|---|"]  # fmt: skip
    for r in shift["modes"]:
        lines.append(f"| {r['mode']} | {r['count_a']}/{shift['n_a']} = {100 * r['share_a']:.0f}% | "
                     f"{r['count_b']}/{shift['n_b']} = {100 * r['share_b']:.0f}% | {100 * r['diff']:+.0f} pts |")  # fmt: skip
    return lines
