"""The paper's figure types from summaries and images: success vs level of one axis (``plot_axis``), every axis side
by side with the runs overlaid (Fig. 3/4, ``axes_figure``), the axes × levels table with each axis's largest drop
from T0 (Table 2, ``overview_lines``) and the labelled grid of level previews (Fig. 5, ``contact_sheet``).

matplotlib's ``Figure``, never pyplot: no GUI backend or figure registry to start (start-up time).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from indgen_vla.core.protocol.training_support import fully_trained
from indgen_vla.core.runs.records import atomic_savefig
from indgen_vla.core.stats.breakpoint import signed_level
from indgen_vla.core.stats.metrics import ci_name, difference_ci, pooled_text, usable_rows

AXES_PLOT = (
    "axes.png"  # plots/axes.png: every axis of a report in one figure, written when it covers >= 2 axes
)
PANELS_PER_ROW = 4  # the paper's Fig. 3/4 row; a report with more axes wraps onto further rows
KSTAR_LABEL = "k* (first level below γ)"
NO_RATE = (
    "no level has enough data for a rate yet\n(every level is below the data floor: see the levels table)"
)


def _once(shown: set[str], label: str) -> str | None:
    """``label`` the first time, None after (one legend entry for a marker every curve draws)."""
    if label in shown:
        return None
    shown.add(label)
    return label


def draw_curves(
    ax, curves: Sequence[tuple[str, dict]], gamma: float, *, colours: Sequence[str] | None = None,
    break_points: bool = True, tasks: bool = True,
) -> tuple[list[int], bool]:  # fmt: skip
    """Draw each run's success vs level with its CI band and its k* ringed on one matplotlib axes.

    Args:
        curves: (label, axis summary) per run.
        colours: one colour per run (the same run keeps its colour across panels); default the colour cycle.
        break_points: mark where each fitted curve crosses γ, with its interval.
        tasks: draw each pooled task's curve faintly behind a run that pools several.

    Returns:
        The levels drawn and whether any run's axis is signed.
    """
    marked: set[str] = set()  # legend entries already shown (markers every curve draws are explained once)
    levels: list[int] = []
    signed = False
    for i, (label, a) in enumerate(curves):
        rows = usable_rows(a["levels"])
        ks = [r["level"] for r in rows]
        levels += ks
        signed |= a["signed"]
        colour = colours[i] if colours else f"C{i}"
        # one run: a grey band (its own colour is its CI band's); several: each run's band in its colour
        one = len(curves) == 1
        shade_trained(
            ax, fully_trained(a), "grey" if one else colour, "trained levels" if one else f"{label}: trained"
        )
        ax.plot(ks, [r["rate"] for r in rows], marker="o", ms=4, color=colour, label=label, zorder=3)
        ax.fill_between(ks, [r["ci_low"] for r in rows], [r["ci_high"] for r in rows], alpha=0.18, color=colour,
                        lw=0, zorder=2)  # fmt: skip
        rate = {r["level"]: r["rate"] for r in rows}
        for k in (a.get("break_level") or {}).values():  # "undetermined" or None: nothing to mark
            if isinstance(k, int) and k in rate:
                ax.plot([k], [rate[k]], ls="none", marker="o", ms=10, mfc="none", mec=colour, mew=1.5, zorder=4,
                        label=_once(marked, KSTAR_LABEL))  # fmt: skip
        if break_points:
            for b in a.get("break_point", {}).values():  # where the fitted curve crosses γ, with its interval
                lo, hi = b.get("ci", {}).get("level", [None, None])
                if b.get("level") is not None and lo is not None and hi is not None:
                    ax.errorbar([b["level"]], [gamma], xerr=[[b["level"] - lo], [hi - b["level"]]], fmt="D",
                                ms=4, color=colour, capsize=3, zorder=4,
                                label=_once(marked, "break point (S = γ), 95% CI"))  # fmt: skip
        per_task = a.get("tasks", {})
        if tasks and len(per_task) > 1:
            for j, t in enumerate(sorted(per_task)):
                tr = usable_rows(per_task[t]["levels"])
                ax.plot([r["level"] for r in tr], [r["rate"] for r in tr], color=colour, alpha=0.25, lw=0.8,
                        zorder=1, label=f"{label}: single tasks ({len(per_task)})" if j == 0 else None)  # fmt: skip
    ax.axhline(gamma, ls="--", color="grey", lw=1, label=f"γ = {gamma}")
    # every level below the data floor: say so over the levels run, not over a blank ±0.04 axis
    if not levels:
        ax.text(
            0.5, 0.5, NO_RATE, transform=ax.transAxes, ha="center", va="center", color="dimgrey", fontsize=8
        )
    _level_axis(ax, levels or sorted({r["level"] for _, a in curves for r in a["levels"]}), signed)
    return levels, signed


def shade_trained(ax, levels: Sequence[int], colour: str, label: str) -> None:
    """A faint band over each trained level (neighbours join into one band: the training support), labelled once."""
    for j, k in enumerate(sorted(levels)):
        ax.axvspan(
            k - 0.5, k + 0.5, color=colour, alpha=0.08, lw=0, zorder=0, label=label if j == 0 else None
        )


def _level_axis(ax, levels: list[int], signed: bool) -> None:
    """Integer level ticks; a signed axis centred on T0 with a faint line at 0 (the paper's demarcation)."""
    if signed and levels:
        m = max(abs(k) for k in levels)
        ax.set_xlim(-m - 0.5, m + 0.5)
        ax.axvline(0, color="black", lw=0.5, alpha=0.4)
    if levels:
        ax.set_xticks(sorted(set(levels)))
    ax.set_ylim(-0.03, 1.03)
    ax.grid(alpha=0.3)


def plot_axis(
    curves: list[tuple[str, dict]], axis: str, gamma: float, path: Path, ci: str = "", note: str = ""
) -> Path:
    """Success vs level of one axis in the style of the paper's Fig. 3: level 0 centred, γ line, CI bands, k*
    ringed, the break point on the γ line; each task's curve faintly behind a run that pools several; levels
    without enough data are not drawn. Each run's legend entry says its n per level and the tasks it pools; ``note``
    (e.g. whether a comparison is paired) goes under the title."""
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    fig = Figure(figsize=(6.4, 4.2), dpi=120)
    ax = fig.subplots()
    draw_curves(ax, curves, gamma)
    ax.set_xlabel(f"level k along {axis}")
    ax.set_ylabel("success rate")
    ax.set_title(f"{axis}\n{note}" if note else axis, fontsize=10 if note else None)
    handles, labels = ax.get_legend_handles_labels()  # below the axes, so the curves keep the full width
    notes = {lbl: curve_note([a]) for lbl, a in curves}
    labels = [f"{lbl} ({notes[lbl]})" if notes.get(lbl) else lbl for lbl in labels]
    handles.append(Patch(color="grey", alpha=0.25, lw=0))
    labels.append(f"{ci_name(ci) + ' ' if ci else ''}95 % CI (shaded)")
    ncol = 2 if len(labels) > 1 and max(map(len, labels)) <= 48 else 1
    fig.legend(handles, labels, fontsize=7, loc="lower center", ncol=ncol, frameon=False)
    fig.tight_layout(rect=(0, 0.01 + 0.045 * -(-len(labels) // ncol), 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_savefig(fig, path)
    return path


def axis_order(
    summaries: Sequence[tuple[str, dict]], manifests: Sequence[Mapping[str, Any]] = ()
) -> list[str]:
    """The axes of a report in the order the runs planned them (their manifests), then any other alphabetically."""
    present = {a for _, s in summaries for a in s["axes"]}
    planned = [a for m in manifests for a in (m.get("axes") or {}) if a in present]
    return list(dict.fromkeys(planned)) + sorted(present - set(planned))


def axis_specs(manifests: Sequence[Mapping[str, Any]]) -> dict[str, dict]:
    """Each axis's spec from the runs' manifests (step and unit for panel titles); an axis whose runs used different
    steps gets none, so no panel claims one step for all of them."""
    specs: dict[str, dict] = {}
    for m in manifests:
        for axis, info in (m.get("axes") or {}).items():
            seen = specs.setdefault(axis, dict(info))
            if (seen.get("step"), seen.get("unit")) != (info.get("step"), info.get("unit")):
                specs[axis] = {}
    return specs


def _step_text(info: Mapping[str, Any] | None) -> str:
    """An axis's atomic step for a panel title ("2.5 cm per level"), "" when unknown or a composition's."""
    if not info or "step" not in info or info.get("unit") in (None, "level"):
        return ""
    step, unit = float(info["step"]), info["unit"]
    if unit == "m":
        return f"{100 * step:.3g} cm per level"
    if unit == "fraction":
        return f"{100 * step:.3g} % per level"
    return f"{step:g} {unit_name(unit, step)} per level"


def unit_name(unit: str, x: float) -> str:
    """A plural unit in the singular for one of it ("1 object"), as is otherwise ("2 objects", "0.25 in")."""
    return unit[:-1] if x == 1 and unit.endswith("s") else unit


def curve_note(axes: Sequence[dict]) -> str:
    """The episodes behind each point and the tasks pooled, for a legend or title: "n = 10 per level; pooled over 2
    tasks: bread, milk" (``metrics.pooled_text``)."""
    ns = [r["n"] for a in axes for r in usable_rows(a["levels"])]
    return count_note(ns, sorted({t for a in axes for t in a.get("pooled_tasks") or []}))


def count_note(ns: Sequence[int], tasks: Sequence[str]) -> str:
    """``curve_note`` from the counts behind each point (their range) and the tasks pooled."""
    n = "" if not ns else f"n = {min(ns)}" if min(ns) == max(ns) else f"n = {min(ns)}–{max(ns)}"
    return "; ".join(p for p in (f"{n} per level" if n else "", pooled_text(tasks)) if p)


def _legend_label(label: str, s: dict) -> str:
    """A run's legend entry with the episodes behind each point and the tasks it pools."""
    detail = curve_note(list(s["axes"].values()))
    return f"{label} ({detail})" if detail else label


def axes_figure(
    summaries: Sequence[tuple[str, dict]], gamma: float, order: Sequence[str] | None = None,
    axis_info: Mapping[str, Mapping[str, Any]] | None = None,
):  # fmt: skip
    """The paper's Fig. 3/4: one panel per axis (``PANELS_PER_ROW`` to a row) sharing the success axis, every run
    overlaid in its own colour with its CI band and k* ringed, the γ line, one legend below.

    Args:
        summaries: (label, summary.json dict) per run.
        order: the axes in panel order (default ``axis_order``).
        axis_info: per axis the manifest's axis spec (``step``, ``unit``) for the panel titles.
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    axes = list(order) if order else axis_order(summaries)
    ncols = min(len(axes), PANELS_PER_ROW)
    nrows = -(-len(axes) // ncols)
    fig = Figure(figsize=(3.1 * ncols + 0.5, 2.6 * nrows + 0.5 + 0.2 * len(summaries)), dpi=130,
                 layout="constrained")  # fmt: skip
    grid = fig.subplots(nrows, ncols, sharey=True, squeeze=False)
    colours = [f"C{i}" for i in range(len(summaries))]
    for i, ax in enumerate(grid.flat):
        if i >= len(axes):
            ax.set_visible(False)
            continue
        axis = axes[i]
        present = [(j, lbl, s["axes"][axis]) for j, (lbl, s) in enumerate(summaries) if axis in s["axes"]]
        draw_curves(ax, [(lbl, a) for _, lbl, a in present], gamma, colours=[colours[j] for j, _, _ in present],
                    break_points=False, tasks=False)  # fmt: skip
        step = _step_text((axis_info or {}).get(axis))
        ax.set_title(f"{axis}\n{step}" if step else axis, fontsize=9)
        ax.set_xlabel("level k", fontsize=8)
        ax.tick_params(labelsize=7)
        if i % ncols == 0:
            ax.set_ylabel("success rate", fontsize=8)
    ci = summaries[0][1].get("ci", "wilson")
    handles = [Line2D([], [], color=c, marker="o", ms=4, label=_legend_label(lbl, s))
               for c, (lbl, s) in zip(colours, summaries, strict=True)]  # fmt: skip
    handles += [Patch(color="grey", alpha=0.25, lw=0, label=f"{ci_name(ci)} 95 % CI"),
                Line2D([], [], ls="--", color="grey", lw=1, label=f"γ = {gamma}"),
                Line2D([], [], ls="none", marker="o", ms=9, mfc="none", mec="dimgrey", mew=1.5, label=KSTAR_LABEL)]  # fmt: skip
    ncol = _legend_columns([h.get_label() for h in handles], ncols)
    fig.legend(handles=handles, loc="outside lower center", ncol=ncol, fontsize=7, frameon=False)
    return fig


def _legend_columns(labels: list[str], panels: int) -> int:
    """One row when the labels fit under the panels, else two columns (runs | markers), else one (long labels)."""
    if sum(map(len, labels)) <= 24 * panels:
        return len(labels)
    return 2 if max(map(len, labels)) <= 16 * panels else 1


def plot_axes(
    summaries: Sequence[tuple[str, dict]], gamma: float, path: Path, order: Sequence[str] | None = None,
    axis_info: Mapping[str, Mapping[str, Any]] | None = None,
) -> Path | None:  # fmt: skip
    """Write ``axes_figure`` to ``path`` when the report covers two or more axes (None otherwise: the axis's own
    plot is the same figure)."""
    if len({a for _, s in summaries for a in s["axes"]}) < 2:
        return None
    fig = axes_figure(summaries, gamma, order, axis_info)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_savefig(fig, path)
    return path


def largest_drop(rows: list[dict]) -> dict | None:
    """The level with the lowest rate below T0's and the drop from T0 with its 95 % interval: the paired one of the
    level's ``vs_t0`` (episodes sharing seeds, contrasts.py) where the run pairs them, else unpaired (MOVER from the
    two levels' intervals); ties go to the level nearer T0. None when T0 or every other level lacks data."""
    rows = usable_rows(rows)
    t0 = next((r for r in rows if r["level"] == 0), None)
    rest = [r for r in rows if r["level"] != 0]
    if t0 is None or not rest:
        return None
    worst = min(rest, key=lambda r: (r["rate"], abs(r["level"]), r["level"] < 0))
    if worst["rate"] >= t0["rate"]:
        return {"level": None, "drop": 0.0}
    v = worst.get("vs_t0")
    if v and v["n_pairs"] and not v.get("insufficient") and not math.isnan(v["ci"][0]):
        return {
            "level": worst["level"],
            "drop": -v["delta"],
            "ci": (-v["ci"][1], -v["ci"][0]),
            "paired": True,
        }
    lo, hi = difference_ci(*((r["rate"], r["ci_low"], r["ci_high"]) for r in (t0, worst)))
    return {"level": worst["level"], "drop": t0["rate"] - worst["rate"], "ci": (lo, hi), "paired": False}


def _cell(row: dict | None, bold: bool) -> str:
    if row is None:
        return "–"
    if row["n"] == 0 or row.get("insufficient", False):
        return f"insufficient (n={row['n']})"
    text = f"{100 * row['rate']:.0f}% [{100 * row['ci_low']:.0f}, {100 * row['ci_high']:.0f}] n={row['n']}"
    return f"**{text}**" if bold else text


def _drop_text(d: dict | None) -> str:
    if d is None:
        return "— (no usable T0 or no other level)"
    if d["level"] is None:
        return "none: no level below T0"
    lo, hi = d["ci"]
    how = "paired" if d["paired"] else "unpaired"
    return f"{100 * d['drop']:.0f} pp at {signed_level(d['level'], minus='−')} [{100 * lo:.0f}, {100 * hi:.0f}] {how}"


def overview_lines(summaries: Sequence[tuple[str, dict]], order: Sequence[str] | None = None) -> list[str]:
    """The paper's Table 2 as markdown: one row per axis (and run), one column per level, the largest drop from T0
    in bold and in its own column; [] for a single axis, whose own table shows the same."""
    axes = list(order) if order else axis_order(summaries)
    if len(axes) < 2:
        return []
    levels = sorted({r["level"] for _, s in summaries for a in s["axes"].values() for r in a["levels"]})
    several = len(summaries) > 1
    tasks = {tuple(a.get("pooled_tasks") or ()) for _, s in summaries for a in s["axes"].values()}
    only = next(iter(tasks)) if len(tasks) == 1 else ()
    pooled = (
        f"Every row: {pooled_text(only)}."
        if only
        else "Each row pools the tasks its axis's section below names."
    )
    header = ["axis", *(["run"] if several else []), *(f"{signed_level(k, minus='−')}{' (T0)' * (k == 0)}" for k in levels),
              "largest drop from T0 (pp, 95 % CI)"]  # fmt: skip
    lines = ["## Overview: success per axis and level (the paper's Table 2)", "",
             f"Each cell: success % [{ci_name(summaries[0][1].get('ci', 'wilson'))} 95 % CI] n = finished episodes; – = level "
             "not evaluated on that axis. Bold: the level with the largest drop from T0; its interval is paired over the "
             "episodes the two levels share (seeds; Newcombe) where the run pairs them, else unpaired (MOVER from the "
             f"two levels' CIs). {pooled}", "",
             "| " + " | ".join(header) + " |", "|---" * len(header) + "|"]  # fmt: skip
    for axis in axes:
        for label, s in summaries:
            a = s["axes"].get(axis)
            if a is None:
                continue
            drop = largest_drop(a["levels"])
            worst = drop["level"] if drop else None
            by_level = {r["level"]: r for r in a["levels"]}
            cells = [_cell(by_level.get(k), k == worst) for k in levels]
            lines.append("| " + " | ".join([f"`{axis}`", *([label] if several else []), *cells, _drop_text(drop)])
                         + " |")  # fmt: skip
    return [*lines, ""]


def contact_sheet(
    rows: Sequence[tuple[str, Sequence[tuple[Any, str]]]], title: str, tile_inches: float = 1.9
):
    """A labelled grid of images (the paper's Fig. 5): one row per name, e.g. an axis, one tile per (image, caption),
    e.g. a level's initial observation; each row's name along its first tile."""
    import textwrap

    from matplotlib.figure import Figure

    ncols = max(len(tiles) for _, tiles in rows)
    side = max(max(img.shape[:2]) for _, tiles in rows for img, _ in tiles)
    lines = max(caption.count("\n") + 1 for _, tiles in rows for _, caption in tiles)
    width = max(tile_inches * ncols + 0.4, 3.0)
    wrap = int(width * 13)  # about 13 characters per inch at 8 pt
    title = "\n".join(textwrap.fill(t, width=wrap) for t in title.splitlines())
    height = (tile_inches + 0.15 + 0.2 * lines) * len(rows) + 0.2 + 0.15 * (title.count("\n") + 1)
    fig = Figure(figsize=(width, height), dpi=max(100, round(side / tile_inches)), layout="constrained")
    grid = fig.subplots(len(rows), ncols, squeeze=False)
    for r, (name, tiles) in enumerate(rows):
        for c, ax in enumerate(grid[r]):
            if c >= len(tiles):
                ax.set_visible(False)
                continue
            img, caption = tiles[c]
            ax.imshow(img)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_xlabel(caption, fontsize=7)
            if c == 0 and len(rows) > 1:
                ax.set_ylabel(name, fontsize=8)
    fig.suptitle(title, fontsize=8)
    return fig
