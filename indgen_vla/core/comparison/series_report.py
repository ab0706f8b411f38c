"""A checkpoint series' numbers, words and plots from its run directories (``indgen series``): success per level and
k* per direction against the training step, a trend test over the steps, paired tests between checkpoints.

Every checkpoint runs the same plan (same seeds), so two checkpoints are paired episode by episode and compared with
``indgen compare``'s tests (``compare.compare_summaries``: exact McNemar, Holm over the levels of an axis). The trend
over the steps is Cochran–Armitage on the success counts with the step as score per level, a rise and a fall each
(one-sided), Holm-corrected over the 2 × levels tests of an axis: without it, a null series of 7 levels flagged at
least one trend 53 % of the time (docs/statistics.md). The levels ≠ 0 pooled ("OOD success") get no trend test: a
checkpoint's effect is shared by all its levels, so the pooled episodes are not independent, and with one training
run there is no replicate to take it from (the pooled test erred 14 % at a nominal 5 %). Kendall's τ between step and
k* per direction is a separate claim per direction.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from indgen_vla.core.comparison.two_runs import compare_summaries
from indgen_vla.core.reporting.caveats import rate_text
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.runs.records import RunDir, atomic_savefig, write_result
from indgen_vla.core.stats.metrics import (
    UNDETERMINED,
    cochran_armitage,
    holm,
    is_usable,
    pooled_text,
    success_rate,
    usable_rows,
)

ALPHA = 0.05
OOD_NO_TEST = ("no trend test: a checkpoint's effect is shared by its levels, and one training run gives no "
                "replicate of it (several training seeds would)")  # fmt: skip


def _kstar_value(k, levels: Sequence[int], side: str) -> float | None:
    """k* as a number for the trend: "none in range" is one step past the last level run (censored), undetermined
    is missing."""
    if k == UNDETERMINED:
        return None
    if k is None:
        return (max(levels) + 1) if side == "pos" else (min(levels) - 1)
    return float(k)


def kendall(x: Sequence[float], y: Sequence[float]) -> dict | None:
    """Kendall's τ-b of y against x with its two-sided p (scipy), None with fewer than 3 points or no spread."""
    if len(x) < 3 or len(set(y)) < 2:
        return None
    from scipy.stats import kendalltau

    r = kendalltau(x, y)
    return {"tau": float(r.statistic), "p_two_sided": float(r.pvalue), "n": len(x)}


def _trend(steps: list[int], rows: list[dict]) -> dict | None:
    """Cochran–Armitage over the checkpoints (score: step) of one level's (successes, n); p for a rise and a fall."""
    keep = [(s, r) for s, r in zip(steps, rows, strict=True) if r and r["n"]]
    if len(keep) < 2:
        return None
    t = cochran_armitage([s for s, _ in keep], [r["successes"] for _, r in keep], [r["n"] for _, r in keep])
    return {
        "z": t.statistic,
        "p_rising": 1 - t.p_decreasing,
        "p_falling": t.p_decreasing,
        "p_two_sided": t.p_two_sided,
    }


def build_series(entries: Sequence[tuple[int, Path]], gamma: float = 0.2) -> dict[str, Any]:
    """series.json: per axis, per level each checkpoint's rate with its Wilson CI, k* per direction, the trends and
    the paired comparisons of consecutive checkpoints. ``entries``: (step, run directory) in step order."""
    runs = [(step, RunDir.open(path)) for step, path in entries]
    frames = {step: run.episodes() for step, run in runs}
    sums = {step: summarize(frames[step], run.manifest, gamma) for step, run in runs}
    steps = [s for s, _ in runs]
    out: dict[str, Any] = {
        "gamma": gamma,
        "steps": steps,
        "runs": {str(s): str(p) for s, p in entries},
        "axes": {},
    }
    for axis in sorted({a for s in sums.values() for a in s["axes"]}):
        per = {s: sums[s]["axes"].get(axis) for s in steps}
        levels = sorted({r["level"] for a in per.values() if a for r in a["levels"]})
        tasks = sorted({t for a in per.values() if a for t in a.get("pooled_tasks") or []})
        ax: dict[str, Any] = {"tasks": pooled_text(tasks), "levels": {}, "kstar": {}, "trend": {}}
        for k in levels:
            found = [
                next((r for r in per[s]["levels"] if r["level"] == k), None) if per[s] else None
                for s in steps
            ]
            rows = [r if r is not None and is_usable(r) else None for r in found]
            ax["levels"][str(k)] = [_point(s, f, r) for s, f, r in zip(steps, found, rows, strict=True)]
            ax["trend"][str(k)] = _trend(steps, rows)
        ood = []
        for s in steps:
            rows = [r for r in usable_rows(per[s]["levels"]) if r["level"] != 0] if per[s] else []
            ood.append({"successes": sum(r["successes"] for r in rows), "n": sum(r["n"] for r in rows)})
        ax["ood"] = [{"step": s, **o, **_rate(o)} for s, o in zip(steps, ood, strict=True)]
        ax["trend"]["ood"] = None
        ax["ood_trend"] = OOD_NO_TEST
        _holm_trends(ax["trend"], [str(k) for k in levels])
        sides = ["pos", "neg"] if any(k < 0 for k in levels) else ["pos"]
        for side in sides:
            ks = [(s, per[s]["break_level"].get(side) if per[s] else UNDETERMINED) for s in steps]
            ax["kstar"][side] = [{"step": s, "k": k, "break_point": _bp(per[s], side)} for s, k in ks]
            vals = [(s, _kstar_value(k, levels, side)) for s, k in ks]
            vals = [(s, v) for s, v in vals if v is not None]
            ax["trend"][f"kstar_{side}"] = kendall([s for s, _ in vals], [v for _, v in vals])
        out["axes"][axis] = ax
    out["pairs"] = _pairs(steps, sums, frames, gamma)
    return out


def _holm_trends(trend: dict, keys: list[str]) -> None:
    """Holm over every one-sided trend test of an axis's table (a rise and a fall per level): ``p_rising_holm``,
    ``p_falling_holm``."""
    tests = [(k, side) for k in keys if trend.get(k) for side in ("p_rising", "p_falling")]
    for (k, side), p in zip(tests, holm([trend[k][side] for k, side in tests]), strict=True):
        trend[k][f"{side}_holm"] = p
    for k in keys:
        if trend.get(k):
            trend[k]["holm_over"] = len(tests)


def _point(step: int, found: dict | None, usable: dict | None) -> dict:
    """One checkpoint's point of a level: its rate and CI when above the data floor, else its count only."""
    if usable is not None:
        r = usable
        return {
            "step": step,
            "successes": r["successes"],
            "n": r["n"],
            "rate": r["rate"],
            "ci": [r["ci_low"], r["ci_high"]],
        }
    n = found["n"] if found else 0
    return {"step": step, "successes": found["successes"] if found else 0, "n": n, "insufficient": True}


def _rate(c: dict) -> dict:
    if not c["n"]:
        return {"rate": math.nan, "ci": [math.nan, math.nan]}
    r = success_rate(c["successes"], c["n"])
    return {"rate": r.rate, "ci": [r.ci_low, r.ci_high]}


def _bp(axis: dict | None, side: str) -> dict | None:
    """The continuous break point of one direction with its bootstrap CI (summary ``break_point``), if any."""
    b = (axis or {}).get("break_point", {}).get(side)
    if not b or b.get("level") is None:
        return None
    return {"level": b["level"], "ci": b.get("ci", {}).get("level")}


def _pairs(steps: list[int], sums: dict, frames: dict, gamma: float) -> list[dict]:
    """Consecutive checkpoints compared level by level (paired exact McNemar when seeds and plan match)."""
    out = []
    for a, b in zip(steps, steps[1:], strict=False):
        res = compare_summaries(sums[a], sums[b], "auto", gamma, episodes=(frames[a], frames[b]))
        levels = {axis: [{k: r[k] for k in ("level", "n_a", "successes_a", "n_b", "successes_b", "p_value", "p_holm")}
                         for r in ax["levels"]] for axis, ax in res["axes"].items()}  # fmt: skip
        out.append({"from": a, "to": b, "paired": res["paired"], "test": res["test"], "axes": levels})
    return out


def _cell(c: dict) -> str:
    if c.get("insufficient"):
        return f"insufficient data (n = {c['n']})" if c["n"] else "—"
    return rate_text(c["successes"], c["n"])


def _k(k) -> str:
    if k is None:
        return "none in range"
    return str(k) if k == UNDETERMINED or k == 0 else f"{k:+d}".replace("-", "−")


def _p(t: dict | None, key: str) -> str:
    return "—" if not t else f"{t[key]:.3g}"


def render_markdown(series: dict, title: str = "Checkpoint series") -> str:
    """series.md: per axis the success table (checkpoints × levels), k* per step, the trends, then the paired tests."""
    steps = series["steps"]
    lines = [f"# {title}", "", f"{len(steps)} checkpoint(s), steps {', '.join(map(str, steps))}; every checkpoint runs "
             "the same plan (same seeds), so checkpoints are paired episode by episode.", "",
             "Rates: successes/n = rate [Wilson 95 % CI]. Trend: Cochran–Armitage over the checkpoints with the step "
             "as score, one-sided p for a rise and for a fall, Holm-corrected over every test of the axis's table "
             "(a trend is shown at α = 0.05 only where its Holm p is below 0.05); no trend test of the pooled OOD "
             "success (one training run: its checkpoint effect is shared by the levels). k*: Kendall's τ of k* "
             "against the step (\"none in range\" counts as one level past the last run), one claim per direction. "
             "Both treat checkpoints as independent samples: a checkpoint effect shared by the levels makes them "
             "err more (the table's 5 % becomes 11.2 % at a logit sd of 0.2, 7 levels, 5 checkpoints: "
             "docs/statistics.md).", ""]  # fmt: skip
    for axis, ax in series["axes"].items():
        levels = list(ax["levels"])
        lines += [f"## Axis `{axis}` ({ax['tasks']})", "", "| step | " + " | ".join(f"L{k}" for k in levels)
                  + " | OOD (levels ≠ 0) |", "|---|" + "---|" * (len(levels) + 1)]  # fmt: skip
        for i, s in enumerate(steps):
            cells = [
                rate_text(c["successes"], c["n"]) if c["n"] else "—"
                for c in (ax["levels"][k][i] for k in levels)
            ]
            o = ax["ood"][i]
            lines.append(
                f"| {s} | "
                + " | ".join(cells)
                + f" | {rate_text(o['successes'], o['n']) if o['n'] else '—'} |"
            )
        tr = ax["trend"]
        holm_n = next((t["holm_over"] for t in tr.values() if t and "holm_over" in t), 0)
        lines += ["", "| trend over steps | z | p (rise) | p (fall) | Holm p (rise) | Holm p (fall) |",
                  "|---|---|---|---|---|---|"]  # fmt: skip
        for key in levels:
            t = tr.get(key)
            lines.append(f"| L{key} | {'—' if not t else f'{t["z"]:+.2f}'} | {_p(t, 'p_rising')} | "
                         f"{_p(t, 'p_falling')} | {_p(t, 'p_rising_holm')} | {_p(t, 'p_falling_holm')} |")  # fmt: skip
        lines.append(f"| OOD success | {ax.get('ood_trend', OOD_NO_TEST)} | | | | |")
        lines.append(f"\nHolm over the {holm_n} one-sided tests above (a rise and a fall per level).")
        for side, ks in ax["kstar"].items():
            t = tr.get(f"kstar_{side}")
            trend = (
                f"Kendall τ = {t['tau']:+.2f}, p = {t['p_two_sided']:.3g} (n = {t['n']})"
                if t
                else "no trend test (fewer than 3 checkpoints or no change)"
            )
            lines += ["", f"k* ({'+' if side == 'pos' else '−'} side) by step: "
                      + ", ".join(f"{x['step']}: {_k(x['k'])}" for x in ks) + f"; {trend}."]  # fmt: skip
        lines.append("")
    if series["pairs"]:
        lines += ["## Consecutive checkpoints", "", "Exact McNemar on the episode pairs (unpaired: Boschloo), Holm over the "
                  "levels of each axis; a level listed differs at α = 0.05.", ""]  # fmt: skip
        for p in series["pairs"]:
            kind = "paired" if p["paired"] else "unpaired"
            for axis, rows in p["axes"].items():
                sig = [r for r in rows if not math.isnan(r["p_holm"]) and r["p_holm"] < ALPHA]
                what = ", ".join(f"L{r['level']} ({rate_text(r['successes_a'], r['n_a'])} → "
                                 f"{rate_text(r['successes_b'], r['n_b'])}, Holm p = {r['p_holm']:.3g})" for r in sig)  # fmt: skip
                lines.append(f"- step {p['from']} → {p['to']} ({kind}), `{axis}`: "
                             + (what if sig else "no level differs (this does not show they are equal)"))  # fmt: skip
    return "\n".join(lines) + "\n"


def plot_series(series: dict, out: Path) -> list[Path]:
    """plots/<axis>_success.png and plots/<axis>_kstar.png (``series_figures``)."""
    written = []
    for name, fig in series_figures(series):
        path = out / "plots" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_savefig(fig, path)
        written.append(path)
    return written


def series_figures(series: dict) -> list[tuple[str, Any]]:
    """Per axis, ``<axis>_success.png`` (success per level against step, Wilson 95 % bands, the episodes behind each
    point) and ``<axis>_kstar.png`` (k* per direction against step, with the continuous break point's bootstrap CI
    where there is one); legends beside the panel, never over a curve."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    figures = []
    for axis, ax in series["axes"].items():
        fig = Figure(figsize=(7.2, 4.0), layout="constrained")
        a = fig.add_subplot()
        ns = []
        for k, pts in ax["levels"].items():
            pts = [p for p in pts if not p.get("insufficient")]
            xs = [p["step"] for p in pts]
            if not xs:
                continue
            ns += [p["n"] for p in pts]
            ys = [p["rate"] for p in pts]
            line = a.plot(xs, ys, marker="o", label=f"L{k}")[0]
            a.fill_between(xs, [p["ci"][0] for p in pts], [p["ci"][1] for p in pts],
                           alpha=0.15, color=line.get_color())  # fmt: skip
        a.axhline(series["gamma"], ls="--", color="grey", lw=0.8, label="γ")
        n = "" if not ns else f"n = {min(ns)}" if min(ns) == max(ns) else f"n = {min(ns)}–{max(ns)}"
        a.set(xlabel="training step", ylabel="success rate", ylim=(-0.02, 1.02),
              title=f"{axis}: success per level vs step\n{n} per point; Wilson 95 % CI; {ax['tasks']}")  # fmt: skip
        a.title.set_fontsize(8)
        fig.legend(fontsize=7, loc="outside right upper")
        figures.append((f"{axis}_success.png", fig))
        fig = Figure(figsize=(7.2, 4.0), layout="constrained")
        a = fig.add_subplot()
        levels = [int(k) for k in ax["levels"]]
        for side, ks in ax["kstar"].items():
            sign = "+" if side == "pos" else "−"
            pts = [(x["step"], _kstar_value(x["k"], levels, side), x["break_point"]) for x in ks]
            pts = [p for p in pts if p[1] is not None]
            if pts:
                line = a.step([p[0] for p in pts], [p[1] for p in pts], where="post", marker="s",
                              label=f"k* ({sign})")[0]  # fmt: skip
            bps = [(s, b) for s, _, b in pts if b and b["ci"] and None not in b["ci"]]
            if pts and bps:
                a.errorbar([s for s, _ in bps], [b["level"] for _, b in bps],
                           yerr=[[b["level"] - b["ci"][0] for _, b in bps], [b["ci"][1] - b["level"] for _, b in bps]],
                           fmt="o", ms=3, color=line.get_color(), alpha=0.6,
                           label=f"break point ({sign}),\n95 % bootstrap CI")  # fmt: skip
        a.yaxis.set_major_locator(MaxNLocator(integer=True))
        a.margins(x=0.05, y=0.1)
        a.set(xlabel="training step", ylabel="level",
              title=f"{axis}: k* per direction vs step (none in range: drawn one level past the last)")  # fmt: skip
        a.title.set_fontsize(8)
        if a.get_legend_handles_labels()[0]:
            fig.legend(fontsize=7, loc="outside right upper")
        figures.append((f"{axis}_kstar.png", fig))
    return figures


def write_series(
    entries: Sequence[tuple[int, Path]], out: Path, gamma: float = 0.2, extra: dict | None = None
) -> dict:
    """series.json, series.md and the plots for the finished checkpoints ``entries``; returns series.json."""
    series = build_series(entries, gamma)
    series.update(extra or {})
    series["plots"] = [str(p) for p in plot_series(series, out)]
    write_result(out, "series", series, render_markdown(series))
    return series
