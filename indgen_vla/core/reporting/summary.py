"""The numbers of summary.json (rates, k*, trends, break point, verdicts), apart from how report prints them."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from indgen_vla.core.protocol.training_support import cells_from_json, trained_levels
from indgen_vla.core.reporting.certification_view import basis_entry, certification_entry, infeasible_entry
from indgen_vla.core.reporting.levels import (
    axis_verdicts,
    by_task,
    condition2_validation,
    decide,
    design_text,
    episodes_used,
    kstar_status_of,
    level_rows,
    pool_ladders,
    run_regime,
    sequential,
    task_entry,
    usable_rates,
)
from indgen_vla.core.stats.breakpoint import break_point, cells_from_frame
from indgen_vla.core.stats.contrasts import add_vs_t0
from indgen_vla.core.stats.metrics import (
    DEFAULT_GAMMA,
    MIN_N,
    break_levels,
    cochran_armitage,
    monotone_decreasing_test,
    usable_levels,
)


def _axis_signed(manifest: dict[str, Any], axis: str, levels: Sequence[int]) -> bool:
    info = manifest.get("axes", {}).get(axis, {})
    return bool(info["signed"]) if "signed" in info else any(k < 0 for k in levels)


def summarize(episodes, manifest: dict[str, Any], gamma: float = DEFAULT_GAMMA, ci: str = "wilson",
              margin: float | None = None) -> dict:  # fmt: skip
    """The summary.json dict: per axis, per level n/successes/rate/CI (pooled over tasks and per task), break
    levels, the linear (Cochran–Armitage) and monotone (isotonic LRT) trend tests, and each level's paired change
    from level 0 (``vs_t0``; with ``margin``, its equivalence test).

    Rows with status "error" are excluded from n and counted in ``errors``; levels planned in the manifest
    but not yet run appear with n = 0; a level below the floor is marked ``insufficient`` and k* treats it as
    missing (``"undetermined"`` when it comes before the break).
    """
    plan = manifest.get("plan") or {}
    per_task = plan.get("episodes") if isinstance(plan.get("episodes"), int) else None
    plan_levels = plan.get("levels") if isinstance(plan.get("levels"), dict) else {}
    out: dict[str, Any] = {"gamma": gamma, "ci": ci, "min_n": MIN_N, "axes": {}}
    # the policy's declaration (PolicySpec.reads_observations); None: unknown (a run made before it was recorded)
    out["reads_observations"] = manifest.get("reads_observations")
    if manifest.get("measurement"):  # --smoke: the report says so before any rate (caveats.report_caveats)
        out["measurement"] = manifest["measurement"]
    if manifest.get("placeholder_assets"):  # simulated on placeholder assets: said first, too
        out["placeholder_assets"] = True
    # the levels the policy's training data covered, when it declared them (manifest training_levels)
    training = cells_from_json(manifest.get("training_levels"))
    seen = set(episodes["axis"].unique()) if len(episodes) else set()
    for axis in sorted(seen | set(plan_levels)):
        df = episodes[episodes["axis"] == axis]
        tasks = sorted(set(plan.get("tasks") or []) | set(df["task"].unique()))
        levels = sorted({int(k) for k in df["level"].unique()} | {int(k) for k in plan_levels.get(axis, [])})
        signed = _axis_signed(manifest, axis, levels)
        adaptive = plan.get("adaptive") if per_task else None
        frames, counts = by_task(df)
        task_entries = {t: task_entry(frames.get(t, df.iloc[:0]), levels, per_task, ci, gamma, signed, adaptive,
                                      counts.get(t, {}))
                        for t in tasks}  # fmt: skip
        pooled = level_rows(df, levels, per_task * len(tasks) if per_task else None, ci)
        decide(pooled, gamma)
        if adaptive and len(tasks) == 1:
            sequential(pooled, df, adaptive, per_task)
        elif adaptive:  # each task's ladder was decided on its own; pool what they ran
            pool_ladders(pooled, task_entries)
            decide(pooled, gamma)
        out["axes"][axis] = {
            "signed": signed,
            "pooled_tasks": tasks,
            "levels": pooled,
            "break_level": break_levels(usable_rates(pooled), gamma, signed=signed),
            "trend": _trend(pooled, signed),
            "monotone": _monotone(pooled, signed),
            "regime": run_regime(manifest),
            "kstar_status": kstar_status_of(pooled, signed),
            "break_point": _break_point(df, gamma, multi_task=len(tasks) > 1, levels=pooled),
            "episodes": episodes_used(df, per_task, len(tasks), len(levels)),
            "tasks": task_entries,
        }
        a = out["axes"][axis]
        a["certification"] = certification_entry(manifest, axis)  # per task: certified / uncertified / failed
        a["certification_basis"] = basis_entry(
            manifest, axis
        )  # per task: held-out / in-sample (tuned) levels
        a["infeasible"] = infeasible_entry(
            df
        )  # per task and level: episodes whose initial state cannot hold it
        if design := design_text(adaptive, per_task):
            a["design"] = design
        a["condition2"] = condition2_validation(a["monotone"], a["regime"])  # None: vanilla (by construction)
        a["verdict"] = axis_verdicts(pooled, a["break_level"], gamma, signed, ci, a["kstar_status"])
        for e in task_entries.values():
            e["verdict"] = axis_verdicts(e["levels"], e["break_level"], gamma, signed, ci, e["kstar_status"])
        add_vs_t0(a, df, margin)
        if training:
            task_levels = {t: e["levels"] for t, e in task_entries.items()}
            a["trained"] = trained_levels(training, manifest.get("scene", ""), axis, task_levels)
    return out


def _break_point(df, gamma: float, multi_task: bool, levels: list[dict]) -> dict:
    """The continuous break point per direction with a bootstrap CI (over tasks, then episodes, when pooled), from
    the levels above the data floor only (``levels``: the axis's pooled rows), like every other printed result."""
    ok = df[(df["status"] == "ok") & df["level"].isin(usable_levels(levels))]
    if ok["level"].nunique() < 2:
        return {}
    keys = ("task",) if multi_task else ()
    cells = cells_from_frame(ok[["level", "param", "success", "status", "task"]], keys)
    return break_point(cells, gamma, cluster_names=keys)


def _directions(levels: list[dict], signed: bool):
    """(name, usable rows in increasing |k|) per direction; levels below the data floor are left out."""
    sides = (("pos", lambda k: k >= 0), ("neg", lambda k: k <= 0)) if signed else (("pos", lambda k: True),)
    for name, keep in sides:
        rows = sorted(
            (r for r in levels if keep(r["level"]) and not r["insufficient"]), key=lambda r: abs(r["level"])
        )
        if len(rows) >= 2:
            yield name, rows


def _trend(levels: list[dict], signed: bool) -> dict:
    """One-sided Cochran–Armitage test per direction: the post-hoc ordering check of appendix B (linear)."""
    res = {}
    for name, rows in _directions(levels, signed):
        t = cochran_armitage(
            [abs(r["level"]) for r in rows], [r["successes"] for r in rows], [r["n"] for r in rows]
        )
        res[name] = {"z": t.statistic, "p_decreasing": t.p_decreasing}
    return res


def _monotone(levels: list[dict], signed: bool) -> dict:
    """Isotonic likelihood-ratio test per direction (any monotone decrease, not only a linear one)."""
    res = {}
    for name, rows in _directions(levels, signed):
        t = monotone_decreasing_test([r["successes"] for r in rows], [r["n"] for r in rows])
        res[name] = {"lrt": t.statistic, "p_decreasing": t.p_decreasing, "method": t.method,
                     "levels": [r["level"] for r in rows]}  # fmt: skip
    return res
