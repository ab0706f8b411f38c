"""2-D grids from held axes (``A@B=j``): success over (level k of A) × (held level j of B), a table and a heatmap."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.axis_ref import AxisRef
from indgen_vla.core.runs.records import atomic_savefig
from indgen_vla.core.stats.metrics import is_usable, pooled_text


@dataclass(frozen=True)
class Grid:
    """One run's rows of the grid A × B: per held level j the summary of the axis that ran that ladder (``names``):
    ``A@B=j``, or A itself as row 0 where the run has A but not ``A@B=0`` (the same environments)."""

    inner: str
    held: str
    rows: Mapping[int, dict]
    names: Mapping[int, str]

    @property
    def levels(self) -> list[int]:
        """The levels k of A evaluated in any row, ascending."""
        return sorted({r["level"] for a in self.rows.values() for r in a["levels"]})

    @property
    def tasks(self) -> list[str]:
        """Every task any row pools, sorted (the table's and the heatmap's "pooled over")."""
        return sorted({t for a in self.rows.values() for t in a.get("pooled_tasks") or []})


def find_grids(axes: Mapping[str, dict]) -> list[Grid]:
    """The grids in one summary's ``axes``: per (A, B) every held axis ``A@B=j`` (and A as row 0 when ``A@B=0`` is
    absent), kept where there are two or more rows; ordered by (A, B), rows by j."""
    found: dict[tuple[str, str], dict[int, str]] = {}
    for name in axes:
        try:
            ref = AxisRef.parse(name)
        except ConfigError:  # an '@' name that is no held axis: no grid
            continue
        if ref.held is not None:
            found.setdefault((ref.ladder.name, ref.held), {})[ref.held_level] = name
    grids = []
    for (inner, b), names in sorted(found.items()):
        if 0 not in names and inner in axes:
            names[0] = inner
        if len(names) >= 2:
            names = dict(sorted(names.items()))
            grids.append(Grid(inner, b, {j: axes[n] for j, n in names.items()}, names))
    return grids


def grid_matrix(grid: Grid) -> tuple[list[int], list[int], np.ndarray, np.ndarray]:
    """(held levels j, levels k, rate[j, k], n[j, k]): rate NaN where the level was not run or is below the data
    floor, n 0 where it was not run."""
    js, ks = list(grid.rows), grid.levels
    rate = np.full((len(js), len(ks)), np.nan)
    n = np.zeros((len(js), len(ks)), dtype=int)
    for i, j in enumerate(js):
        by_level = {r["level"]: r for r in grid.rows[j]["levels"]}
        for c, k in enumerate(ks):
            row = by_level.get(k)
            n[i, c] = row["n"] if row else 0
            if is_usable(row):
                rate[i, c] = row["rate"]
    return js, ks, rate, n


def cell_text(rate: float, n: int, ci: tuple[float, float] | None = None) -> str:
    """A heatmap cell's annotation: "57%" over its 95 % CI "[40, 72]" (when given) over "n=14"; "insufficient" over
    n below the data floor; "–" not run."""
    if n == 0:
        return "–"
    if np.isnan(rate):
        return f"insufficient\nn={n}"
    interval = f"\n[{100 * ci[0]:.0f}, {100 * ci[1]:.0f}]" if ci else ""
    return f"{100 * rate:.0f}%{interval}\nn={n}"


def _signed(k: int) -> str:
    return f"−{-k}" if k < 0 else str(k)


def grid_lines(
    summaries: Sequence[tuple[str, dict]],
    fmt_rate: Callable[[dict], str],
    fmt_break: Callable[[dict, bool], str],
) -> list[str]:
    """A markdown section per grid of each run: one row per held level j, one column per level k of A, each cell
    ``fmt_rate`` of that level (the report's rate, CI and n, or its "insufficient data"), and each row's k*
    (``fmt_break``); [] when no run holds a grid."""
    lines: list[str] = []
    several = len(summaries) > 1
    for label, s in summaries:
        for g in find_grids(s["axes"]):
            tasks = g.tasks
            own = f"; row 0 is `{g.inner}` itself, the same environments" if g.names.get(0) == g.inner else ""
            first, last = g.names[min(g.names)], g.names[max(g.names)]
            lines += [
                f"## Grid `{g.inner}` × `{g.held}`" + (f" — {label}" if several else ""), "",
                f"Success per level k of `{g.inner}` (columns) with `{g.held}` held at level j (rows: axis "
                f"`{g.inner}@{g.held}=j`{own}). Cells as in the axis tables, each row its own ladder; "
                f"{pooled_text(tasks)}. k*: the row's first level below "
                f"γ = {s['gamma']}. No test between rows here: `indgen compare RUN --axes {last}:{first}` pairs two "
                "rows episode by episode (same seeds).", "",
                f"| {g.held} j \\ {g.inner} k | " + " | ".join(_signed(k) for k in g.levels) + " | k\\* |",
                "|---" * (len(g.levels) + 2) + "|",
            ]  # fmt: skip
            for j, a in g.rows.items():
                by_level = {r["level"]: r for r in a["levels"]}
                cells = [fmt_rate(by_level[k]) if k in by_level else "–" for k in g.levels]
                lines.append(
                    f"| {_signed(j)} | "
                    + " | ".join(cells)
                    + f" | {fmt_break(a['break_level'], a['signed'])} |"
                )
            lines.append("")
    return lines


def grid_plot_name(grid: Grid) -> str:
    """The heatmap's file name in plots/: ``grid_<A>_<B>.png`` (characters other than letters, digits, '-', '_' as
    '_')."""
    text = f"grid_{grid.inner}_{grid.held}"
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in text) + ".png"


def grid_figure(panels: Sequence[tuple[str, Grid]], gamma: float):
    """A heatmap per run of one grid A × B, side by side: rate by colour, each cell annotated with its rate and n
    ("insufficient" below the data floor, grey; "–" not run), each row's k* outlined."""
    from matplotlib.figure import Figure

    g0 = panels[0][1]
    ncols = len(panels)
    width = max(3.6, 0.75 * len(g0.levels) + 1.4)
    fig = Figure(figsize=(width * ncols + 0.8, 0.55 * len(g0.rows) + 1.9), dpi=130, layout="constrained")
    axs = fig.subplots(1, ncols, squeeze=False)[0]
    image = None
    for ax, (label, g) in zip(axs, panels, strict=True):
        js, ks, rate, n = grid_matrix(g)
        cmap = _cmap()
        image = ax.imshow(
            np.ma.masked_invalid(rate), cmap=cmap, vmin=0.0, vmax=1.0, aspect="auto", origin="lower"
        )
        for i, j in enumerate(js):
            kstar = set((g.rows[j].get("break_level") or {}).values())
            by_level = {r["level"]: r for r in g.rows[j]["levels"]}
            for c, k in enumerate(ks):
                row = by_level.get(k) or {}
                ci = (row["ci_low"], row["ci_high"]) if row.get("ci_low") is not None else None
                text = cell_text(rate[i, c], int(n[i, c]), ci)
                dark = not np.isnan(rate[i, c]) and not 0.25 < rate[i, c] < 0.8
                ax.text(
                    c, i, text, ha="center", va="center", fontsize=6.5, color="white" if dark else "black"
                )
                if k in kstar:
                    ax.add_patch(_outline(c, i))
        ax.set_xticks(range(len(ks)), [_signed(k) for k in ks], fontsize=7)
        ax.set_yticks(range(len(js)), [_signed(j) for j in js], fontsize=7)
        ax.set_xlabel(f"level k of {g.inner}", fontsize=8)
        ax.set_ylabel(f"{g.held} held at level j", fontsize=8)
        ax.set_title(f"{label}\n{pooled_text(g.tasks)}; cells: rate, 95 % CI, n", fontsize=8)
    cbar = fig.colorbar(image, ax=list(axs), shrink=0.9)
    cbar.set_label("success rate", fontsize=8)
    cbar.ax.axhline(gamma, color="black", lw=1, ls="--")
    cbar.ax.tick_params(labelsize=7)
    fig.suptitle(f"{g0.inner} × {g0.held}: success rate\noutlined: k*, the row's first level below γ = {gamma}",
                 fontsize=8)  # fmt: skip
    return fig


def _cmap():
    """Red (0) to green (1), grey where a cell has no rate."""
    from matplotlib import colormaps

    return colormaps["RdYlGn"].with_extremes(bad="lightgrey")


def _outline(c: int, i: int):
    from matplotlib.patches import Rectangle

    return Rectangle((c - 0.5, i - 0.5), 1, 1, fill=False, ec="black", lw=1.6)


def plot_grids(summaries: Sequence[tuple[str, dict]], gamma: float, plots: Path) -> list[Path]:
    """Write one heatmap per grid A × B the runs hold (``grid_figure``, a panel per run) into ``plots``."""
    by_pair: dict[tuple[str, str], list[tuple[str, Grid]]] = {}
    for label, s in summaries:
        for g in find_grids(s["axes"]):
            by_pair.setdefault((g.inner, g.held), []).append((label, g))
    paths = []
    for panels in by_pair.values():
        path = plots / grid_plot_name(panels[0][1])
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_savefig(grid_figure(panels, gamma), path)
        paths.append(path)
    return paths
