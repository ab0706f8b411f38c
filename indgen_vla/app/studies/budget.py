"""``indgen budget``: size a protocol before it runs. It takes the protocol exactly as ``evaluate`` does (flags or
--config), resolves its plan (no scene is built) and answers: episodes per level for the fixed design and the power
to see a drop from T0; the expected and 95th-percentile episodes of the adaptive rule under an assumed or piloted
success curve; the whole command's wall time and GPU-hours per worker count from a smoke run's clocks; and, with
--write, a plan.lock that ``evaluate --preregistered`` enforces (docs/budget.md)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from indgen_vla.app.config_fields import from_args
from indgen_vla.app.engine.config import config_from_args
from indgen_vla.app.engine.preregister import check_preregistered, manifest_plan, pre_policy_fingerprint
from indgen_vla.app.engine.run import build_plan, package_versions
from indgen_vla.app.studies.config import DEFAULT_STARTUP_S, BudgetConfig, budget_workers
from indgen_vla.app.studies.wall_time import HELDOUT, Costs, from_timing, project
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.plan_lock import make_lock
from indgen_vla.core.runs.records import RunDir, atomic_write_json
from indgen_vla.core.stats.adaptive_cost import Curve, assumed_curve, simulate_protocol
from indgen_vla.core.stats.contrasts import ALPHA
from indgen_vla.core.stats.metrics import wilson_ci
from indgen_vla.core.stats.sample_size import (
    decided_rates,
    fixed_design,
    paired_power,
    pairs_for_power,
    stable_episodes,
)
from indgen_vla.core.stats.sprt import make_rule
from scenes.family import Scene

POWER = 0.8  # the power the pairs are sized for


def config_from_budget_args(args: argparse.Namespace) -> BudgetConfig:
    """The budget's config from its parsed flags: the protocol resolved as evaluate resolves it
    (``config_from_args``), at the first worker count and no run directory."""
    workers = budget_workers(args.workers)
    ns = argparse.Namespace(**vars(args))
    ns.workers, ns.out = workers[0], getattr(args, "out", None) or "(budget)"
    return from_args(BudgetConfig, args, command="budget", protocol=config_from_args(ns))


def _pilot_curve(path: str, levels: dict[str, list[int]]):

    df = RunDir.open(path).episodes()
    df = df[df["status"] == "ok"]
    counts: dict[str, dict[int, tuple[int, int]]] = {}
    for axis, want in levels.items():
        for k in want:
            rows = df[(df["axis"] == axis) & (df["level"] == k)]
            if not len(rows):
                raise ConfigError(f"--pilot {path} has no finished episode of {axis} level {k}: pilot every level "
                                  "of the protocol, or use --assume")  # fmt: skip
            counts.setdefault(axis, {})[k] = (int(rows["success"].sum()), len(rows))
    return Curve(counts=counts)


def _costs(req: BudgetConfig, plan, horizon: int):
    """The per-unit costs (``wall_time.Costs``), the smoke's replan steps, and notes on what was assumed."""

    if req.steps_per_s is not None:
        fixed = DEFAULT_STARTUP_S if req.startup_s is None else req.startup_s
        return Costs(sim_s_per_step=1 / req.steps_per_s, reset_s=0.0, build_s=0.0, act_s={}, batched=True,
                     coord_s_per_reply=0.0, fixed_s=fixed, steps_per_episode=float(horizon), cores=10**6,
                     on_cpu_policy=False), None, [f"--steps-per-s {req.steps_per_s:g}: every episode runs its "
                     f"{horizon} steps, start-up {fixed:g} s; no act latency known, so no bound is named"]  # fmt: skip
    if not req.timing:
        return None, None, ["no --timing RUN or --steps-per-s: no wall time projected"]
    run = RunDir.open(req.timing)
    timing = run.manifest.get("timing")
    if not timing:
        raise ConfigError(f"--timing {req.timing}: its manifest has no timing; make the smoke run with this version "
                          "of indgen evaluate (local backend)")  # fmt: skip
    eps = run.episodes()
    ok = eps[(eps["status"] == "ok") & (eps["shared_from"] == "")]
    steps = float(ok["steps"].mean()) if len(ok) else float(horizon)
    notes = []
    smoke_h = (run.manifest.get("fingerprint") or {}).get("horizon")
    if smoke_h and smoke_h != horizon:
        steps *= horizon / smoke_h
        notes.append(
            f"the smoke ran {smoke_h}-step episodes, this protocol {horizon}: its steps per episode scaled"
        )
    for key, now in (("scene", req.protocol.plan.scene), ("policy", req.protocol.policy.spec)):
        if run.manifest.get(key) != now:
            notes.append(f"the smoke's {key} is {run.manifest.get(key)}, this protocol's {now}")
    costs = from_timing(timing, steps)
    if costs.box_load > 1.5:
        notes.append(f"the smoke ran with load {timing.get('load_avg_1m')} on {costs.cores} cores (other jobs): the "
                     f"interval is {costs.box_load ** 0.5:.1f}x wider; smoke an idle box for a firmer one")  # fmt: skip
    return costs, timing.get("replan_steps"), notes


def plan_budget(req: BudgetConfig, family: Scene) -> dict[str, Any]:
    """The budget of ``req``'s protocol on ``family`` (its scene, looked up by the API) as ``indgen budget --json``
    prints it (writes the lock when asked)."""
    cfg = req.protocol
    plan = build_plan(cfg, family)
    levels = {a: list(v) for a, v in plan.levels.items()}
    rollouts = plan.rollouts()
    cells = len({(j.task, j.axis, j.level) for j in rollouts})
    horizon = int(
        cfg.plan.max_steps or plan.record()["environment"].get("protocol", {}).get("max_steps") or 0
    )
    episodes, gamma, mode = cfg.plan.episodes, cfg.plan.gamma, cfg.adaptive.mode
    out: dict[str, Any] = {"protocol": {
        "scene": cfg.plan.scene, "policy": cfg.policy.spec, "tasks": len(plan.tasks), "axes": list(plan.axes),
        "levels": levels, "episodes_per_level": episodes, "rollouts_planned": len(rollouts), "cells": cells,
        "horizon": horizon, "adaptive": mode}}  # fmt: skip
    delta, alpha = cfg.adaptive.delta, cfg.adaptive.alpha
    fixed = fixed_design(gamma, delta, alpha, req.ci)
    miss = decided_rates(episodes, gamma, delta, req.ci)
    stable, fail_again = stable_episodes(fixed)
    out["episodes_fixed"] = {**fixed.as_dict(), "stable_per_level": stable, "fail_again": fail_again,
                             "protocol": fixed.episodes * cells if fixed.episodes else None,
                             "at_episodes": {"episodes": episodes, "miss_intact": miss[0], "miss_broken": miss[1]}}  # fmt: skip
    curve = None
    if req.assume is not None:
        curve = assumed_curve(req.assume, list(plan.axes), levels)
    elif req.pilot:
        curve = _pilot_curve(req.pilot, levels)
    p0 = req.assume[0] if req.assume else (_pooled_t0(curve) if curve else 0.9)
    tested = max(1, max(len([k for k in v if k]) for v in levels.values()))
    a_level = ALPHA / tested
    out["power"] = {"t0_rate": p0, "drop": req.drop, "alpha": ALPHA, "alpha_per_level": a_level,
                    "test": f"exact McNemar, paired on seeds, at α/{tested} (Holm's first step over {tested} levels)",
                    **{m: {"at_episodes": paired_power(p0, max(0.0, p0 - req.drop), episodes, a_level, m),
                           "pairs_for_80": pairs_for_power(p0, max(0.0, p0 - req.drop), a_level, POWER, m)}
                       for m in ("independent", "nested", "most-discordant")}}  # fmt: skip
    if not mode and not curve:
        out["episodes_adaptive"] = None
    elif curve is None:
        raise ConfigError("--adaptive needs a success curve to size: --assume 0.95,0.9,0.5,0.1 (per |level|) or "
                          "--pilot RUN")  # fmt: skip
    else:
        sized = mode or "kstar"
        rule = cfg.sequential_rule() if mode else make_rule(sized, gamma, delta, alpha, cfg.adaptive.round_size,
                                                            episodes)  # fmt: skip
        first = plan.tasks[0]
        owners = {a: plan.shared.get((first, a), a) for a in plan.axes}
        cost = simulate_protocol(
            rule, sized, len(plan.tasks), levels, curve, owners, len(rollouts), req.replicates
        )
        out["episodes_adaptive"] = {**cost.summary(), "mode": sized, "as_configured": bool(mode),
                                    "curve": "pilot " + req.pilot if req.pilot else f"assumed {list(req.assume)}"}  # fmt: skip
    costs, smoke_replan, notes = _costs(req, plan, horizon)
    out["notes"] = notes
    out["workers"] = {}
    if costs is not None:
        replan = cfg.policy.replan_steps or smoke_replan or 1
        rounds = [[len(rollouts)]] * 3
        if mode:
            rounds = _percentile_rounds(cost)
        gpus = req.gpus if req.gpus is not None else (1 if cfg.policy.device.startswith("cuda") else 0)
        for w in req.workers:
            pr = project(costs, w, replan, cells, rounds[1], rounds[0], rounds[2])
            out["workers"][str(w)] = pr.as_dict(gpus)
        out["gpus"] = gpus
        out["projected_from"] = "steps_per_s" if req.steps_per_s is not None else "timing"
    if (
        cfg.plan.preregistered
    ):  # budget a locked protocol: the same check evaluate makes, one line on a deviation
        out["preregistered"] = check_preregistered(cfg, plan, package_versions())["hash"]
    if req.write:
        out["lock"] = _write_lock(req, plan, out)
    return out


def _pooled_t0(curve) -> float:
    rates = [by[0] for by in (curve.rates or {}).values() if 0 in by]
    counts = [by[0] for by in (curve.counts or {}).values() if 0 in by]
    if rates:
        return sum(rates) / len(rates)
    s, n = sum(c[0] for c in counts), sum(c[1] for c in counts)
    return s / n if n else 0.9


def _percentile_rounds(cost) -> list[list[int]]:
    """The simulated protocols at the 5th percentile, the mean and the 95th percentile of total rollouts."""
    totals = np.asarray(cost.totals)
    picks = [float(np.percentile(totals, 5)), float(totals.mean()), float(np.percentile(totals, 95))]
    return [list(cost.rounds[int(np.argmin(np.abs(totals - t)))]) for t in picks]


def _write_lock(req: BudgetConfig, plan, out: dict) -> dict:
    cfg = req.protocol
    analysis = {"gamma": cfg.plan.gamma, "ci": req.ci, "alpha": ALPHA,
                "test": "exact McNemar vs T0, Holm over levels", "delta": cfg.adaptive.delta,
                "error_rate": cfg.adaptive.alpha}  # fmt: skip
    budget = {"rollouts_planned": out["protocol"]["rollouts_planned"],
              "episodes_adaptive_expected": (out.get("episodes_adaptive") or {}).get("expected"),
              "wall_s": {w: v["wall_s"] for w, v in out["workers"].items()}}  # fmt: skip
    fingerprint = pre_policy_fingerprint(cfg, plan, package_versions())
    lock = make_lock(manifest_plan(cfg, plan), plan.jobs_hash(), fingerprint, analysis, budget)
    path = Path(req.write)
    if path.parent and not path.parent.exists():
        raise ConfigError(f"--write {path}: folder {path.parent} does not exist")
    atomic_write_json(path, lock)
    return {"path": str(path), "hash": lock["hash"]}


def _fmt_s(s: float) -> str:
    return f"{s / 3600:.2f} h" if s >= 5400 else f"{s / 60:.1f} min" if s >= 120 else f"{s:.0f} s"


def _coverage() -> str:
    """The interval's measured coverage on held-out runs, as it is printed beside the interval."""
    h = HELDOUT
    lo, hi = wilson_ci(h["covered"], h["runs"])  # 16 of 16 is a rate of 16 runs: its interval says how firm
    return (f"such intervals covered {h['covered']} of {h['runs']} held-out runs (Wilson 95 % CI {100 * lo:.0f}-"
            f"{100 * hi:.0f} %), {h['covered_unwidened']} unwidened by load: {h['where']}")  # fmt: skip


def render(out: dict) -> list[str]:
    """The terminal text of a budget."""
    p, f = out["protocol"], out["episodes_fixed"]
    lines = [f"protocol: {p['scene']}, {p['tasks']} task(s) × {len(p['axes'])} axes ({', '.join(p['axes'])}), "
             f"{p['cells']} level cells rolled out, {p['episodes_per_level']} episodes a level "
             f"({p['rollouts_planned']} rollouts; adaptive: {p['adaptive'] or 'off'}); policy {p['policy']}"]  # fmt: skip
    at = f["at_episodes"]
    stable = ""
    if f.get("stable_per_level") and f["stable_per_level"] != f["per_level"]:
        stable = (f" (the first n that does; {len(f['fail_again'])} n above it fail again, every n from "
                  f"{f['stable_per_level']} through {int(1.5 * f['per_level']) + 1} passes)")  # fmt: skip
    lines.append(
        f"fixed design: {f['per_level'] or 'more than 5000'} episodes a level{stable} decide each level at γ = "
        f"{f['gamma']:g} ± δ = {f['delta']:g} with error ≤ {f['alpha']:g} ({f['ci']}; {f['protocol']} rollouts for "
        f"the protocol); with this protocol's {at['episodes']} a level, a level at S = {f['gamma'] + f['delta']:g} is "
        f"not called intact with chance {at['miss_intact']:.1%}, one at {f['gamma'] - f['delta']:g} not called broken "
        f"{at['miss_broken']:.1%}"
    )
    pw = out["power"]
    lines.append(
        f"power vs T0 ({pw['test']}): a drop of {pw['drop']:g} from T0 = {pw['t0_rate']:g} with {at['episodes']} "
        f"pairs: {pw['most-discordant']['at_episodes']:.0%} (most discordant pairs) / "
        f"{pw['independent']['at_episodes']:.0%} (independent outcomes) / {pw['nested']['at_episodes']:.0%} (nested, "
        f"fewest discordant); {POWER:.0%} power needs {pw['most-discordant']['pairs_for_80']} / "
        f"{pw['independent']['pairs_for_80']} / {pw['nested']['pairs_for_80']} pairs"
    )
    ad = out.get("episodes_adaptive")
    if ad:
        how = "" if ad["as_configured"] else " (if run with --adaptive kstar)"
        lines.append(
            f"adaptive {ad['mode']}{how}: expected {ad['expected']:.0f} rollouts (5-95 %: {ad['p5']:.0f}-"
            f"{ad['p95']:.0f}; {ad['share_of_fixed']:.0%} of {p['rollouts_planned']}), {ad['rounds_expected']:.1f} "
            f"rounds; {ad['replicates']} protocols drawn from simulated tasks, curve {ad['curve']}"
        )
    # the held-out coverage was measured on projections from smoke runs, not from a rate given by hand
    coverage = (
        _coverage() if out.get("projected_from") == "timing" else "coverage not measured for --steps-per-s"
    )
    for w, v in out["workers"].items():
        ws, gh = v["wall_s"], v["gpu_hours"]
        gpu = (
            f", GPU-hours {gh['low']:.2f}-{gh['high']:.2f} (expected {gh['expected']:.2f})"
            if out.get("gpus")
            else ""
        )
        lines.append(f"--workers {w}: wall {_fmt_s(ws['expected'])} (interval {_fmt_s(ws['low'])}-"
                     f"{_fmt_s(ws['high'])}, the whole evaluate command; {coverage}){gpu}; bound: {v['bound']}; "
                     f"{v['steps_per_s']:.0f} steps/s in rounds; act {v['act']}")  # fmt: skip
    lines += [f"note: {n}" for n in out.get("notes", [])]
    if out.get("lock"):
        lines.append(f"wrote {out['lock']['path']} (hash {out['lock']['hash'][:12]}): run it with "
                     f"indgen evaluate ... --preregistered {out['lock']['path']}")  # fmt: skip
    return lines
