"""Benchmark: what runs after or between episodes (report, overlay, compare, the resume scan, the adaptive decision
step) on run directories of the paper's protocol size and beyond.

Usage: python scripts/bench_report_scale.py [--tasks 1,10,30,100] [--keep DIR] [--json out.json]
       python scripts/bench_report_scale.py build --tasks 10 --out DIR [--shift 0.4] [--adaptive kstar]
       python scripts/bench_report_scale.py resume --tasks 10 --out DIR   # `indgen evaluate` on a finished run

A run has the LIBERO-Object protocol's shape: T tasks × pick_y, goal_y, scale × levels −3..3 × 50 episodes
(T = 10: the paper's 10,500 episodes). Its manifest is the engine's own (``build_plan``, ``build_manifest``, the
protocol fingerprint of ``standin:random --max-steps 1`` on pick_place); tasks beyond pick_place's seven repeat
its tasks under new names (``milk_1``...) with their cells, since the rows, not the scene, are being measured.
Its rows are written by ``RunDir``; each episode's outcome comes from a per-task logistic curve in |k| with
common random numbers per (task, episode, level), so run B (``--shift``) pairs with run A episode by episode like
two checkpoints evaluated with the same seeds; 1 % of the episodes are error rows, failures carry a failure mode
and a progress score consistent with it. Its Parquet schema and manifest keys are those of a real
``indgen evaluate --policy standin:random --config pick_place_libero_object_style --task all --max-steps 1`` run
(checked when this script was written, docs/results/benchmarks/report_scale.md); tests/scripts/test_bench_report_scale.py checks that
report, compare and a resume read it as a real run.

Each command runs in its own process under ``/usr/bin/time -v`` (wall time, peak RSS): ``report A``, ``report A B``
(overlay), ``compare A B`` (paired, exact McNemar), ``compare --a A --b B``, and the resume scan (``evaluate`` with
the run's own flags on the finished run: nothing to run, then the report; the only change is that the plan's
extra tasks come from ``build``'s extension, see ``resume``). The adaptive decision step is timed in-process:
``next_round`` (what ``run_adaptive`` calls between rounds) once on the finished fixed-design records, and over a
whole synthetic ``--adaptive kstar`` run driven by ``engine.adaptive.run_adaptive`` (decisions + reading episodes,
summed over rounds). The last line is JSON.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
# the in-process parts (build, the decisions) time this checkout, like the commands it runs
sys.path.insert(0, str(ROOT))
SCENE, POLICY = "pick_place", "standin:random"
AXES, LEVELS, EPISODES = ("pick_y", "goal_y", "scale"), "-3:3", 50  # the LIBERO-Object protocol's shape
ERROR_RATE = 0.01
MODES = ("no_contact", "no_grasp", "dropped", "misplaced", "timeout_holding")
MODE_PROGRESS = {"no_contact": (0, 0), "no_grasp": (1, 2), "dropped": (3, 3), "misplaced": (4, 4),
                 "timeout_holding": (3, 3)}  # fmt: skip


def eval_args(tasks: int, out: str, adaptive: str | None = None, episodes: int = EPISODES) -> list[str]:
    """The ``indgen evaluate`` flags of a run of ``tasks`` tasks (its plan is the one ``build`` writes)."""
    args = ["evaluate", "--policy", POLICY, "--scene", SCENE, "--task", "all" if tasks > 1 else "milk",
            "--axis", ",".join(AXES), "--levels", LEVELS, "--episodes", str(episodes), "--max-steps", "1",
            "--allow-infeasible", "--workers", "1", "--out", out]  # fmt: skip
    return args + (["--adaptive", adaptive] if adaptive else [])


def _config(tasks: int, out: str, adaptive: str | None = None, episodes: int = EPISODES):
    from indgen_vla.app.cli import build_parser
    from indgen_vla.app.engine.config import config_from_args

    return config_from_args(build_parser().parse_args(eval_args(tasks, out, adaptive, episodes)))


def patch_tasks(tasks: int) -> None:
    """Make the plan resolve ``tasks`` tasks: pick_place's seven, then renamed copies with their cells (patched
    where the engine calls the scene layer: ``engine.run`` imports ``resolve_scene_plan`` at its top)."""
    from indgen_vla.app.engine import run

    original = run.resolve_scene_plan

    def resolve(*a, **k):
        sp = original(*a, **k)
        if tasks <= len(sp.tasks):
            return sp
        base = {(f"{t}_{i // len(sp.tasks)}" if i >= len(sp.tasks) else t): t
                for i, t in ((i, sp.tasks[i % len(sp.tasks)]) for i in range(tasks))}  # fmt: skip
        cells = tuple(
            dataclasses.replace(c, task=n) for n, t in base.items() for c in sp.cells if c.task == t
        )
        return dataclasses.replace(sp, tasks=tuple(base), cells=cells)

    run.resolve_scene_plan = resolve


def synthetic_records(jobs, meta: dict, shift: float, world: int = 0, error_rate: float = ERROR_RATE):
    """EpisodeRecords for ``jobs``: the outcome model of the module docstring (vectorised; ``shift`` moves run
    B's curves on the logit scale; ``world`` fixes the curves and the common random numbers)."""
    from indgen_vla.core.runs.records import EpisodeRecord

    tasks = sorted({j.task for j in jobs})
    axes = sorted({j.axis for j in jobs})
    rng = np.random.default_rng(world)
    a = rng.uniform(1.0, 3.5, (len(tasks), len(axes)))  # logit at level 0
    b = rng.uniform(0.4, 1.6, (len(tasks), len(axes)))  # fall per level
    ti = np.array([tasks.index(j.task) for j in jobs])
    ai = np.array([axes.index(j.axis) for j in jobs])
    k = np.array([abs(j.level) for j in jobs], float)
    p = 1 / (1 + np.exp(-(a[ti, ai] - b[ti, ai] * k + shift)))
    crn = np.array([(j.seed * 1_000_003 + 7 * j.level + 3) % 2**32 for j in jobs], dtype=np.uint64)
    u = _uniform(crn)  # the same draw for the same episode in runs A and B: paired like common seeds
    own = np.random.default_rng([world, int(shift * 1000) & 0xFFFF])
    success = u < p
    error = own.random(len(jobs)) < error_rate
    mode = own.integers(0, len(MODES), len(jobs))
    pick = own.random(len(jobs))
    out = []
    for i, j in enumerate(jobs):
        ok = not error[i]
        if not ok:
            fail, prog, steps = "error", None, int(own.integers(1, 280))
        elif success[i]:
            fail, prog, steps = "none", 5, int(80 + 200 * u[i])
        else:
            fail = MODES[mode[i]]
            lo, hi = MODE_PROGRESS[fail]
            prog, steps = lo if pick[i] < 0.5 else hi, 280
        out.append(EpisodeRecord(
            run_id=meta["run_id"], policy=meta["policy"], data_regime=meta["data_regime"], scene=meta["scene"],
            task=j.task, axis=j.axis, level=j.level, param=j.param, episode=j.episode, seed=j.seed,
            success=bool(success[i]) and ok, steps=steps, status="ok" if ok else "error",
            error="" if ok else "RuntimeError: simulator diverged (synthetic)", wall_s=round(0.5 + u[i], 3),
            video="", failure=fail, progress=prog,
        ))  # fmt: skip
    return out


def _uniform(x: np.ndarray) -> np.ndarray:
    """A uniform draw per integer key (splitmix64), so each episode's draw depends on its key only."""
    z = (x + np.uint64(0x9E3779B97F4A7C15)) & np.uint64(2**64 - 1)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) / 2.0**53


def build(
    tasks: int,
    out: str,
    shift: float = 0.0,
    adaptive: str | None = None,
    error_rate: float = ERROR_RATE,
    episodes: int = EPISODES,
) -> dict:
    """Write a complete run directory (every planned episode; with ``adaptive``, what its rule runs); with
    ``error_rate`` 0 every episode is ok, so a resume finds nothing to run."""
    from indgen_vla.app.api import family_of
    from indgen_vla.app.engine.policy_source import runner_config as _runner_config
    from indgen_vla.app.engine.run import _fingerprint, build_manifest, build_plan
    from indgen_vla.core.runs.records import RunDir
    from policy_wrappers.specs import load_policy

    patch_tasks(tasks)
    cfg = _config(tasks, out, adaptive, episodes)
    plan = build_plan(cfg, family_of(cfg.plan))
    run_id = f"bench{tasks:03d}{'b' if shift else 'a'}{'ad' if adaptive else ''}"
    manifest = build_manifest(cfg, plan, run_id)
    manifest["created"] = "2026-11-25T00:00:00+00:00"  # equal builds, equal manifests
    manifest["command"] = "indgen " + " ".join(eval_args(tasks, out, adaptive, episodes))
    policy = load_policy(POLICY, scene=SCENE, env_spec=getattr(plan.builder, "env_spec", None))
    fingerprint = _fingerprint(
        cfg, plan, manifest["resolved"], _runner_config(cfg, plan, policy.spec), policy
    )
    run = RunDir.create_or_resume(out, manifest)
    run.update_manifest(fingerprint=fingerprint)
    meta = {k: manifest[k] for k in ("run_id", "policy", "data_regime", "scene")}
    timing = {"rows": 0, "decide_s": 0.0, "read_s": 0.0, "rounds": 0}
    if not adaptive:
        run.rewrite(synthetic_records(plan.jobs, meta, shift, error_rate=error_rate))
        timing["rows"] = len(plan.jobs)
        return timing
    from indgen_vla.app.engine.adaptive import run_adaptive

    def read():
        t0 = time.perf_counter()
        e = run.episodes()
        timing["read_s"] += time.perf_counter() - t0
        return e

    from indgen_vla.app.engine.share import copies, taken_keys

    taken = taken_keys(plan, run)

    def run_jobs(batch):
        t0 = time.perf_counter()
        recs = synthetic_records(batch, meta, shift, error_rate=error_rate)
        run.append(
            [c for r in recs for c in (r, *copies(plan, r, taken))]
        )  # shared T0: as evaluate records it
        timing["rounds"] += 1
        timing["write_s"] = timing.get("write_s", 0.0) + time.perf_counter() - t0

    t0 = time.perf_counter()
    run_adaptive(plan, read, run_jobs, cfg)
    run.flush()
    timing["decide_s"] = time.perf_counter() - t0 - timing["read_s"] - timing["write_s"]
    timing["rows"] = len(run.episodes())
    return timing


def decide_once(tasks: int, run_dir: str) -> float:
    """Seconds of one ``next_round`` (the adaptive decision over every ladder) on a finished fixed-design run."""
    from indgen_vla.app.engine.adaptive import next_round
    from indgen_vla.app.engine.run import build_plan
    from indgen_vla.core.runs.records import RunDir
    from scenes.family import get_scene

    patch_tasks(tasks)
    cfg = _config(tasks, run_dir, "kstar")
    plan, episodes = build_plan(cfg, get_scene(cfg.plan.scene)), RunDir.open(run_dir).episodes()
    t0 = time.perf_counter()
    next_round(plan, episodes, cfg)
    return time.perf_counter() - t0


def timed(cmd: list[str], cwd: Path) -> dict:
    """Wall seconds and peak RSS (MiB) of one command under /usr/bin/time -v."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MUJOCO_GL": "egl", "HF_HUB_OFFLINE": "1"}
    t0 = time.perf_counter()
    r = subprocess.run(["/usr/bin/time", "-v", *cmd], cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stdout[-2000:]}\n{r.stderr[-3000:]}")
    rss = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", r.stderr).group(1))
    return {"wall_s": round(wall, 2), "peak_rss_mib": round(rss / 1024)}


def bench(sizes: list[int], root: Path) -> list[dict]:
    py, me, cli = sys.executable, str(Path(__file__).resolve()), [sys.executable, "-m", "indgen_vla.app.cli"]
    rows = []
    for t in sizes:
        d = root / f"t{t}"
        a, b, full, ad = d / "a", d / "b", d / "complete", d / "adaptive"
        for run, extra in ((a, []), (b, ["--shift", "0.4"]), (full, ["--error-rate", "0"])):
            if not (run / "episodes.parquet").exists():
                subprocess.run([py, me, "build", "--tasks", str(t), "--out", str(run), *extra], check=True,
                               env={**os.environ, "PYTHONPATH": str(ROOT)})  # fmt: skip
        row: dict = {"tasks": t, "rows": t * len(AXES) * 7 * EPISODES, "n_per_cell": EPISODES,
                     "cells": t * len(AXES) * 7}  # fmt: skip
        row["report"] = timed([*cli, "report", str(a)], ROOT)
        row["report_overlay"] = timed([*cli, "report", str(a), str(b), "--out", str(d / "overlay")], ROOT)
        row["compare"] = timed([*cli, "compare", str(a), str(b), "--out", str(d / "compare")], ROOT)
        row["compare_groups"] = timed(
            [*cli, "compare", "--a", str(a), "--b", str(b), "--out", str(d / "cg")], ROOT
        )
        row["resume_scan"] = timed([py, me, "resume", "--tasks", str(t), "--out", str(full)], ROOT)
        row["decide_full_s"] = round(decide_once(t, str(a)), 3)
        if ad.exists():
            import shutil

            shutil.rmtree(ad)
        adapt = build(t, str(ad), 0.0, "kstar")
        row["adaptive"] = {k: round(v, 3) if isinstance(v, float) else v for k, v in adapt.items()}
        row["report_adaptive"] = timed([*cli, "report", str(ad)], ROOT)
        print(json.dumps(row), flush=True)
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd")
    pb = sub.add_parser("build", help="write one run directory")
    pr = sub.add_parser(
        "resume", help="the resume scan: `indgen evaluate` with the run's flags on a finished run"
    )
    for q in (pb, pr):
        q.add_argument("--tasks", type=int, required=True)
        q.add_argument("--out", required=True)
        q.add_argument("--episodes", type=int, default=EPISODES, help="episodes per level and task")
    pb.add_argument("--shift", type=float, default=0.0)
    pb.add_argument("--adaptive", choices=("kstar", "curve"), default=None)
    pb.add_argument(
        "--error-rate", type=float, default=ERROR_RATE, help="share of error rows (0: a complete run)"
    )
    p.add_argument("--tasks", default="1,10,30,100", help="sizes: tasks per run (× 3 axes × 7 levels × 50)")
    p.add_argument("--keep", default=None, help="build the run directories here (reused when present)")
    p.add_argument("--json", default=None)
    a = p.parse_args(argv)
    if a.cmd == "build":
        print(json.dumps(build(a.tasks, a.out, a.shift, a.adaptive, a.error_rate, a.episodes)))
        return
    if a.cmd == "resume":
        patch_tasks(a.tasks)
        from indgen_vla.app.cli import main as cli_main

        raise SystemExit(cli_main(eval_args(a.tasks, a.out, episodes=a.episodes)))
    sizes = [int(x) for x in a.tasks.split(",")]
    t0, load_start = time.perf_counter(), os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(a.keep or tmp)
        rows = bench(sizes, root)
    res = {"machine": f"{platform.machine()} {os.cpu_count()} cores", "load_avg_start": load_start,
           "load_avg_end": os.getloadavg(), "sizes": rows, "wall_s": round(time.perf_counter() - t0, 1)}  # fmt: skip
    if a.json:
        Path(a.json).write_text(json.dumps(res, indent=1) + "\n")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
